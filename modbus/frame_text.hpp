#pragma once
// Frames written as text: the hex spellings `mbscope frame` takes on its command line and in a frames file
// (one frame a line, as captures/manual-examples.txt holds the manuals' worked examples), the decoding of
// one such frame field by field, and its rendering as text or JSON. Whatever the text holds, the result is a
// frame or an error naming the line and what is wrong, never an exception; the rendered text holds no
// control character of the input (a frames file, an ASCII frame or a device's identification strings could
// otherwise move the cursor or recolour a terminal): those are written as \r, \n, \t or \xNN.

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::modbus {

struct DecodedFrame {
    Framing framing = Framing::Rtu;
    std::vector<std::uint8_t> wire;  // the bytes as given
    std::optional<Frame> frame;      // set when the ADU structure was recovered
    std::optional<Pdu> pdu;          // set when the PDU structure was recovered
    std::string direction_note;      // e.g. "request (identical to its echo response)"
    std::string error;               // why the ADU or PDU could not be decoded
    std::string source;              // optional label (file line, manual reference)

    bool clean() const;  // decoded, checksum ok, no rule broken
    // Decoded, and a rule broken at error severity (a checksum, a limit): what `mbscope frame` exits 1 for,
    // as decode does. Notes and warnings (a function code that is not public, lowercase ASCII hex) are said,
    // not failed.
    bool broken() const;
};

// "11 03 00 60", "1103 0060", "0x11,0x03", "11-03": hex digits two to a byte, with 0x prefixes, blanks,
// commas, colons and dashes between groups of digits. Returns nullopt and sets error on anything else or on
// a group with an odd number of digits (the digits of a byte stand together: "11 3 0" is an error, not
// 11 30).
std::optional<std::vector<std::uint8_t>> parse_hex(std::span<const std::string> tokens, std::string& error);

// The bytes of a frame given as tokens: hex as above, or for ASCII also the frame's text
// (":1103...", CR LF written as literal \r\n or added when missing).
std::optional<std::vector<std::uint8_t>> wire_from_tokens(Framing framing,
                                                          std::span<const std::string> tokens,
                                                          std::string& error);

// One line of a frames file that holds something: "rtu|ascii|tcp HEX... [# comment]".
struct FrameLine {
    std::size_t number = 0;  // 1-based
    Framing framing = Framing::Rtu;
    std::vector<std::uint8_t> wire;
    std::string comment;  // after '#', leading blanks dropped
    std::string error;    // set when the line is not a frame (then framing and wire mean nothing)
};

// Every line of a frames file in order; blank lines and lines with only a comment are skipped. Lines end at
// LF (a CR before it is dropped); a last line without LF counts.
std::vector<FrameLine> parse_frames_text(std::string_view text);

DecodedFrame decode_frame(Framing framing, std::vector<std::uint8_t> wire, Direction direction);

std::string render_text(const DecodedFrame& d);
nlohmann::json render_json(const DecodedFrame& d);

// The well-formed UTF-8 character at text[i] (RFC 3629: no overlong forms, no surrogates, nothing past
// U+10FFFF): its code point and byte length; length 0 when the byte there starts none.
struct Utf8Char {
    char32_t code = 0;
    std::size_t length = 0;
};
Utf8Char utf8_at(std::string_view text, std::size_t i) noexcept;

// Text safe to print: well-formed UTF-8 as it is, except what a terminal acts on (C0 and C1 controls, DEL,
// U+2028/U+2029, bidirectional overrides and isolates), written byte by byte as \r, \n, \t or \xNN; bytes
// that are not well-formed UTF-8 as \xNN too. A backslash stays itself.
std::string printable(std::string_view text);
// A piece of input quoted in an error: printable, in single quotes, cut at 40 characters with "..." (a
// hostile line may hold a megabyte in one word).
std::string quote_excerpt(std::string_view text);
// The first character printable() escapes, as printable() writes it ("\x1B", "\xC2\x9B"), or nothing when
// there is none: for readers that refuse such text in a file rather than print it escaped.
std::optional<std::string> first_unprintable(std::string_view text);

}  // namespace mbscope::modbus
