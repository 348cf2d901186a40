#include "analyzer/rtac_serial.hpp"

#include "modbus/byte_reader.hpp"

namespace mbscope::analyzer {

std::string_view to_string(RtacEvent event) noexcept {
    switch (event) {
        case RtacEvent::StatusChange:
            return "STATUS_CHANGE";
        case RtacEvent::TxStart:
            return "DATA_TX_START";
        case RtacEvent::RxStart:
            return "DATA_RX_START";
        case RtacEvent::TxEnd:
            return "DATA_TX_END";
        case RtacEvent::RxEnd:
            return "DATA_RX_END";
        case RtacEvent::DataLost:
            return "CAPTURE_DATA_LOST";
        case RtacEvent::CaptureComplete:
            return "CAPTURE_COMPLETE";
        case RtacEvent::FramingError:
            return "FRAMING_ERROR";
        case RtacEvent::ParityError:
            return "PARITY_ERROR";
        case RtacEvent::Break:
            return "SERIAL_BREAK_EVENT";
        case RtacEvent::Overflow:
            return "SERIAL_OVERFLOW_EVENT";
    }
    return "unknown";
}

std::optional<RtacRecord> parse_rtac_serial(std::span<const std::uint8_t> record) noexcept {
    modbus::ByteReader in(record);
    const auto s_hi = in.u16(), s_lo = in.u16(), us_hi = in.u16(), us_lo = in.u16();
    const auto event = in.u8(), lines = in.u8();
    const auto footer = in.u16();
    if (!s_hi || !s_lo || !us_hi || !us_lo || !event || !lines || !footer) return std::nullopt;
    RtacRecord r;
    r.arrived = std::chrono::seconds((std::uint32_t{*s_hi} << 16) | *s_lo) +
                std::chrono::microseconds((std::uint32_t{*us_hi} << 16) | *us_lo);
    r.event = *event;
    r.control_lines = *lines;
    r.footer = *footer;
    r.payload = in.rest();
    return r;
}

}  // namespace mbscope::analyzer
