#pragma once
// Error checks of the serial framings.
//   CRC-16/MODBUS (SL §2.5.1.2, 000:4264-4288): init 0xFFFF, reflected polynomial 0xA001, no final xor.
//   It is transmitted low byte first: the MK manual prints the register "MSB" first, but its Appendix B
//   (000:4330) shows CalcCRC = 0x1401 sent as 01 14, i.e. low byte first, as the specification says.
//   LRC (SL §2.5.2.2, 000:4290-4301): two's complement of the 8-bit sum of the binary bytes.

#include <cstdint>
#include <span>

namespace mbscope::modbus {

// CRC-16/MODBUS of bytes; `crc` continues a previous computation (start with crc16_init).
inline constexpr std::uint16_t crc16_init = 0xFFFF;
std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc = crc16_init) noexcept;

// The reference bit-by-bit algorithm of the specification; used by tests to check the fast one.
std::uint16_t crc16_bitwise(std::span<const std::uint8_t> bytes) noexcept;

std::uint8_t lrc(std::span<const std::uint8_t> bytes) noexcept;

}  // namespace mbscope::modbus
