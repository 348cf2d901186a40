#include "modbus/result.hpp"

namespace mbscope::modbus {

std::string_view to_string(ErrorCode code) noexcept {
    switch (code) {
        case ErrorCode::Truncated:
            return "truncated: fewer bytes than the structure needs";
        case ErrorCode::TrailingBytes:
            return "trailing bytes after the structure";
        case ErrorCode::ByteCountMismatch:
            return "byte count disagrees with the bytes present";
        case ErrorCode::ChecksumMismatch:
            return "checksum mismatch";
        case ErrorCode::BadStartCharacter:
            return "ASCII frame does not start with ':'";
        case ErrorCode::BadEndCharacters:
            return "ASCII frame does not end with CR LF";
        case ErrorCode::BadHexDigit:
            return "character is not a hex digit";
        case ErrorCode::OddHexLength:
            return "odd number of hex digits";
        case ErrorCode::LengthFieldInvalid:
            return "MBAP length field invalid (2..254, matching the bytes)";
        case ErrorCode::TooLong:
            return "longer than the specification's maximum";
        case ErrorCode::EmptyPdu:
            return "empty PDU: no function code";
        case ErrorCode::BadReference:
            return "not a reference number (0xxxx, 1xxxx, 3xxxx, 4xxxx)";
        case ErrorCode::BadArgument:
            return "value cannot be encoded";
    }
    return "unknown error";
}

}  // namespace mbscope::modbus
