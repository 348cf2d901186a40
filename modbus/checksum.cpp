#include "modbus/checksum.hpp"

#include <array>

namespace mbscope::modbus {
namespace {

// Slicing-by-4 tables: table[0] is the classic byte table; table[k][b] is the CRC of byte b followed by
// k zero bytes. Four bytes per step keeps the CRC well above memory-scan speed on long frames.
constexpr std::array<std::array<std::uint16_t, 256>, 4> make_tables() {
    std::array<std::array<std::uint16_t, 256>, 4> t{};
    for (unsigned b = 0; b < 256; ++b) {
        std::uint16_t c = static_cast<std::uint16_t>(b);
        for (int i = 0; i < 8; ++i)
            c = (c & 1) ? static_cast<std::uint16_t>((c >> 1) ^ 0xA001) : (c >> 1);
        t[0][b] = c;
    }
    for (unsigned b = 0; b < 256; ++b) {
        for (int k = 1; k < 4; ++k) {
            std::uint16_t prev = t[k - 1][b];
            t[k][b] = static_cast<std::uint16_t>((prev >> 8) ^ t[0][prev & 0xFF]);
        }
    }
    return t;
}

constexpr auto tables = make_tables();

}  // namespace

std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc) noexcept {
    // Plain pointers into the tables: the fuzzing builds (-O1, sanitizers) leave std::array's operator[] out
    // of line, five calls for every four bytes.
    const std::uint16_t* t0 = tables[0].data();
    const std::uint16_t* t1 = tables[1].data();
    const std::uint16_t* t2 = tables[2].data();
    const std::uint16_t* t3 = tables[3].data();
    const std::uint8_t* p = bytes.data();
    std::size_t n = bytes.size();
    while (n >= 4) {
        const std::uint16_t x0 = static_cast<std::uint16_t>(crc ^ (p[0] | (p[1] << 8)));
        crc = static_cast<std::uint16_t>(t3[x0 & 0xFF] ^ t2[x0 >> 8] ^ t1[p[2]] ^ t0[p[3]]);
        p += 4;
        n -= 4;
    }
    while (n-- > 0)
        crc = static_cast<std::uint16_t>((crc >> 8) ^ t0[(crc ^ *p++) & 0xFF]);
    return crc;
}

std::uint16_t crc16_bitwise(std::span<const std::uint8_t> bytes) noexcept {
    std::uint16_t crc = 0xFFFF;
    for (std::uint8_t b : bytes) {
        crc ^= b;
        for (int i = 0; i < 8; ++i)
            crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001) : (crc >> 1);
    }
    return crc;
}

std::uint8_t lrc(std::span<const std::uint8_t> bytes) noexcept {
    std::uint8_t sum = 0;
    for (std::uint8_t b : bytes)
        sum = static_cast<std::uint8_t>(sum + b);
    return static_cast<std::uint8_t>(-sum);
}

}  // namespace mbscope::modbus
