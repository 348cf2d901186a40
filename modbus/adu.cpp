#include "modbus/adu.hpp"

#include <algorithm>
#include <cstring>

#include "modbus/checksum.hpp"
#include "modbus/hex.hpp"

namespace mbscope::modbus {

std::vector<std::uint8_t> encode_rtu(std::uint8_t unit_id, std::span<const std::uint8_t> pdu) {
    std::vector<std::uint8_t> out;
    out.reserve(pdu.size() + 3);
    out.push_back(unit_id);
    out.insert(out.end(), pdu.begin(), pdu.end());
    const std::uint16_t crc = crc16(out);
    out.push_back(static_cast<std::uint8_t>(crc & 0xFF));  // low byte first (SL §2.5.1.2)
    out.push_back(static_cast<std::uint8_t>(crc >> 8));
    return out;
}

std::vector<std::uint8_t> encode_adu(Framing framing, std::uint16_t transaction_id, std::uint8_t unit_id,
                                     std::span<const std::uint8_t> pdu) {
    switch (framing) {
        case Framing::Rtu:
            return encode_rtu(unit_id, pdu);
        case Framing::Tcp:
            return encode_tcp(transaction_id, unit_id, pdu);
        case Framing::Ascii: {
            const std::string text = encode_ascii(unit_id, pdu);
            return {text.begin(), text.end()};
        }
    }
    return {};
}

std::string encode_ascii(std::uint8_t unit_id, std::span<const std::uint8_t> pdu) {
    static constexpr char hex[] = "0123456789ABCDEF";
    // One allocation: the LRC of unit and PDU together is the PDU's LRC less the unit (the LRC is the
    // two's complement of the byte sum, SL §2.5.2.2), so no binary copy of the frame is made.
    const auto check = static_cast<std::uint8_t>(lrc(pdu) - unit_id);
    std::string out;
    out.reserve((pdu.size() + 2) * 2 + 3);
    out.push_back(':');
    const auto put = [&](std::uint8_t b) {
        out.push_back(hex[b >> 4]);
        out.push_back(hex[b & 0x0F]);
    };
    put(unit_id);
    for (auto b : pdu)
        put(b);
    put(check);
    out += "\r\n";
    return out;
}

std::vector<std::uint8_t> encode_tcp(std::uint16_t transaction_id, std::uint8_t unit_id,
                                     std::span<const std::uint8_t> pdu, std::uint16_t protocol_id) {
    std::vector<std::uint8_t> out;
    out.reserve(pdu.size() + 7);
    const auto length = static_cast<std::uint16_t>(pdu.size() + 1);
    for (std::uint16_t v : {transaction_id, protocol_id, length}) {
        out.push_back(static_cast<std::uint8_t>(v >> 8));
        out.push_back(static_cast<std::uint8_t>(v & 0xFF));
    }
    out.push_back(unit_id);
    out.insert(out.end(), pdu.begin(), pdu.end());
    return out;
}

bool rtu_crc_ok(std::span<const std::uint8_t> adu) noexcept {
    const std::size_t n = adu.size();
    return crc16(adu.first(n - 2)) == static_cast<std::uint16_t>(adu[n - 2] | (adu[n - 1] << 8));
}

namespace detail {

void fill_rtu_frame(std::span<const std::uint8_t> adu, Frame& frame) noexcept {
    frame.framing = Framing::Rtu;
    frame.length = static_cast<std::uint16_t>(adu.size());
    std::memcpy(frame.bytes.data(), adu.data(), adu.size());
    frame.wire_length = static_cast<std::uint32_t>(adu.size());
    frame.checksum_ok = rtu_crc_ok(adu);
    if (!frame.checksum_ok) frame.findings.add(FindingCode::RtuCrcMismatch);
    if (adu[0] >= 248) frame.findings.add(FindingCode::RtuUnitIdReserved);
}

Result<void> ascii_hex_to_frame(std::span<const std::uint8_t> hex, Frame& frame) noexcept {
    frame.framing = Framing::Ascii;
    // One lookup per character, its flags gathered and its value written without a branch, in one pass over
    // the pairs (this runs over every character of every ASCII frame: a pass for the flags and another for
    // the values made the deframer 1.7 times slower, bench/README.md); the first bad digit is looked for only
    // when there is one. A body too long for the frame's buffer is only checked.
    const std::uint8_t* const table = detail::hex_table.data();  // not std::array's operator[]: see crc16
    std::uint8_t seen = 0;
    const std::size_t pairs = hex.size() / 2;
    const std::uint8_t* p = hex.data();
    if (pairs <= max_rtu_adu_length - 1) {
        std::uint8_t* out = frame.bytes.data();
        for (const std::uint8_t* const end = p + 2 * pairs; p != end; p += 2) {
            const std::uint8_t high = table[p[0]];
            const std::uint8_t low = table[p[1]];
            seen |= high | low;
            *out++ = static_cast<std::uint8_t>(((high & 0x0F) << 4) | (low & 0x0F));
        }
    }
    for (const std::uint8_t* const end = hex.data() + hex.size(); p != end; ++p)
        seen |= table[*p];
    if (seen & detail::not_hex) {
        const auto bad =
            std::find_if(hex.begin(), hex.end(), [](std::uint8_t c) { return hex_digit(c) < 0; });
        return make_error(ErrorCode::BadHexDigit, static_cast<std::size_t>(bad - hex.begin()) + 1);
    }
    const bool lower = (seen & detail::lower_hex) != 0;
    if (hex.size() % 2 != 0) return make_error(ErrorCode::OddHexLength, hex.size());
    const std::size_t n = hex.size() / 2;
    if (n < 3) return make_error(ErrorCode::Truncated, hex.size());
    if (n > max_rtu_adu_length - 1) return make_error(ErrorCode::TooLong, hex.size());
    frame.length = static_cast<std::uint16_t>(n);
    frame.checksum_ok = lrc({frame.bytes.data(), n - 1}) == frame.bytes[n - 1];
    if (!frame.checksum_ok) frame.findings.add(FindingCode::AsciiLrcMismatch);
    if (lower) frame.findings.add(FindingCode::AsciiLowercaseHex);
    return {};
}

}  // namespace detail

Result<Frame> decode_rtu(std::span<const std::uint8_t> adu) noexcept {
    if (adu.size() < 4) return make_error(ErrorCode::Truncated, adu.size());
    if (adu.size() > max_rtu_adu_length) return make_error(ErrorCode::TooLong, max_rtu_adu_length);
    Frame frame;
    detail::fill_rtu_frame(adu, frame);
    return frame;
}

Result<Frame> decode_ascii(std::span<const std::uint8_t> chars) noexcept {
    if (chars.empty() || chars[0] != ':') return make_error(ErrorCode::BadStartCharacter, 0);
    if (chars.size() > max_ascii_frame_length) return make_error(ErrorCode::TooLong, max_ascii_frame_length);
    if (chars.size() < 3 || chars[chars.size() - 2] != '\r' || chars[chars.size() - 1] != '\n')
        return make_error(ErrorCode::BadEndCharacters, chars.size() < 2 ? chars.size() : chars.size() - 2);
    Frame frame;
    frame.wire_length = static_cast<std::uint32_t>(chars.size());
    auto r = detail::ascii_hex_to_frame(chars.subspan(1, chars.size() - 3), frame);
    if (!r) return r.error();
    return frame;
}

Result<Frame> decode_tcp(std::span<const std::uint8_t> adu) noexcept {
    if (adu.size() < 8) return make_error(ErrorCode::Truncated, adu.size());
    const std::size_t length = static_cast<std::size_t>((adu[4] << 8) | adu[5]);
    if (length < 2 || length > max_frame_bytes - 6) return make_error(ErrorCode::LengthFieldInvalid, 4);
    if (adu.size() < 6 + length) return make_error(ErrorCode::Truncated, adu.size());
    if (adu.size() > 6 + length) return make_error(ErrorCode::LengthFieldInvalid, 4);
    Frame frame;
    frame.framing = Framing::Tcp;
    frame.length = static_cast<std::uint16_t>(adu.size());
    frame.wire_length = frame.length;
    std::memcpy(frame.bytes.data(), adu.data(), adu.size());
    if (frame.protocol_id() != 0) frame.findings.add(FindingCode::TcpProtocolIdNonzero);
    if (length > max_pdu_length + 1)
        frame.findings.add(FindingCode::TcpLengthInvalid);  // kept: see frame.hpp
    return frame;
}

Result<Frame> decode_adu(Framing framing, std::span<const std::uint8_t> adu) noexcept {
    switch (framing) {
        case Framing::Rtu:
            return decode_rtu(adu);
        case Framing::Ascii:
            return decode_ascii(adu);
        case Framing::Tcp:
            break;
    }
    return decode_tcp(adu);
}

}  // namespace mbscope::modbus
