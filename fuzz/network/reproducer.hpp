#pragma once
// A finding of the network fuzzer as a file anyone can run again: the exact bytes sent (each request in
// the pieces and with the pauses it was written in), the rule broken, and the command that replays it.
// `mbscope replay --target URI FILE` sends the steps to a target and judges them with the same oracle; the
// fuzzer uses the same replay to shorten a reproducer before saving it.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "conformance/oracle.hpp"
#include "modbus/profile.hpp"
#include "modbus/result.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::fuzz::network {

struct Step {
    std::vector<std::vector<std::uint8_t>> parts;  // written in this order
    std::chrono::microseconds pause{0};            // between parts
    bool reconnect_after = false;                  // a stream left out of step (MBAP length probes)
    bool void_by_gap = false;                      // a pause inside it beyond t1.5 on a serial line
    std::string recipe;
    std::vector<std::uint8_t> joined() const;
};

struct Reproducer {
    std::string rule, source, expected, observed;
    std::string target, profile;
    std::uint8_t unit = 1;
    std::string framing;  // "rtu", "ascii", "tcp"
    std::uint64_t seed = 0;
    std::uint64_t request = 0;  // index of the request that showed it in the campaign
    bool minimised = false;     // shortened and shown to break the rule again when replayed
    // Whether the steps broke the rule again sent on a connection opened for them, as `mbscope replay` sends
    // them: the minimisation replays on the campaign's own connection, and a rule broken there may depend
    // on that connection's history or timing. nullopt: not tried (a serial line, or not reproduced).
    std::optional<bool> replays_on_new_connection;
    // timing.slow_reply: the limit the replies broke, which a replay judges every reply by (0: none).
    std::uint32_t slow_ms = 0;
    std::size_t original_steps = 0;
    std::vector<Step> steps;
};

// What a reproducer may hold. The campaign saves at most 32 steps of two or three pieces; a file from
// elsewhere is refused past these, by name, instead of being parsed into memory it has no use for.
inline constexpr std::size_t max_reproducer_steps = 10'000;
inline constexpr std::size_t max_step_parts = 256;
inline constexpr std::uintmax_t max_reproducer_size = std::uintmax_t{4} << 20;

nlohmann::json to_json(const Reproducer& r);
modbus::Result<Reproducer, std::string> reproducer_from_json(const nlohmann::json& j);
modbus::Result<Reproducer, std::string> load_reproducer(const std::string& path);
// Writes FILE atomically; returns an error naming it.
modbus::Result<void, std::string> save_reproducer(const Reproducer& r, const std::string& path);

struct ReplayedStep {
    modbus::transport::Exchange exchange;
    // ReplayOptions::stop came during a pause between the step's pieces: the rest was not sent, and the
    // exchange holds nothing to judge.
    bool interrupted = false;
    std::vector<conformance::OracleViolation> violations;
    // The rules want a reply (not silence: a bad checksum, a broadcast, another unit, a request voided by a
    // gap; nor no opinion).
    bool reply_due = false;
    // Replies that came after the step was given up, during a later step or after the last (replay() judges
    // them as this step's): a write acknowledged late changed its points all the same.
    std::vector<modbus::Frame> late_replies;
};

struct ReplayOptions {
    std::chrono::milliseconds timeout{1000};
    std::chrono::microseconds silence_wait{1'000'000};
    // A reply later than this breaks timing.slow_reply (`slow_source` its source); 0: not judged.
    std::chrono::milliseconds slow{0};
    std::string slow_source;
    // Once set, no further step is sent, nor the rest of a step paused between its pieces; the replies still
    // due are awaited and judged as usual.
    const std::atomic<bool>* stop = nullptr;
};

// Sends one step (its parts with their pauses) and judges the exchange: the oracle's rules, and for a
// request voided by a gap on a serial line, silence (silence.gap_inside_request, SL §2.5.1.1). A request the
// rules want unanswered is waited for `silence_wait`, any other for `timeout`. `owed`: RTU and ASCII, the
// earlier requests given up whose late replies are set aside (exchange.stale_replies), not taken for this
// step's.
ReplayedStep send_step(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                       const Step& step, const ReplayOptions& options,
                       std::span<const modbus::transport::OwedRequest> owed = {});

// RTU and ASCII: listens (nothing is written) until every owed request due a reply (OwedRequest::reply_due)
// has had it, or `until`. Each reply heard settles its request (appended to `settled`); returns the bytes
// heard that no owed request accounts for.
std::vector<std::uint8_t> await_owed(modbus::transport::Client& client, modbus::transport::OwedRequests& owed,
                                     std::chrono::steady_clock::time_point until,
                                     std::vector<modbus::transport::SettledRequest>& settled);

// RTU and ASCII: the step's bytes as the request a late reply may answer (whatever their checksum: a device
// that skips the check answers them); none over Modbus/TCP (transaction ids say it), for bytes that are no
// request, and for a request voided by a gap (the device must not answer it at all).
std::optional<modbus::Frame> step_request(modbus::Framing framing, const Step& step);

// `bytes` that came after `previous` ended (found before the next request went out), judged as its reply:
// the violations a late reply shows (a reply to a broadcast after the silence wait, a frame with a bad
// checksum).
std::vector<conformance::OracleViolation> late_bytes(conformance::ExchangeOracle& oracle,
                                                     modbus::Framing framing,
                                                     const modbus::transport::Exchange& previous,
                                                     std::vector<std::uint8_t> bytes);

// A whole frame that came after `request` was given up, judged as its reply; every observation begins with
// `when` ("during the next request: ").
std::vector<conformance::OracleViolation> judge_late_frame(conformance::ExchangeOracle& oracle,
                                                           const modbus::transport::Exchange& request,
                                                           const modbus::Frame& reply, std::string_view when);

// `later`, bytes that came after `previous` was answered, when they begin with its reply again: the request
// answered twice (reply.duplicate; SL §2.1, MK-MS-01: exactly one reply). `when` begins the observation.
std::vector<conformance::OracleViolation> repeated_reply(const modbus::transport::Exchange& previous,
                                                         std::span<const std::uint8_t> later,
                                                         std::string_view when);

// Whether no whole reply with a good checksum came for `ex`: its reply may still come.
bool reply_may_come(const modbus::transport::Exchange& ex);

// Sends every step over `client` and judges each exchange with `oracle`. Besides the oracle's rules: a
// reply to a request voided by a gap (silence.gap_inside_request), and replies that came after their
// request was given up, judged as the reply of the step it answers: over Modbus/TCP the step whose
// transaction id it carries (unanswered.hpp), over RTU and ASCII the earlier step given up that it could
// answer (exchange.hpp); what answers none is judged as the last step's (late_bytes) when that step is
// unanswered, and when it was answered only for being its reply again (repeated_reply). At the end the
// replies still due are waited for, up to a timeout.
std::vector<ReplayedStep> replay(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                                 const std::vector<Step>& steps, const ReplayOptions& options);

// Whether a replay broke `rule` (at any step).
bool breaks(const std::vector<ReplayedStep>& replayed, const std::string& rule);

}  // namespace mbscope::fuzz::network
