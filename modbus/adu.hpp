#pragma once
// Application data units: the three framings of a PDU, encoders and whole-buffer decoders.
//
//  RTU (SL §2.5.1):   +------+----------+-----------+--------+--------+
//                     | unit | function | data      | CRC lo | CRC hi |    at most 256 bytes
//                     +------+----------+-----------+--------+--------+
//  ASCII (SL §2.5.2): ':' | unit (2 hex) | function (2 hex) | data (2n hex) | LRC (2 hex) | CR | LF
//  Modbus/TCP (TCP §3.1.3):
//                     +----------------+-------------+--------+------+----------+------+
//                     | transaction id | protocol id | length | unit | function | data |
//                     |    2 bytes     |   2 (= 0)   |   2    |  1   |    1     |      |
//                     +----------------+-------------+--------+------+----------+------+
//                     length counts the unit id and the PDU: 2..254.
//
// Decoders return a Frame for anything whose structure can be recovered: a checksum mismatch is *not* an
// error but a Frame with checksum_ok = false and a finding, so the analyzer can still show it.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/result.hpp"

namespace mbscope::modbus {

std::vector<std::uint8_t> encode_rtu(std::uint8_t unit_id, std::span<const std::uint8_t> pdu);
// Upper-case hex, as the specification and the MK manual (000:258-264) require.
std::string encode_ascii(std::uint8_t unit_id, std::span<const std::uint8_t> pdu);
std::vector<std::uint8_t> encode_tcp(std::uint16_t transaction_id, std::uint8_t unit_id,
                                     std::span<const std::uint8_t> pdu, std::uint16_t protocol_id = 0);
// The ADU of `pdu` in `framing`, as bytes (ASCII: the frame's characters); `transaction_id` is used by
// Modbus/TCP only.
std::vector<std::uint8_t> encode_adu(Framing framing, std::uint16_t transaction_id, std::uint8_t unit_id,
                                     std::span<const std::uint8_t> pdu);

// RTU ADU (unit .. CRC). Errors: Truncated (< 4 bytes), TooLong (> 256 bytes).
Result<Frame> decode_rtu(std::span<const std::uint8_t> adu) noexcept;
// Whether an RTU ADU's last two bytes (low byte first) are the CRC of the bytes before them; `adu` holds at
// least 3 bytes. The one place the comparison is made: fuzzing builds trace it (it is how libFuzzer learns to
// write a valid CRC), while the deframers' own files are built without comparison tracing (CMakeLists.txt).
bool rtu_crc_ok(std::span<const std::uint8_t> adu) noexcept;
// ASCII frame from ':' to LF inclusive. Errors: BadStartCharacter, BadEndCharacters, BadHexDigit,
// OddHexLength, Truncated (< 3 binary bytes), TooLong.
Result<Frame> decode_ascii(std::span<const std::uint8_t> chars) noexcept;
// Modbus/TCP ADU. Errors: Truncated, LengthFieldInvalid (length outside 2..254 or not the bytes present).
Result<Frame> decode_tcp(std::span<const std::uint8_t> adu) noexcept;
// One ADU as the framing writes it: decode_rtu, decode_ascii or decode_tcp.
Result<Frame> decode_adu(Framing framing, std::span<const std::uint8_t> adu) noexcept;

namespace detail {
// Decode the hex characters between ':' and CR into frame.bytes; sets the LRC status and findings.
// Returns the offset of the first offending character on failure.
Result<void> ascii_hex_to_frame(std::span<const std::uint8_t> hex, Frame& frame) noexcept;
void fill_rtu_frame(std::span<const std::uint8_t> adu, Frame& frame) noexcept;
}  // namespace detail

}  // namespace mbscope::modbus
