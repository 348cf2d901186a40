#include "conformance/context.hpp"

#include <fnmatch.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <map>

#include "modbus/adu.hpp"
#include "modbus/function_code.hpp"
#include "modbus/hex.hpp"

namespace mbscope::conformance {

namespace tp = modbus::transport;

std::string_view to_string(Outcome o) noexcept {
    switch (o) {
        case Outcome::Pass:
            return "pass";
        case Outcome::Fail:
            return "fail";
        case Outcome::Skip:
            return "skip";
        case Outcome::Error:
            return "error";
    }
    return "?";
}

std::string_view to_string(Authority a) noexcept {
    switch (a) {
        case Authority::Specification:
            return "specification";
        case Authority::Manual:
            return "manual";
        case Authority::Implied:
            return "implied";
    }
    return "?";
}

std::optional<std::uint16_t> TableFacts::first_valid() const {
    if (runs.empty()) return std::nullopt;
    return runs.front().first;
}

std::optional<std::uint16_t> TableFacts::last_valid() const {
    if (runs.empty()) return std::nullopt;
    return runs.back().second;
}

std::optional<std::uint16_t> TableFacts::run_of(std::uint32_t quantity) const {
    for (const auto& [first, last] : runs)
        if (static_cast<std::uint32_t>(last - first) + 1 >= quantity) return first;
    return std::nullopt;
}

std::optional<std::uint16_t> TableFacts::hole() const {
    if (runs.size() < 2) return std::nullopt;
    return static_cast<std::uint16_t>(runs.front().second + 1);
}

bool TableFacts::valid(std::uint16_t address) const {
    for (const auto& [first, last] : runs)
        if (address >= first && address <= last) return true;
    return false;
}

std::string TableFacts::no_address_reason() const {
    return unknown.empty() ? "the map has no address in " + std::string(modbus::to_string(table)) : unknown;
}

bool TableFacts::lacks_address(RuleResult& r) const {
    if (first_valid()) return false;
    r.outcome = damaged.empty() ? Outcome::Skip : Outcome::Error;
    r.reason = damaged.empty() ? no_address_reason() : "not judged: " + damaged;
    return true;
}

bool Context::selected(const std::string& rule_id) const {
    if (options.rule_globs.empty()) return true;
    for (const auto& g : options.rule_globs)
        if (fnmatch(g.c_str(), rule_id.c_str(), 0) == 0) return true;
    return false;
}

namespace {
// The function a rule is about, from its id's segment "fcN" (quantity.fc2.zero, echo.fc6); none for others.
std::optional<std::uint8_t> function_of_rule(std::string_view id) {
    for (std::size_t at = 0; at <= id.size();) {
        const std::size_t end = std::min(id.find('.', at), id.size());
        const std::string_view part = id.substr(at, end - at);
        if (part.size() > 2 && part.size() <= 5 && part.starts_with("fc") &&
            part.find_first_not_of("0123456789", 2) == std::string_view::npos) {
            const int n = std::stoi(std::string(part.substr(2)));
            if (n <= 255) return static_cast<std::uint8_t>(n);
        }
        at = end + 1;
    }
    return std::nullopt;
}
}  // namespace

bool Context::refused_every_request_of(const std::vector<Evidence>& evidence, std::uint8_t fc) const {
    const auto framing = session.client().framing();
    bool any = false;
    for (const auto& e : evidence) {
        const auto sent = modbus::decode_adu(framing, e.sent);
        if (!sent || sent->pdu().empty() || sent->pdu()[0] != fc) continue;
        const auto got = modbus::decode_adu(framing, e.received);
        if (!got || got->pdu().size() != 2 || got->pdu()[0] != (fc | 0x80) || got->pdu()[1] != 0x01)
            return false;
        any = true;
    }
    return any;
}

void Context::run(const RuleInfo& rule, const std::function<void(RuleResult&)>& body) {
    if (!selected(rule.id) || (stop && stop->load())) return;
    if (silent()) {
        rules_not_run = true;
        return;
    }
    RuleResult r;
    r.rule = rule;
    if (rule.writes && options.read_only) {
        r.outcome = Outcome::Skip;
        r.reason = "writes to the device (--read-only)";
        results.push_back(std::move(r));
        return;
    }
    if (const auto fc = function_of_rule(rule.id); fc && functions_refused.test(*fc)) {
        r.outcome = Outcome::Skip;
        r.reason = "the device does not implement function " + std::to_string(*fc) +
                   ": it refused it with exception 01 earlier in the run, as AP §7 allows";
        results.push_back(std::move(r));
        return;
    }
    const auto start = std::chrono::steady_clock::now();
    const auto unsent_before = session.unsent_requests();
    body(r);
    // A request that could not be sent (the connection lost and refused until its timeout: a device
    // rebooting) got no answer the device is to blame for: the rule is not judged, neither failed nor passed
    // (one that expects silence heard it from nobody).
    if (const auto unsent = session.unsent_requests() - unsent_before;
        unsent > 0 && r.outcome != Outcome::Skip) {
        r.outcome = Outcome::Error;
        r.reason = "could not connect: " + std::to_string(unsent) + (unsent == 1 ? " request" : " requests") +
                   " not sent (" + session.connect_error() + ")";
    }
    // Ctrl-C cuts a wait short (a silence listened for, a reply waited for): a pass is then not proven.
    // What failed before the stop did fail.
    if (stop && stop->load() && r.outcome == Outcome::Pass) {
        r.outcome = Outcome::Skip;
        r.reason = "interrupted before the rule finished: not judged";
    }
    r.duration = std::chrono::steady_clock::now() - start;
    r.evidence = session.take_evidence();
    // The generic profile knows no device's functions: a rule of function N that failed because every
    // request of N it sent was refused with 01 found a device that does not implement N, which AP §7 allows
    // (fc.supported.N passes it). Skipped, saying so; and so are the rules of N after it.
    if (profile.open_address_space && r.outcome == Outcome::Fail)
        if (const auto fc = function_of_rule(rule.id); fc && refused_every_request_of(r.evidence, *fc)) {
            functions_refused.set(*fc);
            r.outcome = Outcome::Skip;
            r.reason = "the device does not implement function " + std::to_string(*fc) +
                       ": it refused it with exception 01, as AP §7 allows";
        }
    if (options.progress) options.progress(r);
    results.push_back(std::move(r));
}

bool Context::silent() const {
    return session.requests_owed_reply() >= silent_after && session.response_times().empty() &&
           !session.late_replies();
}

bool Context::serial_framing() const {
    return session.client().framing() != modbus::Framing::Tcp;
}
bool Context::true_serial() const {
    return modbus::transport::is_serial(session.client().endpoint().scheme);
}

std::string exception_text(std::uint8_t code) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "%02X", code);
    const auto name = modbus::exception_name(code);
    return "exception " + std::string(buf) + (name ? " (" + std::string(*name) + ")" : "");
}

Authority authority_for(const modbus::Profile& p, const char* condition) {
    const auto it = p.functions.exceptions.find(condition);
    if (it == p.functions.exceptions.end() || !it->second || p.open_address_space)
        return Authority::Specification;
    if (p.functions.implied_exceptions.count(condition)) return Authority::Implied;
    return Authority::Manual;
}

std::string spec_section(std::uint8_t fc) {
    static const std::map<int, const char*> sections = {
        {1, "6.1"},   {2, "6.2"},   {3, "6.3"},   {4, "6.4"},   {5, "6.5"},   {6, "6.6"},   {7, "6.7"},
        {8, "6.8"},   {11, "6.9"},  {12, "6.10"}, {15, "6.11"}, {16, "6.12"}, {17, "6.13"}, {20, "6.14"},
        {21, "6.15"}, {22, "6.16"}, {23, "6.17"}, {24, "6.18"}, {43, "6.19"}};
    const auto it = sections.find(fc);
    return it == sections.end() ? "AP §5.1, §7" : std::string("AP §") + it->second;
}

std::optional<std::uint16_t> valid_alternative(const modbus::Point* p, std::uint16_t current) {
    if (!p) return static_cast<std::uint16_t>(current == 0 ? 1 : 0);
    const auto& e = p->encoding;
    if ((e.type == modbus::EncodingType::Enum || e.type == modbus::EncodingType::Status) &&
        !e.values.empty()) {
        for (const auto& v : e.values)
            if (!v.forbidden && v.value != static_cast<std::int64_t>(current) && v.value >= 0 &&
                v.value <= 65535)
                return static_cast<std::uint16_t>(v.value);
        return std::nullopt;
    }
    // A boolean in a register takes 0 or 1 (Walchem, 002:424-429), not the register's whole range.
    if (e.type == modbus::EncodingType::Bool) return static_cast<std::uint16_t>(current == 0 ? 1 : 0);
    if (e.type == modbus::EncodingType::AsciiChar && !e.allowed.empty()) {
        for (char ch : e.allowed)
            if (static_cast<unsigned char>(ch) != current) return static_cast<unsigned char>(ch);
        return std::nullopt;
    }
    const bool is_signed = e.type == modbus::EncodingType::S16 || e.is_signed;
    const std::int64_t lo = p->min.value_or(is_signed ? -32768 : 0),
                       hi = p->max.value_or(is_signed ? 32767 : 65535);
    const std::int64_t now = is_signed ? static_cast<std::int16_t>(current) : current;
    if (lo == hi) return std::nullopt;
    return static_cast<std::uint16_t>(now == lo ? hi : lo);
}

bool freely_writable(const modbus::Point& p) {
    // A point mirroring a line setting is never written: a valid value takes the device off the line.
    // Nor is a momentary command: writing it acts, and writing the old value back undoes nothing.
    if (p.access != modbus::Access::ReadWrite || p.reserved || p.momentary || p.fixed_value ||
        p.encoding.words != 1 || p.min_from || p.max_from || p.mirrors || p.read_only_when)
        return false;
    std::string n = p.name_en + " " + p.name;
    std::transform(n.begin(), n.end(), n.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    for (const char* word :
         {"address", "baud", "parity", "protocol", "communication", "endere", "comunica", "paridade"})
        if (n.find(word) != std::string::npos) return false;
    return true;
}

namespace {

// The unit a request was addressed to, read from its bytes in the reply's framing.
std::optional<std::uint8_t> request_unit(const tp::Exchange& ex) {
    const auto& s = ex.sent;
    switch (ex.response->framing) {
        case modbus::Framing::Tcp:
            if (s.size() > 6) return s[6];
            break;
        case modbus::Framing::Rtu:
            if (!s.empty()) return s[0];
            break;
        case modbus::Framing::Ascii:
            if (s.size() > 2 && modbus::hex_digit(s[1]) >= 0 && modbus::hex_digit(s[2]) >= 0)
                return static_cast<std::uint8_t>(modbus::hex_digit(s[1]) * 16 + modbus::hex_digit(s[2]));
            break;
    }
    return std::nullopt;
}

}  // namespace

// What is wrong with the reply's envelope, "" when nothing: TCP §4.4.1 (the server copies the transaction
// and unit identifiers, the protocol identifier is 0) and SL §2.2 (the slave puts its own address in the
// reply). A reply that breaks them is no answer to the request, whatever its PDU says.
std::string envelope_fault(const tp::Exchange& ex) {
    if (!ex.response) return "";
    const auto& f = *ex.response;
    if (f.framing == modbus::Framing::Tcp && ex.sent.size() >= 7) {
        const auto tid = static_cast<std::uint16_t>((ex.sent[0] << 8) | ex.sent[1]);
        if (f.transaction_id() != tid)
            return "reply to transaction " + std::to_string(f.transaction_id()) + " instead of " +
                   std::to_string(tid);
        if (f.protocol_id() != 0) return "reply with protocol identifier " + std::to_string(f.protocol_id());
    }
    const auto unit = request_unit(ex);
    if (unit && *unit != 0 && f.unit_id() != *unit)
        return "reply from unit " + std::to_string(f.unit_id()) + " to a request for unit " +
               std::to_string(*unit);
    return "";
}

std::optional<modbus::Pdu> response_pdu(const tp::Exchange& ex) {
    if (!ex.response || !ex.response->checksum_ok || !envelope_fault(ex).empty()) return std::nullopt;
    auto pdu = modbus::decode_response(ex.response->pdu());
    if (!pdu) return std::nullopt;
    return std::move(pdu).value();
}

std::optional<modbus::Pdu> request_pdu(const tp::Exchange& ex) {
    if (!ex.response) return std::nullopt;
    const auto frame = modbus::decode_adu(ex.response->framing, ex.sent);
    if (!frame) return std::nullopt;
    auto pdu = modbus::decode_request(frame->pdu());
    if (!pdu) return std::nullopt;
    return std::move(pdu).value();
}

std::optional<modbus::ReplyMisfit> reply_misfit(const tp::Exchange& ex) {
    const auto reply = response_pdu(ex);
    if (!reply) return std::nullopt;
    const auto request = request_pdu(ex);
    if (!request) return std::nullopt;
    return modbus::reply_misfit(*request, *reply);
}

std::string misfit_text(const modbus::ReplyMisfit& m) {
    switch (m.kind) {
        case modbus::ReplyMisfit::Kind::DataSize:
            return "the request asks for " + m.expected + ", the reply carries " +
                   std::to_string(m.got_bytes) + " data bytes (" + m.source + ")";
        case modbus::ReplyMisfit::Kind::Padding:
            return "the reply sets bits of its last byte past the quantity asked (" + std::string(m.source) +
                   ")";
        case modbus::ReplyMisfit::Kind::Echo:
            break;
    }
    return "the reply is not " + m.expected + " (" + m.source + ")" +
           (m.differs.empty() ? "" : ": " + m.differs);
}

std::string describe(const tp::Exchange& ex) {
    if (ex.closed && ex.received.empty()) return "connection closed, no reply";
    if (ex.received.empty()) return "no reply";
    if (!ex.response && !ex.stale_replies.empty())
        return "no reply (only " + std::to_string(ex.stale_replies.size()) +
               " late reply to an earlier request)";
    if (!ex.response) return std::to_string(ex.received.size()) + " bytes that form no frame";
    if (!ex.response->checksum_ok) return "reply with a bad checksum";
    if (auto fault = envelope_fault(ex); !fault.empty()) return fault;
    const auto pdu_bytes = ex.response->pdu();
    if (pdu_bytes.empty()) return "reply without a PDU";
    auto pdu = modbus::decode_response(pdu_bytes);
    if (!pdu) return "malformed reply to function " + std::to_string(pdu_bytes[0] & 0x7F);
    if (pdu->is_exception()) {
        const auto& e = std::get<modbus::ExceptionResponse>(pdu->body);
        return exception_text(e.exception_code) + " to function " + std::to_string(pdu->function_code());
    }
    std::string out = "normal response, function " + std::to_string(pdu->function_code());
    if (!pdu->violations.empty())
        out += " (breaks " + std::string(modbus::info(*pdu->violations.begin()).name) + ")";
    if (const auto misfit = reply_misfit(ex)) out += "; " + misfit_text(*misfit);
    return out;
}

std::vector<std::optional<modbus::Pdu>> replies_in(const Context& c, const tp::Exchange& ex) {
    std::vector<std::optional<modbus::Pdu>> out;
    // Late replies to earlier requests, set aside, are none of these.
    for (const auto& f : tp::frames_in(c.session.client().framing(), ex.own_received())) {
        auto& reply = out.emplace_back();
        if (!f.checksum_ok || f.unit_id() != c.session.options().unit) continue;
        if (auto p = modbus::decode_response(f.pdu())) reply = std::move(p).value();
    }
    return out;
}

std::string describe_reply(const std::optional<modbus::Pdu>& p) {
    if (!p) return "a damaged or foreign frame";
    if (!p->is_exception()) return "normal response, function " + std::to_string(p->function_code());
    return exception_text(std::get<modbus::ExceptionResponse>(p->body).exception_code) + " to function " +
           std::to_string(p->function_code());
}

bool is_normal_reply(const std::optional<modbus::Pdu>& p, std::uint8_t fc) {
    return p && !p->is_exception() && p->function_code() == fc && p->violations.empty();
}

bool is_exception(const tp::Exchange& ex, std::uint8_t fc, std::uint8_t code) {
    auto pdu = response_pdu(ex);
    return pdu && pdu->is_exception() && pdu->function_code() == fc &&
           std::get<modbus::ExceptionResponse>(pdu->body).exception_code == code;
}

bool is_normal_of_function(const tp::Exchange& ex, std::uint8_t fc) {
    auto pdu = response_pdu(ex);
    return pdu && !pdu->is_exception() && pdu->function_raw == fc && pdu->violations.empty();
}

bool is_normal(const tp::Exchange& ex, std::uint8_t fc) {
    return is_normal_of_function(ex, fc) && !reply_misfit(ex);
}

void expect_exception(RuleResult& r, const tp::Exchange& ex, std::uint8_t fc, std::uint8_t code) {
    r.expected = exception_text(code);
    r.observed = describe(ex);
    r.outcome = is_exception(ex, fc, code) ? Outcome::Pass : Outcome::Fail;
}

void expect_normal(RuleResult& r, const tp::Exchange& ex, std::uint8_t fc) {
    r.expected = "normal response, function " + std::to_string(fc);
    r.observed = describe(ex);
    r.outcome = is_normal(ex, fc) ? Outcome::Pass : Outcome::Fail;
}

void expect_silence(RuleResult& r, const tp::Exchange& ex) {
    r.expected = "no reply";
    r.observed = describe(ex);
    // A late reply to an earlier request, set aside, is no reply to this one.
    r.outcome = ex.own_received().empty() ? Outcome::Pass : Outcome::Fail;
}

std::optional<Context::ProbeRead> Context::probe_read() const {
    // The first table the device reads that has a point: a device with input registers but no holding
    // register at all (or none found) lost the whole Modbus/TCP family and two robustness rules, unsaid.
    using modbus::Table;
    const std::pair<std::uint8_t, Table> reads[] = {{3, Table::HoldingRegisters},
                                                    {4, Table::InputRegisters},
                                                    {1, Table::Coils},
                                                    {2, Table::DiscreteInputs}};
    for (const auto& [fc, table] : reads) {
        if (!profile.functions.supports(fc)) continue;
        const auto address = facts(table).first_valid();
        if (!address) continue;
        return ProbeRead{fc, modbus::encode_pdu(modbus::make_read_request(
                                 static_cast<modbus::FunctionCode>(fc), *address, 1))};
    }
    return std::nullopt;
}

void Context::run_with_probe(const RuleInfo& rule, const std::function<void(RuleResult&)>& body) {
    const bool known = probe_read().has_value();
    run(rule, [&](RuleResult& r) {
        if (known) return body(r);
        r.outcome = Outcome::Skip;
        r.reason =
            "no point the device reads is known (the map lists none in a table it reads, or none "
            "answered when the address space was probed): nothing to send as the valid request";
    });
}

}  // namespace mbscope::conformance
