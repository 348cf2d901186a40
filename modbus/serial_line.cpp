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

}  // namespace mbscope::modbus
