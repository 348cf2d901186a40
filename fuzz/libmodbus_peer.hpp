#pragma once
// libmodbus's server side on one request, without a network: the request's bytes are written into one end of
// a socket pair (then the end is shut, so an incomplete request ends instead of waiting), libmodbus's
// modbus_receive reads them from the other end as a Modbus/TCP server would, and modbus_reply answers from
// a mapping that covers the whole address space with every value 0. The differential fuzz target and the
// tests of the documented differences use it.

#include <cstdint>
#include <span>
#include <vector>

namespace mbscope::fuzz {

struct LibmodbusOutcome {
    int received = -1;                // modbus_receive's result: the request's length, or -1
    std::vector<std::uint8_t> reply;  // what modbus_reply wrote (MBAP header included); empty: nothing
};

LibmodbusOutcome libmodbus_serve(std::span<const std::uint8_t> adu);

}  // namespace mbscope::fuzz
