#pragma once
// What a deframer produces: a Frame (one ADU found on a link) or an Unparsed record (bytes that formed no
// frame). Every byte a deframer is given ends up in exactly one of the two; tests and fuzzers check that.
// A Frame holds the ADU in binary form inside a fixed buffer (no allocation per frame):
//   RTU:   unit | PDU | CRC lo | CRC hi
//   ASCII: unit | PDU | LRC            (decoded from the hex characters; wire offsets index the characters)
//   TCP:   transaction id (2) | protocol id (2) | length (2) | unit | PDU

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>
#include <variant>
#include <vector>

#include "modbus/finding_codes.hpp"
#include "modbus/framing.hpp"
#include "modbus/function_code.hpp"

namespace mbscope::modbus {

// Largest ADU a Frame holds. The specification caps Modbus/TCP at 260 bytes (MBAP length 254), but real
// devices exceed it: the Walchem manual allows FC16 of 125 registers, a 263-byte ADU (002:362-381), and
// Schneider UMAS traffic carries MBAP length 255. Such frames are kept, flagged tcp.length_invalid.
inline constexpr std::size_t max_frame_bytes = 263;

// Time since an arbitrary epoch (capture time, or steady clock for live input). Zero means "no timing".
using Timestamp = std::chrono::nanoseconds;

struct Frame {
    Framing framing = Framing::Rtu;
    std::uint64_t offset = 0;       // stream offset of the first byte on the wire
    std::uint32_t wire_length = 0;  // bytes on the wire (ASCII: characters, ':' to LF)
    std::uint16_t length = 0;       // binary ADU length held in bytes
    // A new frame's bytes are zero; a copy copies only the first `length` of them (most ADUs are a tenth of
    // the buffer, and frames are copied from the deframer to the analyzer's records): past `length` the
    // bytes of a copy are unspecified.
    std::array<std::uint8_t, max_frame_bytes> bytes;
    bool checksum_ok = true;  // RTU CRC / ASCII LRC; always true for TCP
    FindingList findings;     // framing-level rule breaks (rtu.*, ascii.*, tcp.*)
    Timestamp start{0};       // end of the first byte on the wire (timed input only)
    Timestamp end{0};         // end of the last byte (timed input only)
    float max_gap_chars = 0;  // longest silence inside the frame, in character times (timed RTU only)
    // Timed RTU: the silence between the line's bytes before the frame and its first byte, in character
    // times, when it was above t1.5 but below t3.5 (0: none so measured).
    float short_silence_before_chars = 0;
    float short_silence_after_chars = 0;  // the same between its last byte and the bytes after it
    std::uint16_t gap_before_byte = 0;    // index of the byte that followed that silence
    // That silence was t3.5 or more: the frame came in two runs, joined as their CRC verifies together (a
    // receiver keeping t3.5 took two frames whose CRCs both fail).
    bool gap_at_t3_5 = false;
    // (a field added here must be added to operator= above: the size check below is there to say so)

    static constexpr std::size_t short_copy = 32;
    static_assert(short_copy <= max_frame_bytes);
    Frame() noexcept : bytes{} {}
    // For a deframer that fills the frame at once (length and the bytes before it): the bytes past `length`
    // are left as they are, as in a copy, instead of zeroing 263 bytes per frame (half the time of the TCP
    // deframer's loop).
    struct Unfilled {};
    explicit Frame(Unfilled) noexcept {}
    Frame(const Frame& other) noexcept { *this = other; }
    Frame& operator=(const Frame& other) noexcept {
        if (this == &other) return *this;
        framing = other.framing;
        offset = other.offset;
        wire_length = other.wire_length;
        length = other.length;
        // Most ADUs are short: a copy of a fixed 32 bytes is two vector moves, where a copy of `length` bytes
        // was a `rep movs` whose start-up was a quarter of the analyzer's making of a frame record. The bytes
        // past `length` are unspecified in both frames (unsigned char: copying them is defined).
        if (other.length <= short_copy)
            std::memcpy(bytes.data(), other.bytes.data(), short_copy);
        else
            std::memcpy(bytes.data(), other.bytes.data(),
                        std::min<std::size_t>(other.length, max_frame_bytes));
        checksum_ok = other.checksum_ok;
        findings = other.findings;
        start = other.start;
        end = other.end;
        max_gap_chars = other.max_gap_chars;
        short_silence_before_chars = other.short_silence_before_chars;
        short_silence_after_chars = other.short_silence_after_chars;
        gap_before_byte = other.gap_before_byte;
        gap_at_t3_5 = other.gap_at_t3_5;
        return *this;
    }

    std::span<const std::uint8_t> adu() const noexcept { return {bytes.data(), length}; }
    std::uint8_t unit_id() const noexcept;
    std::span<const std::uint8_t> pdu() const noexcept;  // function code onwards, checksum excluded
    // TCP only
    std::uint16_t transaction_id() const noexcept {
        return static_cast<std::uint16_t>((bytes[0] << 8) | bytes[1]);
    }
    std::uint16_t protocol_id() const noexcept {
        return static_cast<std::uint16_t>((bytes[2] << 8) | bytes[3]);
    }
    std::uint16_t length_field() const noexcept {
        return static_cast<std::uint16_t>((bytes[4] << 8) | bytes[5]);
    }
    // RTU: the CRC as received (low byte first on the wire); ASCII: the LRC
    std::uint16_t checksum_received() const noexcept;
    std::uint16_t checksum_computed() const noexcept;
};
static_assert(sizeof(void*) != 8 || sizeof(Frame) == 344,
              "Frame changed: copy the new field in Frame::operator=");

enum class UnparsedReason : std::uint8_t {
    Garbage = 0,             // no frame could start here
    TooShort = 1,            // a silence-delimited run too short to be a frame
    Truncated = 2,           // the input ended inside a frame
    UnknownFunction = 3,     // RTU without timing: unknown function code, length cannot be predicted
    NoStart = 4,             // ASCII: characters outside ':' ... CR LF
    MissingEnd = 5,          // ASCII: a new ':' or a bad character before CR LF
    Timeout = 6,             // ASCII: inter-character timeout inside a frame
    BadCharacter = 7,        // ASCII: a character that is not a hex digit
    OddLength = 8,           // ASCII: odd number of hex digits
    TooLong = 9,             // longer than the framing's maximum
    BadHeader = 10,          // TCP: MBAP length field impossible, stream resynchronised
    BeforeStreamStart = 11,  // TCP: bytes before the first one captured of their stream, arriving after it
    BeforeFirstHeader = 12,  // TCP: a stream begun before the capture, before its first header (an ADU's end)
    AfterGap = 13,           // TCP: after bytes the capture lacks, before the next header (an ADU's end)
    RtuOverTcp = 14,         // TCP: a connection on a Modbus/TCP port that carries raw RTU frames
};
std::string_view to_string(UnparsedReason r) noexcept;

struct Unparsed {
    std::uint64_t offset = 0;
    std::uint32_t length = 0;
    UnparsedReason reason = UnparsedReason::Garbage;
    Timestamp time{0};
    // RTU: its first two bytes when it has them (a unit and a function code, if it is the start of a frame);
    // ASCII: the two bytes its first four hex digits after ':' spell. A reply the end of a capture cut is
    // still known to have begun. Zero when there are none (unit 0 never replies).
    std::array<std::uint8_t, 2> head{};
};

using DeframeEvent = std::variant<Frame, Unparsed>;
using DeframeEvents = std::vector<DeframeEvent>;

// One step of a stateless deframer over a buffer (the sawp shape): a complete frame of `length` bytes at
// the front, or "need at least N bytes in total", or "skip `length` bytes: they start no frame".
struct DeframeStep {
    enum class Kind : std::uint8_t { Complete, NeedMore, Skip } kind = Kind::NeedMore;
    std::size_t length = 0;  // Complete: frame bytes; NeedMore: total bytes needed; Skip: bytes to drop
    bool checksum_ok = true;
    UnparsedReason reason = UnparsedReason::Garbage;  // Skip only
};

}  // namespace mbscope::modbus
