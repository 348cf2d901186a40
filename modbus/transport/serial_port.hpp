#pragma once
// Serial ports and pseudo-terminals, configured raw (no echo, no line discipline) for the given line.
// Pseudo-terminals stand in for RS-485 adapters in tests: what one side writes the other reads, byte for
// byte; they have no baud rate, so timing there is only what the writer's pauses make it.

#include <string>

#include "modbus/result.hpp"
#include "modbus/serial_line.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::modbus::transport {

// Opens DEVICE non-blocking, raw, at the line's speed, parity, data and stop bits.
Result<UniqueFd, std::string> open_serial(const std::string& device, const SerialLine& line);

// Sets an open port to the line's speed, parity, data and stop bits, raw, as open_serial does: a slave
// whose device was told another speed or parity. `pty`: the port is a pseudo-terminal, where parity and
// 7-bit characters may be refused and are then left out (they only time the line there).
Result<void, std::string> set_line(int fd, const SerialLine& line, bool pty);
// DEVICE is a pseudo-terminal's client side (/dev/pts/N, or a link to one).
bool is_pty(const std::string& device);

struct Pty {
    UniqueFd master;         // the side mbscope reads and writes
    UniqueFd slave_keep;     // held open so the master never reads EIO between two clients
    std::string slave_path;  // what a client opens (/dev/pts/N)
};
Result<Pty, std::string> open_pty(const SerialLine& line);

}  // namespace mbscope::modbus::transport
