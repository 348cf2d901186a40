#include "conformance/oracle.hpp"

#include <algorithm>
#include <span>
#include <utility>

#include "conformance/context.hpp"
#include "modbus/addressing.hpp"
#include "modbus/adu.hpp"
#include "modbus/function_code.hpp"
#include "modbus/pdu.hpp"
#include "modbus/reply_fit.hpp"

namespace mbscope::conformance {

namespace tp = modbus::transport;
using modbus::Framing;
using modbus::Table;

std::string to_string(const OracleViolation& v) {
    return v.rule + " (" + v.source + "): expected " + v.expected + ", observed " + v.observed;
}

struct ExchangeOracle::Request {
    std::uint8_t unit = 0;
    bool checksum_ok = true;
    std::uint16_t protocol_id = 0;
    std::vector<std::uint8_t> pdu;
    std::optional<modbus::Pdu> decoded;  // nullopt: the structure could not be recovered
};

ExchangeOracle::ExchangeOracle(Framing framing, std::vector<Unit> units, bool ip_network)
    : framing_(framing), units_(std::move(units)), ip_network_(ip_network) {}

void ExchangeOracle::reset() {
    listen_only_.clear();
    listen_only_unknown_.clear();
    written_.clear();
}

void ExchangeOracle::moved(std::size_t index, std::uint8_t to) {
    if (index >= units_.size() || units_[index].id == to) return;
    const std::uint8_t from = std::exchange(units_[index].id, to);
    const auto rekey = [&](std::set<std::uint8_t>& units) {
        if (units.erase(from)) units.insert(to);
    };
    rekey(listen_only_);
    rekey(listen_only_unknown_);
    std::map<ShadowKey, std::uint16_t> written;
    for (const auto& [key, value] : written_) {
        auto k = key;
        if (std::get<0>(k) == from) std::get<0>(k) = to;
        written[k] = value;
    }
    written_ = std::move(written);
}

namespace {

Table table_of_fc(std::uint8_t fc) {
    return modbus::table_of_function(fc).value_or(Table::HoldingRegisters);
}

bool serial(Framing f) {
    return f != Framing::Tcp;
}

// FC8 sub-function 01 or 04 of any data: a request that may change a device's listen-only mode.
bool listen_only_diagnostics(std::span<const std::uint8_t> pdu) {
    return pdu.size() >= 3 && pdu[0] == 8 && pdu[1] == 0 && (pdu[2] == 1 || pdu[2] == 4);
}

std::string codes_text(const std::bitset<256>& codes) {
    std::string out;
    for (unsigned c = 0; c < codes.size(); ++c)
        if (codes.test(c)) out += (out.empty() ? "" : " or ") + exception_text(static_cast<std::uint8_t>(c));
    return out;
}

// The points the simulated process moves: their values are the process's, not the last write's.
bool simulated(const modbus::Profile& p, Table t, std::uint16_t address) {
    for (const auto& s : p.simulation.signals) {
        if (s.hidden || p.resolve(s.point.table) != p.resolve(t)) continue;
        const modbus::Point* point = p.find(s.point.table, s.point.address);
        const int words = point ? point->encoding.words : 1;
        if (address >= s.point.address && address < s.point.address + words) return true;
    }
    return false;
}

}  // namespace

std::optional<ExchangeOracle::Request> ExchangeOracle::decode_sent(
    const std::vector<std::uint8_t>& sent) const {
    modbus::Result<modbus::Frame> frame = modbus::decode_adu(framing_, sent);
    if (!frame) return std::nullopt;
    Request r;
    r.unit = frame->unit_id();
    r.checksum_ok = frame->checksum_ok;
    r.protocol_id = framing_ == Framing::Tcp ? frame->protocol_id() : 0;
    const auto pdu = frame->pdu();
    r.pdu.assign(pdu.begin(), pdu.end());
    if (auto d = modbus::decode_request(r.pdu); d) r.decoded = std::move(d).value();
    return r;
}

const ExchangeOracle::Unit* ExchangeOracle::route(std::uint8_t unit) const {
    for (const Unit& u : units_)
        if (u.id == unit) return &u;
    if (ip_network_ && units_.size() == 1 && (unit == 0xFF || units_.front().profile->line.any_unit_answered))
        return &units_.front();
    return nullptr;
}

ExchangeOracle::Expected ExchangeOracle::expect(const Request& r) const {
    Expected e;
    const auto silence = [&](const char* rule, const char* source) {
        e.silence = true;
        e.rule = rule;
        e.source = source;
        return e;
    };
    if (!r.checksum_ok) return silence("silence.bad_checksum", "SL §2.5.1.2");
    if (r.protocol_id != 0) return silence("silence.protocol_id", "TCP §3.1.3");
    if (r.pdu.empty()) return silence("silence.empty_pdu", "AP §4.1");
    if (r.unit == 0) {
        // A broadcast on a serial line is never answered (SL §2.1); over Modbus/TCP unit 0 is not a broadcast
        // address and the specification leaves the answer to the device.
        if (serial(framing_)) return silence("silence.broadcast", "SL §2.1");
        e.judged = false;
        return e;
    }
    const Unit* u = route(r.unit);
    // Address 0 set on a device disables its communication (MK-ADR-01, 000:220): over Modbus/TCP unit 0xFF
    // still reaches the lone device, which stays silent.
    if (u && u->id == 0) return silence("silence.address_disabled", "MK-ADR-01");
    if (!u) {
        if (serial(framing_)) return silence("silence.other_unit", "SL §2.1");
        // Over Modbus/TCP the unit id is of no use to a server reached by its IP address (TCP §4.4.1.2):
        // a lone device may serve any unit id as its own (pymodbus with one context, many embedded servers),
        // judged as its own request then; or refuse it as a gateway does (0A, 0B); or not answer. A normal
        // reply was "reply.other_unit", a finding saved against a device the specification lets do so.
        if (const Unit* lone = lone_on_ip(r.unit)) {
            Expected answer = expect_served(r, *lone);
            answer.silence_allowed = true;
            answer.exceptions.insert(0x0A);
            answer.exceptions.insert(0x0B);
            return answer;
        }
        // Several devices served: one that serves none of them: silence, or a gateway's exceptions 0A/0B.
        e.silence = true;
        e.exceptions = {0x0A, 0x0B};
        e.rule = "reply.other_unit";
        e.source = "TCP §4.4.1.2";
        return e;
    }
    return expect_served(r, *u);
}

const ExchangeOracle::Unit* ExchangeOracle::lone_on_ip(std::uint8_t unit) const {
    if (!ip_network_ || units_.size() != 1 || unit == 0 || route(unit)) return nullptr;
    return &units_.front();
}

const ExchangeOracle::Unit* ExchangeOracle::served_by(std::uint8_t unit) const {
    const Unit* u = route(unit);
    return u ? u : lone_on_ip(unit);
}

ExchangeOracle::Expected ExchangeOracle::expect_served(const Request& r, const Unit& u) const {
    const auto silence = [](const char* rule, const char* source) {
        Expected e;
        e.silence = true;
        e.rule = rule;
        e.source = source;
        return e;
    };
    // A PDU longer than the device takes (AP §4.1's 253 bytes, or its manual's limit) reaches it only over
    // Modbus/TCP: not a request it can handle. No reply, or a refusal; never a normal reply, which would
    // carry the over-long PDU back (an FC8 echo of 256 bytes is a 263-byte ADU).
    if (r.pdu.size() > u.profile->line.pdu_max_bytes) {
        Expected e = silence("silence.pdu_too_long", "AP §4.1");
        e.exceptions = {0x01, 0x03};
        return e;
    }
    if (listen_only_unknown_.count(u.id)) {
        Expected e;
        e.judged = false;  // silence and a reply may both be right (see judge())
        return e;
    }
    if (listen_only_.count(u.id)) {
        // Only "restart communications" acts, and even it is not answered (AP §6.8.1 sub-function 01).
        return silence(modbus::is_restart_communications(r.pdu) ? "silence.restart_from_listen_only"
                                                                : "silence.listen_only",
                       "AP §6.8.1");
    }
    Expected answer = expect_pdu(r, *u.profile);
    // The generic profile knows no device's functions either: one it does not implement is refused (AP §7,
    // 01). libmodbus's server, which has no FC8, was "exception for valid" on every diagnostics request, and
    // "expected exception 03" on a malformed one: the state diagrams of AP §6 test the function code before
    // the data, so 01 is right whatever else the request gets wrong.
    if (u.profile->open_address_space && !answer.silence) answer.exceptions.insert(0x01);
    if (framing_ == Framing::Rtu) {
        const auto predicted = modbus::predict_pdu_length(r.pdu, modbus::Direction::Request);
        answer.silence_allowed =
            predicted.kind != modbus::LengthPrediction::Kind::Known || predicted.length != r.pdu.size();
    }
    return answer;
}

ExchangeOracle::Expected ExchangeOracle::expect_pdu(const Request& r, const modbus::Profile& p) const {
    Expected e;
    const std::uint8_t fc = r.pdu[0];
    const auto refuse = [&](std::uint8_t code, const char* rule, const char* source) {
        e.exceptions = {code};
        e.rule = rule;
        e.source = source;
        return e;
    };
    if ((fc & 0x80) != 0 || !p.functions.supports(fc))
        return refuse(modbus::exception_for(p, "unsupported_function", 0x01), "reply.unsupported_function",
                      "AP §7 (exception 01)");
    // The structure cannot be recovered: the data are inconsistent with the function (AP §7, code 03).
    if (!r.decoded) return refuse(0x03, "reply.malformed_request", "AP §7 (exception 03)");
    const modbus::Pdu& req = *r.decoded;
    const auto bad_quantity = [&](std::uint32_t q, bool write_part = false) {
        const int max = p.functions.max_for(fc, write_part);
        return q == 0 || (max > 0 && q > static_cast<std::uint32_t>(max));
    };
    const std::uint8_t quantity_code = modbus::exception_for(p, "bad_quantity", 0x03);
    const bool byte_count_wrong = req.violations.contains(modbus::FindingCode::PduByteCountMismatch);
    const auto write_check = [&](Table t, std::uint16_t start, const std::vector<std::uint16_t>& values) {
        if (start + values.size() > 65536u)
            return refuse(modbus::exception_for(p, "bad_address", 0x02), "reply.address",
                          "AP §6 (exception 02)");
        if (auto rej = modbus::check_writes(p, t, start, values))
            return refuse(rej->exception_code, "reply.rejected_write", "profile ranges and access");
        e.normal = true;
        // The generic profile knows no device's map: an address it lacks (02) and a value out of its range
        // (03) are the device's to refuse (AP §7). `check` probes the address space; a fuzzer does not.
        if (p.open_address_space) {
            e.exceptions.insert(modbus::exception_for(p, "bad_address", 0x02));
            e.exceptions.insert(modbus::exception_for(p, "bad_value", 0x03));
        }
        // A limit held in another register (MK-RNG-02), and a lone half of a 32-bit value (judged with the
        // other half the device holds), depend on the image: 03 may also be right.
        const std::uint32_t end = start + static_cast<std::uint32_t>(values.size());
        for (std::size_t i = 0; i < values.size(); ++i) {
            const auto* pt = p.find(t, static_cast<std::uint16_t>(start + i));
            if (pt && (pt->min_from || pt->max_from ||
                       (pt->encoding.words == 2 && (pt->address < start || pt->address + 2u > end))))
                e.exceptions.insert(modbus::exception_for(p, "bad_value", 0x03));
            // Read-only while another point holds certain values (conditional_access): so is its refusal.
            if (pt && pt->read_only_when)
                e.exceptions.insert(modbus::exception_for(p, "write_read_only", 0x02));
        }
        return e;
    };
    switch (fc) {
        case 1:
        case 2:
        case 3:
        case 4: {
            const auto& rr = std::get<modbus::ReadRequest>(req.body);
            if (bad_quantity(rr.quantity))
                return refuse(quantity_code, "reply.quantity", "AP §6 (exception 03)");
            if (auto code = modbus::check_read(p, table_of_fc(fc), rr.starting_address, rr.quantity))
                return refuse(*code, "reply.address", "AP §6 (exception 02)");
            e.normal = true;
            // The generic profile knows no device's map: an address the device lacks is refused (AP §7, 02).
            // Against libmodbus's server (10,000 registers) every read past them was "exception for valid".
            if (p.open_address_space) e.exceptions.insert(modbus::exception_for(p, "bad_address", 0x02));
            return e;
        }
        case 5: {
            const auto& w = std::get<modbus::WriteSingle>(req.body);
            if (w.value != 0xFF00 && w.value != 0x0000) return refuse(0x03, "reply.coil_value", "AP §6.5");
            return write_check(Table::Coils, w.address, {static_cast<std::uint16_t>(w.value ? 1 : 0)});
        }
        case 6: {
            const auto& w = std::get<modbus::WriteSingle>(req.body);
            return write_check(Table::HoldingRegisters, w.address, {w.value});
        }
        case 15: {
            const auto& w = std::get<modbus::WriteMultipleCoilsRequest>(req.body);
            if (bad_quantity(w.quantity)) return refuse(quantity_code, "reply.quantity", "AP §6.11");
            if (byte_count_wrong || w.values.size() * 8 < w.quantity)
                return refuse(0x03, "reply.byte_count", "AP §6.11");
            std::vector<std::uint16_t> values(w.quantity);
            for (std::size_t i = 0; i < w.quantity; ++i)
                values[i] = modbus::bit_at(w.values, i) ? 1 : 0;
            return write_check(Table::Coils, w.starting_address, values);
        }
        case 16: {
            const auto& w = std::get<modbus::WriteMultipleRegistersRequest>(req.body);
            if (bad_quantity(w.quantity)) return refuse(quantity_code, "reply.quantity", "AP §6.12");
            if (byte_count_wrong || w.values.size() != w.quantity)
                return refuse(0x03, "reply.byte_count", "AP §6.12");
            return write_check(Table::HoldingRegisters, w.starting_address, w.values);
        }
        case 8: {
            const auto& d = std::get<modbus::Diagnostics>(req.body);
            const auto& subs = p.functions.diagnostics;
            if (std::find(subs.begin(), subs.end(), d.sub_function) == subs.end())
                return refuse(modbus::exception_for(p, "fc8_unknown_sub_function", 0x01), "reply.diagnostics",
                              "AP §6.8");
            if (req.violations.contains(modbus::FindingCode::PduDiagnosticDataLength))
                return refuse(0x03, "reply.diagnostics", "AP §6.8.1 (one data field)");
            if (d.sub_function == 0x04) {  // force listen only mode: no response (AP §6.8.1)
                e.silence = true;
                e.rule = "silence.listen_only";
                e.source = "AP §6.8.1";
                // Data other than 00 00 may be refused (AP §6.8's state diagram); silence is then the mode.
                if (!modbus::diagnostic_request_data_defined(d.sub_function, d.data)) e.exceptions = {0x03};
                return e;
            }
            e.normal = true;
            if (d.sub_function != 0x00) e.exceptions = {0x03};  // the sub-function's data may be refused
            return e;
        }
        default:
            // Functions whose outcome depends on what the oracle does not model (event logs, FIFOs, file
            // records, identification objects): any reply of the right form.
            e.normal = true;
            e.exceptions = {0x01, 0x02, 0x03, 0x04};
            return e;
    }
}

void ExchangeOracle::check_normal_shape(const Request& r, const modbus::Pdu& reply,
                                        std::vector<OracleViolation>& out) const {
    if (!r.decoded) return;
    const auto misfit = modbus::reply_misfit(*r.decoded, reply);
    if (!misfit) return;
    using Kind = modbus::ReplyMisfit::Kind;
    const char* rule = misfit->kind == Kind::DataSize  ? "reply.byte_count"
                       : misfit->kind == Kind::Padding ? "reply.padding"
                                                       : "reply.echo";
    out.push_back({rule, misfit->source, misfit->expected,
                   misfit->differs.empty() ? "a response that differs" : "a response: " + misfit->differs});
}

bool ExchangeOracle::tracked(const modbus::Profile& p, Table t, std::uint16_t address) const {
    if (simulated(p, t, address)) return false;
    if (p.coils_view_registers && t == Table::Coils) return false;  // views of registers: tracked there
    if (p.open_address_space) return true;
    const modbus::Point* point = p.find(t, address);
    return point && !point->reserved && point->access == modbus::Access::ReadWrite && !point->fixed_value;
}

void ExchangeOracle::forget_points_written(const Request& r) {
    // The points a write names (FC5, 6, 15, 16): what they hold is unknown. Mask writes and FC23 are not
    // modelled point by point: everything written on the unit is.
    const Unit* u = served_by(r.unit);
    if (!u || !r.decoded) return;
    const modbus::Profile& p = *u->profile;
    const auto forget = [&](Table t, std::uint16_t start, std::uint32_t quantity) {
        for (std::uint32_t i = 0; i < quantity && start + i <= 0xFFFF; ++i) {
            const auto address = static_cast<std::uint16_t>(start + i);
            written_.erase(ShadowKey{u->id, static_cast<int>(p.resolve(t)), address});
            // Walchem: a coil write sets the register at its address (002:244, 493).
            if (t == Table::Coils && p.coils_view_registers)
                written_.erase(
                    ShadowKey{u->id, static_cast<int>(p.resolve(Table::HoldingRegisters)), address});
        }
    };
    const modbus::Pdu& q = *r.decoded;
    switch (q.function_code()) {
        case 5:
            forget(Table::Coils, std::get<modbus::WriteSingle>(q.body).address, 1);
            return;
        case 6:
            forget(Table::HoldingRegisters, std::get<modbus::WriteSingle>(q.body).address, 1);
            return;
        case 15: {
            const auto& w = std::get<modbus::WriteMultipleCoilsRequest>(q.body);
            forget(Table::Coils, w.starting_address, w.quantity);
            return;
        }
        case 16: {
            const auto& w = std::get<modbus::WriteMultipleRegistersRequest>(q.body);
            forget(Table::HoldingRegisters, w.starting_address, w.quantity);
            return;
        }
        default:
            forget_written(r);
            return;
    }
}

void ExchangeOracle::forget_written(const Request& r) {
    // Writes the oracle does not model (mask write, FC23, broadcasts): the addresses they touch are unknown.
    if (!r.decoded) return;
    const Unit* u = served_by(r.unit);
    std::erase_if(written_, [&](const auto& kv) { return !u || std::get<0>(kv.first) == u->id; });
}

void ExchangeOracle::learn(const Request& r, const modbus::Pdu& reply) {
    const Unit* u = route(r.unit);
    if (!u || !r.decoded || reply.is_exception()) return;
    const modbus::Profile& p = *u->profile;
    const modbus::Pdu& req = *r.decoded;
    const std::uint8_t fc = req.function_code();
    const auto key = [&](Table t, std::uint32_t address) {
        return ShadowKey{u->id, static_cast<int>(p.resolve(t)), static_cast<std::uint16_t>(address)};
    };
    const auto remember = [&](Table t, std::uint16_t start, const std::vector<std::uint16_t>& values) {
        for (std::size_t i = 0; i < values.size(); ++i) {
            const auto address = static_cast<std::uint16_t>(start + i);
            const modbus::Point* point = p.open_address_space ? nullptr : p.find(t, address);
            // Half of a 32-bit value written alone: the device may keep the pair consistent its own way.
            const bool whole = !point || point->encoding.words == 1 ||
                               (point->address >= start && point->address + 1u < start + values.size());
            if (tracked(p, t, address) && whole)
                written_[key(t, address)] = values[i];
            else
                written_.erase(key(t, address));
            // Walchem: a coil write sets the register at its address to 1 or 0 (002:244, 493).
            if (t == Table::Coils && p.coils_view_registers)
                written_.erase(key(Table::HoldingRegisters, address));
        }
    };
    switch (fc) {
        case 5: {
            const auto& w = std::get<modbus::WriteSingle>(req.body);
            remember(Table::Coils, w.address, {static_cast<std::uint16_t>(w.value ? 1 : 0)});
            return;
        }
        case 6: {
            const auto& w = std::get<modbus::WriteSingle>(req.body);
            remember(Table::HoldingRegisters, w.address, {w.value});
            return;
        }
        case 15: {
            const auto& w = std::get<modbus::WriteMultipleCoilsRequest>(req.body);
            std::vector<std::uint16_t> values(w.quantity);
            for (std::size_t i = 0; i < w.quantity; ++i)
                values[i] = modbus::bit_at(w.values, i) ? 1 : 0;
            remember(Table::Coils, w.starting_address, values);
            return;
        }
        case 16: {
            const auto& w = std::get<modbus::WriteMultipleRegistersRequest>(req.body);
            remember(Table::HoldingRegisters, w.starting_address, w.values);
            return;
        }
        case 8:
            if (std::get<modbus::Diagnostics>(req.body).sub_function == 0x01) listen_only_.erase(u->id);
            return;
        case 22:  // mask write and read/write multiple: what they stored is not modelled
        case 23:
            forget_written(r);
            return;
        default:
            return;
    }
}

namespace {

// The bytes of an RTU request cut where its function code says it ends, when that is before the end and
// the cut is a CRC-valid frame; nothing otherwise.
std::optional<std::vector<std::uint8_t>> rtu_content_frame(const std::vector<std::uint8_t>& sent) {
    if (sent.size() < 5) return std::nullopt;
    const std::span<const std::uint8_t> pdu(sent.data() + 1, sent.size() - 3);
    const auto predicted = modbus::predict_pdu_length(pdu, modbus::Direction::Request);
    if (predicted.kind != modbus::LengthPrediction::Kind::Known || predicted.length < 1) return std::nullopt;
    const std::size_t length = 1 + predicted.length + 2;
    if (length >= sent.size()) return std::nullopt;
    std::vector<std::uint8_t> cut(sent.begin(), sent.begin() + static_cast<std::ptrdiff_t>(length));
    const auto frame = modbus::decode_adu(Framing::Rtu, cut);
    if (!frame || !frame->checksum_ok) return std::nullopt;
    return cut;
}

}  // namespace

std::vector<OracleViolation> ExchangeOracle::judge(const tp::Exchange& ex,
                                                   std::optional<bool> state_changed) {
    if (framing_ == Framing::Rtu && !ex.received.empty()) {
        if (auto cut = rtu_content_frame(ex.sent)) {
            // Judged on a copy first: what it learns (writes, listen-only mode) is kept only if the reply
            // was the cut request's. Rare (a CRC that also holds over a prefix), so the copy costs nothing.
            ExchangeOracle as_cut = *this;
            tp::Exchange shorter = ex;
            shorter.sent = std::move(*cut);
            auto found = as_cut.judge_frame(shorter, state_changed);
            if (found.empty()) {
                *this = std::move(as_cut);
                return found;
            }
        }
    }
    return judge_frame(ex, state_changed);
}

std::vector<OracleViolation> ExchangeOracle::judge_frame(const tp::Exchange& ex,
                                                         std::optional<bool> state_changed) {
    std::vector<OracleViolation> out;
    const auto r = decode_sent(ex.sent);
    if (!r) return out;  // not a frame: nothing the rules say about it
    // Unit 0: a broadcast on a serial line, and executed as one by many Modbus/TCP devices (the reference
    // slave among them) though TCP does not define it: what it may have written is no longer known.
    if (r->unit == 0 && r->decoded) written_.clear();
    // Whether a broadcast diagnostics request acts is not said anywhere: SL §2.1 lets a broadcast carry
    // writes, AP §6.8.1 speaks of "the addressed remote device". After a broadcast that may force listen-only
    // mode (04) or leave it (01), a device's mode is unknown until it answers (it is not in the mode) or is
    // sent an addressed restart (it is out of the mode either way); until then its silence and its replies
    // are not judged.
    if (r->unit == 0 && r->checksum_ok && listen_only_diagnostics(r->pdu)) {
        const bool force = r->pdu[2] == 4;
        for (const Unit& unit : units_) {
            if (!force && !listen_only_.count(unit.id)) continue;  // a restart outside the mode changes none
            listen_only_unknown_.insert(unit.id);
            listen_only_.erase(unit.id);
        }
    }
    // Late replies to earlier requests (set aside by the client's ReplyScanner: over Modbus/TCP by
    // transaction id, over RTU and ASCII by what they answer) are not this request's.
    const std::size_t own = ex.own_received().size();
    const bool silent = own == 0;
    const Unit* u = route(r->unit);
    if (u && r->checksum_ok && listen_only_unknown_.count(u->id)) {
        const bool restart = modbus::is_restart_communications(r->pdu);
        if (silent && !restart) return out;  // still unknown
        listen_only_unknown_.erase(u->id);
        if (silent) return out;  // a restart that left the mode, unanswered as AP §6.8.1 says
    }
    // A write the reply does not settle (no reply where one was due, a reply that is neither its
    // acknowledgement nor its refusal, an acknowledgement unlike the request) may have been done or not:
    // what the unit was written is unknown until read again. A refusal (not done, AP §7) and a clean
    // acknowledgement settle it; so does silence where the rules demand it (the request was not taken).
    struct WriteOutcome {
        ExchangeOracle& oracle;
        const Request& request;
        bool settled;
        ~WriteOutcome() {
            if (!settled) oracle.forget_points_written(request);
        }
    };
    // Another unit's request to a lone device over Modbus/TCP (lone_on_ip): a device serving it as its own
    // took its write or its listen-only switch, a gateway passed it on; which, the replies do not tell.
    const Unit* lone = u ? nullptr : lone_on_ip(r->unit);
    WriteOutcome write_outcome{*this, *r, (!u && !lone) || !r->decoded || !modbus::writes_points(r->pdu[0])};
    const Expected e = expect(*r);
    // (A restart outside listen-only mode changes none: as for a broadcast, above.)
    if (lone && r->checksum_ok && listen_only_diagnostics(r->pdu) &&
        (r->pdu[2] == 4 || listen_only_.count(lone->id))) {
        listen_only_unknown_.insert(lone->id);
        listen_only_.erase(lone->id);
    }
    if (!e.judged) return out;
    // The reply in words, only for a violation: most exchanges keep every rule, and describing one decodes
    // the reply again and formats text.
    const auto fail = [&](std::string_view rule, std::string_view source, std::string expected) {
        out.push_back({std::string(rule), std::string(source), std::move(expected), describe(ex)});
    };
    const bool is_listen_only_request =
        e.silence && e.rule == "silence.listen_only" && u && !listen_only_.count(u->id);

    if (silent) {
        if (e.silence && !state_changed.value_or(false)) write_outcome.settled = true;
        if (!e.silence && !e.silence_allowed) fail("reply.missing", "AP §4.1, SL §2.1", "a reply");
        if (is_listen_only_request) listen_only_.insert(u->id);
        // A restart that leaves listen-only mode is not answered (AP §6.8.1). Nothing else leaves it: not a
        // frame the device never took (a bad checksum, another unit's).
        if (u && e.rule == "silence.restart_from_listen_only") listen_only_.erase(u->id);
        if (state_changed.value_or(false) && !(r->unit == 0 && r->decoded && r->checksum_ok))
            fail("state.changed_without_reply", "AP §4.1", "no change of the device's registers");
        return out;
    }
    const auto pdu = response_pdu(ex);
    const bool exception_allowed_silence = e.silence && !e.exceptions.empty();
    if (e.silence && !exception_allowed_silence) {
        fail(e.rule, e.source, "no reply");
        return out;
    }
    if (!ex.response) {
        fail("reply.unframed", "AP §4.1", "a reply framed like the request");
        return out;
    }
    if (!ex.response->checksum_ok) {
        fail("reply.checksum", framing_ == Framing::Ascii ? "SL §2.5.2.2" : "SL §2.5.1.2",
             "a reply with a valid checksum");
        return out;
    }
    if (const auto envelope = envelope_fault(ex); !envelope.empty()) {
        fail("reply.envelope", framing_ == Framing::Tcp ? "TCP §3.1.3" : "SL §2.1",
             "the request's transaction, protocol and unit identifiers");
        return out;
    }
    const auto bytes = ex.response->pdu();
    if (bytes.empty() || (bytes[0] & 0x7F) != (r->pdu[0] & 0x7F)) {
        fail("reply.function", "AP §4.1", "a reply to function " + std::to_string(r->pdu[0] & 0x7F));
        return out;
    }
    // Notes and warnings (a function code that is not public, an exception code the specification does not
    // define) are not malformations; the exception code is judged below.
    const bool malformed = !pdu || std::any_of(pdu->violations.begin(), pdu->violations.end(), [](auto code) {
        return modbus::info(code).severity == modbus::Severity::Error;
    });
    if (malformed) {
        fail("reply.malformed", "AP §6", "a well-formed reply");
        return out;
    }
    if (own > ex.response->wire_length) {
        // The same reply again is a request answered twice (a transmit buffer sent again), not a longer one.
        if (tp::repeats_response(ex))
            fail("reply.duplicate", "SL §2.1, AP §4.1", "one reply to one request");
        else
            fail("reply.trailing_bytes", "AP §4.1", "nothing after the reply");
    }
    if (pdu->is_exception()) {
        const auto code = std::get<modbus::ExceptionResponse>(pdu->body).exception_code;
        if (!e.exceptions.count(code)) {
            const std::string expected =
                e.normal ? (e.exceptions.empty() ? "a normal response"
                                                 : "a normal response or " + codes_text(e.exceptions.bits))
                         : codes_text(e.exceptions.bits);
            fail(e.normal ? "reply.exception_for_valid" : e.rule, e.normal ? "AP §4.1" : e.source, expected);
        }
        if (state_changed.value_or(false))
            fail("state.changed_on_exception", "AP §7", "no change of the device's registers");
        else
            write_outcome.settled = true;
        return out;
    }
    if (!e.normal) {
        fail(e.rule, e.source, codes_text(e.exceptions.bits));
        return out;
    }
    const std::size_t before_shape = out.size();
    check_normal_shape(*r, *pdu, out);
    // An acknowledgement like the request settles it (a repeat or bytes after it do not unsettle the
    // write); one unlike it (another value, another quantity) leaves which values were stored unknown.
    if (out.size() == before_shape && !lone) write_outcome.settled = true;
    // Values written with an acknowledgement read back as written.
    if (u && r->decoded) {
        const modbus::Pdu& req = *r->decoded;
        const std::uint8_t fc = req.function_code();
        if (fc >= 1 && fc <= 4) {
            const auto& rr = std::get<modbus::ReadRequest>(req.body);
            const modbus::Profile& p = *u->profile;
            const Table t = table_of_fc(fc);
            for (std::uint32_t i = 0; i < rr.quantity; ++i) {
                const auto address = static_cast<std::uint16_t>(rr.starting_address + i);
                const auto it = written_.find(ShadowKey{u->id, static_cast<int>(p.resolve(t)), address});
                if (it == written_.end()) continue;
                std::uint16_t got = 0;
                if (const auto* regs = std::get_if<modbus::ReadRegistersResponse>(&pdu->body)) {
                    if (i >= regs->values.size()) break;
                    got = regs->values[i];
                } else if (const auto* bits = std::get_if<modbus::ReadBitsResponse>(&pdu->body)) {
                    if (i / 8 >= bits->values.size()) break;
                    got = modbus::bit_at(bits->values, i) ? 1 : 0;
                }
                if (got != it->second) {
                    out.push_back({"state.lost_write", "AP §6.6, §6.12 (a write acknowledged is done)",
                                   "address " + std::to_string(address) + " reads " +
                                       std::to_string(it->second) + ", the value written",
                                   "it reads " + std::to_string(got)});
                    break;
                }
            }
        }
    }
    learn(*r, *pdu);
    return out;
}

std::string ExchangeOracle::expectation(const std::vector<std::uint8_t>& sent) const {
    const auto r = decode_sent(sent);
    if (!r) return "";
    const Expected e = expect(*r);
    if (!e.judged) return "";
    if (e.silence) return e.exceptions.empty() ? "no reply" : "no reply or " + codes_text(e.exceptions.bits);
    const std::string quiet = e.silence_allowed ? ", or no reply" : "";
    if (!e.normal) return codes_text(e.exceptions.bits) + quiet;
    return (e.exceptions.empty() ? "a normal response"
                                 : "a normal response or " + codes_text(e.exceptions.bits)) +
           quiet;
}

ExchangeOracle::Answer ExchangeOracle::answer_due(const std::vector<std::uint8_t>& sent) const {
    const auto r = decode_sent(sent);
    if (!r) return Answer::Unjudged;
    const Expected e = expect(*r);
    if (!e.judged) return Answer::Unjudged;
    if (e.silence) return Answer::Silence;
    return e.silence_allowed ? Answer::Optional : Answer::Reply;
}

}  // namespace mbscope::conformance
