#pragma once
// SEL RTAC serial captures (link type 250, LINKTYPE_RTAC_SERIAL): what the RTAC's Communication Monitor
// saves for a serial port. Each record is a 12-byte header, then the bytes of the line (layout as
// Wireshark's epan/dissectors/packet-rtacser.c reads it):
//
//   +-------------+--------------+-------+---------------+------------+----------------------+
//   | seconds (4) | microsec (4) | event | control lines | footer (2) | payload (the rest)   |
//   +-------------+--------------+-------+---------------+------------+----------------------+
//   big-endian; seconds and microseconds since the epoch when the data arrived; event 0 status change,
//   1/2 data TX/RX start, 3/4 data TX/RX end, 5 capture data lost, 6 capture complete, 7 framing error,
//   8 parity error, 9 break, 10 overflow; control lines bit 0 CTS, 1 DCD, 2 DSR, 3 RTS, 4 DTR, 5 RING,
//   6 MBOK. TX is what the RTAC sent, RX what it received.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

enum class RtacEvent : std::uint8_t {
    StatusChange = 0,
    TxStart = 1,
    RxStart = 2,
    TxEnd = 3,
    RxEnd = 4,
    DataLost = 5,
    CaptureComplete = 6,
    FramingError = 7,
    ParityError = 8,
    Break = 9,
    Overflow = 10,
};
std::string_view to_string(RtacEvent event) noexcept;  // "DATA_TX_START" ...; "unknown" for other values

struct RtacRecord {
    modbus::Timestamp arrived{0};  // header time; zero when the RTAC wrote none
    std::uint8_t event = 0;        // RtacEvent, raw: values above 10 are kept as they are
    std::uint8_t control_lines = 0;
    std::uint16_t footer = 0;
    std::span<const std::uint8_t> payload;
};

// nullopt when the record is shorter than its header.
std::optional<RtacRecord> parse_rtac_serial(std::span<const std::uint8_t> record) noexcept;

}  // namespace mbscope::analyzer
