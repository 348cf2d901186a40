#pragma once
// `mbscope fuzz`: a fuzzing campaign against any slave over any transport. Each probe (generator.hpp) is
// sent, and its exchange judged by the exchange oracle `mbscope check` and the in-process slave target
// share (conformance/oracle.hpp). Besides the oracle's rules the campaign watches what only a live target
// shows: a hung or crashed target (no reply to a known-good health-check request after a failure, a
// connection that cannot be made again), a slow one (replies later than --slow, confirmed by a second
// slow health check), replies that arrive after their request was given up, and a request voided by a
// silence inside it on a serial line that is answered anyway.
//
// A finding is confirmed before it is kept (a missing reply must be missing twice), saved once per rule and
// function code as a reproducer (reproducer.hpp: the bytes sent since the last known-good state, shortened
// to the fewest steps that still break the rule) and counted after that. Every point written is read first
// and written back at the end, as the conformance runner does; --read-only sends nothing that writes.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "conformance/session.hpp"
#include "fuzz/network/reproducer.hpp"
#include "fuzz/network/written_points.hpp"
#include "modbus/profile.hpp"
#include "modbus/transport/endpoint.hpp"

namespace mbscope::fuzz::network {

struct CampaignOptions {
    modbus::transport::Endpoint endpoint;
    std::string target;  // the URI as given, for reproducers' commands
    std::uint8_t unit = 1;
    bool read_only = false;
    std::uint64_t seed = 1;
    std::optional<std::uint64_t> requests;              // stop after this many probes
    std::optional<std::chrono::milliseconds> duration;  // stop after this long
    std::chrono::milliseconds timeout{1000};            // wait for a reply that is due
    // Wait where the rules demand silence; unset: none over Modbus/TCP (a reply that comes anyway is matched
    // to its request by transaction id: unanswered.hpp), else learnt from the target's replies
    // (reply_latency.hpp), `timeout` until the first reply. Replays while minimising use the learnt wait.
    std::optional<std::chrono::milliseconds> silence_wait;
    std::chrono::milliseconds slow{0};      // slower replies are findings (0: from the profile, else 250)
    std::chrono::milliseconds interval{0};  // between requests (the manual's polling interval)
    std::string artifacts;                  // directory for reproducers; empty: none written
    std::size_t minimise_budget = 64;       // replays spent shortening one reproducer
    std::size_t max_findings = 0;           // stop once this many are saved (0: run the whole budget)
    std::function<void(const struct CampaignSummary&)> progress;  // called about four times a second
    const std::atomic<bool>* stop = nullptr;
    // Set by a second interrupt while stopping: the read-back of points written by writes that drew no reply
    // ends (they are listed unread); the restore after it does not. After a run that ended by its budget,
    // `stop` ends the read-back.
    const std::atomic<bool>* stop_again = nullptr;
    // Said, when given, before the read-back (what it will read and at what pace) and, at a polling interval,
    // before the restore: for a person at a terminal, as at a manual's interval either can take minutes.
    std::function<void(const std::string&)> note;
};

struct CampaignFinding {
    std::string rule;  // an oracle rule, or target.unresponsive, timing.slow_reply, ...
    std::string source;
    std::string expected;
    std::string observed;
    std::uint8_t function = 0;  // of the request that showed it
    std::uint64_t first_request = 0;
    std::uint64_t count = 0;
    Reproducer reproducer;
    std::string file;        // where the reproducer was saved; empty when none was
    std::string file_error;  // why it could not be saved in --artifacts (then `file` is empty)
};

struct CampaignSummary {
    bool reachable = false;
    std::string error;  // why the target could not be reached
    std::uint64_t requests = 0;
    std::uint64_t replies = 0, exceptions = 0, silences = 0;
    std::uint64_t skipped_writes = 0;  // write probes not sent: the original values could not be read
    // Write probes not sent because, paced at the polling interval, the reads before them and the write
    // would have run past --duration.
    std::uint64_t writes_past_deadline = 0;
    // Write probes sent with the values the line-setting points they reach hold (Campaign's
    // keep_line_settings).
    std::uint64_t line_settings_kept = 0;
    std::uint64_t unconfirmed = 0;  // failures that did not happen again when checked
    // Replies that came after their request was given up (--timeout, or the silence wait), each judged as
    // that request's: matched by transaction id over Modbus/TCP, by what they answer over RTU and ASCII.
    std::uint64_t late_replies = 0;
    // Of those, replies to requests that were due one: they came after --timeout (a slow target). The
    // others answered requests the rules want unanswered, which over Modbus/TCP are not waited for at all.
    std::uint64_t replies_after_timeout = 0;
    std::uint64_t health_checks = 0;
    std::chrono::nanoseconds elapsed{0};
    std::chrono::microseconds silence_wait{0};  // learnt where the rules demand silence, when the run ended
    std::size_t response_classes = 0;
    // FNV-1a of every request as written, in order: the same seed against a target that answers alike
    // sends the same requests, and two runs show it by this value (a reply's timing does not steer them).
    std::uint64_t requests_digest = 0xCBF29CE484222325ull;
    std::map<std::string, std::uint64_t> outcomes;  // "normal", "exception 02", "silence", each rule broken
    std::vector<CampaignFinding> findings;
    std::vector<conformance::Touched> restored;
    // Points a write the device acknowledged reached before their values could be read (outside the map,
    // or the read failed): what they held before the run is unknown, so they are not restored.
    std::vector<WriteRange> not_read;
    // Points a write that drew no reply reached before their values could be read: read when the run ended,
    // those the device answered for (read_held), with what they hold now, perhaps the fuzzer's value. Not
    // restored.
    std::vector<HeldPoint> unanswered_writes;
    // Of those points, the ones no read could tell about (read_held), or all of them when the target was
    // lost: whether they changed is unknown. Not restored.
    std::vector<WriteRange> unanswered_unread;
    // Of those points, ranges the device refused to read as a whole and that were not read point by point
    // (HeldReading::refused): taken for points it does not hold, as the map says. Not counted as unrestored.
    std::vector<WriteRange> unanswered_refused;
    // The read-back was interrupted (CampaignOptions::stop or stop_again): its points not read are in
    // unanswered_unread.
    bool read_back_interrupted = false;
    bool stopped = false;      // interrupted
    bool target_lost = false;  // the run ended because the target stopped answering
    double requests_per_second() const;
};

CampaignSummary run_campaign(const modbus::Profile& profile, const CampaignOptions& options);

nlohmann::json to_json(const CampaignSummary& s);

}  // namespace mbscope::fuzz::network
