#include "analyzer/word_order.hpp"

#include <bit>
#include <charconv>
#include <cmath>

namespace mbscope::analyzer {

std::vector<Register32> registers32(std::uint16_t starting_address, std::span<const std::uint16_t> values,
                                    modbus::WordOrder order) {
    std::vector<Register32> out;
    out.reserve(values.size() / 2);
    // Pairs whose second register would be past 65535 (a reply to a read that ran past the end) are left
    // out: wrapped round, their address would name a register at the start of the map.
    for (std::size_t i = 0; i + 1 < values.size() && starting_address + i + 1 <= 0xFFFF; i += 2) {
        const std::uint32_t u = modbus::join_words(values[i], values[i + 1], order);
        out.push_back({static_cast<std::uint16_t>(starting_address + i), u, std::bit_cast<float>(u)});
    }
    return out;
}

}  // namespace mbscope::analyzer
