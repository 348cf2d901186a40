#include "modbus/frame.hpp"

#include "modbus/checksum.hpp"

namespace mbscope::modbus {

std::string_view to_string(Framing f) noexcept {
    switch (f) {
        case Framing::Rtu:
            return "rtu";
        case Framing::Ascii:
            return "ascii";
        case Framing::Tcp:
            return "tcp";
    }
    return "?";
}

std::string_view to_string(UnparsedReason r) noexcept {
    switch (r) {
        case UnparsedReason::Garbage:
            return "garbage";
        case UnparsedReason::TooShort:
            return "too_short";
        case UnparsedReason::Truncated:
            return "truncated";
        case UnparsedReason::UnknownFunction:
            return "unknown_function";
        case UnparsedReason::NoStart:
            return "no_start";
        case UnparsedReason::MissingEnd:
            return "missing_end";
        case UnparsedReason::Timeout:
            return "timeout";
        case UnparsedReason::BadCharacter:
            return "bad_character";
        case UnparsedReason::OddLength:
            return "odd_length";
        case UnparsedReason::TooLong:
            return "too_long";
        case UnparsedReason::BadHeader:
            return "bad_header";
        case UnparsedReason::BeforeStreamStart:
            return "before_stream_start";
        case UnparsedReason::BeforeFirstHeader:
            return "before_first_header";
        case UnparsedReason::AfterGap:
            return "after_gap";
        case UnparsedReason::RtuOverTcp:
            return "rtu_over_tcp";
    }
    return "?";
}

std::uint8_t Frame::unit_id() const noexcept {
    if (framing == Framing::Tcp) return length > 6 ? bytes[6] : 0;
    return length > 0 ? bytes[0] : 0;
}

std::span<const std::uint8_t> Frame::pdu() const noexcept {
    switch (framing) {
        case Framing::Tcp:
            return length > 7 ? std::span<const std::uint8_t>(bytes.data() + 7, length - 7u)
                              : std::span<const std::uint8_t>{};
        case Framing::Rtu:
            return length > 3 ? std::span<const std::uint8_t>(bytes.data() + 1, length - 3u)
                              : std::span<const std::uint8_t>{};
        case Framing::Ascii:
            return length > 2 ? std::span<const std::uint8_t>(bytes.data() + 1, length - 2u)
                              : std::span<const std::uint8_t>{};
    }
    return {};
}

std::uint16_t Frame::checksum_received() const noexcept {
    if (framing == Framing::Rtu && length >= 2)
        return static_cast<std::uint16_t>(bytes[length - 2] | (bytes[length - 1] << 8));
    if (framing == Framing::Ascii && length >= 1) return bytes[length - 1];
    return 0;
}

std::uint16_t Frame::checksum_computed() const noexcept {
    if (framing == Framing::Rtu && length >= 2) return crc16({bytes.data(), length - 2u});
    if (framing == Framing::Ascii && length >= 1) return lrc({bytes.data(), length - 1u});
    return 0;
}

}  // namespace mbscope::modbus
