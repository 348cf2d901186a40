#pragma once
// Register pairs read as 32-bit values when no profile says what a device holds (--word-order). The order
// names where the value's bytes sit on the wire, A the most significant (modbus::join_words, libmodbus's
// modbus_get_float_abcd() and its siblings): "abcd" is big-endian with the first register high, "cdab"
// swaps the registers, "badc" swaps the bytes inside each register, "dcba" both.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "analyzer/records.hpp"
#include "modbus/profile.hpp"

namespace mbscope::analyzer {

// Registers starting at `starting_address`, taken two at a time; an odd last register is left out.
std::vector<Register32> registers32(std::uint16_t starting_address, std::span<const std::uint16_t> values,
                                    modbus::WordOrder order);

using modbus::float_text;

}  // namespace mbscope::analyzer
