// Serial captures: raw RTU dumps (no timing) and the timed text format, with half-duplex direction
// inference, broadcasts, gaps inside frames, timeouts and bad CRCs. Input frames are the MK manual's worked
// examples (000:356-484); the expected findings are written by hand.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>

#include <atomic>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>
#include <utility>

#include "analyzer/serial_input.hpp"
#include "analyzer/sinks.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/pdu.hpp"
#include "test_packets.hpp"

namespace test_analyzer_serial_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::Collect;
using mbscope::test::write_temp;

namespace {

std::string bytes(std::initializer_list<int> b) {
    std::string s;
    for (int x : b)
        s.push_back(static_cast<char>(x));
    return s;
}

struct Run {
    Collect sink;
    an::Summary summary;
    bool ok = false;
};

// Several inputs; `one_line`: the serial ones are parts of one line.
std::unique_ptr<Run> decode_all(const std::vector<std::string>& paths, bool one_line,
                                an::InputFormat format = an::InputFormat::Auto) {
    auto r = std::make_unique<Run>();
    an::Analyzer a({}, r->sink);
    an::SerialLogOptions logs;
    logs.parts_of_one_line = one_line;
    r->ok = an::read_inputs(a, paths, format, logs);
    a.finish();
    r->summary = a.summary();
    return r;
}

std::unique_ptr<Run> decode(const std::string& path, an::InputFormat format = an::InputFormat::Auto) {
    return decode_all({path}, false, format);
}

// The run as the text output writes it: its transactions, findings and summary.
std::string text_output(const Run& r) {
    std::ostringstream text;
    an::TextSink sink(text);
    for (const auto& t : r.sink.transactions)
        sink.transaction(t);
    for (const auto& f : r.sink.findings)
        sink.finding(f);
    sink.end(r.summary);
    return text.str();
}

}  // namespace

TEST(SerialInput, FormatDetection) {
    auto d = [](const std::string& s) {
        return an::detect_input_format({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()});
    };
    EXPECT_EQ(d(bytes({0xD4, 0xC3, 0xB2, 0xA1, 0, 0})), an::InputFormat::Pcap);
    EXPECT_EQ(d(bytes({0x0A, 0x0D, 0x0D, 0x0A})), an::InputFormat::Pcap);
    EXPECT_EQ(d(":11030060000389\r\n"), an::InputFormat::AsciiRaw);
    EXPECT_EQ(d("1.000 > 11 03 00 60\n"), an::InputFormat::Text);
    // An ASCII dump cut inside its first frame is a raw dump (its line then tells ASCII), not a text log.
    EXPECT_EQ(d("0060000389\r\n:11030060000389\r\n"), an::InputFormat::RtuRaw);
    EXPECT_EQ(d(bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45})), an::InputFormat::RtuRaw);
    // A text log whose first line the format cannot read was its characters as a raw dump ("no Modbus
    // frame", no line named, its good lines lost): the reader now names the bad line.
    EXPECT_EQ(d("abc > 11 03 00 60 00 03 07 45\n1.0 > 11 03 00 60 00 03 07 45\n"), an::InputFormat::Text);
    EXPECT_EQ(d("-5 > 11 03 00 60 00 03 07 45\n"), an::InputFormat::Text);
    EXPECT_EQ(d("nan 11 03\n\n  2.5 M 11 03 00 60 00 03 07 45\n"), an::InputFormat::Text);
    // Printable lines none of which is in the format, or bytes that are not all printable: still raw.
    EXPECT_EQ(d("abc def\nghi jkl\n"), an::InputFormat::RtuRaw);
    EXPECT_EQ(d(bytes({'a', ' ', 'b', '\n', '1', ' ', '2', 0x11, '\n'})), an::InputFormat::RtuRaw);
}

// Traffic pasted as hex lines without times: the text format read each line's first byte as its time ("01"
// at 1 s), the rest of the line a frame with a bad CRC, and the byte taken for a time counted nowhere
// ("0 unparsed bytes"). Lines of two-digit hex tokens alone are a hex dump when something tells them from
// "TIME HEX...": a line that is a whole RTU frame, or a first byte with a hex letter. Two-digit times
// ("10 11 03 ...") with nothing of the kind stay the text format.
TEST(SerialInput, AHexDumpWithoutTimesIsReadAsItsBytes) {
    auto d = [](const std::string& s) {
        return an::detect_input_format({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()});
    };
    EXPECT_EQ(d("01 03 00 00 00 01 84 0A\n01 03 02 00 64 B9 AF\n"), an::InputFormat::Hex);
    EXPECT_EQ(d("3A 30 31\n"), an::InputFormat::Hex);
    EXPECT_EQ(d("10 11 03 00 60\n11 11 03 06\n"), an::InputFormat::Text);
    EXPECT_EQ(d("1.000 11 03 00 60\n"), an::InputFormat::Text);
    const auto path = write_temp("pasted.txt",
                                 "# pasted\n01 03 00 00 00 01 84 0A\n01 03 02 00 64 B9 AF\n"
                                 "11 03 00 6B\n00 03 76 87 # split across lines\n");
    auto r = decode(path);
    EXPECT_TRUE(r->ok);
    EXPECT_TRUE(r->summary.input_errors.empty());
    EXPECT_EQ(r->summary.unparsed_bytes, 0u);
    ASSERT_EQ(r->sink.frames.size(), 3u);
    EXPECT_EQ(r->sink.frames[2].frame.offset, 15u);
    ASSERT_EQ(r->sink.transactions.size(), 2u);  // the last request's reply is not in the dump
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 0);
    const auto bad = write_temp("pasted_bad.txt", "01 03 00 00 00 01 84 0A\n01 0X\n");
    r = decode(bad, an::InputFormat::Hex);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 1u);
    EXPECT_EQ(r->summary.input_errors[0].rfind(bad + ":2: not hex bytes: ", 0), 0u)
        << r->summary.input_errors[0];
}

// The same bad line first or later: named, and the good lines decode either way.
TEST(SerialInput, ABadFirstLineOfATextLogIsNamedAndTheRestDecodes) {
    const auto path = write_temp("bad_first_line.txt",
                                 "abc > 11 03 00 60 00 03 07 45\n"
                                 "1.000 > 11 03 00 60 00 03 07 45\n"
                                 "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 1u);
    EXPECT_NE(r->summary.input_errors[0].find("bad_first_line"), std::string::npos);
    EXPECT_NE(r->summary.input_errors[0].find(".txt:1: not a time"), std::string::npos)
        << r->summary.input_errors[0];
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());
    EXPECT_EQ(r->summary.unparsed_bytes, 0u);
}

TEST(SerialInput, RawRtuDumpPairsEchoesAndExceptions) {
    // FC3 request and reply (000:356, 365), FC6 and its identical echo (000:396, 405), one noise byte, FC1
    // and the manual's exception 02 (000:330, 484).
    const auto path = write_temp(
        "mk.bin", bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45, 0x11, 0x03, 0x06, 0x02, 0x2B,
                         0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA, 0x11, 0x06, 0x00, 0x54, 0x03, 0x9E, 0x4B,
                         0xD2, 0x11, 0x06, 0x00, 0x54, 0x03, 0x9E, 0x4B, 0xD2, 0xFF, 0x11, 0x01, 0x00,
                         0x13, 0x00, 0x15, 0x0E, 0x90, 0x11, 0x81, 0x02, 0xC0, 0x54}));
    auto r = decode(path);
    ASSERT_TRUE(r->ok);
    ASSERT_EQ(r->sink.transactions.size(), 3u);
    for (const auto& t : r->sink.transactions)
        EXPECT_TRUE(t.response.has_value());
    EXPECT_EQ(r->sink.transactions[1].request.pdu->function_code(), 6);
    EXPECT_EQ(r->sink.transactions[1].response->direction,
              mb::Direction::Response);  // the echo, not a new request
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairExceptionResponse), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::StreamUnparsedBytes), 1);
    EXPECT_EQ(r->summary.unparsed_bytes, 1u);
    EXPECT_FALSE(r->sink.transactions[0].latency.has_value());  // a raw dump has no clock
}

TEST(SerialInput, TimedTextFindsGapsTimeoutsBroadcastRepliesAndBadCrc) {
    const auto line = [](double t, const char* dir, const std::vector<std::uint8_t>& b) {
        char head[32];
        std::snprintf(head, sizeof head, "%.6f", t);
        return std::string(head) + (dir ? std::string(" ") + dir : "") + " " + mb::hex_bytes(b) + "\n";
    };
    const auto fc3 = mb::encode_rtu(
        0x11, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0x60, 3)));
    const std::uint16_t regs[] = {555, 0, 100};
    const auto fc3_reply = mb::encode_rtu(
        0x11, mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, regs)));
    const auto fc6 = mb::encode_rtu(0x11, mb::encode_pdu(mb::make_write_single_register(0x54, 926)));
    const auto broadcast = mb::encode_rtu(0x00, mb::encode_pdu(mb::make_write_single_register(0x54, 926)));
    auto bad_crc = fc3;
    bad_crc.back() ^= 0x01;  // MK-ERR-01: 07 45 → 07 44
    std::string text = "# time dir bytes\n";
    text += line(1.000, ">", fc3);
    text += line(1.020, "<", fc3_reply);
    // 2.0 s: the FC3 request again, with a 3-character silence (3.125 ms at 9600 8N1) after its 4th byte
    text += line(2.000000, nullptr, {fc3.begin(), fc3.begin() + 4});
    text += line(2.007292, nullptr, {fc3.begin() + 4, fc3.end()});
    text += line(2.030, nullptr, fc3_reply);
    text += line(3.000, nullptr, fc6);  // never answered: 1 s serial timeout
    text += line(5.000, nullptr, broadcast);
    text += line(5.050, "<", broadcast);  // a slave "answers" the broadcast
    text += line(6.000, nullptr, bad_crc);
    text += line(6.020, nullptr, fc3_reply);
    auto r = decode(write_temp("line.txt", text));
    ASSERT_TRUE(r->ok) << (r->summary.input_errors.empty() ? "" : r->summary.input_errors[0]);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuGapInsideFrame), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairBroadcastResponse), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_FALSE(r->sink.transactions.empty());
    ASSERT_TRUE(r->sink.transactions[0].latency.has_value());
    const double latency_ms =
        std::chrono::duration<double, std::milli>(*r->sink.transactions[0].latency).count();
    EXPECT_NEAR(latency_ms, 20.0, 0.01);
}

// Which device did it: the summary counted bad CRCs per device (RTU only) and findings for the whole
// capture only, and said neither per device. Each device now has its findings and its frames with a bad CRC
// or LRC.
TEST(SerialInput, EachDeviceHasItsOwnFindingsAndBadChecksums) {
    const auto rtu = write_temp("two_units.txt",
                                "1.000 > 11 03 00 60 00 03 07 45\n"
                                "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BB\n"  // CRC C8 BA, one bit off
                                "2.000 > 05 03 00 60 00 03 04 51\n"           // unit 5: never answered
                                "4.000 > 11 03 00 60 00 03 07 45\n"
                                "4.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(rtu, an::InputFormat::Text);
    const auto& devices = r->summary.devices;
    ASSERT_EQ(devices.size(), 2u);
    const auto& seventeen = devices.at("serial " + rtu + " unit 17");
    const auto& five = devices.at("serial " + rtu + " unit 5");
    EXPECT_EQ(seventeen.checksum_errors, 1u);
    EXPECT_EQ(seventeen.findings, (std::map<std::string, std::uint64_t>{{"rtu.crc_mismatch", 1}}));
    EXPECT_EQ(five.checksum_errors, 0u);
    EXPECT_EQ(five.findings, (std::map<std::string, std::uint64_t>{{"pair.no_response", 1}}));
    const auto json = an::summary_to_json(r->summary)["devices"];
    EXPECT_EQ(json["serial " + rtu + " unit 17"]["checksum_errors"], 1);
    EXPECT_EQ(json["serial " + rtu + " unit 17"]["findings"]["rtu.crc_mismatch"], 1);
    EXPECT_FALSE(json["serial " + rtu + " unit 5"].contains("checksum_errors"));
    EXPECT_EQ(json["serial " + rtu + " unit 5"]["findings"]["pair.no_response"], 1);

    // An ASCII line's LRC, from a raw dump (no clock, no timeout).
    const auto ascii = write_temp("ascii_lrc.txt", ":11030060000389\r\n:110306022B0000006456\r\n");
    r = decode(ascii, an::InputFormat::AsciiRaw);
    const auto& device = r->summary.devices.at("serial " + ascii + " unit 17");
    EXPECT_EQ(device.checksum_errors, 1u);
    EXPECT_EQ(device.findings.at("ascii.lrc_mismatch"), 1u);
}

// A reply to unit 17 garbled on the line, its unit byte among the damage (0x11 read as 0x13, the CRC
// failing): it stood in the summary as a device "unit 19" that nobody asked, with a bad CRC and a
// pair.unit_mismatch, and unit 17 had no bad CRC. It is unit 17's reply with a bad CRC, and its damaged
// bytes are not held against the request.
TEST(SerialInput, AGarbledReplyIsTheAskedUnitsNotAnotherDevice) {
    for (const bool marked : {true, false}) {
        SCOPED_TRACE(marked ? "directions in the log" : "directions told by the analyzer");
        const std::string to = marked ? "> " : "", from = marked ? "< " : "";
        const auto path =
            write_temp("garbled_unit.txt", "1.000 " + to + "11 03 00 60 00 03 07 45\n" +  //
                                               "1.020 " + from + "13 03 06 02 2B 00 00 00 64 C8 BA\n" +
                                               "2.000 " + to + "11 03 00 60 00 03 07 45\n" + "2.020 " + from +
                                               "11 03 06 02 2B 00 00 00 64 C8 BA\n");
        auto r = decode(path, an::InputFormat::Text);
        ASSERT_EQ(r->summary.devices.size(), 1u);
        const auto& device = r->summary.devices.at("serial " + path + " unit 17");
        EXPECT_EQ(device.checksum_errors, 1u);
        EXPECT_EQ(device.responses, 2u);
        EXPECT_EQ(device.findings, (std::map<std::string, std::uint64_t>{{"rtu.crc_mismatch", 1}}));
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnitMismatch), 0);
        ASSERT_EQ(r->sink.transactions.size(), 2u);
        EXPECT_FALSE(r->sink.transactions[0].response->frame.checksum_ok);
    }
}

// Four bytes of line noise between two polls, "00 03 07 45", read as a frame to unit 0 whose CRC fails: it
// was a broadcast transaction and a device "unit 0" with one request. Every slave discards a frame whose CRC
// fails (MK-ERR-01, 000:270-272), so it is no broadcast and names no device; its CRC finding stays, and the
// summary counts it. A reply right after such a frame is unsolicited, and says what it may answer.
TEST(SerialInput, NoiseToUnitZeroIsNoBroadcastAndNoDevice) {
    const auto path = write_temp("noise_unit0.txt",
                                 "1.000 > 11 03 00 60 00 03 07 45\n"
                                 "1.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "1.500 00 03 07 45\n"
                                 "2.000 > 11 03 00 60 00 03 07 45\n"
                                 "2.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "3.000 > 00 06 00 01 00 03 98 1A\n"  // a write to unit 0, its CRC damaged
                                 "3.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_EQ(r->summary.devices.size(), 1u);
    const auto& device = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(device.requests, 2u);
    EXPECT_EQ(device.checksum_errors, 0u);
    EXPECT_EQ(r->summary.damaged_broadcasts, 2u);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    for (const auto& t : r->sink.transactions)
        EXPECT_FALSE(t.broadcast);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 2);
    // The reply after the damaged write: not "one request answered twice", though its bytes are the last
    // reply's again.
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code != mb::FindingCode::PairUnsolicitedResponse) continue;
        EXPECT_NE(f.message.find("after frame 6, a request whose checksum failed"), std::string::npos)
            << f.message;
    }
    EXPECT_EQ(an::summary_to_json(r->summary)["damaged_broadcasts"], 2);
}

// On the slaves' side too: five bytes of noise after a poll's reply, "00 00 00 00 00", and the tail of a
// reply cut by a silence, "00 00 00 64 C8 BB" (damaged too: head and tail do not verify joined, so they stay
// two pieces, see AReplyCutInTwoByASilenceOfT35IsUnit17sReplyNotADamagedBroadcast), were frames from unit 0
// whose CRC fails, each reported as
// pair.broadcast_response (an error: a slave answering a broadcast nobody sent) from a device "unit 0".
// A damaged reply that no request waits for, naming no unit seen on the line, is its CRC finding alone.
// A unit the line knows still has a damaged reply nobody asked for held against it.
TEST(SerialInput, DamagedBytesFromTheSlavesSideNameNoDeviceTheLineDoesNotHave) {
    const auto path = write_temp("damaged_replies.txt",
                                 "1.000 > 11 03 00 60 00 03 07 45\n"
                                 "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "1.500 < 00 00 00 00 00\n"
                                 "2.000 > 11 03 00 60 00 03 07 45\n"
                                 "2.020 < 11 03 06 02 2B\n"  // the reply cut by a 20 ms silence
                                 "2.040 < 00 00 00 64 C8 BB\n"
                                 "3.000 < 11 03 06 02 2B 00 00 00 64 C8 BB\n");  // unasked, damaged
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    ASSERT_EQ(r->summary.devices.size(), 1u);
    const auto& device = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(device.requests, 2u);
    EXPECT_EQ(device.checksum_errors, 2u);  // the cut reply, and the unasked one
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairBroadcastResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 4);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::PairUnsolicitedResponse) {
            EXPECT_EQ(f.device.str(), "serial " + path + " unit 17");
        }
        const bool noise =
            f.frames == std::vector<std::uint64_t>{3} || f.frames == std::vector<std::uint64_t>{6};
        if (f.code == mb::FindingCode::RtuCrcMismatch && noise) {
            EXPECT_TRUE(f.device.empty()) << f.message;
        }
    }
}

// A request to a unit whose CRC fails is discarded by the slave (SL §2.5.1.2; MK-ERR-01, 000:270-272): its
// silence is right. Before, it was pair.no_response, an error and a timeout held against unit 17, which did
// what the rules want. It is a note now, counted apart; a reply that does come is still paired with it (the
// capture may have damaged what the device got whole).
TEST(SerialInput, ADamagedRequestLeftUnansweredIsNoTimeout) {
    const auto path = write_temp("damaged_request.txt",
                                 "1.000 > 11 03 00 60 00 03 07 46\n"  // its CRC damaged: no reply
                                 "2.500 > 11 03 00 60 00 03 07 45\n"
                                 "2.550 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "3.000 > 11 03 00 60 00 03 07 46\n"  // damaged, and answered all the same
                                 "3.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "4.000 > 11 03 00 60 00 03 07 46\n");  // damaged, the capture ends
    auto r = decode(path, an::InputFormat::Text);
    const auto& device = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(device.requests, 4u);
    EXPECT_EQ(device.responses, 2u);
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.unanswered_at_end, 0u);
    EXPECT_EQ(device.damaged_unanswered, 2u);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairDamagedRequestUnanswered), 2);
    for (const auto& f : r->sink.findings) {
        if (f.code != mb::FindingCode::PairDamagedRequestUnanswered) continue;
        EXPECT_NE(f.message.find("its CRC failed and no reply came"), std::string::npos) << f.message;
    }
    EXPECT_EQ(r->summary.errors, 3u);  // the three CRC mismatches, nothing more
    ASSERT_EQ(r->sink.transactions.size(), 4u);
    EXPECT_TRUE(r->sink.transactions[0].discarded);
    EXPECT_FALSE(r->sink.transactions[0].timed_out);
    EXPECT_TRUE(r->sink.transactions[2].response.has_value());
    EXPECT_EQ(an::summary_to_json(r->summary)["devices"]["serial " + path + " unit 17"]["damaged_unanswered"],
              2);
}

// A request with a silence above t1.5 inside it is incomplete, and a slave keeping t1.5 discards it (SL
// §2.5.1.1), as the reference slave does: no reply is its right answer, not a timeout held against unit 17
// (it was pair.no_response, an error, exit 1). The gap finding says where the silence was and how long. A
// device that ignores t1.5 and answers is paired as before.
TEST(SerialInput, ARequestWithASilenceInsideLeftUnansweredIsNoTimeout) {
    // 9600 8N1: a character is 1.042 ms; 2 character times of silence after the request's 4th byte (a line's
    // time is its last byte's).
    const auto path = write_temp("gapped_request.txt",
                                 "1.000000 > 11 03 00 60\n"
                                 "1.006250 > 00 03 07 45\n"  // no reply: the master asks again
                                 "1.500000 > 11 03 00 60 00 03 07 45\n"
                                 "1.520000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "2.000000 > 11 03 00 60\n"
                                 "2.006250 > 00 03 07 45\n"
                                 "2.030000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");  // answered all the same
    auto r = decode(path, an::InputFormat::Text);
    const auto& device = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(device.requests, 3u);
    EXPECT_EQ(device.responses, 2u);
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.damaged_unanswered, 1u);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::RtuGapInsideFrame), 2);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairDamagedRequestUnanswered), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::RtuGapInsideFrame) {
            EXPECT_EQ(f.message,
                      "silence of 2.0 character times between bytes 4 and 5 of 8, above t1.5: a receiver "
                      "keeping t1.5 discards the frame");
        }
        if (f.code == mb::FindingCode::PairDamagedRequestUnanswered) {
            EXPECT_NE(
                f.message.find(": a silence of 2.0 character times between bytes 4 and 5 of 8 inside it "
                               "and no reply came"),
                std::string::npos)
                << f.message;
        }
    }
    ASSERT_EQ(r->sink.transactions.size(), 3u);
    EXPECT_TRUE(r->sink.transactions[0].discarded);
    EXPECT_FALSE(r->sink.transactions[0].timed_out);
    EXPECT_TRUE(r->sink.transactions[2].response.has_value());
}

// A request counted discarded at its timeout (a silence inside it, or its CRC failed) that the device then
// answers: it got the request, late. A timeout answered late, not also a discarded request (the summary said
// "0 timeouts (1 answered late), 1 damaged requests discarded").
TEST(SerialInput, ADiscardedRequestAnsweredLateIsATimeoutAnsweredLate) {
    for (const bool gap : {true, false}) {
        SCOPED_TRACE(gap ? "a silence inside" : "a bad CRC");
        const auto path =
            write_temp("late_discarded.txt", gap ? "1.000000 > 11 03 00 60\n"
                                                   "1.006250 > 00 03 07 45\n"
                                                   "2.500000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                                 : "1.000000 > 11 03 00 60 00 03 07 46\n"
                                                   "2.500000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
        auto r = decode(path, an::InputFormat::Text);
        const auto& device = r->summary.devices.at("serial " + path + " unit 17");
        EXPECT_EQ(device.requests, 1u);
        EXPECT_EQ(device.timeouts, 1u);
        EXPECT_EQ(device.late_responses, 1u);
        EXPECT_EQ(device.damaged_unanswered, 0u);
    }
}

// Line noise of a few bytes is a frame to some unit whose CRC fails: "3C 03 A1 22 7F" made unit 60 a device
// with a discarded request, "FF 83 11 22" unit 255 (its function named FC3 on its line, FC131 in the
// summary). A damaged request to a unit no frame of its line has shown is no device's, unless the unit shows
// itself before its wait ends: by its reply (the capture damaged what it got whole), or by the master
// asking it again (the test above).
TEST(SerialInput, LineNoiseMakesNoDevice) {
    const auto path = write_temp("noise_units.txt",
                                 "1.000 11 03 00 60 00 03 07 45\n"
                                 "1.020 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "1.300 3C 03 A1 22 7F\n"  // noise: unit 60, never seen
                                 "1.500 11 03 00 60 00 03 07 45\n"
                                 "1.520 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "1.800 FF 83 11 22\n"                // noise: unit 255
                                 "2.000 05 03 00 00 00 01 85 8F\n"    // unit 5, first seen, its CRC damaged,
                                 "2.020 05 03 02 00 07 08 46\n"       // and it answers
                                 "2.500 11 83 00 60 00 01 87 5B\n");  // function byte 0x83, CRC damaged
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    EXPECT_EQ(r->summary.damaged_to_unseen_units, 2u);
    EXPECT_EQ(an::summary_to_json(r->summary)["damaged_to_unseen_units"], 2);
    ASSERT_EQ(r->summary.devices.size(), 2u);
    const auto& unit5 = r->summary.devices.at("serial " + path + " unit 5");
    EXPECT_EQ(unit5.requests, 1u);
    EXPECT_EQ(unit5.responses, 1u);
    EXPECT_EQ(unit5.checksum_errors, 1u);
    EXPECT_EQ(unit5.functions.at(3), 1u);
    EXPECT_EQ(unit5.findings.at("rtu.crc_mismatch"), 1u);
    const auto& unit17 = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(unit17.requests, 3u);
    EXPECT_EQ(unit17.responses, 2u);
    EXPECT_EQ(unit17.damaged_unanswered, 1u);
    EXPECT_EQ(unit17.functions.at(0x83), 1u);
    ASSERT_EQ(r->sink.transactions.size(), 4u);
    EXPECT_EQ(r->sink.transactions[2].request.device.str(), "serial " + path + " unit 5");
    EXPECT_TRUE(r->sink.transactions[2].response.has_value());
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairDamagedRequestUnanswered), 1);
    for (const auto& f : r->sink.findings)
        if (f.code == mb::FindingCode::PairDamagedRequestUnanswered) {
            EXPECT_EQ(f.message.rfind("FC131 to serial " + path + " unit 17", 0), 0u) << f.message;
        }
    // Another unit's reply while such a request waits answers a request the capture does not hold: no unit
    // mismatch held against it for noise naming unit 18, and its unsolicited finding names the damaged
    // frame before it. Nor is the same reply as before "one request answered twice" there.
    for (const char* reply : {"11 03 06 02 2B 00 00 00 64 C8 BA", "11 03 06 02 2B 00 00 00 65 09 7A"}) {
        const auto other = write_temp("noise_then_other.txt",
                                      "0.500 11 03 00 60 00 03 07 45\n"
                                      "0.520 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                      "1.000 12 03 00 60 00 03 06 94\n"
                                      "1.020 " +
                                          std::string(reply) + "\n");
        r = decode(other, an::InputFormat::Text);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnitMismatch), 0);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 0);
        ASSERT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
        for (const auto& f : r->sink.findings)
            if (f.code == mb::FindingCode::PairUnsolicitedResponse) {
                EXPECT_NE(f.message.find("after frame 3, a request whose checksum failed"), std::string::npos)
                    << f.message;
            }
        EXPECT_EQ(r->summary.damaged_to_unseen_units, 1u);
        EXPECT_EQ(r->summary.devices.count("serial " + other + " unit 18"), 0u);
    }
    // Its unit's reply past the timeout is late, as it is to a unit seen before: not a clean answer in 4 s.
    const auto late = write_temp("unseen_late.txt",
                                 "1.000 05 03 00 00 00 01 85 8F\n"
                                 "5.000 05 03 02 00 07 08 46\n");
    r = decode(late, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
    const auto& late5 = r->summary.devices.at("serial " + late + " unit 5");
    EXPECT_EQ(late5.requests, 1u);
    EXPECT_EQ(late5.responses, 0u);
    EXPECT_EQ(late5.late_responses, 1u);
    EXPECT_EQ(late5.timeouts, 1u);  // answered after all: a timeout answered late, not a discarded request
    EXPECT_EQ(late5.damaged_unanswered, 0u);
    EXPECT_EQ(r->summary.damaged_to_unseen_units, 0u);
}

// Around broadcasts on a serial line: a master sends nothing while it waits, so a broadcast after an
// unanswered request moves on from it as any request does (unit 2's reply after it was a clean answer in
// 210 ms); a reply carrying unit 0 in the slot of unit 2's reply is no broadcast response and no device
// "unit 0", but a frame with a wrong address where unit 2's reply should be; slaves that answer a broadcast
// with their own address answered the broadcast, not "nothing", and an FC16 echo is no late reply to an FC3.
TEST(SerialInput, RepliesAroundBroadcastsAreNamedForWhatTheyAre) {
    const auto path = write_temp("broadcasts.txt",
                                 "1.000 > 02 03 00 20 00 02 C5 F2\n"
                                 "1.200 > 00 06 00 05 00 09 58 1C\n"
                                 "1.210 < 02 03 04 00 02 00 07 29 31\n"
                                 "2.000 > 02 03 00 20 00 02 C5 F2\n"
                                 "2.020 < 00 03 04 00 02 00 07 0A F1\n"
                                 "3.500 > 03 03 00 30 00 02 C5 E6\n"
                                 "3.520 < 03 03 04 00 03 00 07 68 31\n"
                                 "4.000 > 00 10 00 01 00 01 02 00 05 6A 12\n"
                                 "4.010 < 01 10 00 01 00 01 50 09\n"
                                 "4.020 < 02 10 00 01 00 01 50 3A\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    const std::string unit = "serial " + path + " unit ";
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairUnitMismatch), 1);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairBroadcastResponse), 2);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairFunctionMismatch), 0);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::PairLateResponse) {
            EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{1, 3}));
            EXPECT_NE(f.message.find("moved on to frame 2"), std::string::npos) << f.message;
        }
        if (f.code == mb::FindingCode::PairUnitMismatch) {
            EXPECT_EQ(f.device.str(), unit + "2");
            EXPECT_NE(f.message.find("carries unit 0"), std::string::npos) << f.message;
        }
        if (f.code == mb::FindingCode::PairBroadcastResponse) {
            EXPECT_TRUE(f.device.str() == unit + "1" || f.device.str() == unit + "2") << f.device.str();
            EXPECT_NE(f.message.find("answered the broadcast of frame 8"), std::string::npos) << f.message;
        }
    }
    const auto& unit2 = r->summary.devices.at(unit + "2");
    EXPECT_EQ(unit2.responses, 0u);
    EXPECT_EQ(unit2.timeouts, 2u);
    EXPECT_EQ(unit2.late_responses, 1u);
    EXPECT_EQ(unit2.answered_by_other_unit, 1u);
    // The broadcasts are unit 0's requests; nothing is held against a "unit 0" for the reply carrying it.
    EXPECT_TRUE(r->summary.devices.at(unit + "0").findings.empty());
    // The same broadcast twice, answered twice the same: each answer answers a broadcast, not "one request
    // answered twice".
    const auto twice = write_temp("broadcast_twice.txt",
                                  "1.000 > 00 10 00 01 00 01 02 00 05 6A 12\n"
                                  "1.010 < 01 10 00 01 00 01 50 09\n"
                                  "2.000 > 00 10 00 01 00 01 02 00 05 6A 12\n"
                                  "2.010 < 01 10 00 01 00 01 50 09\n");
    r = decode(twice, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairBroadcastResponse), 2);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 0);
}

// Without direction markers, unit 2 echoing an FC6 broadcast ("02 06 00 05 00 09", the broadcast's own PDU
// under its address) read as the master asking unit 2 the same: a request that drew "no response", a
// timeout for a unit whose only fault was to answer. An echo of the broadcast just sent is the slave's
// answer to it (a master sends nothing during its turnaround delay after a broadcast, SL §2.1). The same
// with an FC5 broadcast on an ASCII line.
TEST(SerialInput, AUnitsEchoOfABroadcastIsItsAnswerWithoutDirectionMarkers) {
    const std::pair<std::string, an::InputFormat> lines[] = {
        {"1.000 02 03 00 20 00 02 C5 F2\n"
         "1.020 02 03 04 00 02 00 07 29 31\n"
         "1.200 00 06 00 05 00 09 58 1C\n"
         "1.230 02 06 00 05 00 09 59 FE\n"
         "2.000 02 03 00 20 00 02 C5 F2\n"
         "2.020 02 03 04 00 02 00 07 29 31\n",
         an::InputFormat::Text},
        {":00050054FF00A8\r\n:02050054FF00A6\r\n:02030060000398\r\n", an::InputFormat::AsciiRaw},
    };
    for (const auto& [text, format] : lines) {
        const auto path = write_temp("broadcast_echo.txt", text);
        auto r = decode(path, format);
        ASSERT_TRUE(r->ok);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairBroadcastResponse), 1) << text;
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0) << text;
        for (const auto& f : r->sink.findings)
            if (f.code == mb::FindingCode::PairBroadcastResponse) {
                EXPECT_EQ(f.device.str(), "serial " + path + " unit 2");
            }
        const auto& unit2 = r->summary.devices.at("serial " + path + " unit 2");
        EXPECT_EQ(unit2.timeouts, 0u) << text;
        EXPECT_EQ(unit2.requests, format == an::InputFormat::Text ? 2u : 1u) << text;
    }
}

// A slow ASCII line (300 baud 7E1, which the MK instruments offer, 000:224) logged in chunks of 32
// characters, each stamped when its last character arrived: a chunk takes 1.07 s to arrive, so the 1 s
// between one chunk's stamp and the next is no pause (SL §2.5.2.1's inter-character timeout is between
// characters), and a 71-character reply that began 133 ms after its request and took 2.4 s to send was
// answered in time (a master's response timeout runs until a reply begins). Unit 1's reply was abandoned
// as "timeout" and the request was "no response".
TEST(SerialInput, ASlowAsciiLinesChunksAreTimedFromTheirFirstCharacter) {
    const auto path = write_temp("slow_ascii.txt",
                                 "1.566667 > 3A 30 31 30 33 30 30 30 30 30 30 30 46 45 44 0D 0A\n"
                                 "2.733333 < 3A 30 31 30 33 31 45 30 30 36 34 30 30 36 35 30 30 36 36 30 30 "
                                 "36 37 30 30 36 38 30 30 36 39 30\n"
                                 "3.800000 < 30 36 41 30 30 36 42 30 30 36 43 30 30 36 44 30 30 36 45 30 30 "
                                 "36 46 30 30 37 30 30 30 37 31 30\n"
                                 "4.033333 < 30 37 32 39 39 0D 0A\n");
    auto r = std::make_unique<test_analyzer_serial_test::Run>();  // (Run alone is the test's own method)
    an::AnalyzerOptions options;
    options.serial_line = mb::SerialLine{300, 7, mb::Parity::Even, 1};
    an::Analyzer a(options, r->sink);
    ASSERT_TRUE(an::read_inputs(a, {path}, an::InputFormat::Auto, {}));
    a.finish();
    const auto summary = a.summary();
    EXPECT_EQ(summary.unparsed_bytes, 0u);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 0);
    const auto& unit1 = summary.devices.at("serial " + path + " unit 1");
    EXPECT_EQ(unit1.responses, 1u);
    EXPECT_EQ(unit1.timeouts, 0u);
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    ASSERT_TRUE(r->sink.transactions[0].response);
    // The reply's first character arrived 31 character times before its first chunk's stamp (2.733 s).
    EXPECT_NEAR(std::chrono::duration<double>(r->sink.transactions[0].response->frame.start).count(), 1.7,
                0.001);
}

// Noise on an ASCII line damaged unit 2's reply so that it formed no frame (the character '0' arriving with
// bit 7 set, 0xB0): the request read "no response", a timeout held against a unit that answered, while the
// same noise on another character, failing only the LRC, made a damaged response. Characters that form no
// frame but begin with the waiting request's unit and function code are its reply, damaged on the way
// (pair.response_damaged): answered, values unknown, no timeout. Noise that begins no such frame leaves the
// request to time out as before.
TEST(SerialInput, AnAsciiReplyDamagedIntoNoFrameIsAnsweredNotATimeout) {
    for (const bool begins_reply : {true, false}) {
        const std::string damaged = begins_reply ? ":0203\xB0"
                                                   "6000700080009DD\r\n"
                                                 : ":\xB0"
                                                   "2030600070008009DD\r\n";
        const auto path =
            write_temp("ascii_damaged_reply.txt",
                       ":02030060000398\r\n" + damaged + ":02030060000398\r\n:020306000700080009DD\r\n");
        auto r = decode(path, an::InputFormat::AsciiRaw);
        const auto& unit2 = r->summary.devices.at("serial " + path + " unit 2");
        EXPECT_EQ(r->summary.unparsed_bytes,
                  damaged.size());  // still reported as characters that formed no frame
        EXPECT_EQ(unit2.responses, 1u);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseDamaged), begins_reply ? 1 : 0);
        EXPECT_EQ(unit2.damaged_replies, begins_reply ? 1u : 0u);
        EXPECT_EQ(unit2.timeouts, begins_reply ? 0u : 1u);
        if (!begins_reply) continue;
        for (const auto& f : r->sink.findings)
            if (f.code == mb::FindingCode::PairResponseDamaged) {
                EXPECT_EQ(f.device.str(), "serial " + path + " unit 2");
                EXPECT_NE(
                    f.message.find("the reply formed no frame (bad_character, 23 characters at offset 17 "
                                   "beginning with unit 2, function code 3)"),
                    std::string::npos)
                    << f.message;
            }
        ASSERT_EQ(r->sink.transactions.size(), 2u);
        EXPECT_TRUE(r->sink.transactions[0].reply_damaged);
        EXPECT_FALSE(r->sink.transactions[0].timed_out);
    }
}

// Where the capture does not tell sides, the master's retry damaged by the same noise begins with the same
// unit and function and is as long as the request: it is not taken for the device's reply (which would hold a
// damaged reply and then an unsolicited one against a unit that answered the retry well).
TEST(SerialInput, ADamagedRetryWithoutDirectionMarkersIsNoDamagedReply) {
    const auto path = write_temp("ascii_damaged_retry.txt", std::string(":02030060000398\r\n:0203006") +
                                                                '\0' + "000398\r\n:020306000700080009DD\r\n");
    auto r = decode(path, an::InputFormat::AsciiRaw);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseDamaged), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(r->summary.devices.at("serial " + path + " unit 2").responses, 1u);
}

// The capture ends five bytes into unit 2's reply ("02 03 04 00 02": its unit, FC3, its byte count): the
// request was answered and the capture holds only part of the reply, as a Modbus/TCP reply cut by the
// snapshot length is said to be; not "no response". Bytes that begin no reply to it (another unit, another
// function) leave it unanswered at the end. The same on an ASCII line, eleven characters into unit 17's reply
// (":110306022B", the FC3 example reply of MK-ASC-02, 000:304-309, cut after its byte count and first byte).
TEST(SerialInput, AReplyTheEndOfTheCaptureCutsIsAnsweredNotCapturedWhole) {
    struct Line {
        an::InputFormat format;
        std::string before;        // the capture up to the request's reply
        std::string reply, other;  // the reply cut, and a cut frame of another unit
        std::string unit;
        std::string cut;  // how far into the reply the capture ends
        std::uint64_t length;
    };
    const Line lines[] = {
        {an::InputFormat::Text,
         "1.000 03 03 00 30 00 02 C5 E6\n1.020 03 03 04 00 03 00 07 68 31\n1.500 02 03 00 20 00 02 C5 "
         "F2\n1.520 ",
         "02 03 04 00 02\n", "05 03 04 00 02\n", "unit 2", "5 bytes into the reply (unit 2, function code 3)",
         5},
        {an::InputFormat::AsciiRaw, ":11030060000389\r\n", ":110306022B", ":050306022B", "unit 17",
         "11 characters into the reply (unit 17, function code 3)", 11},
    };
    for (const auto& line : lines)
        for (const bool begins_reply : {true, false}) {
            const auto path =
                write_temp("cut_at_end.txt", line.before + (begins_reply ? line.reply : line.other));
            auto r = decode(path, line.format);
            const auto& unit = r->summary.devices.at("serial " + path + " " + line.unit);
            EXPECT_EQ(unit.replies_not_captured, begins_reply ? 1u : 0u) << line.unit;
            EXPECT_EQ(unit.unanswered_at_end, begins_reply ? 0u : 1u) << line.unit;
            EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseNotCaptured), begins_reply ? 1 : 0);
            EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), begins_reply ? 0 : 1);
            for (const auto& f : r->sink.findings)
                if (f.code == mb::FindingCode::PairResponseNotCaptured) {
                    EXPECT_NE(f.message.find("the capture ends " + line.cut), std::string::npos) << f.message;
                }
            EXPECT_EQ(r->summary.unparsed_bytes, line.length);  // still reported as formed no frame
        }
}

// Broadcast requests are writes (SL §2.1; the MK manual runs FC5, 6, 15 and 16 in broadcast, 000:313): a
// read sent to unit 0 passed without a word, though nothing it reads can ever come back; so did FC8's
// sub-functions that return a counter. A broadcast write and FC8's listen-only (which changes a device's
// state) are what broadcasts are for.
TEST(SerialInput, ABroadcastThatOnlyReadsIsSaid) {
    const auto path = write_temp("broadcast_read.txt",
                                 "1.000 > 00 03 00 60 00 03 04 04\n"    // FC3, read 96+3
                                 "2.000 > 00 06 00 01 00 03 99 DA\n"    // FC6, write 1 = 3
                                 "3.000 > 00 08 00 04 00 00 A0 1B\n"    // FC8/04, force listen only
                                 "4.000 > 00 08 00 0B 00 00 90 18\n");  // FC8/0B, a counter: reads
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_EQ(r->sink.transactions.size(), 4u);
    for (const auto& t : r->sink.transactions)
        EXPECT_TRUE(t.broadcast);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairBroadcastRead), 2);
    std::vector<std::uint64_t> frames;
    for (const auto& f : r->sink.findings)
        frames.insert(frames.end(), f.frames.begin(), f.frames.end());
    EXPECT_EQ(frames, (std::vector<std::uint64_t>{1, 4}));
    EXPECT_EQ(r->sink.findings.size(), 2u);
}

// A read of 21 coils answered in three bytes leaves the last byte's three high bits unused, padded with zeros
// (AP §6.1; the MK manual's example answers 1B, 000:343). Bits set there passed: only the request says how
// many are used, and the response was judged alone.
TEST(SerialInput, PaddingBitsSetInACoilReplyAreSaid) {
    const auto path = write_temp("coil_padding.txt",
                                 "1.000 > 11 01 00 13 00 15 0E 90\n"
                                 "1.050 < 11 01 03 B2 0E 1B DA 92\n"  // the manual's reply
                                 "2.000 > 11 01 00 13 00 15 0E 90\n"
                                 "2.050 < 11 01 03 CD 6B F5 40 56\n");  // F5: bits 5-7 set
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PduPaddingBitsSet), 1);
    for (const auto& f : r->sink.findings) {
        EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{3, 4}));
        EXPECT_NE(f.message.find("the response's last byte, 0xF5, sets bits past the 21 asked"),
                  std::string::npos)
            << f.message;
    }
}

// "One request answered twice" means the last reply again. After a request answered with a damaged reply,
// a copy of the good reply before it is not that: it was called a duplicate of frame 2 across frames 3 and
// 4. It is a reply nobody waits for.
TEST(SerialInput, AReplyAfterADamagedOneIsNoCopyOfTheOneBefore) {
    const auto path = write_temp("after_damaged.txt",
                                 "1.000 > 11 03 00 60 00 03 07 45\n"
                                 "1.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                 "2.000 > 11 03 00 60 00 03 07 45\n"
                                 "2.050 < 11 03 06 02 2B 00 00 00 64 C8 BB\n"  // its CRC damaged
                                 "3.000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
}

TEST(SerialInput, MalformedTextLinesAreNamedAndTheRestDecoded) {
    const auto path = write_temp("bad.txt",
                                 "1.0 11 03 00 60 00 03 07 45\nnot-a-time 11\n1.5 zz\n1.6 > 11 3 0 60\n"
                                 "1.02 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 3u);
    EXPECT_NE(r->summary.input_errors[0].find("bad.txt:2"), std::string::npos);
    EXPECT_EQ(r->summary.input_errors[1], path + ":3: not hex bytes: not a hex digit: 'z' in 'zz'");
    // A byte's two digits stand together: "11 3 0 60" is not 11 30 60.
    EXPECT_EQ(r->summary.input_errors[2],
              path + ":4: not hex bytes: odd number of hex digits in '3': a byte is two digits (03)");
    EXPECT_EQ(r->sink.transactions.size(), 1u);
}

// A reply nobody asked for on a serial line is named by its unit: a serial line has no transaction ids (the
// message spoke of "transaction id 0").
TEST(SerialInput, AnUnsolicitedReplyIsNamedByItsUnit) {
    const auto path = write_temp("unsolicited.txt", "1.02 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    for (const auto& f : r->sink.findings)
        if (f.code == mb::FindingCode::PairUnsolicitedResponse) {
            EXPECT_EQ(f.message, "no request to unit 17 waits for a reply on this link");
        }
}

// A log whose clock goes back (set back, or two sessions' logs joined): the timed deframer took the later
// bytes for ones right after the earlier, so every frame after the step was restamped at the end of the
// first session (the second session's exchanges 11.458 ms apart instead of 20), with no word. The step is an
// input note naming where (the log is read whole: no input error); the frames after it keep the log's times.
TEST(SerialInput, ALogsClockGoingBackIsNamedAndItsFramesKeepTheirTimes) {
    const std::string fc3 = "11 03 00 60 00 03 07 45", reply = "11 03 06 02 2B 00 00 00 64 C8 BA";
    const auto path =
        write_temp("back.txt", "100.000 " + fc3 + "\n100.020 " + reply + "\n101.000 " + fc3 + "\n5.000 " +
                                   reply + "\n5.500 " + fc3 + "\n5.520 " + reply + "\n");
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_TRUE(r->summary.input_errors.empty());
    ASSERT_EQ(r->summary.input_notes.size(), 1u);
    EXPECT_EQ(r->summary.input_notes[0],
              path +
                  ": packet 4, the chunk stamped 5.000000 s: the capture's clock goes back "
                  "96000 ms; requests are timed out by the clock from here (later "
                  "steps back are not listed)");
    ASSERT_EQ(r->sink.frames.size(), 6u);
    EXPECT_EQ(r->sink.frames[4].time, mb::Timestamp(5'500'000'000));  // as the log says
    // Each frame names its record and its offset in the stream, after the step as before it: the deframer
    // started again there counted its offsets from 0, and the records after the step named earlier ones.
    for (std::size_t i = 0; i < r->sink.frames.size(); ++i) {
        EXPECT_EQ(r->sink.frames[i].packet, i + 1) << i;
        EXPECT_EQ(r->sink.frames[i].frame.offset, i % 2 ? 8 + (i / 2) * 19 : (i / 2) * 19) << i;
    }
    ASSERT_EQ(r->sink.transactions.size(), 3u);
    ASSERT_TRUE(r->sink.transactions[2].latency.has_value());
    EXPECT_EQ(*r->sink.transactions[2].latency, std::chrono::milliseconds(20));
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseBeforeRequest), 1);  // the reply stamped 5.000
}

// A serial line's step back is judged against its own timeout (1 s), not the TCP one (3 s): a reply
// stamped 2.9 s before its request was set back to back after it, a latency of 11.458 ms made up from the
// baud rate, no finding and no note, where `--timeout 1` said the step.
TEST(SerialInput, AStepBackLongerThanTheLinesTimeoutIsNamed) {
    const auto path = write_temp("back_2s.txt",
                                 "10.000 11 03 00 60 00 03 07 45\n"
                                 "7.100 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_EQ(r->summary.input_notes.size(), 1u);
    EXPECT_NE(r->summary.input_notes[0].find("the capture's clock goes back 2900 ms"), std::string::npos)
        << r->summary.input_notes[0];
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseBeforeRequest), 1);
    for (const auto& t : r->sink.transactions)
        EXPECT_FALSE(t.latency.has_value());
}

// A reply cut by the end of its input is "answered, not captured whole" whether or not other inputs follow:
// with a second file named, the same file's request was "no response before the capture ended".
TEST(SerialInput, AReplyCutByItsInputsEndIsJudgedAloneOrWithOthers) {
    const auto cut = write_temp("cut_reply.txt", "1.0 11 03 00 60 00 03 07 45\n1.02 11 03 06 02 2B\n");
    const auto whole = write_temp("whole_reply.txt",
                                  "1.000 11 03 00 60 00 03 07 45\n"
                                  "1.020 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    for (const auto& paths : {std::vector<std::string>{cut}, std::vector<std::string>{cut, whole}}) {
        auto r = decode_all(paths, false);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairResponseNotCaptured), 1) << paths.size();
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), 0) << paths.size();
    }
}

// An ASCII frame begun with ':' and broken before its CR LF is damaged, each way with its finding (SL
// §2.5.2.1), an error as an RTU frame's gap is: a request paused for 1.5 s and answered all the same was two
// warnings of unparsed bytes, exit 0. Characters outside any frame stay unparsed bytes.
TEST(SerialInput, ABrokenAsciiFrameIsAnErrorNamedByHowItBroke) {
    const auto path = write_temp("ascii_pause.txt",
                                 "1.0 > 3A 31 31 30 33 30 30 36\n"                    // ":110306" ...
                                 "2.5 > 30 30 30 30 33 38 39 0D 0A\n"                 // ... 1.5 s later
                                 "3.0 > 3A 31 31 30 33 30 30 36 30 30 30 3A 0D 0A\n"  // a ':' inside it
                                 "3.5 > 41 42\n");                                    // noise
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::AsciiInterCharTimeout), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::AsciiMissingEnd), 1);
    EXPECT_GE(r->sink.count(mb::FindingCode::StreamUnparsedBytes), 1);
    for (const auto& f : r->sink.findings)
        if (f.code == mb::FindingCode::AsciiInterCharTimeout) {
            EXPECT_EQ(f.message, "8 bytes at offset 0 formed no frame (timeout)");
        }
}

// A master retrying after a timeout, as RS-485 masters do: each retry was classified before the timed-out
// request expired, so every second one was taken for that request's response (a malformed FC3 reply, byte
// count 0) and reported unsolicited. Each is a request, timed out in its turn.
TEST(SerialInput, AMastersRetryAfterATimeoutIsARequest) {
    const auto path = write_temp("retry.txt",
                                 "1.000 11 03 00 60 00 03 07 45\n2.500 11 03 00 60 00 03 07 45\n"
                                 "4.000 11 03 00 60 00 03 07 45\n5.500 11 03 00 60 00 03 07 45\n");
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_EQ(r->sink.findings.size(), 4u);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 3);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), 1);
    ASSERT_EQ(r->sink.frames.size(), 4u);
    for (const auto& f : r->sink.frames)
        EXPECT_EQ(f.direction, mb::Direction::Request) << f.index;
    EXPECT_EQ(r->summary.devices.begin()->second.requests, 4u);
}

// A slave that answers after the master's timeout (the MK manual's FC3 example, answered 1.5 s late at a
// 1 s serial timeout): the reply was "unsolicited" (a rogue master or bus contention, to the reader), or,
// carrying the same bytes as the poll's reply before, "one request answered twice". It is late, naming its
// request; another unit's reply stays unsolicited, and a request sent meanwhile takes the reply as its own.
TEST(SerialInput, AReplyAfterTheTimeoutIsLate) {
    const std::string fc3 = "11 03 00 60 00 03 07 45", reply = "11 03 06 02 2B 00 00 00 64 C8 BA";
    const auto path = write_temp("late.txt", "1.000 " + fc3 + "\n1.020 " + reply + "\n3.000 " + fc3 +
                                                 "\n4.500 " + reply + "\n4.600 " + reply + "\n");
    auto r = decode(path, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 1);  // the late reply again
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
    for (const auto& f : r->sink.findings)
        if (f.code == mb::FindingCode::PairLateResponse) {
            EXPECT_EQ(
                f.message,
                "the reply to frame 3 (FC3 Read Holding Registers 96+3) came 1500 ms after it, past the "
                "1000 ms timeout: the request was reported unanswered");
            EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{3, 4}));
        }
    for (const auto& f : r->sink.findings)
        if (f.code == mb::FindingCode::PairDuplicateResponse) {
            EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{4, 5}));
        }
    // Unit 18 asked and timed out; unit 17's reply after it is nobody's.
    const auto other = write_temp("late-other.txt", "1.000 12 03 00 60 00 03 07 76\n2.500 " + reply + "\n");
    r = decode(other, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    // The master asked again before the late reply: the reply answers the new request.
    const auto again =
        write_temp("late-again.txt", "1.000 " + fc3 + "\n2.500 " + fc3 + "\n2.600 " + reply + "\n");
    r = decode(again, an::InputFormat::Text);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
    ASSERT_FALSE(r->sink.transactions.empty());
    EXPECT_TRUE(r->sink.transactions.back().response.has_value());
}

// A slow unit's reply comes while the master already waits on the next unit: it was paired with the next
// unit's request (a pair.unit_mismatch, unit 17's values in unit 5's transaction) and unit 5's own reply was
// "unsolicited". It is unit 17's late reply; unit 5's exchange is whole. The master moved on after its
// timeout ran out (1 s), or before (300 ms), or in a dump without times.
TEST(SerialInput, ASlowUnitsReplyWhileTheMasterWaitsOnAnotherIsLate) {
    const std::string to_17 = "11 03 00 60 00 03 07 45", from_17 = "11 03 06 02 2B 00 00 00 64 C8 BA",
                      to_5 = "05 03 00 60 00 03 04 51", from_5 = "05 03 06 00 01 00 02 00 03 CF B4";
    struct Case {
        const char* name;
        std::string log;
        std::string said;
    };
    const Case cases[] = {
        {"after the timeout",
         "1.000 " + to_17 + "\n2.100 " + to_5 + "\n2.150 " + from_17 + "\n2.200 " + from_5 + "\n",
         "came 1150 ms after it, past the 1000 ms timeout"},
        {"before the timeout",
         "1.000 " + to_17 + "\n1.300 " + to_5 + "\n1.350 " + from_17 + "\n1.400 " + from_5 + "\n",
         "came 350 ms after it, after the master had moved on to frame 2 (300 ms after it)"},
        {"without times", "", "came after the master had moved on to frame 2"},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        const auto r = [&] {
            if (!c.log.empty()) return decode(write_temp("slow_unit.txt", c.log), an::InputFormat::Text);
            std::string dump;
            for (const auto* frame : {&to_17, &to_5, &from_17, &from_5})
                for (std::size_t i = 0; i < frame->size(); i += 3)
                    dump.push_back(static_cast<char>(std::stoi(frame->substr(i, 2), nullptr, 16)));
            return decode(write_temp("slow_unit.bin", dump), an::InputFormat::RtuRaw);
        }();
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnitMismatch), 0);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
        ASSERT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
        for (const auto& f : r->sink.findings)
            if (f.code == mb::FindingCode::PairLateResponse) {
                EXPECT_EQ(f.message, "the reply to frame 1 (FC3 Read Holding Registers 96+3) " + c.said +
                                         ": the request was reported unanswered");
                EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{1, 3}));
            }
        // Unit 5's transaction holds unit 5's reply.
        bool five = false;
        for (const auto& t : r->sink.transactions)
            if (t.request.frame.unit_id() == 5) {
                five = true;
                ASSERT_TRUE(t.response.has_value());
                EXPECT_EQ(t.response->index, 4u);
            }
        EXPECT_TRUE(five);
    }
}

// The findings of a run whose first request timed out, whose last is left at the end, and where a reply
// naming another unit answered neither: the unit mismatch is between `frames`, and returned.
const an::FindingRecord* expect_timeout_and_unit_mismatch(const Run& r, std::vector<std::uint64_t> frames) {
    EXPECT_EQ(r.summary.findings,
              (std::map<std::string, std::uint64_t>{
                  {"pair.no_response", 1}, {"pair.no_response_at_end", 1}, {"pair.unit_mismatch", 1}}));
    const auto* mismatch = r.sink.first(mb::FindingCode::PairUnitMismatch);
    if (mismatch) {
        EXPECT_EQ(mismatch->frames, frames);
    }
    return mismatch;
}

// Unit 18 asked for 1 register and timed out; 1.5 s later the master asks unit 17 for 3 (the MK manual's
// example, 000:356), and 20 ms after that a reply carrying unit 18 and 3 registers comes. It was unit 18's
// late reply (1520 ms in its latency, and a size mismatch against it) and unit 17 a plain timeout. Its size
// fits only unit 17's request: that request's reply with a wrong unit byte, pair.unit_mismatch, as with no
// earlier request of unit 18. A reply that fits only unit 18's request is still its late one (so is one
// that fits both: ASlowUnitsReplyWhileTheMasterWaitsOnAnotherIsLate).
TEST(SerialInput, AnotherUnitsReplyThatFitsOnlyTheWaitingRequestIsNoLateReply) {
    const std::string to_18 = "12 03 00 00 00 01 86 A9", to_17 = "11 03 00 60 00 03 07 45";
    for (const char* marks : {"> ", ""}) {
        SCOPED_TRACE(marks);
        const std::string reply = marks[0] ? "< " : "";
        const auto path =
            write_temp("cross_unit.txt", "1.000 " + std::string(marks) + to_18 + "\n2.500 " + marks + to_17 +
                                             "\n2.520 " + reply + "12 03 06 02 2B 00 00 00 64 DC 4A\n");
        auto r = decode(path, an::InputFormat::Text);
        ASSERT_TRUE(r->ok);
        const auto* mismatch = expect_timeout_and_unit_mismatch(*r, {2, 3});
        ASSERT_NE(mismatch, nullptr);
        EXPECT_EQ(
            mismatch->message,
            "request to unit 17 (frame 2) waits, response from unit 18: no answer from unit 17 (a master "
            "discards it), nor its values; it fits this request, not unit 18's frame 1 (FC3 Read Holding "
            "Registers 0+1) given up before: no late reply to that");
        ASSERT_EQ(r->sink.transactions.size(), 2u);
        for (const auto& t : r->sink.transactions) {
            EXPECT_FALSE(t.response.has_value()) << t.request.index;
            EXPECT_FALSE(t.late_past.has_value()) << t.request.index;
            EXPECT_EQ(t.answered_by_other_unit, t.request.index == 2) << t.request.index;
        }
        const auto& unit18 = r->summary.devices.at("serial " + path + " unit 18");
        EXPECT_EQ(unit18.timeouts, 1u);
        EXPECT_EQ(unit18.late_responses, 0u);
        EXPECT_EQ(unit18.latency.count(), 0u);  // no 1520 ms
        const auto& unit17 = r->summary.devices.at("serial " + path + " unit 17");
        EXPECT_EQ(unit17.unanswered_at_end, 1u);
        EXPECT_EQ(unit17.answered_by_other_unit, 1u);
        EXPECT_EQ(unit17.findings.count("pair.unit_mismatch"), 0u);  // held against unit 18, who sent it
    }
    // Unit 18's reply of 1 register in the same place fits only its request: its late one, as before.
    const auto late = write_temp("cross_unit_late.txt", "1.000 > " + to_18 + "\n2.500 > " + to_17 +
                                                            "\n2.520 < 12 03 02 00 2A BC 58\n");
    auto r = decode(late, an::InputFormat::Text);
    EXPECT_EQ(r->summary.findings,
              (std::map<std::string, std::uint64_t>{
                  {"pair.late_response", 1}, {"pair.no_response", 1}, {"pair.no_response_at_end", 1}}));
    const auto& unit18 = r->summary.devices.at("serial " + late + " unit 18");
    EXPECT_EQ(unit18.late_responses, 1u);
    EXPECT_EQ(unit18.latency.max(), std::chrono::milliseconds(1520));
    EXPECT_EQ(r->summary.devices.at("serial " + late + " unit 17").answered_by_other_unit, 0u);
}

// Unit 17 was asked and timed out; then unit 18 was asked and answered, and asked again, and 20 ms after
// that an exception from unit 17 comes. It was unit 17's reply 2020 ms late (in its exceptions and its
// latency). On a half-duplex line a slave does not answer across another device's exchange: once 18's had
// completed, 17's request was over for good, and the exception is a wrong-address reply in unit 18's slot,
// pair.unit_mismatch. Without the completed exchange between (unit 18 asked but silent, or not asked), it is
// still unit 17's late reply.
TEST(SerialInput, AnExchangeOnTheLineEndsTheWaitForALateReply) {
    const std::string to_17 = "4.000 > 11 03 00 60 00 03 07 45\n", to_18 = " > 12 03 00 00 00 01 86 A9\n";
    const std::string exception_17 = "6.020 < 11 83 02 C1 34\n";
    const auto path =
        write_temp("late_after_traffic.txt",
                   to_17 + "5.100" + to_18 + "5.120 < 12 03 02 00 2A BC 58\n6.000" + to_18 + exception_17);
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    EXPECT_NE(expect_timeout_and_unit_mismatch(*r, {4, 5}), nullptr);
    for (const auto& t : r->sink.transactions) {
        EXPECT_FALSE(t.late_past.has_value()) << t.request.index;
        EXPECT_EQ(t.response.has_value(), t.request.index == 2) << t.request.index;
        EXPECT_EQ(t.answered_by_other_unit, t.request.index == 4) << t.request.index;
    }
    const auto& unit17 = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(unit17.timeouts, 1u);
    EXPECT_EQ(unit17.late_responses, 0u);
    EXPECT_EQ(unit17.exceptions, 0u);
    EXPECT_TRUE(unit17.exception_codes.empty());
    EXPECT_EQ(unit17.latency.count(), 0u);  // no 2020 ms
    const auto& unit18 = r->summary.devices.at("serial " + path + " unit 18");
    EXPECT_EQ(unit18.responses, 1u);
    EXPECT_EQ(unit18.unanswered_at_end, 1u);
    EXPECT_EQ(unit18.answered_by_other_unit, 1u);
    EXPECT_EQ(unit18.latency.max(), std::chrono::milliseconds(20));
    // No exchange completed after unit 17's request: the exception is its late one.
    for (const std::string& between : {std::string(), "5.100" + to_18}) {
        SCOPED_TRACE(between);
        const auto no_exchange =
            write_temp("late_no_exchange.txt", to_17 + between + "6.000" + to_18 + exception_17);
        auto q = decode(no_exchange, an::InputFormat::Text);
        EXPECT_EQ(q->sink.count(mb::FindingCode::PairLateResponse), 1);
        EXPECT_EQ(q->sink.count(mb::FindingCode::PairUnitMismatch), 0);
        const auto& late17 = q->summary.devices.at("serial " + no_exchange + " unit 17");
        EXPECT_EQ(late17.late_responses, 1u);
        EXPECT_EQ(late17.latency.max(), std::chrono::milliseconds(2020));
    }
    // An exchange completed, and nothing waits when unit 17's reply comes: a slow slave answers when it is
    // done, whatever the master did meanwhile. Still its late one.
    const auto nothing_waits =
        write_temp("late_nothing_waits.txt", to_17 + "5.100" + to_18 + "5.120 < 12 03 02 00 2A BC 58\n" +
                                                 "5.300 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto q = decode(nothing_waits, an::InputFormat::Text);
    EXPECT_EQ(q->sink.count(mb::FindingCode::PairLateResponse), 1);
    EXPECT_EQ(q->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(q->summary.devices.at("serial " + nothing_waits + " unit 17").latency.max(),
              std::chrono::milliseconds(1300));
}

// A capture file given with a serial --format decoded to thousands of unparsed bytes, no error finding and
// exit 0. It is still decoded as asked, and the run fails naming what the file is.
TEST(SerialInput, ACaptureReadAsSerialBytesIsNamed) {
    const auto pcap = std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap";
    for (auto format : {an::InputFormat::RtuRaw, an::InputFormat::AsciiRaw, an::InputFormat::Text}) {
        auto r = decode(pcap, format);
        EXPECT_FALSE(r->ok);
        ASSERT_FALSE(r->summary.input_errors.empty());
        EXPECT_EQ(r->summary.input_errors[0],
                  pcap +
                      ": holds a pcap or pcapng capture (its magic number) but --format reads it as serial "
                      "bytes; leave --format out to decode the capture");
    }
    EXPECT_TRUE(decode(pcap)->ok);
}

// A tap that recorded nothing, or the wrong file: no format decodes an empty file to "no frames, no faults".
TEST(SerialInput, AnEmptyFileIsAnInputErrorInEveryFormat) {
    const auto path = write_temp("empty.bin", "");
    for (const auto format :
         {an::InputFormat::Auto, an::InputFormat::Pcap, an::InputFormat::RtuRaw, an::InputFormat::AsciiRaw,
          an::InputFormat::Text, an::InputFormat::Jpnevulator, an::InputFormat::Socat}) {
        auto r = decode(path, format);
        EXPECT_FALSE(r->ok) << static_cast<int>(format);
        ASSERT_EQ(r->summary.input_errors.size(), 1u) << static_cast<int>(format);
        EXPECT_NE(r->summary.input_errors[0].find(path), std::string::npos) << r->summary.input_errors[0];
        EXPECT_EQ(r->summary.frames, 0u);
    }
    // One byte is not empty: a raw dump of it is one unparsed byte, reported as such.
    auto one = decode(write_temp("one.bin", std::string(1, '\x11')), an::InputFormat::RtuRaw);
    EXPECT_TRUE(one->ok);
    EXPECT_TRUE(one->summary.input_errors.empty());
    EXPECT_EQ(one->summary.unparsed_bytes, 1u);
}

// A pipe or FIFO (a shell's <(zcat log.gz), a capture piped over ssh) can be read once: the format is told
// from its head, an empty one refused, a socat log read twice. Each is decoded as the same file on disk is,
// under the FIFO's own name, in every format that reads it.
TEST(SerialInput, AFifoDecodesAsTheSameFileDoes) {
    const std::string dir = std::string(MBSCOPE_SOURCE_DIR) + "/";
    const std::string text = "1.000 > 11 03 00 6B 00 03 76 87\n1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n";
    const struct {
        std::string file;
        an::InputFormat format;
    } cases[] = {
        {write_temp("fifo-reference.txt", text), an::InputFormat::Auto},
        {write_temp("fifo-reference.txt", text), an::InputFormat::Text},
        {dir + "captures/pymodbus-socat-rtu.log", an::InputFormat::Auto},
        {dir + "captures/suricata-modbus.pcap", an::InputFormat::Auto},
        {dir + "captures/suricata-modbus.pcap", an::InputFormat::Pcap},
        {write_temp("fifo-empty.txt", ""), an::InputFormat::Auto},
    };
    const std::string fifo = ::testing::TempDir() + "mbscope-input.fifo";
    for (const auto& c : cases) {
        std::ifstream in(c.file, std::ios::binary);
        const std::string content{std::istreambuf_iterator<char>(in), {}};
        ::unlink(fifo.c_str());
        ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
        std::thread writer([&] { std::ofstream(fifo, std::ios::binary) << content; });
        const auto piped = decode(fifo, c.format);
        writer.join();
        const auto file = decode(c.file, c.format);
        EXPECT_EQ(piped->ok, file->ok) << c.file;
        EXPECT_EQ(piped->summary.frames, file->summary.frames) << c.file;
        EXPECT_EQ(piped->summary.transactions, file->summary.transactions) << c.file;
        EXPECT_EQ(piped->summary.unparsed_bytes, file->summary.unparsed_bytes) << c.file;
        ASSERT_EQ(piped->summary.input_errors.size(), file->summary.input_errors.size()) << c.file;
        for (std::size_t i = 0; i < file->summary.input_errors.size(); ++i) {
            auto expected = file->summary.input_errors[i];
            expected.replace(expected.find(c.file), c.file.size(), fifo);
            EXPECT_EQ(piped->summary.input_errors[i], expected);
        }
        ASSERT_EQ(piped->sink.frames.size(), file->sink.frames.size()) << c.file;
        for (std::size_t i = 0; i < file->sink.frames.size(); ++i) {
            const auto got = piped->sink.frames[i].frame.adu(), want = file->sink.frames[i].frame.adu();
            EXPECT_TRUE(std::equal(got.begin(), got.end(), want.begin(), want.end())) << c.file << " " << i;
            EXPECT_EQ(piped->sink.frames[i].source.str(), fifo);
        }
    }
    EXPECT_GT(decode(dir + "captures/suricata-modbus.pcap")->summary.frames, 0u);
    ::unlink(fifo.c_str());
}

// A capture through a pipe (`tcpdump -U -w - | mbscope decode -`, or from another host through ssh) was
// copied to its end before a byte was decoded: nothing was shown while the capture ran. It is read as it
// comes, and what was decoded is written out whenever the pipe is quiet: here the first exchange comes
// out, flushed, before the writer sends the second.
TEST(SerialInput, ACaptureThroughAPipeIsDecodedAsItComes) {
    mbscope::test::Conversation first;
    const auto read = mb::encode_tcp(
        1, 17, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 3)));
    const auto answer = mbscope::test::bytes({0, 1, 0, 0, 0, 9, 17, 3, 6, 2, 0x2B, 0, 0, 0, 0x64});
    first.send(true, read, std::chrono::seconds(1));
    first.send(false, answer, std::chrono::seconds(1) + std::chrono::milliseconds(2));
    auto both = first;
    auto second_read = read, second_answer = answer;
    second_read[1] = second_answer[1] = 2;  // transaction id 2
    both.send(true, second_read, std::chrono::seconds(2));
    both.send(false, second_answer, std::chrono::seconds(2) + std::chrono::milliseconds(2));
    const auto whole = both.file();
    const std::size_t first_part = first.file().size();

    struct Watch : Collect {
        std::atomic<bool> answered{false}, flushed{false};
        void transaction(const an::TransactionRecord& t) override {
            Collect::transaction(t);
            answered = true;
        }
        void flush() override { flushed = answered.load(); }
    } sink;
    const std::string fifo = ::testing::TempDir() + "mbscope-stream.fifo";
    ::unlink(fifo.c_str());
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::atomic<bool> shown_before_the_rest{false};
    std::thread writer([&] {
        std::ofstream out(fifo, std::ios::binary);
        out.write(reinterpret_cast<const char*>(whole.data()), static_cast<std::streamsize>(first_part));
        out.flush();
        // Not for ever: copied to its end first, the capture would show nothing until the writer closes.
        for (int i = 0; i < 200 && !sink.flushed; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        shown_before_the_rest = sink.flushed.load();
        out.write(reinterpret_cast<const char*>(whole.data() + first_part),
                  static_cast<std::streamsize>(whole.size() - first_part));
    });
    an::Analyzer a({}, sink);
    EXPECT_TRUE(an::read_input(a, fifo, an::InputFormat::Auto));
    a.finish();
    writer.join();
    ::unlink(fifo.c_str());
    EXPECT_TRUE(shown_before_the_rest);
    ASSERT_EQ(sink.transactions.size(), 2u);
    EXPECT_TRUE(sink.transactions[1].response.has_value());
    EXPECT_TRUE(a.summary().input_errors.empty());
}

// A binary file read as the text format: an error for every line, listed up to the limit and counted beyond,
// none of them carrying the file's control characters to the terminal.
TEST(SerialInput, AFileInTheWrongFormatListsAHundredErrorsAndCountsTheRest) {
    std::string text;
    for (int i = 0; i < 250; ++i)
        text += "\x1b[31m\x07" + std::string(100, 'x') + "\r\n";
    auto r = decode(write_temp("binary.txt", text), an::InputFormat::Text);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), an::Analyzer::max_listed_input_errors);
    EXPECT_EQ(r->summary.input_errors_unlisted, 250u - an::Analyzer::max_listed_input_errors);
    for (const auto& e : r->summary.input_errors) {
        EXPECT_EQ(
            std::count_if(e.begin(), e.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; }), 0)
            << e;
        EXPECT_NE(e.find("\\x1B[31m\\x07"), std::string::npos) << e;
        EXPECT_LT(e.size(), 200u) << e;  // the line is quoted in part
    }
    EXPECT_NE(r->summary.input_errors[0].find("binary.txt:1:"), std::string::npos)
        << r->summary.input_errors[0];
}

// The bundled file of the manuals' frames is read by `mbscope frame --file`, not by decode: decode says so
// instead of only that "rtu" is no time.
TEST(SerialInput, AFileOfFramesIsNamedForWhatReadsIt) {
    auto r = decode(std::string(MBSCOPE_SOURCE_DIR) + "/captures/manual-examples.txt");
    EXPECT_FALSE(r->ok);
    ASSERT_FALSE(r->summary.input_errors.empty());
    EXPECT_NE(r->summary.input_errors[0].find(
                  "'rtu' (a file of frames, one a line: mbscope frame --file reads it)"),
              std::string::npos)
        << r->summary.input_errors[0];
}

// A logger that writes a file an hour, or a capture handed over in pieces: each part was a line of its own,
// so a request at the end of one part and its reply at the start of the next were a timeout and an
// unsolicited reply on clean traffic (exit 1), and each part's devices stood apart in the summary. Named as
// parts of one line, they are read as one stream in the order given: the exchange across the cut is paired,
// a frame cut in two (a raw dump split by size) is whole again, and the records keep the file they came from.
TEST(SerialInput, PartsOfOneLineAreReadAsOneStream) {
    const std::string fc3 = "11 03 00 60 00 03 07 45", reply = "11 03 06 02 2B 00 00 00 64 C8 BA";
    const auto first =
        write_temp("part-1.txt", "1.000 " + fc3 + "\n1.020 " + reply + "\n2.000 " + fc3 + "\n");
    const auto second =
        write_temp("part-2.txt", "2.020 " + reply + "\n3.000 " + fc3 + "\n3.020 " + reply + "\n");
    const auto apart = decode_all({first, second}, false);
    EXPECT_EQ(apart->summary.devices.size(), 2u);
    EXPECT_EQ(apart->sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);

    const auto joined = decode_all({first, second}, true);
    ASSERT_TRUE(joined->ok);
    EXPECT_TRUE(joined->sink.findings.empty());
    ASSERT_EQ(joined->summary.devices.size(), 1u);
    const auto& [name, device] = *joined->summary.devices.begin();
    EXPECT_EQ(name, "serial " + first + " unit 17");
    EXPECT_EQ(device.requests, 3u);
    EXPECT_EQ(device.responses, 3u);
    ASSERT_EQ(joined->sink.transactions.size(), 3u);
    EXPECT_EQ(*joined->sink.transactions[1].latency, std::chrono::milliseconds(20));
    EXPECT_EQ(joined->sink.transactions[1].request.source, first);
    EXPECT_EQ(joined->sink.transactions[1].response->source, second);

    // A raw dump cut in the middle of a frame.
    const std::string stream = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45, 0x11, 0x03, 0x06, 0x02,
                                      0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
    const auto head = write_temp("dump-1.bin", stream.substr(0, 12));
    const auto tail = write_temp("dump-2.bin", stream.substr(12));
    const auto dump = decode_all({head, tail}, true);
    ASSERT_TRUE(dump->ok);
    EXPECT_EQ(dump->summary.unparsed_bytes, 0u);
    ASSERT_EQ(dump->sink.transactions.size(), 1u);
    ASSERT_TRUE(dump->sink.transactions[0].response.has_value());
    EXPECT_TRUE(dump->sink.findings.empty());
}

// A master retries after its own timeout (000:274: a master that gets no valid reply sends again), here
// shorter than the analyzer's (AMastersRetryAfterATimeoutIsARequest has it longer): the retry carries the
// request's unit and function, and decodes as a reply only with violations (byte count 0, three bytes too
// many). It is a request, and the reply that follows answers it; it was taken for a malformed reply to the
// first, four errors against a healthy device and the real reply "unsolicited". MK manual's FC3 example
// (000:356, 365), without direction markers, and FC1's (000:330, 343).
TEST(SerialInput, AMastersRetryBeforeOurTimeoutIsARequestNotAMalformedReply) {
    const std::string fc3 =
        "1.000 11 03 00 60 00 03 07 45\n"
        "1.500 11 03 00 60 00 03 07 45\n"
        "1.520 11 03 06 02 2B 00 00 00 64 C8 BA\n";
    const std::string fc1 =
        "1.000 11 01 00 13 00 15 0E 90\n"
        "1.500 11 01 00 13 00 15 0E 90\n"
        "1.520 11 01 03 B2 0E 1B DA 92\n";
    for (const auto& log : {fc3, fc1}) {
        SCOPED_TRACE(log);
        auto r = decode(write_temp("retry.txt", log));
        ASSERT_TRUE(r->ok);
        ASSERT_EQ(r->sink.frames.size(), 3u);
        EXPECT_EQ(r->sink.frames[1].direction, mb::Direction::Request);
        EXPECT_EQ(r->sink.frames[2].direction, mb::Direction::Response);
        ASSERT_EQ(r->sink.transactions.size(), 2u);
        EXPECT_EQ(r->sink.transactions[1].request.index, 2u);
        ASSERT_TRUE(r->sink.transactions[1].response.has_value());
        EXPECT_EQ(r->sink.transactions[1].response->index, 3u);
        // The first went unanswered before the master moved on; nothing else is wrong.
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
        EXPECT_EQ(r->sink.findings.size(), 1u);
    }
    // A short reply that decodes as some other request (byte count 4, three data bytes: "read register 1024")
    // is the device's malformed reply, not a retry: only the waiting request's own bytes are one.
    auto short_reply =
        decode(write_temp("short.txt", "1.000 11 03 00 6B 00 02 B7 47\n1.020 11 03 04 00 00 01 87 AA\n"));
    ASSERT_EQ(short_reply->sink.frames.size(), 2u);
    EXPECT_EQ(short_reply->sink.frames[1].direction, mb::Direction::Response);
    EXPECT_EQ(short_reply->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(short_reply->sink.count(mb::FindingCode::PduByteCountMismatch), 1);
    // So is one whose byte count, odd, counts its own three bytes (it reads as a request for register 768):
    // a device's fault, not the master's request and two timeouts.
    auto odd_reply =
        decode(write_temp("odd.txt", "1.000 11 03 00 00 00 01 86 9A\n1.020 11 03 03 00 00 05 87 1D\n"));
    ASSERT_EQ(odd_reply->sink.frames.size(), 2u);
    EXPECT_EQ(odd_reply->sink.frames[1].direction, mb::Direction::Response);
    EXPECT_EQ(odd_reply->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(odd_reply->sink.count(mb::FindingCode::PduByteCountMismatch), 1);
    // An echo (FC6, 000:396, 405) is both a request and its reply: it stays the reply.
    auto echo =
        decode(write_temp("echo.txt", "1.000 11 06 00 54 03 9E 4B D2\n1.020 11 06 00 54 03 9E 4B D2\n"));
    ASSERT_EQ(echo->sink.transactions.size(), 1u);
    ASSERT_TRUE(echo->sink.transactions[0].response.has_value());
    EXPECT_EQ(echo->sink.transactions[0].response->index, 2u);
    EXPECT_TRUE(echo->sink.findings.empty());
}

// A master polling several blocks of one unit moves on to the next block before the reply to the first came:
// the new request (FC4 0+1 after 10+2, ASCII as RTU; FC16 to register 10 after one to 0) decodes as a reply
// only with violations (byte count 0, or an FC16 reply too long) and does not claim to answer the one
// waiting (a byte count the read does not need, another address than the write's). It was taken for a
// malformed reply: made-up values, three errors against the device, the real reply "unsolicited".
TEST(SerialInput, AMasterMovingOnToOtherRegistersOfTheSameUnitSendsARequest) {
    for (const char* log : {"1.000 01 04 00 0A 00 02 51 C9\n1.300 01 04 00 00 00 01 31 CA\n"
                            "1.320 01 04 02 00 05 79 33\n",
                            "1.000 01 10 00 00 00 02 04 00 01 00 02 23 AE\n"
                            "1.300 01 10 00 0A 00 01 02 00 07 E7 38\n1.320 01 10 00 0A 00 01 21 CB\n"}) {
        SCOPED_TRACE(log);
        auto r = decode(write_temp("blocks.txt", log));
        ASSERT_EQ(r->sink.frames.size(), 3u);
        EXPECT_EQ(r->sink.frames[1].direction, mb::Direction::Request);
        ASSERT_EQ(r->sink.transactions.size(), 2u);
        ASSERT_TRUE(r->sink.transactions[1].response.has_value());
        EXPECT_EQ(r->sink.transactions[1].response->index, 3u);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
        EXPECT_EQ(r->sink.findings.size(), 1u);
        EXPECT_EQ(r->summary.devices.begin()->second.requests, 2u);
    }
    auto ascii =
        decode(write_temp("blocks.ascii", ":0104000A0002EF\r\n:010400000001FA\r\n:0104020005F4\r\n"));
    ASSERT_EQ(ascii->sink.frames.size(), 3u);
    EXPECT_EQ(ascii->sink.frames[1].direction, mb::Direction::Request);
    EXPECT_EQ(ascii->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(ascii->sink.findings.size(), 1u);
}

// The reply to the first block comes after the master asked for the second, with direction markers or
// without: its size fits only the first request, so it is that one's, late, and the second keeps waiting
// for its own reply. It was paired with the second (a size mismatch) and the second's reply was
// "unsolicited": two errors against a device that was only slow.
TEST(SerialInput, ALateReplyAfterTheMasterAskedTheSameUnitAgainIsTheFirstRequests) {
    for (const char* log : {"1.000 > 01 03 00 00 00 01 84 0A\n1.300 > 01 03 00 0A 00 02 E4 09\n"
                            "1.350 < 01 03 02 00 05 78 47\n1.400 < 01 03 04 00 01 00 02 2A 32\n",
                            "1.000 01 03 00 00 00 01 84 0A\n1.300 01 03 00 0A 00 02 E4 09\n"
                            "1.350 01 03 02 00 05 78 47\n1.400 01 03 04 00 01 00 02 2A 32\n"}) {
        SCOPED_TRACE(log);
        auto r = decode(write_temp("late-block.txt", log));
        ASSERT_EQ(r->sink.frames.size(), 4u);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
        EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
        EXPECT_EQ(r->sink.findings.size(), 2u);
        for (const auto& t : r->sink.transactions) {
            if (!t.response) continue;
            EXPECT_EQ(t.response->index, t.request.index == 1 ? 3u : 4u) << t.request.index;
        }
        EXPECT_EQ(r->summary.devices.begin()->second.responses, 1u);
    }
}

// A reply nobody waits for, after bytes that formed no frame (a request cut short on the line): its request
// may be among them. It was "the response of frame 1 again: one request answered twice", an error, when the
// device polled twice gave the same answer, as an idle device does.
TEST(SerialInput, AReplyAfterBytesThatFormedNoFrameMayAnswerThem) {
    auto r = decode(write_temp("cut.txt",
                               "1.000 > 11 03 00 60 00 03 07 45\n"
                               "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                               "2.000 > 11 03 00\n"
                               "2.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"));
    ASSERT_TRUE(r->ok);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairRequestNotCaptured), 1);
    EXPECT_EQ(r->summary.unparsed_bytes, 3u);
    // A byte from the slave's side (a turnaround glitch), too short to hold a request, excuses nothing: the
    // same reply again is one request answered twice. Nor does noise before a frame whose CRC fails make it
    // a reply to a request the noise held.
    auto glitch = decode(write_temp("glitch.txt",
                                    "1.000 > 11 03 00 60 00 03 07 45\n"
                                    "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                    "1.500 < 00\n"
                                    "2.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"));
    EXPECT_EQ(glitch->sink.count(mb::FindingCode::PairDuplicateResponse), 1);
    EXPECT_EQ(glitch->sink.count(mb::FindingCode::PairRequestNotCaptured), 0);
    auto damaged = decode(write_temp("damaged.txt", "1.000 AA BB CC DD EE\n2.000 5A 03 02 00 01 1C 48\n"));
    EXPECT_EQ(damaged->sink.count(mb::FindingCode::PairRequestNotCaptured), 0);
    EXPECT_GE(damaged->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    // Without the cut request, the same reply twice is one request answered twice.
    auto twice = decode(write_temp("twice.txt",
                                   "1.000 > 11 03 00 60 00 03 07 45\n"
                                   "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                                   "1.060 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"));
    EXPECT_EQ(twice->sink.count(mb::FindingCode::PairDuplicateResponse), 1);
}

// Two logs of two lines: each ends with its input. The last reply of the first was held until every input
// was read, while the second's clock timed out its request: "no response within 1000 ms" and then "the reply
// came 20 ms after it, past the timeout", a contradiction, exit code 1 for two healthy devices.
TEST(SerialInput, EachLineEndsWithItsOwnInput) {
    const auto a = write_temp("line_a.txt",
                              "1.000 > 11 03 00 60 00 03 07 45\n"
                              "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                              "2.000 > 11 03 00 60 00 03 07 45\n"
                              "2.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                              "2.500 > 11 03 00 60 00 03 07 45\n");
    std::string b_log;
    for (int i = 0; i < 8; ++i)
        b_log += std::to_string(1 + i / 2.0) + " > 12 03 00 60 00 03 07 76\n" +
                 std::to_string(1.02 + i / 2.0) + " < 12 03 06 02 2B 00 00 00 64 DC 4A\n";
    const auto b = write_temp("line_b.txt", b_log);
    auto r = decode_all({a, b}, false);
    ASSERT_TRUE(r->ok);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 0);
    // The first line's last request, 0 ms before its input ended: unanswered at its end, not timed out.
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponseAtEnd), 1);
    EXPECT_EQ(r->sink.transactions.size(), 11u);
}

// A frame must follow the line's bytes before it after a silence of at least t3.5 (SL §2.5.1.1): a reply
// that began 2 character times after its request's end broke it, and a receiver keeping t3.5 took both as
// one frame with a bad CRC. Frames are split by their content, so nothing said which device came too soon.
// At 9600 8N1 a character is 1.042 ms; a line's time is its last byte's end. (Lines without a direction:
// one tap on the line, deframed as one; with '>'/'<' each direction is deframed alone.)
TEST(SerialInput, AFrameThatBeganBeforeT35IsTheWarningOfItsSender) {
    auto r = decode(write_temp("too_soon.txt",
                               "1.000000 11 03 00 60 00 03 07 45\n"
                               "1.013542 11 03 06 02 2B 00 00 00 64 C8 BA\n"));  // 2.0 characters after
    ASSERT_EQ(r->sink.count(mb::FindingCode::RtuShortSilenceBeforeFrame), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::RtuShortSilenceBeforeFrame) {
            EXPECT_EQ(mb::info(f.code).severity, mb::Severity::Warning);
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{2});
            EXPECT_NE(std::string(f.device.view()).find("unit 17"), std::string::npos);
            EXPECT_EQ(f.message,
                      "began after a silence of 2.0 character times from the line's bytes before it, below "
                      "t3.5: a receiver keeping t3.5 takes them and it as one frame, whose CRC fails (the "
                      "silence as the capture's timestamps measure it)");
        }
    }
    // The reply is still the request's: a master that does not keep t3.5 took it.
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());

    // Time stamps that cannot tell (one stamp for both, a silence of 4 characters) say nothing.
    for (const char* text :
         {"1.000000 11 03 00 60 00 03 07 45\n1.000000 11 03 06 02 2B 00 00 00 64 C8 BA\n",
          "1.000000 11 03 00 60 00 03 07 45\n1.015625 11 03 06 02 2B 00 00 00 64 C8 BA\n"}) {
        auto quiet = decode(write_temp("not_too_soon.txt", text));
        EXPECT_EQ(quiet->sink.count(mb::FindingCode::RtuShortSilenceBeforeFrame), 0) << text;
    }
}

// The master's request 2 characters after the last reply: a slave keeping t3.5 saw the two as one frame and
// rightly answered nothing. It was pair.no_response, an error against the slave; it is a discarded request.
TEST(SerialInput, ARequestJoinedToTheBytesBeforeItAndUnansweredIsNoTimeout) {
    auto r = decode(write_temp("glued_request.txt",
                               "2.000000 11 03 00 60 00 03 07 45\n"
                               "2.020000 11 03 06 02 2B 00 00 00 64 C8 BA\n"
                               "2.030417 11 03 00 60 00 03 07 45\n"  // 2.0 characters after the reply
                               "3.500000 11 03 00 60 00 03 07 45\n"
                               "3.520000 11 03 06 02 2B 00 00 00 64 C8 BA\n"));
    const auto& device = r->summary.devices.begin()->second;
    EXPECT_EQ(device.requests, 3u);
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.damaged_unanswered, 1u);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    ASSERT_EQ(r->sink.count(mb::FindingCode::RtuShortSilenceBeforeFrame), 1);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairDamagedRequestUnanswered), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::PairDamagedRequestUnanswered) {
            EXPECT_NE(
                f.message.find(": only 2.0 character times of silence before it, below t3.5, joined it to "
                               "the bytes before and no reply came"),
                std::string::npos)
                << f.message;
        }
    }
}

// A serial line is named after its file, and findings quote the name: a file named with an ESC sequence
// ("ls" shows it as '?') drove the reader's terminal through the text output, where the error messages
// escaped it. Written as the errors write it; JSON carries the name as it is, escaped by JSON's rules.
TEST(SerialInput, AFileNameIsWrittenEscapedInTheTextOutput) {
    const auto path = write_temp(
        "line\x1b[2J\x9b"
        "31m.txt",
        "1.000 > 11 03 00 60 00 03 07 45\n"
        "3.000 > 11 03 00 60 00 03 07 45\n"
        "3.050 < 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    ASSERT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 1);
    const std::string out = text_output(*r);
    EXPECT_EQ(out.find('\x1b'), std::string::npos) << out;
    EXPECT_EQ(out.find('\x9b'), std::string::npos) << out;
    const std::string shown = "line\\x1B[2J\\x9B31m.txt";
    // The transaction lines, the finding (its link and its message) and the summary's device and line.
    std::size_t times = 0;
    for (auto at = out.find(shown); at != std::string::npos; at = out.find(shown, at + 1))
        ++times;
    EXPECT_EQ(times, 2u + 2u + 2u) << out;
    const auto json = an::summary_to_json(r->summary)["devices"].dump(
        -1, ' ', false, nlohmann::json::error_handler_t::replace);  // as the JSON sink writes it
    EXPECT_NE(json.find("line\\u001b[2J\xEF\xBF\xBD"
                        "31m.txt"),
              std::string::npos)
        << json;
}

// A frame a silence cut, joined: no damaged broadcast made of its tail, no bad CRC, no request left
// unanswered.
void expect_joined_and_answered(const Run& r) {
    EXPECT_EQ(r.summary.damaged_broadcasts, 0u);
    EXPECT_EQ(r.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(r.sink.count(mb::FindingCode::RtuCrcMismatch), 0);
}

// The MK manual's FC3 exchange (000:356, 365), the reply cut after its fifth byte by a silence of 5
// character times (a USB adapter's two reads stamped apart, or a pause of the slave's): its tail "00 00 00 64
// C8 BA" was a frame to unit 0 whose CRC fails, counted as a damaged broadcast, and the head a damaged
// reply: two bad CRCs blaming nobody right. Head and tail verify together: the reply is
// unit 17's, paired with its request, and the silence inside it is the error it is, said to be at or above
// t3.5 (a receiver keeping t3.5 took two frames whose CRCs both fail). 9600 8N1: a character is 1.042 ms; a
// line's time is its last byte's end.
// A damaged reply of one register (7 bytes, shorter than the 8 a request's reading of its bytes asks for) is
// held as the head of a frame a silence may have cut; the next request's bytes cannot complete it: it is
// still the reply to its request, damaged, and the next request is answered in its turn.
TEST(SerialInput, ADamagedShortReplyHeldForATailStillAnswersItsRequest) {
    const auto path = write_temp("held_reply.txt",
                                 "0.000 11 03 00 60 00 01 86 84\n"
                                 "0.950 11 03 02 00 2B 39 99\n"  // its CRC is 39 98
                                 "1.040 11 03 00 60 00 01 86 84\n"
                                 "1.060 11 03 02 00 2B 39 98\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    ASSERT_TRUE(r->sink.transactions[0].response.has_value());
    EXPECT_FALSE(r->sink.transactions[0].response->frame.checksum_ok);
    ASSERT_TRUE(r->sink.transactions[1].response.has_value());
    EXPECT_TRUE(r->sink.transactions[1].response->frame.checksum_ok);
}

TEST(SerialInput, AReplyCutInTwoByASilenceOfT35IsUnit17sReplyNotADamagedBroadcast) {
    const auto path = write_temp("cut_reply.txt",
                                 "1.000000 11 03 00 60 00 03 07 45\n"
                                 "1.020000 11 03 06 02 2B\n"
                                 "1.031458 00 00 00 64 C8 BA\n"  // 5.0 characters after the head
                                 "2.000000 11 03 00 60 00 03 07 45\n"
                                 "2.020000 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    expect_joined_and_answered(*r);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(r->summary.devices.size(), 1u);
    const auto& device = r->summary.devices.at("serial " + path + " unit 17");
    EXPECT_EQ(device.requests, 2u);
    EXPECT_EQ(device.responses, 2u);
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.checksum_errors, 0u);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    for (const auto& t : r->sink.transactions) {
        ASSERT_TRUE(t.response.has_value());
        EXPECT_TRUE(t.response->frame.checksum_ok);
        EXPECT_EQ(t.response->frame.wire_length, 11u);
    }
    ASSERT_EQ(r->sink.count(mb::FindingCode::RtuGapInsideFrame), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::RtuGapInsideFrame) {
            EXPECT_EQ(mb::info(f.code).severity, mb::Severity::Error);
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{2});
            EXPECT_NE(std::string(f.device.view()).find("unit 17"), std::string::npos);
            EXPECT_EQ(
                f.message,
                "silence of 5.0 character times between bytes 5 and 6 of 11, at or above t3.5: unit 17's "
                "reply came in two pieces (its sender paused, or the capture stamped its reads apart) "
                "whose CRC holds over both only; a receiver keeping t3.5 takes two frames whose CRCs both "
                "fail, and a strict master discards the reply");
        }
    }
    EXPECT_EQ(an::summary_to_json(r->summary)["damaged_broadcasts"], 0);
}

// A reply with a silence inside it is paired, as most masters take it, and its transaction line says that a
// strict master (SL §2.5.1.1) discards it, as it says of a bad CRC.
TEST(SerialInput, AReplyWithASilenceInsideSaysAStrictMasterDiscardsIt) {
    const std::string request = "1.000000 11 03 00 60 00 03 07 45\n";
    const auto above_t1_5 = write_temp("reply_gap_t15.txt", request +
                                                                "1.020000 11 03 06 02 2B\n"
                                                                "1.028854 00 00 00 64 C8 BA\n");  // 2.5 chars
    const auto at_t3_5 = write_temp("reply_gap_t35.txt", request +
                                                             "1.020000 11 03 06 02 2B\n"
                                                             "1.031458 00 00 00 64 C8 BA\n");  // 5.0 chars
    for (const auto& [path, shown] :
         {std::pair{above_t1_5, "above t1.5"}, std::pair{at_t3_5, "at or above t3.5"}}) {
        auto r = decode(path, an::InputFormat::Text);
        ASSERT_TRUE(r->ok);
        ASSERT_EQ(r->sink.transactions.size(), 1u);
        ASSERT_TRUE(r->sink.transactions[0].response.has_value());
        EXPECT_EQ(r->sink.count(mb::FindingCode::RtuGapInsideFrame), 1);
        const auto out = text_output(*r);
        EXPECT_NE(out.find(std::string("  silence inside ") + shown + ", a strict master discards it\n"),
                  std::string::npos)
            << out;
    }
}

// The same for the master's request, cut after its fourth byte by a silence of 5 character times (MK-RTU-01
// (a)): one request to unit 17, answered, its tail "00 03 07 45" no damaged broadcast; the finding names the
// master as the one that paused and says unit 17 keeping t3.5 discards it.
TEST(SerialInput, ARequestCutInTwoByASilenceOfT35IsOneRequestAnswered) {
    const auto path = write_temp("cut_request.txt",
                                 "1.000000 11 03 00 60\n"
                                 "1.009375 00 03 07 45\n"  // 5.0 characters after the head
                                 "1.030000 11 03 06 02 2B 00 00 00 64 C8 BA\n");
    auto r = decode(path, an::InputFormat::Text);
    ASSERT_TRUE(r->ok);
    expect_joined_and_answered(*r);
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].request.frame.checksum_ok);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());
    ASSERT_EQ(r->sink.count(mb::FindingCode::RtuGapInsideFrame), 1);
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::RtuGapInsideFrame) {
            EXPECT_EQ(
                f.message,
                "silence of 5.0 character times between bytes 4 and 5 of 8, at or above t3.5: the master's "
                "request to unit 17 came in two pieces (its sender paused, or the capture stamped its reads "
                "apart) whose CRC holds over both only; a receiver keeping t3.5 takes two frames whose CRCs "
                "both fail, and unit 17 discards the request");
        }
    }
}

}  // namespace test_analyzer_serial_test
