#pragma once
// One request of the network fuzzer, before and after it meets the wire. A probe is a unit and a PDU plus
// what is done to its envelope (checksum, MBAP fields, letter case) and how it is written (in one piece or
// split with pauses). Framing it for the target gives the exact bytes: what the reproducer keeps.

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::fuzz::network {

enum class Envelope : std::uint8_t {
    Valid,         // framed as the specification says
    BadChecksum,   // RTU: CRC off by one bit; ASCII: LRC off by one (MBAP has none: sent valid)
    MbapLength,    // Modbus/TCP: the MBAP length field is `envelope_value` instead of the true length
    ProtocolId,    // Modbus/TCP: the protocol identifier is `envelope_value` (not 0)
    LowerCaseHex,  // ASCII: the hex digits in lower case (the specification allows both)
};
std::string_view to_string(Envelope e) noexcept;

struct Probe {
    std::uint8_t unit = 1;
    std::vector<std::uint8_t> pdu;
    Envelope envelope = Envelope::Valid;
    std::uint16_t envelope_value = 0;
    // Written in `split` pieces (1: at once), `pause` apart: TCP reassembly on stream transports, the t1.5
    // rule on a serial line.
    std::uint8_t split = 1;
    std::chrono::microseconds pause{0};
    std::string recipe;  // how it was made, for the reproducer: "fc16 quantity max+1", "mutated: ..."
};

// The wire bytes of a framed probe, in the pieces they are written.
struct Wire {
    std::vector<std::vector<std::uint8_t>> parts;
    std::chrono::microseconds pause{0};
    std::vector<std::uint8_t> joined() const;
};

// Frames `probe` for `framing`; `transaction_id` is used on Modbus/TCP.
Wire frame_probe(const Probe& probe, modbus::Framing framing, std::uint16_t transaction_id);

}  // namespace mbscope::fuzz::network
