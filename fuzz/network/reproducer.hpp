#pragma once
// A finding of the network fuzzer as a file anyone can run again: the exact bytes sent (each request in
// the pieces and with the pauses it was written in), the rule broken, and the command that replays it.
// `mbscope replay --target URI FILE` sends the steps to a target and judges them with the same oracle; the
// fuzzer uses the same replay to shorten a reproducer before saving it.

#include <chrono>
#include <cstdint>
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
    std::size_t original_steps = 0;
    std::vector<Step> steps;
};

nlohmann::json to_json(const Reproducer& r);
modbus::Result<Reproducer, std::string> reproducer_from_json(const nlohmann::json& j);
modbus::Result<Reproducer, std::string> load_reproducer(const std::string& path);
// Writes FILE atomically; returns an error naming it.
modbus::Result<void, std::string> save_reproducer(const Reproducer& r, const std::string& path);

struct ReplayedStep {
    modbus::transport::Exchange exchange;
    std::vector<conformance::OracleViolation> violations;
};

struct ReplayOptions {
    std::chrono::milliseconds timeout{1000};
    std::chrono::microseconds silence_wait{1'000'000};
};

// Sends one step (its parts with their pauses) and judges the exchange: the oracle's rules, and for a
// request voided by a gap on a serial line, silence (silence.gap_inside_request, SL §2.5.1.1). A request the
// rules want unanswered is waited for `silence_wait`, any other for `timeout`.
ReplayedStep send_step(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                       const Step& step, const ReplayOptions& options);

// Bytes that arrived after `previous` ended (nothing is waited for), judged as its reply: the violations
// a late reply shows (a reply to a broadcast after the silence wait, a frame with a bad checksum).
std::vector<conformance::OracleViolation> late_reply(modbus::transport::Client& client,
                                                     conformance::ExchangeOracle& oracle,
                                                     const modbus::transport::Exchange& previous);

// `bytes` that came after `previous` ended, judged as its reply (what late_reply does with what it drains).
std::vector<conformance::OracleViolation> late_bytes(conformance::ExchangeOracle& oracle,
                                                     modbus::Framing framing,
                                                     const modbus::transport::Exchange& previous,
                                                     std::vector<std::uint8_t> bytes);

// A whole frame that came after `request` was given up, judged as its reply; every observation begins with
// `when` ("during the next request: ").
std::vector<conformance::OracleViolation> judge_late_frame(conformance::ExchangeOracle& oracle,
                                                           const modbus::transport::Exchange& request,
                                                           const modbus::Frame& reply, std::string_view when);

// A Modbus/TCP reply to `previous` that came while `current` waited for its own (the client sets it aside
// in current.stale_replies, not taking it for current's): judged as `previous`'s, as late_reply judges
// bytes that came between the two. Nothing when `previous` was answered or no such frame came.
std::vector<conformance::OracleViolation> stale_reply(conformance::ExchangeOracle& oracle,
                                                      const modbus::transport::Exchange& previous,
                                                      const modbus::transport::Exchange& current);

// Sends every step over `client` and judges each exchange with `oracle`. Besides the oracle's rules: a
// reply to a request voided by a gap (silence.gap_inside_request), and replies that came after their
// request was given up (late_reply, judged when the next step begins and at the end).
std::vector<ReplayedStep> replay(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                                 const std::vector<Step>& steps, const ReplayOptions& options);

// Whether a replay broke `rule` (at any step).
bool breaks(const std::vector<ReplayedStep>& replayed, const std::string& rule);

}  // namespace mbscope::fuzz::network
