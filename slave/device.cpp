#include "slave/device.hpp"

#include <algorithm>
#include <string>

#include "modbus/addressing.hpp"
#include "modbus/function_code.hpp"

namespace mbscope::slave {

using modbus::Pdu;
using modbus::Table;

namespace {

constexpr std::uint8_t exc_illegal_function = 0x01;
constexpr std::uint8_t exc_illegal_address = 0x02;
constexpr std::uint8_t exc_illegal_value = 0x03;
constexpr std::uint8_t exc_device_failure = 0x04;

bool has_violation(const Pdu& pdu, modbus::FindingCode code) {
    return pdu.violations.contains(code);
}

// The specification's own limit for a function (AP §6), the most any device may be asked to carry.
int specification_max(std::uint8_t fc, bool write_part) {
    return modbus::FunctionRules{}.max_for(fc, write_part);
}

std::vector<std::uint8_t> encode(const Pdu& pdu) {
    return modbus::encode_pdu(pdu);
}

// A limit held by another register (MK-RNG-02, 000:623: a lower input or retransmission limit must not exceed
// the upper one). modbus::check_writes knows the map only; the device also knows the other register's value:
// the one written in the same block when the block holds it, else the one the image holds.
std::optional<modbus::WriteRejection> check_linked_limits(const modbus::Profile& profile,
                                                          const RegisterImage& image, Table t,
                                                          std::uint16_t start,
                                                          const std::vector<std::uint16_t>& values) {
    const auto signed_value = [](const modbus::Point* p, std::uint16_t raw) -> std::int64_t {
        const bool is_signed = p && (p->encoding.type == modbus::EncodingType::S16 || p->encoding.is_signed);
        return is_signed ? static_cast<std::int16_t>(raw) : raw;
    };
    const auto value_at = [&](const modbus::PointRef& ref) {
        const bool in_block = profile.resolve(ref.table) == profile.resolve(t) && ref.address >= start &&
                              ref.address - start < static_cast<int>(values.size());
        const std::uint16_t raw = in_block ? values[ref.address - start] : image.reg(ref.table, ref.address);
        return signed_value(profile.find(ref.table, ref.address), raw);
    };
    for (std::size_t i = 0; i < values.size(); ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        const modbus::Point* p = profile.find(t, address);
        if (!p || p->reserved || p->access == modbus::Access::Read || p->encoding.words == 2) continue;
        const std::int64_t v = signed_value(p, values[i]);
        const auto bad = [&](const char* why, const modbus::PointRef& ref) {
            return modbus::WriteRejection{
                modbus::exception_for(profile, "bad_value", exc_illegal_value), address,
                "value " + std::to_string(v) + " " + why + " register " + std::to_string(ref.address)};
        };
        if (p->min_from && v < value_at(*p->min_from)) return bad("below the limit held in", *p->min_from);
        if (p->max_from && v > value_at(*p->max_from)) return bad("above the limit held in", *p->max_from);
    }
    return std::nullopt;
}

// A point the manual makes read-only while another holds certain values (conditional_access): refused as a
// read-only point is, with what the device holds now.
std::optional<modbus::WriteRejection> check_conditional_access(const modbus::Profile& profile,
                                                               const RegisterImage& image, Table t,
                                                               std::uint16_t start, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        const modbus::Point* p = profile.find(t, address);
        if (!p || !p->read_only_when) continue;
        const auto& when = p->read_only_when->when;
        const std::uint16_t now = modbus::is_bit_table(when.table)
                                      ? (image.bit(when.table, when.address) ? 1 : 0)
                                      : image.reg(when.table, when.address);
        const auto& values = p->read_only_when->values;
        if (std::find(values.begin(), values.end(), now) != values.end())
            return modbus::WriteRejection{
                modbus::exception_for(profile, "write_read_only", exc_illegal_address), address,
                "read-only while " + std::string(modbus::to_string(when.table)) + " " +
                    std::to_string(when.address) + " holds " + std::to_string(now)};
    }
    return std::nullopt;
}

}  // namespace

Device::Device(const modbus::Profile& profile, std::uint8_t unit, FaultSet* faults)
    : Device(profile, modbus::LineState{unit, std::nullopt, std::nullopt, std::nullopt}, faults) {}

Device::Device(const modbus::Profile& profile, const modbus::LineState& line, FaultSet* faults)
    : profile_(&profile),
      unit_(line.unit),
      configured_unit_(line.unit),
      faults_(faults ? faults : &no_faults_),
      image_(profile, line),
      address_register_(profile.address_register()) {}

void Device::reset() noexcept {
    image_.reset();
    counters_ = Counters{};
    listen_only_ = false;
    unit_ = configured_unit_;
    off_line_ = false;
}

modbus::LineState Device::held_line() const {
    auto held = modbus::held_line_settings(
        *profile_, [this](std::uint16_t a) { return image_.reg(Table::HoldingRegisters, a); });
    held.unit = unit_;
    return held;
}

modbus::LineState Device::made_line() const {
    auto made =
        modbus::held_line_settings(*profile_, [this](std::uint16_t a) { return image_.initial_holding(a); });
    made.unit = configured_unit_;
    return made;
}

void Device::follow_address() noexcept {
    if (!address_register_) return;
    const std::uint16_t held = image_.reg(Table::HoldingRegisters, address_register_->address);
    if (held <= 0xFF) unit_ = static_cast<std::uint8_t>(held);
}

void Device::count_frame(bool checksum_ok) noexcept {
    ++counters_.bus_messages;
    if (!checksum_ok) ++counters_.bus_comm_errors;
}

bool Device::frozen(Table t, std::uint16_t address) const noexcept {
    if (modbus::is_bit_table(t)) return false;
    for (const std::uint16_t stuck : faults_->stuck_addresses()) {
        if (stuck == address) return true;
        // An address of an alternative map (Walchem) is stuck where its value is held: its object's field.
        const modbus::Point* p = profile_->find(Table::HoldingRegisters, stuck);
        if (p && p->same_value_as &&
            static_cast<std::uint16_t>(*p->same_value_as + (stuck - p->address)) == address)
            return true;
    }
    return false;
}

std::uint16_t Device::acknowledged(std::uint16_t quantity) {
    return faults_->fires(Fault::WrongQuantity) ? static_cast<std::uint16_t>(quantity + 1) : quantity;
}

std::uint16_t Device::served(std::uint16_t address) const noexcept {
    return faults_->enabled(Fault::OffByOneAddress) ? static_cast<std::uint16_t>(address + 1) : address;
}

std::vector<std::uint8_t> Device::exception(std::uint8_t fc, std::uint8_t code) {
    ++counters_.exceptions;
    if (faults_->enabled(Fault::WrongException))
        code = static_cast<std::uint8_t>(faults_->arg(Fault::WrongException));
    return encode(modbus::make_exception(fc, code));
}

void Device::take_back_write() noexcept {
    // handle() counted the write as a completion; it was not one.
    --counters_.event_count;  // the exact inverse, wrap-round included
    follow_address();         // a new address taken back with the write
}

std::vector<std::uint8_t> Device::refuse_taken_back_write(std::uint8_t fc) {
    take_back_write();  // the acknowledgement handle() made is never sent
    return exception(fc & 0x7F, exc_device_failure);
}

Reply Device::handle(const Request& request) {
    Reply reply;
    if (request.pdu.empty()) return reply;
    // Longer than the device takes (AP §4.1's 253 bytes, or what its manual allows): only Modbus/TCP can
    // carry it, and a Modbus/TCP stack with a serial line's buffer does not handle it: a character overrun
    // (AP §6.8.1, sub-function 0x12), not answered, not a message processed. Echoed, an FC8 query of 254-256
    // bytes made a reply longer than the specification's 260-byte ADU.
    if (request.pdu.size() > profile_->line.pdu_max_bytes) {
        ++counters_.overruns;
        return reply;
    }
    ++counters_.server_messages;
    const std::uint8_t fc = request.pdu[0];
    const bool answer_broadcast = request.broadcast && faults_->fires(Fault::ReplyToBroadcast);

    // AP §6.8.1: in listen-only mode (sub-function 04) only "restart communications" (sub-function 01, data
    // 0000 or FF00) is acted upon, and even it is not answered ("no response is returned"). Only when it is
    // addressed to the device: a broadcast runs writes alone (SL §2.1), so a broadcast restart no more
    // leaves the mode than a broadcast sub-function 04 enters it.
    if (listen_only_) {
        if (!request.broadcast && modbus::is_restart_communications(request.pdu)) {
            listen_only_ = false;
            counters_ = Counters{};
        } else {
            ++counters_.no_response;
        }
        return reply;
    }
    // A broadcast runs only a write the profile allows in broadcast, and is never answered (SL §2.1).
    if (request.broadcast && !answer_broadcast) {
        ++counters_.no_response;
        if (!modbus::is_write_function(fc) || !profile_->functions.allows_broadcast(fc)) return reply;
    }

    std::vector<std::uint8_t> out;
    if (!profile_->functions.supports(fc & 0x7F) || (fc & 0x80) != 0) {
        out = exception(fc & 0x7F,
                        modbus::exception_for(*profile_, "unsupported_function", exc_illegal_function));
    } else {
        auto decoded = modbus::decode_request(request.pdu);
        if (!decoded) {
            // The structure cannot be recovered (truncated or bytes left over): the request's data are
            // inconsistent, which the specification answers with "illegal data value".
            out = exception(fc, exc_illegal_value);
        } else {
            out = dispatch(*decoded, request.broadcast, reply.wrote);
        }
    }
    // A new address takes effect once the request is done: the reply (formed by the server from the
    // request's unit id) still goes out from the old one, as from a device that obeys after answering.
    if (reply.wrote) follow_address();
    if (!out.empty() && (out[0] & 0x80) == 0 && fc != 8 && fc != 11 && fc != 12) ++counters_.event_count;
    if (!out.empty() && (out[0] & 0x80) == 0 && faults_->fires(Fault::ExceptionForValid)) {
        out = exception(fc, exc_device_failure);
    }
    if (request.broadcast && !answer_broadcast) {
        // Executed, not answered. An exception formed for it was never returned: 0x0D counts the exception
        // responses returned (AP §6.8.1), and the broadcast is counted under no response already.
        if (!out.empty() && (out[0] & 0x80) != 0) --counters_.exceptions;
        return reply;
    }
    reply.pdu = std::move(out);
    return reply;
}

std::optional<std::uint8_t> Device::check_quantity(std::uint8_t fc, std::uint32_t quantity, bool write_part) {
    int limit = profile_->functions.max_for(fc, write_part);
    if (faults_->enabled(Fault::IgnoreMaxQuantity))
        limit = std::max(limit, specification_max(fc, write_part));
    if (quantity == 0 || (limit > 0 && quantity > static_cast<std::uint32_t>(limit)))
        return modbus::exception_for(*profile_, "bad_quantity", exc_illegal_value);
    return std::nullopt;
}

std::optional<std::uint8_t> Device::check_write_block(Table t, std::uint16_t start,
                                                      const std::vector<std::uint16_t>& values) {
    if (start + values.size() > 65536u)
        return modbus::exception_for(*profile_, "bad_address", exc_illegal_address);
    // Judged as the device stores it: a device with the wrong word order judges the value it makes of the
    // words, not the one the master meant.
    const StoredBlock stored = as_stored(t, start, values);
    const auto& block = stored.values;
    // A lone half of a 32-bit point is judged with the other half held.
    auto rejection = modbus::check_writes(*profile_, t, stored.start, block, [&](std::uint16_t a) {
        return std::optional<std::uint16_t>(image_.reg(t, a));
    });
    if (!rejection) rejection = check_conditional_access(*profile_, image_, t, stored.start, block.size());
    if (!rejection) rejection = check_linked_limits(*profile_, image_, t, stored.start, block);
    if (!rejection) return std::nullopt;
    const bool is_value_rule =
        rejection->exception_code == modbus::exception_for(*profile_, "bad_value", exc_illegal_value) &&
        rejection->reason.rfind("value", 0) == 0;
    if (is_value_rule && faults_->enabled(Fault::AcceptOutOfRange)) {
        // Only the address and access rules are still applied. check_writes judged every address and the
        // map's access before any value, so those passed; a value rule that refused the block came before
        // the access that depends on what the device holds (a point read-only in automatic mode), which is
        // still applied.
        if (auto r = check_conditional_access(*profile_, image_, t, stored.start, block.size()))
            return r->exception_code;
        return std::nullopt;
    }
    return rejection->exception_code;
}

std::uint16_t Device::stored_address(Table t, std::uint16_t address) const noexcept {
    if (!faults_->enabled(Fault::WordSwap) || profile_->open_address_space || modbus::is_bit_table(t))
        return address;
    const modbus::Point* p = profile_->find(t, address);
    if (!p) return address;
    if (p->encoding.words == 2)
        return static_cast<std::uint16_t>(address == p->address ? address + 1 : address - 1);
    // A 32-bit value the map gives as two points, its low and high words (CTH2265I's totals).
    const auto type = p->encoding.type;
    if ((type == modbus::EncodingType::U32Low || type == modbus::EncodingType::U32High) && p->encoding.pair)
        return *p->encoding.pair;
    return address;
}

Device::StoredBlock Device::as_stored(Table t, std::uint16_t start,
                                      const std::vector<std::uint16_t>& values) const {
    std::vector<std::uint16_t> at(values.size());
    for (std::size_t i = 0; i < values.size(); ++i)
        at[i] = stored_address(t, static_cast<std::uint16_t>(start + i));
    if (at.empty()) return {start, {}, {}};
    const auto [lo, hi] = std::minmax_element(at.begin(), at.end());
    StoredBlock block{*lo, {}, std::vector<bool>(static_cast<std::size_t>(*hi - *lo + 1), false)};
    for (std::size_t j = 0; j < block.written.size(); ++j)
        block.values.push_back(image_.reg(t, static_cast<std::uint16_t>(block.start + j)));
    for (std::size_t i = 0; i < values.size(); ++i) {
        block.values[at[i] - block.start] = values[i];
        block.written[at[i] - block.start] = true;
    }
    return block;
}

std::uint16_t Device::read_word(Table t, std::uint16_t address) const noexcept {
    const modbus::Point* p = profile_->open_address_space ? nullptr : profile_->find(t, address);
    if (p && p->access == modbus::Access::Write)
        return 0;  // write-only points read as zero (manuals are silent)
    return image_.reg(t, stored_address(t, address));
}

void Device::write_words(Table t, std::uint16_t start, const std::vector<std::uint16_t>& values) {
    if (faults_->fires(Fault::DropWrite)) return;
    const StoredBlock stored = as_stored(t, start, values);
    for (std::size_t i = 0; i < stored.values.size(); ++i) {
        if (!stored.written[i]) continue;
        const auto address = static_cast<std::uint16_t>(stored.start + i);
        if (frozen(t, address)) continue;
        if (!profile_->open_address_space) {
            const modbus::Point* p = profile_->find(t, address);
            if (!p || p->reserved || p->access == modbus::Access::Read)
                continue;                  // unchecked tail (first-only)
            if (p->fixed_value) continue;  // reads its fixed value always
        }
        image_.set_reg(t, address, stored.values[i]);
    }
}

std::vector<std::uint8_t> Device::dispatch(const Pdu& req, bool broadcast, bool& wrote) {
    (void)broadcast;
    switch (req.function_code()) {
        case 1:
        case 2:
            return read_bits(req);
        case 3:
        case 4:
            return read_registers(req);
        case 5:
            return write_single_coil(req, wrote);
        case 6:
            return write_single_register(req, wrote);
        case 7: {
            Pdu rsp{7, modbus::Direction::Response, modbus::ReadExceptionStatusResponse{0}, {}};
            return encode(rsp);
        }
        case 8:
            return diagnostics(req);
        case 11: {
            Pdu rsp{11,
                    modbus::Direction::Response,
                    modbus::CommEventCounterResponse{0, counters_.event_count},
                    {}};
            return encode(rsp);
        }
        case 12: {
            modbus::CommEventLogResponse log{6, 0, counters_.event_count, counters_.bus_messages, {}};
            return encode(Pdu{12, modbus::Direction::Response, log, {}});
        }
        case 15:
            return write_multiple_coils(req, wrote);
        case 16:
            return write_multiple_registers(req, wrote);
        case 17:
            return report_server_id();
        case 22:
            return mask_write(req, wrote);
        case 23:
            return read_write_multiple(req, wrote);
        case 24:
            return read_fifo(req);
        case 43:
            return read_device_id(req);
        default:
            // Supported by the profile but not served by this slave (FC20/21 file records): the device says
            // so.
            return exception(req.function_code(), exc_illegal_function);
    }
}

std::vector<std::uint8_t> Device::read_bits(const Pdu& req) {
    const auto& r = std::get<modbus::ReadRequest>(req.body);
    const std::uint8_t fc = req.function_code();
    if (auto e = check_quantity(fc, r.quantity)) return exception(fc, *e);
    const Table t = fc == 1 ? Table::Coils : Table::DiscreteInputs;
    const std::uint16_t start = served(r.starting_address);
    if (auto e = modbus::check_read(*profile_, t, start, r.quantity)) return exception(fc, *e);
    // AP §6.1: LSB of the first byte is the first bit; unused high bits stay zero.
    modbus::ReadBitsResponse bits;
    bits.values.assign((r.quantity + 7) / 8, 0);
    for (std::uint32_t i = 0; i < r.quantity; ++i)
        if (read_word(t, static_cast<std::uint16_t>(start + i)) != 0)
            bits.values[i / 8] = static_cast<std::uint8_t>(bits.values[i / 8] | (1u << (i % 8)));
    if (faults_->fires(Fault::WrongQuantity)) bits.values.push_back(0);
    bits.byte_count = static_cast<std::uint8_t>(bits.values.size());
    if (faults_->fires(Fault::WrongByteCount)) ++bits.byte_count;
    return encode(Pdu{fc, modbus::Direction::Response, bits, {}});
}

std::vector<std::uint8_t> Device::read_registers(const Pdu& req) {
    const auto& r = std::get<modbus::ReadRequest>(req.body);
    const std::uint8_t fc = req.function_code();
    if (auto e = check_quantity(fc, r.quantity)) return exception(fc, *e);
    const Table t = fc == 3 ? Table::HoldingRegisters : Table::InputRegisters;
    const std::uint16_t start = served(r.starting_address);
    if (auto e = modbus::check_read(*profile_, t, start, r.quantity)) return exception(fc, *e);
    std::vector<std::uint16_t> words(r.quantity);
    for (std::uint32_t i = 0; i < r.quantity; ++i)
        words[i] = read_word(t, static_cast<std::uint16_t>(start + i));
    // One more register, or one fewer where one more would not fit in a PDU (125 asked).
    if (faults_->fires(Fault::WrongQuantity)) {
        if (words.size() < modbus::max_read_registers)
            words.push_back(read_word(t, static_cast<std::uint16_t>(start + r.quantity)));
        else
            words.pop_back();
    }
    Pdu rsp = modbus::make_read_registers_response(static_cast<modbus::FunctionCode>(fc), words);
    if (faults_->fires(Fault::WrongByteCount)) ++std::get<modbus::ReadRegistersResponse>(rsp.body).byte_count;
    return encode(rsp);
}

std::vector<std::uint8_t> Device::write_single_coil(const Pdu& req, bool& wrote) {
    const auto& w = std::get<modbus::WriteSingle>(req.body);
    // AP §6.5: the output value is checked (0xFF00 or 0x0000) before the address.
    if (w.value != 0xFF00 && w.value != 0x0000) return exception(5, exc_illegal_value);
    const std::uint16_t address = served(w.address);
    if (auto e = check_write_block(Table::Coils, address, {static_cast<std::uint16_t>(w.value ? 1 : 0)}))
        return exception(5, *e);
    write_words(Table::Coils, address, {static_cast<std::uint16_t>(w.value ? 1 : 0)});
    wrote = true;
    modbus::WriteSingle echo = w;
    if (faults_->fires(Fault::NoEcho)) echo.value = static_cast<std::uint16_t>(~echo.value);
    return encode(Pdu{5, modbus::Direction::Response, echo, {}});
}

std::vector<std::uint8_t> Device::write_single_register(const Pdu& req, bool& wrote) {
    const auto& w = std::get<modbus::WriteSingle>(req.body);
    const std::uint16_t address = served(w.address);
    if (auto e = check_write_block(Table::HoldingRegisters, address, {w.value})) return exception(6, *e);
    write_words(Table::HoldingRegisters, address, {w.value});
    wrote = true;
    modbus::WriteSingle echo = w;
    if (faults_->fires(Fault::NoEcho)) echo.value = static_cast<std::uint16_t>(~echo.value);
    return encode(Pdu{6, modbus::Direction::Response, echo, {}});
}

std::vector<std::uint8_t> Device::write_multiple_coils(const Pdu& req, bool& wrote) {
    const auto& w = std::get<modbus::WriteMultipleCoilsRequest>(req.body);
    if (auto e = check_quantity(15, w.quantity)) return exception(15, *e);
    if (has_violation(req, modbus::FindingCode::PduByteCountMismatch) || w.values.size() * 8 < w.quantity)
        return exception(15, exc_illegal_value);
    const std::uint16_t start = served(w.starting_address);
    std::vector<std::uint16_t> values(w.quantity);
    for (std::size_t i = 0; i < w.quantity; ++i)
        values[i] = modbus::bit_at(w.values, i) ? 1 : 0;
    if (auto e = check_write_block(Table::Coils, start, values)) return exception(15, *e);
    write_words(Table::Coils, start, values);
    wrote = true;
    return encode(modbus::make_write_multiple_response(modbus::FunctionCode::WriteMultipleCoils,
                                                       w.starting_address, acknowledged(w.quantity)));
}

std::vector<std::uint8_t> Device::write_multiple_registers(const Pdu& req, bool& wrote) {
    const auto& w = std::get<modbus::WriteMultipleRegistersRequest>(req.body);
    if (auto e = check_quantity(16, w.quantity)) return exception(16, *e);
    if (has_violation(req, modbus::FindingCode::PduByteCountMismatch) || w.values.size() != w.quantity)
        return exception(16, exc_illegal_value);
    const std::uint16_t start = served(w.starting_address);
    if (auto e = check_write_block(Table::HoldingRegisters, start, w.values)) return exception(16, *e);
    write_words(Table::HoldingRegisters, start, w.values);
    wrote = true;
    return encode(modbus::make_write_multiple_response(modbus::FunctionCode::WriteMultipleRegisters,
                                                       w.starting_address, acknowledged(w.quantity)));
}

std::vector<std::uint8_t> Device::mask_write(const Pdu& req, bool& wrote) {
    const auto& m = std::get<modbus::MaskWriteRegister>(req.body);
    const std::uint16_t address = served(m.reference_address);
    const std::uint16_t current =
        image_.reg(Table::HoldingRegisters, stored_address(Table::HoldingRegisters, address));
    // AP §6.16: result = (current AND and_mask) OR (or_mask AND (NOT and_mask)).
    const auto result = static_cast<std::uint16_t>((current & m.and_mask) | (m.or_mask & ~m.and_mask));
    if (auto e = check_write_block(Table::HoldingRegisters, address, {result})) return exception(22, *e);
    write_words(Table::HoldingRegisters, address, {result});
    wrote = true;
    return encode(Pdu{22, modbus::Direction::Response, m, {}});
}

std::vector<std::uint8_t> Device::read_write_multiple(const Pdu& req, bool& wrote) {
    const auto& rw = std::get<modbus::ReadWriteMultipleRequest>(req.body);
    if (auto e = check_quantity(23, rw.quantity_to_read)) return exception(23, *e);
    if (auto e = check_quantity(23, rw.quantity_to_write, true)) return exception(23, *e);
    if (has_violation(req, modbus::FindingCode::PduByteCountMismatch) ||
        rw.write_values.size() != rw.quantity_to_write)
        return exception(23, exc_illegal_value);
    const std::uint16_t read_start = served(rw.read_starting_address);
    const std::uint16_t write_start = served(rw.write_starting_address);
    if (auto e = modbus::check_read(*profile_, Table::HoldingRegisters, read_start, rw.quantity_to_read))
        return exception(23, *e);
    if (auto e = check_write_block(Table::HoldingRegisters, write_start, rw.write_values))
        return exception(23, *e);
    // AP §6.17: the write is performed before the read.
    write_words(Table::HoldingRegisters, write_start, rw.write_values);
    wrote = true;
    std::vector<std::uint16_t> words(rw.quantity_to_read);
    for (std::uint32_t i = 0; i < rw.quantity_to_read; ++i)
        words[i] = read_word(Table::HoldingRegisters, static_cast<std::uint16_t>(read_start + i));
    return encode(
        modbus::make_read_registers_response(modbus::FunctionCode::ReadWriteMultipleRegisters, words));
}

std::vector<std::uint8_t> Device::diagnostics(const Pdu& req) {
    const auto& d = std::get<modbus::Diagnostics>(req.body);
    const auto& supported = profile_->functions.diagnostics;
    if (std::find(supported.begin(), supported.end(), d.sub_function) == supported.end())
        return exception(8,
                         modbus::exception_for(*profile_, "fc8_unknown_sub_function", exc_illegal_function));
    // Every sub-function but 00 carries one 16-bit data field (AP §6.8.1): other lengths are inconsistent
    // data, exception 03.
    if (req.violations.contains(modbus::FindingCode::PduDiagnosticDataLength))
        return exception(8, exc_illegal_value);
    // AP §6.8's state diagram: data the sub-function does not define (a counter's query is 00 00) is
    // exception 03.
    if (!modbus::diagnostic_request_data_defined(d.sub_function, d.data))
        return exception(8, exc_illegal_value);
    modbus::Diagnostics rsp = d;
    const auto counter = [&](std::uint16_t v) {
        rsp.data = {static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
    };
    switch (d.sub_function) {
        case 0x00:  // return query data: the echo
            if (faults_->fires(Fault::NoEcho))
                for (auto& b : rsp.data)
                    b = static_cast<std::uint8_t>(~b);
            break;
        case 0x01:  // restart communications option (outside listen-only mode): clear the counters
            counters_ = Counters{};
            break;
        case 0x02:
            counter(counters_.diagnostic_register);
            break;
        case 0x04:  // force listen only mode: no response (AP §6.8.1)
            listen_only_ = true;
            ++counters_.no_response;
            return {};
        case 0x0A:
            counters_ = Counters{};
            break;
        case 0x0B:
            counter(counters_.bus_messages);
            break;
        case 0x0C:
            counter(counters_.bus_comm_errors);
            break;
        case 0x0D:
            counter(counters_.exceptions);
            break;
        case 0x0E:
            counter(counters_.server_messages);
            break;
        case 0x0F:
            counter(counters_.no_response);
            break;
        case 0x10:  // NAK and busy counts: this server never naks and is never busy
        case 0x11:
            counter(0);
            break;
        case 0x12:
            counter(counters_.overruns);
            break;
        case 0x14:  // clear overrun counter and flag: the echo
            counters_.overruns = 0;
            break;
        default:  // 0x03 change ASCII delimiter: echo
            break;
    }
    return encode(Pdu{8, modbus::Direction::Response, rsp, {}});
}

std::vector<std::uint8_t> Device::read_fifo(const Pdu& req) {
    const auto& f = std::get<modbus::ReadFifoQueueRequest>(req.body);
    const std::uint16_t pointer = served(f.fifo_pointer_address);
    const std::uint16_t count = image_.reg(Table::HoldingRegisters, pointer);
    if (count > 31 || pointer + count > 65535) return exception(24, exc_illegal_value);  // AP §6.18
    modbus::ReadFifoQueueResponse rsp;
    rsp.fifo_count = count;
    for (std::uint16_t i = 0; i < count; ++i)
        rsp.values.push_back(
            image_.reg(Table::HoldingRegisters, static_cast<std::uint16_t>(pointer + 1 + i)));
    rsp.byte_count = static_cast<std::uint16_t>(2 + 2 * count);
    return encode(Pdu{24, modbus::Direction::Response, rsp, {}});
}

std::vector<std::uint8_t> Device::read_device_id(const Pdu& req) {
    if (!std::holds_alternative<modbus::ReadDeviceIdRequest>(req.body))
        return exception(43, exc_illegal_function);
    const auto& r = std::get<modbus::ReadDeviceIdRequest>(req.body);
    if (r.read_device_id_code < 1 || r.read_device_id_code > 4) return exception(43, exc_illegal_value);
    const auto text = [](const std::string& s) { return std::vector<std::uint8_t>(s.begin(), s.end()); };
    // The basic objects (AP §6.21): vendor name, product code, revision.
    const std::vector<modbus::DeviceIdObject> objects = {
        {0x00, text(profile_->vendor.empty() ? "mbscope" : profile_->vendor)},
        {0x01, text(profile_->name.empty() ? profile_->id : profile_->name)},
        {0x02, text(MBSCOPE_VERSION)},
    };
    modbus::ReadDeviceIdResponse rsp;
    rsp.read_device_id_code = r.read_device_id_code;
    rsp.conformity_level = 0x81;  // basic identification, stream and individual access
    if (r.read_device_id_code == 4) {
        if (r.object_id >= objects.size()) return exception(43, exc_illegal_address);
        rsp.objects = {objects[r.object_id]};
    } else {
        // Stream access: an object id the device does not have restarts at the first (AP §6.21).
        for (std::size_t i = r.object_id < objects.size() ? r.object_id : 0; i < objects.size(); ++i)
            rsp.objects.push_back(objects[i]);
    }
    rsp.number_of_objects = static_cast<std::uint8_t>(rsp.objects.size());
    return encode(Pdu{43, modbus::Direction::Response, rsp, {}});
}

std::vector<std::uint8_t> Device::report_server_id() {
    modbus::ReportServerIdResponse rsp;
    const std::string id = "mbscope " + profile_->id;
    rsp.data.push_back(unit_);
    rsp.data.push_back(0xFF);  // run indicator: ON
    rsp.data.insert(rsp.data.end(), id.begin(), id.end());
    rsp.byte_count = static_cast<std::uint8_t>(rsp.data.size());
    return encode(Pdu{17, modbus::Direction::Response, rsp, {}});
}

}  // namespace mbscope::slave
