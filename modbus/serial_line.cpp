#include "modbus/serial_line.hpp"

namespace mbscope::modbus {

std::string_view to_string(Parity p) noexcept {
    switch (p) {
        case Parity::None:
            return "none";
        case Parity::Even:
            return "even";
        case Parity::Odd:
            return "odd";
    }
    return "?";
}

std::optional<Parity> parse_parity(std::string_view t) noexcept {
    if (t == "N" || t == "n" || t == "none") return Parity::None;
    if (t == "E" || t == "e" || t == "even") return Parity::Even;
    if (t == "O" || t == "o" || t == "odd") return Parity::Odd;
    return std::nullopt;
}

std::string settings_text(Framing framing, const SerialLine& line, bool serial) {
    std::string s(framing == Framing::Ascii ? "ASCII" : "RTU");
    if (!serial) return s;
    return s + ", " + character_text(line);
}

std::string character_text(const SerialLine& line) {
    std::string s = std::to_string(line.baud) + " baud, ";
    s += line.parity == Parity::None   ? "no parity"
         : line.parity == Parity::Even ? "even parity"
                                       : "odd parity";
    s += " (" + std::to_string(line.data_bits) + "NEO"[static_cast<int>(line.parity)] +
         std::to_string(line.stop_bits) + ")";
    return s;
}

}  // namespace mbscope::modbus
