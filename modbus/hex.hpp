#pragma once
// Hex digits, as the ASCII framing (SL §2.5.2.1) and the project's text formats write bytes: '0'-'9',
// 'A'-'F', and 'a'-'f', which the ASCII framing reads but flags (its frames are written in upper case).

#include <array>
#include <cstdint>

namespace mbscope::modbus {

namespace detail {

inline constexpr std::uint8_t not_hex = 0x80;
inline constexpr std::uint8_t lower_hex = 0x10;

// Per character: the digit's value, with lower_hex for 'a'-'f', or not_hex; one lookup answers validity,
// value and case.
inline constexpr std::array<std::uint8_t, 256> hex_table = [] {
    std::array<std::uint8_t, 256> t{};
    t.fill(not_hex);
    for (int c = '0'; c <= '9'; ++c)
        t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c - '0');
    for (int c = 'A'; c <= 'F'; ++c)
        t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c - 'A' + 10);
    for (int c = 'a'; c <= 'f'; ++c)
        t[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>((c - 'a' + 10) | lower_hex);
    return t;
}();

}  // namespace detail

// The value of a hex digit (either case), or -1.
constexpr int hex_digit(std::uint8_t c) noexcept {
    const std::uint8_t v = detail::hex_table[c];
    return (v & detail::not_hex) ? -1 : (v & 0x0F);
}
constexpr int hex_digit(char c) noexcept {
    return hex_digit(static_cast<std::uint8_t>(c));
}

// 'a'-'f'.
constexpr bool is_lower_hex_letter(std::uint8_t c) noexcept {
    return (detail::hex_table[c] & (detail::not_hex | detail::lower_hex)) == detail::lower_hex;
}

}  // namespace mbscope::modbus
