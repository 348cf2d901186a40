#pragma once
// What every rule family gets: the session, the profile, the facts derived from it (valid address runs,
// writable points), the run's options, and helpers that turn an exchange into words and a verdict.

#include <array>
#include <atomic>
#include <bitset>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "conformance/rule.hpp"
#include "conformance/session.hpp"
#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"
#include "modbus/reply_fit.hpp"

namespace mbscope::conformance {

// The address space of one table as the profile (or, for the generic profile, probing) describes it.
struct TableFacts {
    modbus::Table table = modbus::Table::HoldingRegisters;
    bool present = false;  // the function codes of this table are supported
    // Probing (the generic profile) could not tell: whether the table has points at all (`unknown`), or
    // where it ends (`end_unknown`: runs hold what was found readable). Why, for the rules it skips.
    std::string unknown;
    std::string end_unknown;
    // Probing got replies to address 0 and every one was damaged (a bad checksum, another unit's, no frame):
    // the device answers and damages its replies, so the map is unknown without being empty. Rules needing
    // the map are not judged (in error, failing the verdict) rather than skipped, and fc.supported.N asks
    // again and fails on the damaged reply: skipped, they certified a device damaging every read.
    std::string damaged;
    std::vector<std::pair<std::uint16_t, std::uint16_t>>
        runs;  // [first, last] of consecutive valid addresses
    std::optional<std::uint16_t> first_valid() const;
    std::optional<std::uint16_t> last_valid() const;
    // A start where `quantity` consecutive valid addresses begin, if any.
    std::optional<std::uint16_t> run_of(std::uint32_t quantity) const;
    // An address inside [first, last] that no point occupies (a hole in the map), if any.
    std::optional<std::uint16_t> hole() const;
    bool valid(std::uint16_t address) const;
    // Why a rule that needs an address of this table has none: the map has none, or probing could not tell.
    std::string no_address_reason() const;
    // For a rule that needs an address of this table and has none: skipped with no_address_reason(), or, when
    // the device damaged every reply while the table was probed, in error (not judged) saying so. False when
    // the table has an address (the rule goes on).
    bool lacks_address(RuleResult& r) const;
};

struct RunOptions {
    bool read_only = false;
    // Writes to unit 0 (broadcast.fcN rules) are sent. Every device on the line executes them and only the
    // device under test is put back: for a device alone on its line (a bench), as the user says.
    bool broadcast_writes = false;
    std::vector<std::string> rule_globs;  // empty: every rule
    std::uint64_t seed = 1;
    // How long silence.idle listens with no request out. The manuals' own test idles 10 s (MK-MS-01,
    // 000:246-248) and 15 s (WA-GEN-02, 002:164); a run defaults to a shorter listen.
    std::chrono::milliseconds idle{1000};
    // The unit framing.other_unit addresses: one no device on the line answers (0: the rule is not run).
    // Unset: the device's own unit + 1 (1-247), right for a device alone on its line, as on a bench.
    std::optional<std::uint8_t> other_unit;
    std::function<void(const RuleResult&)> progress;  // after each rule (a terminal shows where the run is)
    // Said, when given, before the restore at a polling interval, where it can take minutes (Walchem: a
    // minute for every 12 points): for a person at a terminal.
    std::function<void(const std::string&)> note;
};

struct Context {
    Session& session;
    const modbus::Profile& profile;
    RunOptions options;
    std::array<TableFacts, 5> tables;  // indexed by Table's value
    std::vector<RuleResult> results;
    const std::atomic<bool>* stop = nullptr;  // set on Ctrl-C: the remaining rules are not run
    // The generic profile: functions the device refused with exception 01 (fc.supported.N), as AP §7 lets a
    // device of unknown make. The other rules of such a function (an id with a segment fcN) are skipped:
    // quantity.fc2.zero failed a device for refusing FC2 with the 01 that passed fc.supported.2.
    std::bitset<256> functions_refused{};

    const TableFacts& facts(modbus::Table t) const { return tables[static_cast<int>(t)]; }
    bool selected(const std::string& rule_id) const;
    // Runs one rule: skips it when not selected or when it writes under --read-only, times it, collects
    // its evidence. The body sets outcome, expected and observed. Nothing is run once the target is silent.
    void run(const RuleInfo& rule, const std::function<void(RuleResult&)>& body);
    // Whether every request of function `fc` among the exchanges was refused with exception 01 (and one was).
    bool refused_every_request_of(const std::vector<Evidence>& evidence, std::uint8_t fc) const;
    // The target answered none of the run's first `silent_after` requests or more in time (a wrong unit id,
    // transport or line settings): every rule after would wait out its timeouts and fail for that one
    // reason, so none is run.
    bool silent() const;
    static constexpr std::uint64_t silent_after = 3;
    bool rules_not_run = false;   // a rule was not run for silence
    bool serial_framing() const;  // RTU or ASCII framing (serial lines and serial over TCP)
    bool true_serial() const;     // a real serial line or pseudo-terminal
    // A read of one valid point (a holding register, else an input register, a coil, a discrete input)
    // that every healthy device answers normally: the reference request of the framing, TCP and robustness
    // rules. nullopt when no such point is known.
    struct ProbeRead {
        std::uint8_t fc = 3;
        std::vector<std::uint8_t> pdu;
    };
    std::optional<ProbeRead> probe_read() const;
    // run() for a rule that sends the probe read: without one it is skipped, saying why, rather than left
    // out of the report.
    void run_with_probe(const RuleInfo& rule, const std::function<void(RuleResult&)>& body);
};

// "exception 02 (Illegal Data Address)", "normal response", "no reply", "reply with a bad CRC" ...
std::string describe(const modbus::transport::Exchange& ex);
// What is wrong with the reply's envelope (transaction, protocol or unit identifier not those of the
// request), "" when nothing.
std::string envelope_fault(const modbus::transport::Exchange& ex);
// The response PDU when the reply is a well-formed frame with a good checksum and the request's envelope,
// else nullopt.
std::optional<modbus::Pdu> response_pdu(const modbus::transport::Exchange& ex);
// Every whole frame among an exchange's bytes (several requests sent in one write), in order: its PDU when
// its checksum holds and it comes from the unit asked, nullopt otherwise.
std::vector<std::optional<modbus::Pdu>> replies_in(const Context& c, const modbus::transport::Exchange& ex);
// The request an exchange sent, when its bytes are one whole request in the reply's framing (not a rule's
// deliberately broken or split frame).
std::optional<modbus::Pdu> request_pdu(const modbus::transport::Exchange& ex);
// How the reply fails to answer the request sent (modbus::reply_misfit: a read's data size, a write's
// echo), nothing when it answers it or either cannot be decoded. A normal reply that does not answer its
// request is not normal (is_normal), and describe() says why.
std::optional<modbus::ReplyMisfit> reply_misfit(const modbus::transport::Exchange& ex);
std::string misfit_text(const modbus::ReplyMisfit& misfit);
// "normal response, function 3", "exception 04 (...) to function 3", "a damaged or foreign frame".
std::string describe_reply(const std::optional<modbus::Pdu>& reply);
bool is_normal_reply(const std::optional<modbus::Pdu>& reply, std::uint8_t fc);
bool is_exception(const modbus::transport::Exchange& ex, std::uint8_t fc, std::uint8_t code);
// A normal reply of function `fc` that answers the request sent (reply_misfit).
bool is_normal(const modbus::transport::Exchange& ex, std::uint8_t fc);
// A normal reply of function `fc`, consistent in itself, whether or not it answers the request: that the
// device took the request as one it serves (the address space's probing: a table whose reads come back one
// item too long is there, and the rules judge those replies).
bool is_normal_of_function(const modbus::transport::Exchange& ex, std::uint8_t fc);
// Judges "expect exception `code`" and fills the result.
void expect_exception(RuleResult& r, const modbus::transport::Exchange& ex, std::uint8_t fc,
                      std::uint8_t code);
void expect_normal(RuleResult& r, const modbus::transport::Exchange& ex, std::uint8_t fc);
void expect_silence(RuleResult& r, const modbus::transport::Exchange& ex);
std::string exception_text(std::uint8_t code);
// Who decides the exception code for a condition ("bad_address", ...): the manual when the profile gives
// its code, graded as implied when the manual only implies it, else the specification.
Authority authority_for(const modbus::Profile& p, const char* condition);
// "AP §6.3" for a function code's section of the specification.
std::string spec_section(std::uint8_t fc);

// A value other than `current` that the point documents as valid (another enumeration value, another allowed
// character, a range limit), so a rule can change it and expect acceptance; nullopt when there is none.
std::optional<std::uint16_t> valid_alternative(const modbus::Point* p, std::uint16_t current);
// A point a rule may write freely: writable, not reserved, not a communication setting (address, baud rate,
// parity, protocol: writing those would cut the runner off the device), one register, no range taken from
// another register.
bool freely_writable(const modbus::Point& p);

// The families, in the order a run takes them.
void check_function_codes(Context& c);
void check_quantities(Context& c);
void check_addresses(Context& c);
void check_values(Context& c);
void check_write_encoding(Context& c);
void check_data(Context& c);
void check_broadcast(Context& c);
void check_framing(Context& c);
void check_tcp(Context& c);
void check_robustness(Context& c);
void check_response_times(Context& c);
void check_alternative_maps(Context& c);  // from check_data
void check_unsolicited(Context& c);

}  // namespace mbscope::conformance
