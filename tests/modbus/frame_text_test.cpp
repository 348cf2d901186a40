// Frames written as text (modbus/frame_text.hpp): the hex spellings, the frames file of the manuals' worked
// examples, errors that name the line, and rendered text that never carries a control character through.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "modbus/adu.hpp"
#include "modbus/frame_text.hpp"

namespace test_modbus_frame_text_test {

using namespace mbscope::modbus;

namespace {

std::vector<std::uint8_t> bytes(std::initializer_list<int> v) {
    std::vector<std::uint8_t> out;
    for (int b : v)
        out.push_back(static_cast<std::uint8_t>(b));
    return out;
}

bool has_control_characters(const std::string& text) {
    for (char c : text) {
        const auto u = static_cast<unsigned char>(c);
        if ((u < 0x20 && c != '\n') || u == 0x7F) return true;
    }
    return false;
}

}  // namespace

TEST(FrameText, ParseHexAcceptsCommonSpellings) {
    std::string error;
    const std::vector<std::string> tokens{"0x11,0x03", "0060", "00-03", "0X0a:0B"};
    auto b = parse_hex(tokens, error);
    ASSERT_TRUE(b.has_value()) << error;
    EXPECT_EQ(*b, bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x0A, 0x0B}));
}

TEST(FrameText, ParseHexNamesTheDigitAndTheToken) {
    std::string error;
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"123"}, error).has_value());
    EXPECT_EQ(error, "odd number of hex digits in '123': a byte is two digits");
    // A byte's digits stand together: a lone digit is not paired with the next group's first.
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"11", "3", "0", "6b"}, error).has_value());
    EXPECT_EQ(error, "odd number of hex digits in '3': a byte is two digits (03)");
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"11-3-00"}, error).has_value());
    EXPECT_EQ(error, "odd number of hex digits in '3': a byte is two digits (03) in '11-3-00'");
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"0x3"}, error).has_value());
    EXPECT_EQ(error, "odd number of hex digits in '3': a byte is two digits (03) in '0x3'");
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"11", "0G"}, error).has_value());
    EXPECT_EQ(error, "not a hex digit: 'G' in '0G'");
    // A prefix with nothing after it was dropped without a word ("01 0X" read as one byte).
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"01", "0X"}, error).has_value());
    EXPECT_EQ(error, "no hex digits after '0X' in '0X'");
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"0x,0x11"}, error).has_value());
    EXPECT_EQ(error, "no hex digits after '0x' in '0x,0x11'");
    // A control character is shown escaped, a long token cut short.
    EXPECT_FALSE(parse_hex(std::vector<std::string>{"11\x1b" + std::string(100, 'A')}, error).has_value());
    EXPECT_EQ(error, "not a hex digit: '\\x1B' in '11\\x1B" + std::string(37, 'A') + "...'");
}

TEST(FrameText, ManyPrefixesInOneTokenAreSkippedInOnePass) {
    std::string token;
    for (int i = 0; i < 100000; ++i)
        token += "0x";
    std::string error;
    auto b = parse_hex(std::vector<std::string>{token + "11"}, error);
    ASSERT_TRUE(b.has_value()) << error;
    EXPECT_EQ(*b, bytes({0x11}));
}

TEST(FrameText, AsciiFrameGivenAsText) {
    std::string error;
    auto w = wire_from_tokens(Framing::Ascii, std::vector<std::string>{":1103", "0060\\r\\n"}, error);
    ASSERT_TRUE(w.has_value()) << error;
    EXPECT_EQ(std::string(w->begin(), w->end()), ":11030060\r\n");
    w = wire_from_tokens(Framing::Ascii, std::vector<std::string>{":1103"}, error);
    ASSERT_TRUE(w.has_value()) << error;
    EXPECT_EQ(std::string(w->begin(), w->end()), ":1103\r\n");  // CR LF added when missing
    // A CR already there (the shell's $(cat frame.txt) keeps it, dropping the LF) gets its LF only: CR LF
    // after it made ":1103\r\r\n", a frame nobody gave, with "not a hex digit" at the first CR.
    w = wire_from_tokens(Framing::Ascii, std::vector<std::string>{":11030060000389\r"}, error);
    ASSERT_TRUE(w.has_value()) << error;
    EXPECT_EQ(std::string(w->begin(), w->end()), ":11030060000389\r\n");
    // So does a CR written out alone, as the shell passes ':11030060000389\r' in single quotes.
    w = wire_from_tokens(Framing::Ascii, std::vector<std::string>{":11030060000389\\r"}, error);
    ASSERT_TRUE(w.has_value()) << error;
    EXPECT_EQ(std::string(w->begin(), w->end()), ":11030060000389\r\n");
}

TEST(FrameText, TheManualsExamplesFileReadsLineByLine) {
    std::ifstream in(std::string(MBSCOPE_SOURCE_DIR) + "/captures/manual-examples.txt", std::ios::binary);
    ASSERT_TRUE(in);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto lines = parse_frames_text(text);
    ASSERT_EQ(lines.size(), 13u);
    for (const auto& l : lines) {
        EXPECT_TRUE(l.error.empty()) << l.number << ": " << l.error;
        EXPECT_TRUE(decode_frame(l.framing, l.wire, Direction::Unknown).clean()) << l.number;
    }
    // The first frame (000:330) and the Appendix B frame in ASCII (000:4330).
    EXPECT_EQ(lines.front().framing, Framing::Rtu);
    EXPECT_EQ(lines.front().wire, bytes({0x11, 0x01, 0x00, 0x13, 0x00, 0x15, 0x0E, 0x90}));
    EXPECT_EQ(lines.front().comment, "000:330 FC1 read 21 coils from coil 19 (request)");
    EXPECT_EQ(lines.back().framing, Framing::Ascii);
    EXPECT_EQ(std::string(lines.back().wire.begin(), lines.back().wire.end()),
              ":11100060000204000A01026C\r\n");
    EXPECT_GT(lines.back().number, lines.front().number);
}

TEST(FrameText, EveryBadLineIsNamedByItsNumber) {
    const auto lines = parse_frames_text(
        "modbus 11 03\n"           // 1: unknown framing
        "\n"                       // 2: blank
        "rtu 11 0G\n"              // 3: bad digit
        "tcp # no bytes\n"         // 4
        "   # only a comment\r\n"  // 5
        "\t\n"                     // 6
        "ascii :1103\\r\\n # c\r\n"
        "rtu 11 03 00 60 00 03 07 45");  // 8, no LF at the end
    ASSERT_EQ(lines.size(), 5u);
    EXPECT_EQ(lines[0].number, 1u);
    EXPECT_EQ(lines[0].error, "unknown framing 'modbus' (rtu, ascii or tcp)");
    EXPECT_EQ(lines[1].number, 3u);
    EXPECT_EQ(lines[1].error, "not a hex digit: 'G' in '0G'");
    EXPECT_EQ(lines[2].number, 4u);
    EXPECT_EQ(lines[2].error, "no frame bytes after 'tcp'");
    EXPECT_EQ(lines[2].comment, "no bytes");
    EXPECT_EQ(lines[3].number, 7u);
    EXPECT_TRUE(lines[3].error.empty());
    EXPECT_EQ(std::string(lines[3].wire.begin(), lines[3].wire.end()), ":1103\r\n");
    EXPECT_EQ(lines[3].comment, "c");
    EXPECT_EQ(lines[4].number, 8u);
    EXPECT_EQ(lines[4].wire, bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45}));
}

TEST(FrameText, PrintableEscapesControlCharactersOnly) {
    EXPECT_EQ(printable("\x1b[31mred\r\n\t\x7f"), "\\x1B[31mred\\r\\n\\t\\x7F");
    EXPECT_EQ(printable("M\xc3\xadnimo"), "M\xc3\xadnimo");  // UTF-8 as it is
    EXPECT_EQ(printable(std::string("a\0b", 3)), "a\\x00b");
}

// A hostile capture's text reached the terminal with its C1 controls: "\xC2\x9B" is U+009B, an 8-bit CSI
// that terminals may take as ESC [. Bytes that are not UTF-8 (a Latin-1 device name) were written raw.
TEST(FrameText, PrintableEscapesC1ControlsOverridesAndBytesThatAreNotUtf8) {
    EXPECT_EQ(printable("\xc2\x9b"
                        "31mRED\xc2\x9d"
                        "0;x"),
              "\\xC2\\x9B31mRED\\xC2\\x9D0;x");
    EXPECT_EQ(printable("a\xe2\x80\xae"
                        "b"),
              "a\\xE2\\x80\\xAEb");  // U+202E right-to-left override
    EXPECT_EQ(printable("a\xe2\x80\xa8"
                        "b"),
              "a\\xE2\\x80\\xA8b");                           // U+2028 line separator
    EXPECT_EQ(printable("Press\xe3o"), "Press\\xE3o");        // Latin-1 ã
    EXPECT_EQ(printable("\xc0\xaf"), "\\xC0\\xAF");           // overlong '/'
    EXPECT_EQ(printable("\xed\xa0\x80"), "\\xED\\xA0\\x80");  // a surrogate
    EXPECT_EQ(printable("\xe2\x82"), "\\xE2\\x82");           // cut short
    EXPECT_EQ(printable("\xc2\xb0"
                        "C \xe2\x82\xac \xf0\x9f\x98\x80"),
              "\xc2\xb0"
              "C \xe2\x82\xac \xf0\x9f\x98\x80");  // °C, €, an emoji: as they are
    EXPECT_EQ(first_unprintable("ok \xc2\xb0"
                                "C"),
              std::nullopt);
    EXPECT_EQ(first_unprintable("a\xc2\x9b"
                                "b\x1b"),
              "\\xC2\\x9B");
    EXPECT_EQ(first_unprintable("a\x07"), "\\x07");
}

TEST(FrameText, RenderedTextCarriesNoControlCharacterOfTheInput) {
    // A device identification response whose vendor name holds an escape sequence (FC43/14, object 0).
    const auto pdu = bytes({0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x05, 'A', 0x1b, '[', '2', 'J'});
    DecodedFrame d = decode_frame(Framing::Rtu, encode_rtu(0x11, pdu), Direction::Response);
    ASSERT_TRUE(d.pdu.has_value()) << d.error;
    d.source = "line 1 \x1b]0;title\x07";
    const std::string text = render_text(d);
    EXPECT_FALSE(has_control_characters(text)) << text;
    EXPECT_NE(text.find("A\\x1B[2J"), std::string::npos) << text;
    EXPECT_NE(text.find("title\\x07"), std::string::npos) << text;
    // JSON keeps the bytes, escaped by JSON's own rules.
    EXPECT_NE(render_json(d).dump().find("\\u001b"), std::string::npos);

    // An ASCII frame given as text with a control character in it.
    const std::string ascii =
        ":11\x1b"
        "030060\r\n";
    const DecodedFrame a = decode_frame(Framing::Ascii, std::vector<std::uint8_t>(ascii.begin(), ascii.end()),
                                        Direction::Unknown);
    const std::string shown = render_text(a);
    EXPECT_FALSE(has_control_characters(shown)) << shown;
    EXPECT_NE(shown.find(":11\\x1B030060\\r\\n"), std::string::npos) << shown;
}

// A frame given without its direction is read as whichever it is more plausibly. A master's FC3 request for
// 252 registers (twice the maximum, a common master bug) was shown as a response whose byte count of 0
// disagrees with the three bytes after it: both readings break a rule, but a byte count that disagrees with
// the bytes present says they are not that kind of PDU at all, while a quantity above the maximum is a rule
// the sender broke.
TEST(FrameText, ADirectionIsChosenByWhatTheBytesBreak) {
    const auto pdu = bytes({0x03, 0x00, 0x00, 0x00, 0xFC});
    const auto too_many = decode_frame(Framing::Rtu, encode_rtu(1, pdu), Direction::Unknown);
    ASSERT_TRUE(too_many.pdu.has_value()) << too_many.error;
    EXPECT_EQ(too_many.direction_note, "request");
    EXPECT_TRUE(std::holds_alternative<ReadRequest>(too_many.pdu->body));
    EXPECT_TRUE(too_many.pdu->violations.contains(FindingCode::PduQuantityOutOfRange));

    // A response whose byte count holds stays a response, though its bytes read as a request too.
    const auto reply =
        decode_frame(Framing::Rtu, encode_rtu(1, bytes({0x03, 0x02, 0x00, 0x7B})), Direction::Unknown);
    ASSERT_TRUE(reply.pdu.has_value()) << reply.error;
    EXPECT_EQ(reply.direction_note, "response");
}

// JSON's "direction" is the word a program compares; an FC6 request, identical to its echo, says so in a note
// beside it (the prose was the direction, and `--direction` refused it back).
TEST(FrameText, JsonDirectionIsOneWordWithTheReadingInANote) {
    const auto echo =
        decode_frame(Framing::Rtu, encode_rtu(1, bytes({0x06, 0x00, 0x01, 0xFF, 0xFF})), Direction::Unknown);
    ASSERT_TRUE(echo.pdu.has_value()) << echo.error;
    const auto j = render_json(echo);
    EXPECT_EQ(j["direction"], "request");
    EXPECT_EQ(j["direction_note"], "request, or its echo response (identical bytes)");
    const auto plain = render_json(
        decode_frame(Framing::Rtu, encode_rtu(1, bytes({0x03, 0x02, 0x00, 0x7B})), Direction::Unknown));
    EXPECT_EQ(plain["direction"], "response");
    EXPECT_FALSE(plain.contains("direction_note"));
}

}  // namespace test_modbus_frame_text_test
