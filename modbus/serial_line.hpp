#pragma once
// Character timing of a serial line (SL §2.5.1.1): a character is start + data + parity + stop bits.
// Inside an RTU frame the silence between characters must not exceed 1.5 character times (t1.5); a frame
// ends after a silence of at least 3.5 character times (t3.5). Above 19200 baud the specification fixes
// t1.5 = 750 µs and t3.5 = 1750 µs.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "modbus/framing.hpp"

namespace mbscope::modbus {

enum class Parity : std::uint8_t { None = 0, Even = 1, Odd = 2 };
std::string_view to_string(Parity p) noexcept;
std::optional<Parity> parse_parity(std::string_view text) noexcept;  // "N"/"E"/"O", "none"/"even"/"odd"

struct SerialLine {
    std::uint32_t baud = 9600;
    std::uint8_t data_bits = 8;
    Parity parity = Parity::None;
    std::uint8_t stop_bits = 1;

    bool operator==(const SerialLine&) const = default;
    std::uint32_t bits_per_character() const noexcept {
        return 1u + data_bits + (parity == Parity::None ? 0u : 1u) + stop_bits;
    }
    std::chrono::nanoseconds character_time() const noexcept {
        return std::chrono::nanoseconds(1'000'000'000ull * bits_per_character() / (baud ? baud : 1));
    }
    std::chrono::nanoseconds t1_5() const noexcept {
        if (baud > 19200) return std::chrono::microseconds(750);
        return character_time() * 3 / 2;
    }
    std::chrono::nanoseconds t3_5() const noexcept {
        if (baud > 19200) return std::chrono::microseconds(1750);
        return character_time() * 7 / 2;
    }
};

// The settings of the line a device is reached on, as far as they are known: the unit always; the framing
// on serial lines and serial framings carried over TCP; baud rate and parity on a serial line only.
struct LineState {
    std::uint8_t unit = 1;
    std::optional<Framing> framing;
    std::optional<std::uint32_t> baud;
    std::optional<Parity> parity;
};

// A line's settings as people say them: "RTU", or on a serial line "ASCII, 9600 baud, even parity (7E1)"
// (the character as a terminal program writes it: 8N1, 7E1, 7N2).
std::string settings_text(Framing framing, const SerialLine& line, bool serial);
// The character part alone: "9600 baud, even parity (7E1)".
std::string character_text(const SerialLine& line);

}  // namespace mbscope::modbus
