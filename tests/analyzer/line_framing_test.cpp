// A serial line's framing as the analyzer reads it: told from the line's first bytes when the capture does
// not say it (timed logs of an ASCII line, a raw dump that starts inside a frame), and followed when a
// device acknowledges other line settings (MK PROT, BAUD, PARID: MK-CFG-01, 000:218-226, 501-503) and every
// unit that answered on the line has been told the same, as the reference slave's line follows.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "analyzer/analyzer.hpp"
#include "analyzer/serial_input.hpp"
#include "modbus/adu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_line_framing_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;

using namespace std::chrono_literals;

using mbscope::test::Collect;
using mbscope::test::write_temp;

namespace {

// The MK manual's worked ASCII example (MK-ASC-02, 000:304-309): FC3 of 3 registers from 0x60 at unit 17,
// and its reply 555, 0, 100.
const std::string manual_request = ":11030060000389\r\n";
const std::string manual_reply = ":110306022B0000006455\r\n";

std::string hex_of(const std::string& chars) {
    std::string hex;
    for (const unsigned char c : chars) {
        char x[4];
        std::snprintf(x, sizeof x, "%02X ", c);
        hex += x;
    }
    return hex;
}

std::string rtu(std::uint8_t unit, std::vector<std::uint8_t> pdu) {
    const auto adu = mb::encode_rtu(unit, pdu);
    return {adu.begin(), adu.end()};
}
std::vector<std::uint8_t> octets(const std::string& s) {
    return {s.begin(), s.end()};
}
std::string ascii(std::uint8_t unit, std::vector<std::uint8_t> pdu) {
    return mb::encode_ascii(unit, pdu);
}

// An analyzer describing every device by `profile` (none: values stay raw).
struct Decoding {
    Collect sink;
    an::Analyzer analyzer;
    explicit Decoding(const std::string& profile = {}, std::optional<mb::Framing> framing = std::nullopt)
        : analyzer(options(profile, framing), sink) {}
    static an::AnalyzerOptions options(const std::string& profile, std::optional<mb::Framing> framing) {
        an::AnalyzerOptions o;
        o.serial_framing = framing;
        if (profile.empty()) return o;
        mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
        auto p = store.load(profile);
        EXPECT_TRUE(p.has_value());
        o.semantics = std::make_shared<an::Semantics>();
        o.semantics->add({}, std::make_shared<const mb::Profile>(std::move(p.value())));
        return o;
    }
    bool read(const std::string& path, an::InputFormat format = an::InputFormat::Auto) {
        const bool ok = an::read_input(analyzer, path, format);
        analyzer.finish();
        return ok;
    }
    std::vector<mb::Framing> framings() const {
        std::vector<mb::Framing> out;
        for (const auto& t : sink.transactions)
            out.push_back(t.request.frame.framing);
        return out;
    }
    std::uint64_t unparsed() const { return analyzer.summary().unparsed_bytes; }
    std::string note() const {
        for (const auto& f : sink.findings)
            if (f.code == mb::FindingCode::ProfileLineSettingsChanged) return f.message;
        return {};
    }
};

constexpr auto A = mb::Framing::Ascii;
constexpr auto R = mb::Framing::Rtu;

}  // namespace

// A jpnevulator or text log of an ASCII line was read as RTU: every frame a CRC mismatch of an unknown
// function at unit 58 (':'). Its first bytes now tell the framing.
TEST(LineFraming, ATimedLogOfAnAsciiLineIsReadAsAscii) {
    Decoding run;
    ASSERT_TRUE(run.read(write_temp(
        "ascii-line.txt", "1.000 > " + hex_of(manual_request) + "\n1.020 < " + hex_of(manual_reply) + "\n")));
    ASSERT_EQ(run.framings(), std::vector<mb::Framing>{A});
    ASSERT_TRUE(run.sink.transactions[0].response.has_value());
    ASSERT_TRUE(run.sink.transactions[0].response->pdu.has_value());
    EXPECT_EQ(std::get<mb::ReadRegistersResponse>(run.sink.transactions[0].response->pdu->body).values,
              (std::vector<std::uint16_t>{555, 0, 100}));
    EXPECT_TRUE(run.sink.findings.empty());
    EXPECT_EQ(run.unparsed(), 0u);
}

// A raw dump that starts in the middle of an ASCII frame (the logger started late) was taken for RTU by its
// first byte. The cut frame is reported as unparsed, the rest decoded as ASCII.
TEST(LineFraming, ARawAsciiDumpThatStartsInsideAFrameIsStillAscii) {
    const std::string cut = manual_request.substr(5);  // "0060000389\r\n"
    Decoding run;
    ASSERT_TRUE(run.read(write_temp("ascii-late.bin", cut + manual_request + manual_reply)));
    EXPECT_EQ(run.framings(), std::vector<mb::Framing>{A});
    EXPECT_EQ(run.unparsed(), cut.size());
    ASSERT_EQ(run.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(run.sink.unparsed_records[0].offset, 0u);
}

// An RTU line whose first frames hold bytes an ASCII line never carries is RTU at once; a stated framing is
// kept whatever the bytes look like.
TEST(LineFraming, AnRtuLineIsRtuAndAStatedFramingIsKept) {
    const std::string line = "1.000 " + hex_of(rtu(17, {0x03, 0x00, 0x60, 0x00, 0x03})) + "\n1.020 " +
                             hex_of(rtu(17, {0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64})) + "\n";
    Decoding found;
    ASSERT_TRUE(found.read(write_temp("rtu-line.txt", line)));
    EXPECT_EQ(found.framings(), std::vector<mb::Framing>{R});
    EXPECT_EQ(found.unparsed(), 0u);

    Decoding stated({}, R);
    ASSERT_TRUE(stated.read(write_temp("ascii-stated-rtu.txt", "1.000 " + hex_of(manual_request) + "\n")));
    ASSERT_FALSE(stated.sink.frames.empty());
    ASSERT_EQ(stated.analyzer.summary().serial_lines.size(), 1u);
    EXPECT_FALSE(stated.analyzer.summary().serial_lines.begin()->second.told);
    for (const auto& f : stated.sink.frames)
        EXPECT_EQ(f.frame.framing, R);
    EXPECT_EQ(stated.sink.count(mb::FindingCode::RtuCrcMismatch), 1);
}

// A live serial line whose first bytes are one RTU request to a device that never answers (sniff's default
// framing, auto): the request's eight bytes hold seven no ASCII line carries, one short of the count that
// told RTU, so the line's framing waited for more bytes and the request was neither shown nor timed out
// while the line stayed quiet. A whole frame with a valid CRC and a byte no ASCII line carries tells RTU.
TEST(LineFraming, ALoneRtuRequestOnAQuietLineIsFramedAndTimedOut) {
    Decoding run;
    const auto request = rtu(17, {0x03, 0x00, 0x60, 0x00, 0x03});
    run.analyzer.serial("line", octets(request), 10s);
    run.analyzer.idle(10s + 5ms);
    ASSERT_EQ(run.sink.frames.size(), 1u);
    EXPECT_EQ(run.sink.frames[0].frame.framing, R);
    EXPECT_TRUE(run.sink.frames[0].frame.checksum_ok);
    run.analyzer.idle(11s + 100ms);
    EXPECT_EQ(run.sink.count(mb::FindingCode::PairNoResponse), 1);
    run.analyzer.finish();
    ASSERT_EQ(run.analyzer.summary().serial_lines.size(), 1u);
    EXPECT_TRUE(run.analyzer.summary().serial_lines.begin()->second.told);
    EXPECT_EQ(run.unparsed(), 0u);
}

// On an ASCII line, an RTU frame made of ASCII characters alone does not tell RTU: "1:" read as unit 0x31 and
// FC 0x3A is no frame, and text whose CRC happened to hold would still be an ASCII line's characters.
TEST(LineFraming, AnAsciiLineWithoutForeignBytesStaysAscii) {
    Decoding run;
    run.analyzer.serial("line", octets(manual_request), 10s);
    run.analyzer.serial("line", octets(manual_reply), 10s + 50ms);
    run.analyzer.finish();
    EXPECT_EQ(run.framings(), std::vector<mb::Framing>{A});
}

// MK PROT := 0 acknowledged in RTU: the device talks ASCII from the byte after the acknowledgement, and the
// capture is read so from there, with timing (a text log with directions) and without (a raw dump read in
// one chunk, where the ASCII frames had already been deframed as RTU when the acknowledgement was judged).
TEST(LineFraming, AnAcknowledgedProtWriteSwitchesTheLineToAscii) {
    const std::string read_prot = rtu(1, {0x03, 0x00, 0x08, 0x00, 0x01});
    const std::string holds_rtu = rtu(1, {0x03, 0x02, 0x00, 0x01});
    const std::string prot_ascii = rtu(1, {0x06, 0x00, 0x08, 0x00, 0x00});
    const std::string read_again = ascii(1, {0x03, 0x00, 0x08, 0x00, 0x01});
    const std::string holds_ascii = ascii(1, {0x03, 0x02, 0x00, 0x00});
    const std::vector<std::string> exchange{read_prot,  holds_rtu,  prot_ascii,
                                            prot_ascii, read_again, holds_ascii};

    std::string log, dump;
    double t = 1.0;
    for (std::size_t i = 0; i < exchange.size(); ++i, t += 0.05) {
        char time[16];
        std::snprintf(time, sizeof time, "%.3f", t);
        log += std::string(time) + (i % 2 ? " < " : " > ") + hex_of(exchange[i]) + "\n";
        dump += exchange[i];
    }
    for (const auto& [name, content] : {std::pair{"prot.txt", log}, std::pair{"prot.bin", dump}}) {
        SCOPED_TRACE(name);
        Decoding run("mmk-2030");
        ASSERT_TRUE(run.read(write_temp(name, content)));
        EXPECT_EQ(run.framings(), (std::vector<mb::Framing>{R, R, A}));
        EXPECT_EQ(run.unparsed(), 0u);
        EXPECT_EQ(run.sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
        EXPECT_NE(
            run.note().find("the device talks ASCII from now on (mmk-2030's manual); a master that keeps "
                            "the old settings no longer reaches it; the line is read as ASCII from here on"),
            std::string::npos)
            << run.note();
        ASSERT_EQ(run.sink.transactions.size(), 3u);
        ASSERT_EQ(run.sink.transactions[2].values.size(), 1u);
        EXPECT_EQ(run.sink.transactions[2].values[0].raw, std::vector<std::uint16_t>{0});  // ASCII
        EXPECT_EQ(run.sink.count(mb::FindingCode::RtuCrcMismatch), 0);
    }
    // Without the device's map nothing says what register 8 is: the ASCII frames stay bytes nobody framed,
    // reported as such, not dropped.
    Decoding blind;
    ASSERT_TRUE(blind.read(write_temp("prot-blind.bin", dump)));
    EXPECT_EQ(blind.framings(), (std::vector<mb::Framing>{R, R}));
    EXPECT_EQ(blind.unparsed(), read_again.size() + holds_ascii.size());
}

// A multi-drop line: the master tells unit 1, then unit 2, and the line changes only when the last unit
// that answered on it has been told (until then the master still talks RTU to unit 2). Back to RTU the
// same way.
TEST(LineFraming, AMultiDropLineFollowsWhenEveryUnitThatAnsweredWasTold) {
    const auto read8 = [](auto frame, std::uint8_t unit, std::uint16_t holds) {
        return frame(unit, {0x03, 0x00, 0x08, 0x00, 0x01}) +
               frame(unit, {0x03, 0x02, 0x00, static_cast<std::uint8_t>(holds)});
    };
    const auto write8 = [](auto frame, std::uint8_t unit, std::uint8_t code) {
        const std::vector<std::uint8_t> pdu{0x06, 0x00, 0x08, 0x00, code};
        return frame(unit, pdu) + frame(unit, pdu);
    };
    const std::string dump = read8(rtu, 1, 1) + read8(rtu, 2, 1) + write8(rtu, 1, 0) + read8(rtu, 2, 1) +
                             write8(rtu, 2, 0) + read8(ascii, 1, 0) + write8(ascii, 1, 1) +
                             write8(ascii, 2, 1) + read8(rtu, 1, 1);
    Decoding run("mmk-2030");
    ASSERT_TRUE(run.read(write_temp("multi-drop.bin", dump)));
    EXPECT_EQ(run.framings(), (std::vector<mb::Framing>{R, R, R, R, R, A, A, A, R}));
    EXPECT_EQ(run.unparsed(), 0u);
    // The summary says what the line was read in, in order, and that the first was told from its bytes.
    const auto& lines = run.analyzer.summary().serial_lines;
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_EQ(lines.begin()->second.framings, (std::vector<mb::Framing>{R, A, R}));
    EXPECT_TRUE(lines.begin()->second.told);
    std::vector<std::string> said;
    for (const auto& f : run.sink.findings)
        if (f.code == mb::FindingCode::ProfileLineSettingsChanged)
            said.push_back(f.message.substr(f.message.rfind("; ")));
    EXPECT_EQ(said,
              (std::vector<std::string>{
                  "; the line is still read as RTU: unit 2, which answered on it, was not told the same",
                  "; the line is read as ASCII from here on",
                  "; the line is still read as ASCII: unit 2, which answered on it, was not told the same",
                  "; the line is read as RTU from here on"}));
}

// BAUD := 3 (2400 baud, 000:501-503): the silences are measured in the new speed's characters. A reply
// whose two halves are 3 ms apart is whole at 2400 baud (t1.5 = 6.25 ms, 8N1), and its bytes
// are timed at 2400 baud: read at 9600 baud they would stand 15 ms apart, a frame cut in two.
TEST(LineFraming, ANewSpeedSetsTheSilences) {
    const std::string baud_2400 = rtu(1, {0x06, 0x00, 0x09, 0x00, 0x03});
    const std::string request = rtu(1, {0x03, 0x00, 0x09, 0x00, 0x01});
    const std::string reply = rtu(1, {0x03, 0x02, 0x00, 0x03});
    const double char_2400 = 10.0 / 2400;  // 8N1 on 2400 baud: 4.17 ms a character
    char times[4][16];
    std::snprintf(times[0], sizeof times[0], "%.6f", 2.0);
    std::snprintf(times[1], sizeof times[1], "%.6f", 2.1 + 3 * char_2400);
    std::snprintf(times[2], sizeof times[2], "%.6f", 2.1 + 3 * char_2400 + 0.003 + 4 * char_2400);
    const std::string log = "1.000 > " + hex_of(baud_2400) + "\n1.050 < " + hex_of(baud_2400) + "\n" +
                            times[0] + " > " + hex_of(request) + "\n" + times[1] + " < " +
                            hex_of(reply.substr(0, 3)) + "\n" + times[2] + " < " + hex_of(reply.substr(3)) +
                            "\n";
    Decoding run("mmk-2030");
    ASSERT_TRUE(run.read(write_temp("baud.txt", log)));
    EXPECT_NE(run.note().find("; the line is read as RTU, 2400 baud, no parity (8N1) from here on"),
              std::string::npos)
        << run.note();
    ASSERT_EQ(run.sink.transactions.size(), 2u);
    ASSERT_TRUE(run.sink.transactions[1].response.has_value());
    EXPECT_TRUE(run.sink.transactions[1].response->frame.checksum_ok);
    EXPECT_EQ(run.sink.count(mb::FindingCode::RtuGapInsideFrame), 0);
    EXPECT_EQ(run.unparsed(), 0u);
}

// A broadcast of new line settings (FC16 to unit 0, which MK devices run: functions.broadcast, SL §2.1)
// is taken by every device on the line at once, without a reply: one note names the units, and the line
// is read the new way from the byte after the broadcast.
TEST(LineFraming, ABroadcastOfTheLineSettingsMovesTheWholeLine) {
    const auto read8 = [](auto frame, std::uint8_t unit, std::uint8_t holds) {
        return frame(unit, {0x03, 0x00, 0x08, 0x00, 0x01}) + frame(unit, {0x03, 0x02, 0x00, holds});
    };
    // PROT, BAUD, PARID := ASCII, 9600 baud, no parity
    const std::string broadcast =
        rtu(0, {0x10, 0x00, 0x08, 0x00, 0x03, 0x06, 0x00, 0x00, 0x00, 0x05, 0x00, 0x00});
    const std::string dump =
        read8(rtu, 1, 1) + read8(rtu, 2, 1) + broadcast + read8(ascii, 1, 0) + read8(ascii, 2, 0);
    Decoding run("mmk-2030");
    ASSERT_TRUE(run.read(write_temp("broadcast.bin", dump)));
    EXPECT_EQ(run.framings(), (std::vector<mb::Framing>{R, R, R, A, A}));
    EXPECT_EQ(run.unparsed(), 0u);
    EXPECT_EQ(run.sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
    EXPECT_EQ(run.note(),
              "PROT. (register 8) := 0, BAUD (register 9) := 5, PARID (register 10) := 0 broadcast: "
              "units 1, 2 talk ASCII, 9600 baud, no parity from now on (mmk-2030's manual); a master "
              "that keeps the old settings no longer reaches them; the line is read as ASCII, 9600 "
              "baud, no parity (7N2) from here on");
    ASSERT_EQ(run.sink.transactions.size(), 5u);
    EXPECT_TRUE(run.sink.transactions[2].broadcast);
}

// A unit that moved to another address (ENDER, MK-CFG-01) is no longer on the line at the old one: the
// line follows the next change without waiting for it there.
TEST(LineFraming, AUnitThatMovedAwayIsNotWaitedFor) {
    const std::string dump = rtu(1, {0x03, 0x00, 0x08, 0x00, 0x01}) + rtu(1, {0x03, 0x02, 0x00, 0x01}) +
                             rtu(1, {0x06, 0x00, 0x07, 0x00, 0x11}) + rtu(1, {0x06, 0x00, 0x07, 0x00, 0x11}) +
                             rtu(17, {0x06, 0x00, 0x08, 0x00, 0x00}) +
                             rtu(17, {0x06, 0x00, 0x08, 0x00, 0x00}) +
                             ascii(17, {0x03, 0x00, 0x08, 0x00, 0x01}) + ascii(17, {0x03, 0x02, 0x00, 0x00});
    Decoding run("mmk-2030");
    ASSERT_TRUE(run.read(write_temp("moved.bin", dump)));
    EXPECT_EQ(run.framings(), (std::vector<mb::Framing>{R, R, R, A}));
    EXPECT_EQ(run.unparsed(), 0u);
    EXPECT_EQ(run.sink.count(mb::FindingCode::ProfileAddressMoved), 1);
    EXPECT_NE(run.note().find("; the line is read as ASCII from here on"), std::string::npos) << run.note();
}

// FC23 writes before it reads (AP §6.17): an acknowledged FC23 that writes PROT tells the device as FC6 and
// FC16 do. (No bundled MK device supports FC23; the map is what is judged here.)
TEST(LineFraming, AnAcknowledgedReadWriteOfTheLineSettingsTellsTheDevice) {
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    auto profile = store.load("mmk-2030");
    ASSERT_TRUE(profile.has_value());
    an::Semantics semantics;
    const std::uint16_t ascii_code[] = {0};
    const std::uint16_t read_back[] = {0};
    auto q = mb::make_read_write_multiple(8, 1, 8, ascii_code);
    auto a = mb::make_read_registers_response(mb::FunctionCode::ReadWriteMultipleRegisters, read_back);
    a.direction = mb::Direction::Response;
    const auto told = semantics.follow_line_settings("unit 1", profile.value(), q, a);
    ASSERT_TRUE(told.has_value());
    EXPECT_EQ(told->settings.framing, A);
    EXPECT_EQ(told->written, "PROT. (register 8) := 0");
    // An exception acknowledges nothing.
    EXPECT_FALSE(semantics.follow_line_settings("unit 1", profile.value(), q, mb::make_exception(23, 1)));
}

// A reply whose CRC fails names a unit nobody may have (noise read as a frame): it does not put that unit
// on the line, and the line follows unit 1 alone.
TEST(LineFraming, AReplyWithABadCrcPutsNoUnitOnTheLine) {
    std::string bad_reply = rtu(9, {0x03, 0x02, 0x00, 0x01});
    bad_reply.back() = static_cast<char>(bad_reply.back() ^ 0x5A);
    const std::string prot_ascii = rtu(1, {0x06, 0x00, 0x08, 0x00, 0x00});
    const std::string dump = rtu(9, {0x03, 0x00, 0x08, 0x00, 0x01}) + bad_reply +
                             rtu(1, {0x03, 0x00, 0x08, 0x00, 0x01}) + rtu(1, {0x03, 0x02, 0x00, 0x01}) +
                             prot_ascii + prot_ascii + ascii(1, {0x03, 0x00, 0x08, 0x00, 0x01}) +
                             ascii(1, {0x03, 0x02, 0x00, 0x00});
    Decoding run("mmk-2030");
    ASSERT_TRUE(run.read(write_temp("bad-crc.bin", dump)));
    EXPECT_EQ(run.sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    EXPECT_EQ(run.framings(), (std::vector<mb::Framing>{R, R, R, A}));
    EXPECT_NE(run.note().find("; the line is read as ASCII from here on"), std::string::npos) << run.note();
}

}  // namespace test_analyzer_line_framing_test
