#pragma once
// The three ways a Modbus ADU is framed on its link: RTU (binary, CRC, silences), ASCII (':' ... CR LF,
// LRC) and Modbus/TCP (MBAP header). A header of its own, so that what names a framing (line settings,
// profiles) does not pull in the frame buffer.

#include <cstdint>
#include <string_view>

namespace mbscope::modbus {

enum class Framing : std::uint8_t { Rtu = 0, Ascii = 1, Tcp = 2 };
std::string_view to_string(Framing f) noexcept;  // "rtu", "ascii", "tcp"

}  // namespace mbscope::modbus
