#pragma once
// A certification run: facts from the profile (or probing, for the generic profile), every rule family in
// turn, then every touched point restored and verified, whatever happened (a stop request, an error).

#include <atomic>
#include <chrono>
#include <string>
#include <string_view>
#include <vector>

#include "conformance/context.hpp"
#include "conformance/rule.hpp"
#include "conformance/session.hpp"
#include "modbus/profile.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance {

struct CheckOptions {
    SessionOptions session;
    RunOptions run;
    std::string target;  // the URI, as given
};

struct Report {
    std::string mbscope_version;
    std::string profile_id;
    std::string profile_file;
    std::string profile_hash;  // FNV-1a 64 of the profile file, so a verdict names the exact map it used
    std::string target;
    std::uint8_t unit = 1;
    std::uint64_t seed = 1;
    bool read_only = false;
    std::vector<std::string> rule_globs;
    std::int64_t interval_ms = 0;
    std::int64_t timeout_ms = 0;
    std::string started;  // UTC, ISO 8601
    std::chrono::nanoseconds wall{0};
    std::uint64_t requests = 0;
    std::uint64_t late_replies = 0;  // came after their request was given up (raise --timeout)
    bool stopped = false;            // interrupted before the end
    // Why no rule could be judged, "" when the target answered: it answered none of the run's requests in
    // time, not even late (a wrong unit id, transport or line settings: the run stops after its first
    // requests), or only after the timeout (raise --timeout). Every rule it ran is in error rather than
    // failed.
    std::string unanswered;
    std::vector<RuleResult> results;
    std::vector<Touched> restored;
    std::vector<std::chrono::nanoseconds> response_times;

    std::size_t count(Outcome o) const;
    std::size_t failures_of(Authority a) const;
    bool all_restored() const;
};

// Exit-code view of a report: 0 nothing failed, 1 a rule of the specification or the manual failed (implied
// rules are warnings) or a point could not be restored.
int verdict(const Report& report);
// "pass" or "fail" as verdict() says; "interrupted" for a run stopped before every rule ran, and "error"
// for a target that answered nothing (Report::unanswered) or a run that judged no rule (nothing_judged),
// which certify nothing whatever their rules said.
std::string_view verdict_text(const Report& report);
// Why a run that was not interrupted judged nothing: its --rules matched no rule ("--rules 'x.*' match no
// rule for PROFILE"), or every rule it selected was skipped; "" when a rule was judged. An empty run is no
// pass (a CI job with a typo in its glob published a green report).
std::string nothing_judged(const Report& report);

Report run_check(modbus::transport::Client& client, const modbus::Profile& profile,
                 const CheckOptions& options, const std::atomic<bool>* stop = nullptr);

// The report of a run that could not begin: the target's connection or device did not open. One rule,
// target.reachable, in error with the reason, so the JSON, JUnit and HTML files a CI job publishes say why
// instead of being missing.
Report unreachable_report(const modbus::Profile& profile, const CheckOptions& options,
                          const std::string& why);

// The report of a run interrupted before it began (a signal while the profile loaded or the target opened):
// no rule run, nothing sent, `stopped` set, so that every report says "interrupted" as a later stop's does.
Report interrupted_report(const modbus::Profile& profile, const CheckOptions& options);

}  // namespace mbscope::conformance
