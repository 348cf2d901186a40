#pragma once
// What a certification run is made of: rules (stable id, source, one sentence), and per run an outcome with
// the bytes that prove it. A rule comes from the specification or from the device's manual; a manual rule
// the text only implies is graded as a warning, never as a failure of the device.

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace mbscope::conformance {

enum class Outcome : std::uint8_t { Pass, Fail, Skip, Error };
std::string_view to_string(Outcome o) noexcept;

enum class Authority : std::uint8_t {
    Specification,  // Modbus Application Protocol V1.1b3, Serial Line V1.02, Messaging on TCP/IP V1.0b
    Manual,         // the device's manual, as the profile transcribes it
    // A failure is a warning: the manual implies the rule without saying it, or what the rule judges this
    // host cannot tell surely (frames told apart by content on a stream, pauses timed by its reads).
    Implied,
};
std::string_view to_string(Authority a) noexcept;

struct RuleInfo {
    std::string id;      // "fc.unsupported.65", "quantity.fc3.max_plus_one"
    std::string family;  // "function codes", "quantities", ...
    std::string source;  // "AP §6.3", "000:325 (MK-FC3-02)"
    std::string text;    // one sentence: what the rule checks
    Authority authority = Authority::Specification;
    bool writes = false;  // changes the device (run only without --read-only, restored afterwards)
};

// One request/response pair (or silence) as seen on the wire.
struct Evidence {
    std::string note;  // what this exchange was for
    std::vector<std::uint8_t> sent;
    std::vector<std::uint8_t> received;  // empty: silence
    std::chrono::nanoseconds elapsed{0};
    bool timed_out = false;
};

struct RuleResult {
    RuleInfo rule;
    Outcome outcome = Outcome::Pass;
    std::string expected;  // "exception 03", "no reply", "echo of the request"
    std::string observed;  // what came back, in words
    std::string reason;    // skips and errors: why
    std::vector<Evidence> evidence;
    std::chrono::nanoseconds duration{0};
};

}  // namespace mbscope::conformance
