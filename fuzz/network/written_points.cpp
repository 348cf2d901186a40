#include "fuzz/network/written_points.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::fuzz::network {
namespace {

std::uint16_t word(std::span<const std::uint8_t> pdu, std::size_t at) {
    return at + 1 < pdu.size() ? static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]) : 0;
}

}  // namespace

std::optional<WriteRange> write_range(std::span<const std::uint8_t> pdu) {
    using modbus::Table;
    if (pdu.size() < 3) return std::nullopt;
    const std::uint16_t a = word(pdu, 1);
    switch (pdu[0]) {
        case 5:
            return WriteRange{Table::Coils, a, 1};
        case 6:
        case 22:
            return WriteRange{Table::HoldingRegisters, a, 1};
        case 15:
            return WriteRange{Table::Coils, a, std::min<std::uint16_t>(word(pdu, 3), modbus::max_write_bits)};
        case 16:
            return WriteRange{Table::HoldingRegisters, a,
                              std::min<std::uint16_t>(word(pdu, 3), modbus::max_write_registers)};
        case 23:
            return WriteRange{Table::HoldingRegisters, word(pdu, 5),
                              std::min<std::uint16_t>(word(pdu, 7), modbus::max_rw_write_registers)};
        default:
            return std::nullopt;
    }
}

bool remember_range(conformance::Session& session, const modbus::Profile& profile, const WriteRange& range) {
    const std::uint32_t end = std::min<std::uint32_t>(0x10000, std::uint32_t{range.start} + range.count);
    if (profile.open_address_space)
        return session.remember(range.table, range.start, static_cast<std::uint16_t>(end - range.start), 100);
    bool ok = true;
    for (std::uint32_t a = range.start; a < end && ok; ++a)
        if (profile.find(range.table, static_cast<std::uint16_t>(a)))
            ok = session.remember(range.table, static_cast<std::uint16_t>(a), 1);
    return ok;
}

std::vector<WriteRange> remember_writes(conformance::Session& session, const modbus::Profile& profile,
                                        const std::vector<Step>& steps) {
    std::vector<WriteRange> unread;
    const auto framing = session.client().framing();
    for (const auto& step : steps) {
        const auto frame = modbus::decode_adu(framing, step.joined());
        if (!frame) continue;
        if (framing != modbus::Framing::Tcp && frame->unit_id() != session.options().unit &&
            frame->unit_id() != 0)
            continue;
        const auto range = write_range(frame->pdu());
        if (!range || range->count == 0) continue;
        if (!remember_range(session, profile, *range)) unread.push_back(*range);
    }
    return unread;
}

}  // namespace mbscope::fuzz::network
