#pragma once
// Where a Modbus device is reached or served: one URI scheme shared by every part of mbscope.
//
//   tcp://HOST:PORT         Modbus/TCP (MBAP header)
//   udp://HOST:PORT         Modbus/UDP (MBAP header, one ADU per datagram)
//   rtu-tcp://HOST:PORT     RTU frames over a TCP stream, as serial-to-Ethernet gateways carry them
//   ascii-tcp://HOST:PORT   ASCII frames over a TCP stream
//   rtu:DEVICE?baud=9600&parity=E&stop=1&data=8    RTU on a serial port or pseudo-terminal
//   ascii:DEVICE?baud=9600&parity=E&stop=1&data=7  ASCII on a serial port or pseudo-terminal
//
// The serial defaults are the specification's (SL §2.5.1: 8E1 for RTU; §2.5.2: 7E1 for ASCII) at 9600 baud;
// a device whose manual says otherwise (the MK instruments run 8N1) is given its options explicitly.
// Parsing only: opening is in serial_port.hpp and socket.hpp.

#include <cstdint>
#include <string>
#include <string_view>

#include "modbus/frame.hpp"
#include "modbus/result.hpp"
#include "modbus/serial_line.hpp"

namespace mbscope::modbus::transport {

enum class Scheme : std::uint8_t { Tcp, Udp, RtuOverTcp, AsciiOverTcp, RtuSerial, AsciiSerial };
std::string_view to_string(Scheme s) noexcept;  // the URI scheme: "tcp", "rtu-tcp", "rtu", ...

Framing framing_of(Scheme s) noexcept;  // Tcp for the MBAP schemes
bool is_serial(Scheme s) noexcept;

struct Endpoint {
    Scheme scheme = Scheme::Tcp;
    std::string host;  // network schemes
    std::uint16_t port = 502;
    std::string device;  // serial schemes: path of the tty or pseudo-terminal
    SerialLine line;     // serial schemes
    std::string text() const;
};

// The line a device reached at `e` as `unit` is on, as far as the endpoint tells: the framing of serial
// schemes (carried over TCP too), and the speed and parity of a serial line.
LineState line_state(const Endpoint& e, std::uint8_t unit) noexcept;

// Errors carry a message naming the offending part of the URI.
Result<Endpoint, std::string> parse_endpoint(std::string_view uri);

}  // namespace mbscope::modbus::transport
