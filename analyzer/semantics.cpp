#include "analyzer/semantics.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <charconv>
#include <functional>
#include <set>
#include <span>

#include "modbus/addressing.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;

std::optional<DeviceSelector> parse_selector(const std::string& text) {
    DeviceSelector s;
    auto number = [](std::string_view v) -> std::optional<int> {
        int n = 0;
        auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
        if (ec != std::errc() || p != v.data() + v.size() || n < 0 || n > 255) return std::nullopt;
        return n;
    };
    // An IPv6 address as devices are named ("[2001:db8::2]:502" has the host "[2001:db8::2]"), whichever
    // of its spellings is given.
    const auto ipv6 = [](const std::string& address) -> std::optional<std::string> {
        std::uint8_t bytes[16];
        char canonical[INET6_ADDRSTRLEN];
        if (::inet_pton(AF_INET6, address.c_str(), bytes) != 1 ||
            !::inet_ntop(AF_INET6, bytes, canonical, sizeof canonical))
            return std::nullopt;
        return "[" + std::string(canonical) + "]";
    };
    if (!text.empty() && text.front() == '[') {  // [IPv6] or [IPv6]:UNIT
        const auto close = text.find(']');
        if (close == std::string::npos) return std::nullopt;
        s.host = ipv6(text.substr(1, close - 1));
        if (!s.host) return std::nullopt;
        const std::string_view rest = std::string_view(text).substr(close + 1);
        if (rest.empty()) return s;
        if (rest.front() != ':') return std::nullopt;
        auto u = number(rest.substr(1));
        if (!u) return std::nullopt;
        s.unit = *u;
        return s;
    }
    if (std::count(text.begin(), text.end(), ':') >= 2) {  // a bare IPv6 address: no unit can follow
        s.host = ipv6(text);
        if (!s.host) return std::nullopt;
        return s;
    }
    if (text.find('.') == std::string::npos) {  // a unit id alone
        auto u = number(text);
        if (!u) return std::nullopt;
        s.unit = *u;
        return s;
    }
    const auto colon = text.rfind(':');
    s.host = text.substr(0, colon);
    if (colon != std::string::npos) {
        auto u = number(std::string_view(text).substr(colon + 1));
        if (!u) return std::nullopt;
        s.unit = *u;
    }
    return s;
}

void Semantics::add(DeviceSelector selector, std::shared_ptr<const Profile> profile) {
    maps_.emplace_back(std::move(selector), std::move(profile));
    uses_.push_back(SelectorUse::Unmatched);
}

std::vector<Semantics::SelectorUse> Semantics::selector_uses() const {
    return uses_;
}

const Profile* Semantics::profile_for(const std::string& server, std::uint8_t unit) const {
    const std::string host = server.substr(0, server.rfind(':'));
    const auto moved = moved_.find({host, unit});
    std::size_t best = maps_.size();
    int best_score = -1;
    for (std::size_t i = 0; i < maps_.size(); ++i) {
        const DeviceSelector& sel = maps_[i].first;
        if (sel.host && *sel.host != host) continue;
        if (sel.unit && *sel.unit != unit) continue;
        if (uses_[i] == SelectorUse::Unmatched) uses_[i] = SelectorUse::Shadowed;
        const int score = (sel.host ? 1 : 0) + (sel.unit ? 2 : 0);
        if (score > best_score) {
            best = i;
            best_score = score;
        }
    }
    // A device that moved here keeps its profile (follow_address); a selector naming its new place
    // described it all the same, its note would say no request went there.
    if (moved != moved_.end()) {
        if (best != maps_.size()) uses_[best] = SelectorUse::Used;
        return moved->second;
    }
    if (best == maps_.size()) return nullptr;
    uses_[best] = SelectorUse::Used;
    return maps_[best].second.get();
}

namespace {

struct Span {
    Table table;
    std::uint16_t start;
    std::uint16_t quantity;
};

std::optional<Span> read_span(const Pdu& p) {
    auto table = table_of_function(p.function_code());
    if (!table) return std::nullopt;
    if (const auto* r = std::get_if<ReadRequest>(&p.body))
        return Span{*table, r->starting_address, r->quantity};
    if (const auto* r = std::get_if<ReadWriteMultipleRequest>(&p.body))
        return Span{Table::HoldingRegisters, r->read_starting_address, r->quantity_to_read};
    return std::nullopt;
}

std::string point_name(const Point& p) {
    return p.name_en.empty() ? p.name : p.name_en;
}

// The holding registers a write request writes (FC6, FC16, FC23's write part): the first address and the
// values (those within the address space). nullopt for any other request.
struct WrittenRegisters {
    std::uint16_t start = 0;
    std::vector<std::uint16_t> values;
};
std::optional<WrittenRegisters> written_registers(const Pdu& q) {
    if (const auto* w = std::get_if<WriteSingle>(&q.body); w && q.function_code() == 6)
        return WrittenRegisters{w->address, {w->value}};
    const auto within = [](std::uint16_t start, const std::vector<std::uint16_t>& values) {
        const auto n = count_within_address_space(start, values.size());
        return WrittenRegisters{start, std::vector<std::uint16_t>(values.begin(), values.begin() + n)};
    };
    if (const auto* m = std::get_if<WriteMultipleRegistersRequest>(&q.body))
        return within(m->starting_address, m->values);
    if (const auto* rw = std::get_if<ReadWriteMultipleRequest>(&q.body))
        return within(rw->write_starting_address, rw->write_values);
    return std::nullopt;
}
void check_write_value(const Profile& profile, Table table, std::uint16_t address, std::uint16_t value,
                       std::vector<RuleBreak>& out) {
    const Point* p = profile.find(table, address);
    if (!p) {
        out.push_back({FindingCode::ProfileAddressUnknown, std::string(to_string(table)) + " " +
                                                               std::to_string(address) +
                                                               " is not in the map of " + profile.id});
        return;
    }
    if (p->access == Access::Read) {
        out.push_back({FindingCode::ProfileWriteReadOnly, std::to_string(address) + " (" + point_name(*p) +
                                                              ") is read-only [" + p->source + "]"});
        return;
    }
    if (p->encoding.words == 2) return;  // judged whole by check_32bit_writes
    if (check_write(profile, table, address, value) == 3) {
        const bool is_signed = p->encoding.type == EncodingType::S16 || p->encoding.is_signed;
        const long long v = is_signed ? static_cast<std::int16_t>(value) : value;
        out.push_back({FindingCode::ProfileValueOutOfRange,
                       "writes " + std::to_string(v) + " to " + std::to_string(address) + " (" +
                           point_name(*p) + "); the manual allows " +
                           (p->range_text.empty() ? std::string("other values") : p->range_text) + " [" +
                           p->source + "]"});
    }
}

// The 32-bit points among registers written from `start`: each judged as one value (a float against its
// range in engineering units, and as a number), both halves from the request, or a lone half with the
// other half `held` says the device holds (Walchem's manual has clients write a 32-bit set-point's halves
// one at a time, 002:499). A half whose other half is unknown is not judged.
void check_32bit_writes(const Profile& profile, std::uint16_t start, std::span<const std::uint16_t> values,
                        const std::function<std::optional<std::uint16_t>(std::uint16_t)>& held,
                        std::vector<RuleBreak>& out) {
    for (std::size_t i = 0; i < values.size(); ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        const Point* p = profile.find(Table::HoldingRegisters, address);
        if (!p || p->encoding.words != 2 || p->access == Access::Read || p->reserved) continue;
        const bool whole = p->address == address && i + 1 < values.size();
        std::vector<std::uint16_t> written{values[i]};
        if (whole) written.push_back(values[i + 1]);
        const auto rejected = check_writes(profile, Table::HoldingRegisters, address, written, held);
        if (whole) ++i;
        if (!rejected || rejected->exception_code == exception_for(profile, "bad_address", 2)) continue;
        out.push_back({FindingCode::ProfileValueOutOfRange,
                       "writes " + std::string(whole ? "" : "one half of ") + std::to_string(p->address) +
                           "-" + std::to_string(p->address + 1) + " (" + point_name(*p) +
                           "): " + rejected->reason + (whole ? "" : " with the other half as last seen") +
                           "; the manual allows " +
                           (p->range_text.empty() ? std::string("other values") : p->range_text) + " [" +
                           p->source + "]"});
    }
}

}  // namespace

std::vector<RuleBreak> Semantics::check_request(const Profile& profile, const std::string& device,
                                                const Pdu& q) const {
    std::vector<RuleBreak> out;
    const std::uint8_t fc = q.function_code();
    if (!profile.functions.supports(fc)) {
        out.push_back({FindingCode::ProfileFunctionUnsupported,
                       "FC" + std::to_string(fc) + " is not among the functions of " + profile.id});
        return out;
    }
    std::optional<std::uint16_t> quantity;
    if (auto s = read_span(q)) quantity = s->quantity;
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&q.body)) quantity = w->quantity;
    if (const auto* w = std::get_if<WriteMultipleCoilsRequest>(&q.body)) quantity = w->quantity;
    const int limit = profile.functions.max_for(fc);
    if (quantity && limit > 0 && *quantity > limit)
        out.push_back({FindingCode::ProfileQuantityAboveLimit,
                       "FC" + std::to_string(fc) + " asks for " + std::to_string(*quantity) + "; " +
                           profile.id + " allows at most " + std::to_string(limit)});
    if (profile.open_address_space) return out;
    if (auto s = read_span(q)) {
        const std::uint32_t last = profile.functions.address_check == AddressCheck::First
                                       ? s->start + 1u
                                       : s->start + std::uint32_t{s->quantity};
        for (std::uint32_t a = s->start; a < last && a <= 0xFFFF; ++a) {
            const Point* p = profile.find(s->table, static_cast<std::uint16_t>(a));
            if (!p || p->access == Access::Write) {
                out.push_back({FindingCode::ProfileAddressUnknown,
                               std::string(to_string(s->table)) + " " + std::to_string(a) +
                                   (p ? " is write-only in the map of " : " is not in the map of ") +
                                   profile.id});
                break;
            }
        }
    }
    if (const auto* w = std::get_if<WriteSingle>(&q.body); w && fc == 5)
        check_write_value(profile, Table::Coils, w->address, w->value == 0xFF00 ? 1 : 0, out);
    if (const auto w = written_registers(q)) {  // FC6, FC16 and FC23's write part
        for (std::size_t i = 0; i < w->values.size(); ++i)
            check_write_value(profile, Table::HoldingRegisters, static_cast<std::uint16_t>(w->start + i),
                              w->values[i], out);
        const auto held = [&](std::uint16_t address) {
            return known(device, profile, PointRef{Table::HoldingRegisters, address});
        };
        check_32bit_writes(profile, w->start, w->values, held, out);
    }
    if (const auto* w = std::get_if<WriteMultipleCoilsRequest>(&q.body))
        for (std::size_t i = 0;
             i < count_within_address_space(w->starting_address, w->quantity) && i / 8 < w->values.size();
             ++i)
            check_write_value(profile, Table::Coils, static_cast<std::uint16_t>(w->starting_address + i),
                              bit_at(w->values, i) ? 1 : 0, out);
    check_conditional(profile, device, q, out, nullptr);
    return out;
}

std::vector<RuleBreak> Semantics::check_line(const Profile& profile, const std::string& device,
                                             const Frame& frame) const {
    std::vector<RuleBreak> out;
    if (frame.framing == Framing::Tcp || frame.unit_id() == 0 || profile.open_address_space ||
        !line_checked_.insert(device).second)
        return out;
    for (auto& departure : line_departures(profile.line, frame.framing, nullptr))
        out.push_back({FindingCode::ProfileLineDeparture, profile.id + ": " + std::move(departure)});
    const int unit = frame.unit_id();
    if (profile.line.disables(unit))
        out.push_back({FindingCode::ProfileLineDeparture,
                       profile.id + ": unit " + std::to_string(unit) +
                           " is the address at which the manual's device does not communicate"});
    else if (unit < profile.line.unit_min || unit > profile.line.unit_max)
        out.push_back({FindingCode::ProfileLineDeparture, profile.id + ": unit " + std::to_string(unit) +
                                                              " is outside the manual's addresses " +
                                                              std::to_string(profile.line.unit_min) + ".." +
                                                              std::to_string(profile.line.unit_max)});
    return out;
}

std::vector<RuleBreak> Semantics::check_response(const Profile& profile, const std::string& device,
                                                 const Pdu& q, const Pdu& a) const {
    std::vector<RuleBreak> out;
    if (!a.is_exception() || profile.open_address_space) return out;
    const auto code = std::get<ExceptionResponse>(a.body).exception_code;
    if (code == 1 && profile.functions.supports(q.function_code()))
        out.push_back({FindingCode::ProfileExceptionUnexpected,
                       "exception 1 (illegal function) to FC" + std::to_string(q.function_code()) +
                           ", which " + profile.id + "'s manual lists as supported"});
    bool condition_unknown = false;
    std::vector<RuleBreak> conditional;
    check_conditional(profile, device, q, conditional, &condition_unknown);
    // The refusal a conditionally read-only point gets (the code a read-only one gets) is the manual's
    // when the traffic never showed the condition's value: the device may well be in that state.
    if (condition_unknown && code == exception_for(profile, "write_read_only", 2)) return out;
    const auto breaks = check_request(profile, device, q);
    if (code == 2 && breaks.empty())
        out.push_back(
            {FindingCode::ProfileExceptionUnexpected,
             "exception 2 (illegal data address) to a request whose addresses are all in the map of " +
                 profile.id});
    // The code the manual gives for what the request breaks (MK 000:475-477, CTH 003:572-574), the first in
    // the specification's order (function, quantity, address, value, AP §7): another code is the device's
    // error too. Where the manual only implies the code, no other is held against the device.
    struct Due {
        int order;
        const char* condition;
        std::uint8_t code;
        const RuleBreak* why;
    };
    std::optional<Due> due;
    // The request's own data as AP §6's state diagrams check them before any address: FC5's value (0000 or
    // FF00, AP §6.5; MK-FC05-01), FC15/FC16's quantity and byte count (AP §6.11, §6.12). A device that
    // answers 03 to an FC5 of value 1234 at a coil outside the map answers as the specification says; the
    // reference slave does, and was held to 02 for it.
    RuleBreak malformed{FindingCode::PduCoilValueInvalid, {}};
    for (const auto& [violation, condition] :
         {std::pair{FindingCode::PduCoilValueInvalid, "bad_value"},
          std::pair{FindingCode::PduQuantityOutOfRange, "bad_quantity"},
          std::pair{FindingCode::PduByteCountMismatch, "bad_quantity"}}) {
        if (!q.violations.contains(violation)) continue;
        malformed = {violation, "the request: " + std::string(info(violation).summary)};
        due = Due{1, condition, 3, &malformed};
        break;
    }
    for (const auto& b : breaks) {
        std::optional<Due> d;
        switch (b.code) {
            case FindingCode::ProfileFunctionUnsupported:
                d = Due{0, "unsupported_function", 1, &b};
                break;
            case FindingCode::ProfileQuantityAboveLimit:
                d = Due{1, "bad_quantity", 3, &b};
                break;
            case FindingCode::ProfileAddressUnknown:
                d = Due{2, "bad_address", 2, &b};
                break;
            case FindingCode::ProfileWriteReadOnly:
                d = Due{2, "write_read_only", 2, &b};
                break;
            case FindingCode::ProfileValueOutOfRange:
                d = Due{3, "bad_value", 3, &b};
                break;
            default:
                break;
        }
        if (d && (!due || d->order < due->order)) due = d;
    }
    if (due && !profile.functions.implied_exceptions.count(due->condition)) {
        const std::uint8_t expected = exception_for(profile, due->condition, due->code);
        if (code != expected && code != 1)  // 1 to a supported function is said above
            out.push_back({FindingCode::ProfileExceptionUnexpected,
                           "exception " + std::to_string(code) + " where the manual of " + profile.id +
                               " answers exception " + std::to_string(expected) + " (" + due->why->message +
                               ")"});
    }
    return out;
}

namespace {

// What the device took: the request's writes when the response acknowledges them (its own function code,
// not an exception; AP §6.17: FC23 writes before it reads).
std::optional<WrittenRegisters> acknowledged_registers(const Pdu& q, const Pdu& a) {
    if (a.is_exception() || a.function_code() != q.function_code()) return std::nullopt;
    return written_registers(q);
}

// "ENDER (register 7)": the manual's mnemonic where it gives one.
std::string register_name(const Point& p) {
    return (p.mnemonic.empty() ? p.name_en : p.mnemonic) + " (register " + std::to_string(p.address) + ")";
}

// A line setting's code as a person says it: "ASCII", "2400 baud", "even parity".
std::string setting_text(LineSetting s, const std::string& means) {
    switch (s) {
        case LineSetting::Framing:
            return means == "ascii" ? "ASCII" : means == "rtu" ? "RTU" : means;
        case LineSetting::Baud:
            return means + " baud";
        case LineSetting::Parity:
            return means == "none" ? "no parity" : means + " parity";
        case LineSetting::UnitId:
            break;
    }
    return means;
}

// Every point a write request writes, with the value written (a coil as 0 or 1): holding registers (FC6,
// FC16, FC23's write part) and coils (FC5, FC15), those within the address space.
struct WrittenPoint {
    Table table;
    std::uint16_t address;
    std::uint16_t value;
};
std::vector<WrittenPoint> written_points(const Pdu& q) {
    std::vector<WrittenPoint> out;
    if (const auto w = written_registers(q))
        for (std::size_t i = 0; i < w->values.size(); ++i)
            out.push_back({Table::HoldingRegisters, static_cast<std::uint16_t>(w->start + i), w->values[i]});
    if (const auto* w = std::get_if<WriteSingle>(&q.body); w && q.function_code() == 5)
        out.push_back({Table::Coils, w->address, static_cast<std::uint16_t>(w->value == 0xFF00 ? 1 : 0)});
    if (const auto* w = std::get_if<WriteMultipleCoilsRequest>(&q.body))
        for (std::size_t i = 0;
             i < count_within_address_space(w->starting_address, w->quantity) && i / 8 < w->values.size();
             ++i)
            out.push_back({Table::Coils, static_cast<std::uint16_t>(w->starting_address + i),
                           static_cast<std::uint16_t>(bit_at(w->values, i) ? 1 : 0)});
    return out;
}

// "coil 0 (loop 1 operating mode (auto/manual)) holds 1 (automatic mode)"
std::string condition_text(const Profile& profile, const PointRef& when, std::uint16_t value) {
    std::string text =
        std::string(is_bit_table(when.table) ? "coil " : "register ") + std::to_string(when.address);
    const Point* c = profile.find(when.table, when.address);
    if (c) text += " (" + point_name(*c) + ")";
    text += " holds " + std::to_string(value);
    if (c)
        for (const auto& v : c->encoding.values)
            if (v.value == value) text += " (" + (v.text_en.empty() ? v.text : v.text_en) + ")";
    return text;
}

}  // namespace

std::optional<std::uint16_t> Semantics::known(const std::string& device, const Profile& profile,
                                              const PointRef& ref) const {
    const auto d = state_.find(device);
    if (d == state_.end()) return std::nullopt;
    const auto v = d->second.find({profile.resolve(ref.table), ref.address});
    if (v == d->second.end()) return std::nullopt;
    return v->second;
}

void Semantics::keep_state(const Profile& profile, const std::string& device, Table table,
                           std::uint16_t start, std::span<const std::uint16_t> values) {
    // Only what is asked later: a point another's access depends on, and the halves of 32-bit values (a
    // register map kept whole cost a fifth of a read-heavy capture's time).
    auto conditions = conditions_.find(&profile);
    if (conditions == conditions_.end()) {
        std::set<std::pair<Table, std::uint16_t>> refs;
        for (const Table t :
             {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters})
            for (const Point& p : profile.table(t))
                if (p.read_only_when)
                    refs.insert(
                        {profile.resolve(p.read_only_when->when.table), p.read_only_when->when.address});
        conditions = conditions_.emplace(&profile, std::move(refs)).first;
    }
    auto& state = state_[device];
    const Table resolved = profile.resolve(table);
    for (std::size_t i = 0; i < count_within_address_space(start, values.size()); ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        const Point* p = profile.find(resolved, address);
        if ((p && p->encoding.words == 2) || conditions->second.count({resolved, address}))
            state[{resolved, address}] = values[i];
    }
}

void Semantics::check_conditional(const Profile& profile, const std::string& device, const Pdu& q,
                                  std::vector<RuleBreak>& out, bool* unknown) const {
    for (const WrittenPoint& w : written_points(q)) {
        const Point* p = profile.find(w.table, w.address);
        if (!p || !p->read_only_when || p->access == Access::Read) continue;
        const auto& condition = *p->read_only_when;
        const auto now = known(device, profile, condition.when);
        if (!now) {
            if (unknown) *unknown = true;
            continue;
        }
        if (std::find(condition.values.begin(), condition.values.end(), *now) == condition.values.end())
            continue;
        out.push_back({FindingCode::ProfileWriteReadOnly,
                       "writes " + std::to_string(w.value) + " to " + std::to_string(w.address) + " (" +
                           point_name(*p) + ") while " + condition_text(profile, condition.when, *now) +
                           " as last seen, which makes it read-only [" + p->source + "]"});
    }
}

std::optional<Semantics::LineSettingsTold> Semantics::line_settings_written(
    const std::string& device, const Profile& profile, std::uint16_t start,
    std::span<const std::uint16_t> values, const std::string& how) const {
    const auto seen = holding_.find(device);
    std::string written, now;
    LineState settings;
    for (const Point& p : profile.table(Table::HoldingRegisters)) {
        if (!p.mirrors || *p.mirrors == LineSetting::UnitId || p.encoding.words != 1 || p.address < start ||
            std::size_t{p.address} - start >= values.size())
            continue;
        const std::uint16_t code = values[p.address - start];
        const EnumValue* v = mirrored_meaning(p, code);
        if (!v) continue;  // a code the manual does not define: a rule break
        if (seen != holding_.end()) {
            const auto before = seen->second.find(p.address);
            if (before != seen->second.end() && before->second == code)
                continue;  // read so before: no change
        }
        written += (written.empty() ? "" : ", ") + register_name(p) + " := " + std::to_string(code);
        now += (now.empty() ? "" : ", ") + setting_text(*p.mirrors, v->means);
        take_meaning(settings, *p.mirrors, v->means);
    }
    if (written.empty()) return std::nullopt;
    return LineSettingsTold{
        RuleBreak{FindingCode::ProfileLineSettingsChanged,
                  written + " " + how + ": the device talks " + now + " from now on (" + profile.id +
                      "'s manual); a master that keeps the old settings no longer reaches it"},
        settings, written, now};
}

std::optional<Semantics::LineSettingsTold> Semantics::follow_line_settings(const std::string& device,
                                                                           const Profile& profile,
                                                                           const Pdu& q, const Pdu& a) const {
    const auto w = acknowledged_registers(q, a);
    if (!w) return std::nullopt;
    return line_settings_written(device, profile, w->start, w->values, "acknowledged");
}

std::optional<Semantics::LineSettingsTold> Semantics::follow_broadcast_line_settings(
    const std::string& device, const Profile& profile, const Pdu& q) {
    if (!profile.functions.allows_broadcast(q.function_code())) return std::nullopt;
    for (const WrittenPoint& p : written_points(q))  // taken without a reply: as acknowledged writes are
        keep_state(profile, device, p.table, p.address, std::span<const std::uint16_t>(&p.value, 1));
    const auto w = written_registers(q);
    if (!w) return std::nullopt;
    auto told = line_settings_written(device, profile, w->start, w->values, "broadcast");
    keep(profile, device, Table::HoldingRegisters, w->start,
         w->values);  // taken without a reply: as an acknowledged write's values
    return told;
}

std::optional<RuleBreak> Semantics::follow_address(const std::string& server, const std::string& device,
                                                   const Profile& profile, const Pdu& q, const Pdu& a) {
    if (profile.open_address_space) return std::nullopt;
    const auto w = acknowledged_registers(q, a);
    if (!w) return std::nullopt;
    const std::uint16_t start = w->start;
    const std::span<const std::uint16_t> written(w->values);
    const Point* p = profile.address_register();
    if (!p || p->address < start) return std::nullopt;
    const std::size_t offset = p->address - start;
    if (offset >= written.size()) return std::nullopt;
    const std::uint16_t value = written[offset];
    if (value > 0xFF) return std::nullopt;
    const auto unit = static_cast<std::uint8_t>(value);
    moved_[{server.substr(0, server.rfind(':')), unit}] = &profile;
    if (const std::string there = server + " unit " + std::to_string(unit); there != device) {
        const auto move = [&](auto& memory) {
            auto node = memory.extract(device);
            memory.erase(there);
            if (!node.empty()) {
                node.key() = there;
                memory.insert(std::move(node));
            }
        };
        move(state_);
        move(registers_);
        move(holding_);
    }
    return RuleBreak{
        FindingCode::ProfileAddressMoved,
        register_name(*p) + " := " + std::to_string(unit) + " acknowledged: the device answers at unit " +
            std::to_string(unit) +
            (profile.line.disables(unit) ? ", which disables its communication (" + profile.id + "'s manual)"
                                         : " from now on (" + profile.id + "'s manual)")};
}

void Semantics::remember(const Profile& profile, const std::string& device, const Pdu& q, const Pdu& a) {
    if (a.is_exception()) return;
    if (const auto w = written_registers(q))
        keep(profile, device, Table::HoldingRegisters, w->start, w->values);  // FC23: before its read
    for (const WrittenPoint& p : written_points(q))
        keep_state(profile, device, p.table, p.address, std::span<const std::uint16_t>(&p.value, 1));
    const auto span = read_span(q);
    if (!span) return;
    if (const auto* regs = std::get_if<ReadRegistersResponse>(&a.body)) {
        keep(profile, device, span->table, span->start, regs->values);
        keep_state(profile, device, span->table, span->start, regs->values);
    }
    if (const auto* bits = std::get_if<ReadBitsResponse>(&a.body)) {
        std::vector<std::uint16_t> values;
        for (std::size_t i = 0; i < span->quantity && i / 8 < bits->values.size(); ++i)
            values.push_back(bit_at(bits->values, i) ? 1 : 0);
        keep_state(profile, device, span->table, span->start, values);
    }
}

void Semantics::keep(const Profile& profile, const std::string& device, Table table, std::uint16_t start,
                     std::span<const std::uint16_t> words) {
    // Every register in its table as the profile resolves it (a decimal point read by FC3 scales an FC4 value
    // of a device that serves one map through both; a device with two maps takes no 32-bit half from the
    // other), and the holding registers read or written apart (what a write of line settings changes).
    const bool holding_table = table == Table::HoldingRegisters;
    auto& context = registers_[device];
    auto& seen = profile.resolve(table) == Table::InputRegisters ? context.input : context.holding;
    auto& holding = holding_[device];
    for (std::size_t i = 0; i < count_within_address_space(start, words.size()); ++i) {
        seen[static_cast<std::uint16_t>(start + i)] = words[i];
        if (holding_table) holding[static_cast<std::uint16_t>(start + i)] = words[i];
    }
}

std::vector<NamedValue> Semantics::values(const Profile& profile, const std::string& device, const Pdu& q,
                                          const Pdu& a) {
    if (a.is_exception()) return {};
    remember(profile, device, q, a);
    const auto& seen = registers_[device];
    // A coil or discrete input under its name, and its value under the point's text for it where it has one.
    const auto named_bit = [&](Table table, std::uint16_t address, bool on) {
        NamedValue v;
        v.address = address;
        v.point = profile.find(table, address);
        v.raw = {static_cast<std::uint16_t>(on)};
        v.number = on;
        v.text = on ? "1" : "0";
        if (v.point)
            for (const auto& ev : v.point->encoding.values)
                if (ev.value == on) v.text = ev.text_en.empty() ? ev.text : ev.text_en;
        return v;
    };
    if (auto s = read_span(q)) {
        if (const auto* regs = std::get_if<ReadRegistersResponse>(&a.body))
            return decode_registers(profile, s->table, s->start, regs->values, seen);
        if (const auto* bits = std::get_if<ReadBitsResponse>(&a.body)) {
            std::vector<NamedValue> out;
            for (std::size_t i = 0;
                 i < count_within_address_space(s->start, s->quantity) && i / 8 < bits->values.size(); ++i)
                out.push_back(
                    named_bit(s->table, static_cast<std::uint16_t>(s->start + i), bit_at(bits->values, i)));
            return out;
        }
    }
    // Coils written, named as the registers written are (FC6, FC16, below); they were shown unnamed. FC5's
    // value is ON (FF00) or OFF (0000) only (AP §6.5): any other names no state.
    if (const auto* w = std::get_if<WriteSingle>(&q.body);
        w && q.function_code() == 5 && (w->value == 0xFF00 || w->value == 0x0000))
        return {named_bit(Table::Coils, w->address, w->value == 0xFF00)};
    if (const auto* w = std::get_if<WriteMultipleCoilsRequest>(&q.body)) {
        std::vector<NamedValue> out;
        for (std::size_t i = 0;
             i < count_within_address_space(w->starting_address, w->quantity) && i / 8 < w->values.size();
             ++i)
            out.push_back(named_bit(Table::Coils, static_cast<std::uint16_t>(w->starting_address + i),
                                    bit_at(w->values, i)));
        return out;
    }
    if (const auto* w = std::get_if<WriteSingle>(&q.body); w && q.function_code() == 6)
        return decode_registers(profile, Table::HoldingRegisters, w->address, {w->value}, seen);
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&q.body))
        return decode_registers(profile, Table::HoldingRegisters, w->starting_address, w->values, seen);
    return {};
}

}  // namespace mbscope::analyzer
