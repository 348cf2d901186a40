// A device that answers a request whose CRC or LRC failed as captured (pair.damaged_request_answered): a
// slave must discard such a frame and not reply (SL §2.5.1.2, §2.5.2.2), so either the device does not check
// the checksum or the capture damaged the request on its side of the line. A passive tap cannot tell which: a
// warning against the device that replied. Before, the reply was paired without a word against the device,
// and only the opposite case (no reply, pair.damaged_request_unanswered) was noted.
//
// Every test here holds one damaged request answered, so each fails where the finding is never made; those
// about when it must not be made hold their other cases beside it, and count the finding exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "analyzer/serial_input.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/finding_codes.hpp"
#include "test_packets.hpp"

namespace test_analyzer_damaged_request_answered_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::Collect;
using mbscope::test::Conversation;
using mbscope::test::decode_pcap;
using mbscope::test::write_temp;

namespace {

constexpr auto answered = mb::FindingCode::PairDamagedRequestAnswered;
constexpr auto unanswered = mb::FindingCode::PairDamagedRequestUnanswered;

struct Run {
    Collect sink;
    an::Summary summary;
};

// A serial capture (the text format, or a raw dump) decoded alone.
std::unique_ptr<Run> decode_serial(const std::string& path, an::InputFormat format) {
    auto r = std::make_unique<Run>();
    an::Analyzer a({}, r->sink);
    an::read_inputs(a, {path}, format);
    a.finish();
    r->summary = a.summary();
    return r;
}

std::vector<const an::FindingRecord*> findings_of(const Collect& sink, mb::FindingCode code) {
    std::vector<const an::FindingRecord*> out;
    for (const auto& f : sink.findings)
        if (f.code == code) out.push_back(&f);
    return out;
}

// What the finding says about a read of holding register 0 by unit 3's `device`, asked in `request`.
std::string message(const std::string& device, int request, const std::string& checksum = "CRC",
                    const std::string& rule = "§2.5.1.2") {
    return device + " answered frame " + std::to_string(request) +
           " (FC3 Read Holding Registers 0+1), a request whose " + checksum +
           " failed as captured: either it does not check the " + checksum +
           " (a slave must discard such a frame and not reply, SL " + rule +
           ") or the capture damaged the request";
}

// The one pair.damaged_request_answered of a run, checked whole: a warning, against `device`, naming the
// request and the reply.
void expect_one_answered(const Collect& sink, const std::string& device, std::uint64_t request,
                         std::uint64_t reply, const std::string& text) {
    const auto found = findings_of(sink, answered);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(mb::info(answered).severity, mb::Severity::Warning);
    EXPECT_EQ(found[0]->device.str(), device);
    EXPECT_EQ(found[0]->frames, (std::vector<std::uint64_t>{request, reply}));
    EXPECT_EQ(found[0]->message, text);
}

std::vector<std::uint8_t> rtu(std::uint8_t unit, const std::vector<std::uint8_t>& pdu) {
    return mb::encode_rtu(unit, pdu);
}
std::vector<std::uint8_t> read3() {
    return rtu(3, {0x03, 0x00, 0x00, 0x00, 0x01});
}
std::vector<std::uint8_t> damaged(std::vector<std::uint8_t> frame) {
    frame.back() ^= 0x10;  // the CRC's high byte: the PDU is what was asked
    return frame;
}
std::vector<std::uint8_t> reply3(std::uint8_t value) {
    return rtu(3, {0x03, 0x02, 0x00, value});
}

// A timed text capture's line: "1.000000 > 03 03 ...".
std::string line(double t, const char* dir, const std::vector<std::uint8_t>& b) {
    char head[32];
    std::snprintf(head, sizeof head, "%.6f %s", t, dir);
    return std::string(head) + " " + mb::hex_bytes(b) + "\n";
}
std::vector<std::uint8_t> chars(const std::string& s) {
    return {s.begin(), s.end()};
}

Conversation gateway_conversation() {
    Conversation c;
    c.server_port = 4001;
    return c;
}
an::AnalyzerOptions gateway_options() {
    an::AnalyzerOptions o;
    o.rtu_over_tcp_ports = {4001};
    return o;
}

}  // namespace

// The tester's capture (s8a_serial.txt): unit 3 answers a read whose CRC failed, then unit 1 a good one.
TEST(DamagedRequestAnswered, OnASerialRtuLineTheUnitThatAnsweredIsWarned) {
    const auto path = write_temp("damaged_answered.txt",
                                 "0.300 > 03 03 00 00 00 01 b1 fa\n"
                                 "0.350 < 03 03 02 00 03 81 85\n"
                                 "5.000 > 01 03 00 00 00 01 84 0a\n"
                                 "5.050 < 01 03 02 00 01 79 84\n");
    const auto r = decode_serial(path, an::InputFormat::Text);
    const std::string unit3 = "serial " + path + " unit 3";
    expect_one_answered(r->sink, unit3, 1, 2, message(unit3, 1));
    EXPECT_EQ(r->summary.errors, 1u);  // the CRC mismatch; the reply is a warning
    const auto& stats = r->summary.devices.at(unit3);
    EXPECT_EQ(stats.responses, 1u);
    EXPECT_EQ(stats.findings.at("pair.damaged_request_answered"), 1u);
    EXPECT_EQ(r->summary.devices.at("serial " + path + " unit 1").findings.size(), 0u);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    const auto& t = r->sink.transactions[0].findings;
    EXPECT_NE(std::find(t.begin(), t.end(), answered), t.end());
    EXPECT_TRUE(r->sink.transactions[1].findings.empty());
}

// The same on an ASCII line: an LRC that fails.
TEST(DamagedRequestAnswered, OnAnAsciiLineTheUnitThatAnsweredIsWarned) {
    // 03 03 00 00 00 01: LRC F9, sent as F8; the reply 03 03 02 00 03: LRC F5.
    const auto path =
        write_temp("damaged_answered_ascii.txt", line(0.300, ">", chars(":030300000001F8\r\n")) +
                                                     line(0.350, "<", chars(":0303020003F5\r\n")));
    const auto r = decode_serial(path, an::InputFormat::Text);
    ASSERT_EQ(r->sink.count(mb::FindingCode::AsciiLrcMismatch), 1);
    EXPECT_EQ(r->sink.first(mb::FindingCode::AsciiLrcMismatch)->message, "LRC 0xF8 received, 0xF9 computed");
    const std::string unit3 = "serial " + path + " unit 3";
    expect_one_answered(r->sink, unit3, 1, 2, message(unit3, 1, "LRC", "§2.5.2.2"));
    EXPECT_EQ(r->summary.devices.at(unit3).findings.at("pair.damaged_request_answered"), 1u);
}

// The tester's capture (s8a.pcap): RTU over TCP through a serial gateway on port 4001.
TEST(DamagedRequestAnswered, OverRtuOverTcpTheUnitThatAnsweredIsWarned) {
    Conversation c = gateway_conversation();
    c.send(true, damaged(read3()), 300ms);
    c.send(false, reply3(3), 350ms);
    c.send(true, rtu(1, {0x03, 0x00, 0x00, 0x00, 0x01}), 5s);
    c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 5s + 50ms);
    c.send(true, {}, 5s + 100ms);
    const auto d = decode_pcap(c.file(), gateway_options());
    expect_one_answered(d->sink, "10.0.0.2:4001 unit 3", 1, 2, message("10.0.0.2:4001 unit 3", 1));
    EXPECT_EQ(d->summary.findings, (std::map<std::string, std::uint64_t>{{"pair.damaged_request_answered", 1},
                                                                         {"rtu.crc_mismatch", 1}}));
    EXPECT_EQ(d->summary.errors, 1u);
    EXPECT_EQ(d->summary.devices.at("10.0.0.2:4001 unit 3").responses, 1u);
}

// RTU in UDP datagrams (paired as on a serial line), once a good frame has shown the link carries RTU; the
// same reads in Modbus/TCP, which has no checksum to fail, make nothing.
TEST(DamagedRequestAnswered, OverRtuInUdpTheUnitThatAnsweredIsWarned) {
    using mbscope::test::packet;
    const auto at = [](std::chrono::milliseconds ms) { return mb::Timestamp(ms); };
    std::vector<mbscope::test::PcapRecord> records{
        {at(100ms), packet(true, 0, read3(), true)},
        {at(150ms), packet(false, 0, reply3(1), true)},
        {at(1100ms), packet(true, 0, damaged(read3()), true)},
        {at(1150ms), packet(false, 0, reply3(2), true)},
    };
    const auto d = decode_pcap(mbscope::test::pcap_file(mbscope::test::link_raw, records));
    expect_one_answered(d->sink, "10.0.0.2:502 unit 3", 3, 4, message("10.0.0.2:502 unit 3", 3));

    Conversation tcp;
    const std::vector<std::uint8_t> read = {0x03, 0x00, 0x00, 0x00, 0x01}, reply = {0x03, 0x02, 0x00, 0x01};
    tcp.send(true, mb::encode_tcp(1, 3, read), 100ms);
    tcp.send(false, mb::encode_tcp(1, 3, reply), 150ms);
    EXPECT_EQ(decode_pcap(tcp.file())->sink.count(answered), 0);
}

// The master sends the request again, its checksum good, and the reply answers that copy: the device did what
// the rules want (it discarded the damaged one), and is not warned. On a serial line the copy ends the
// damaged request's wait (a master waits for one reply at a time), in its timeout or before; through a
// gateway on TCP both wait, and the reply goes to the good copy. Only the damaged request answered at the
// end of each capture is warned about.
TEST(DamagedRequestAnswered, NotWhenTheGoodCopyIsTheOneAnswered) {
    {
        SCOPED_TRACE("serial RTU");
        const auto path = write_temp("damaged_then_good.txt",
                                     line(1.000, ">", damaged(read3())) +  // no reply: asked again
                                         line(2.000, ">", read3()) + line(2.050, "<", reply3(1)) +
                                         line(3.000, ">", damaged(read3())) +  // asked again at once
                                         line(3.100, ">", read3()) + line(3.150, "<", reply3(2)) +
                                         line(4.000, ">", damaged(read3())) + line(4.050, "<", reply3(3)));
        const auto r = decode_serial(path, an::InputFormat::Text);
        const std::string unit3 = "serial " + path + " unit 3";
        expect_one_answered(r->sink, unit3, 7, 8, message(unit3, 7));
        EXPECT_EQ(r->sink.count(unanswered), 2);
        const auto& stats = r->summary.devices.at(unit3);
        EXPECT_EQ(stats.responses, 3u);
        EXPECT_EQ(stats.damaged_unanswered, 2u);
        EXPECT_EQ(stats.timeouts, 0u);
    }
    {
        SCOPED_TRACE("RTU over TCP");
        Conversation c = gateway_conversation();
        auto both = damaged(read3());
        const auto good = read3();
        both.insert(both.end(), good.begin(), good.end());
        c.send(true, both, 1s);  // the damaged request and its good copy in one segment
        c.send(false, reply3(1), 1s + 50ms);
        c.send(true, damaged(read3()), 3s);
        c.send(false, reply3(2), 3s + 50ms);
        c.send(true, {}, 5s);
        const auto d = decode_pcap(c.file(), gateway_options());
        expect_one_answered(d->sink, "10.0.0.2:4001 unit 3", 4, 5, message("10.0.0.2:4001 unit 3", 4));
        EXPECT_EQ(d->sink.count(unanswered), 1);
        // The first damaged request, to a unit the link had not shown yet, timed out before the second: the
        // reply 50 ms after the second is its own, not the first one's late reply (it was, and the second
        // was left unanswered).
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairLateResponse), 0);
        ASSERT_EQ(d->sink.transactions.size(), 3u);
        for (const auto& t : d->sink.transactions) {  // in the order they completed
            EXPECT_EQ(t.response.has_value(), t.request.index != 1) << "frame " << t.request.index;
            if (t.response) {
                EXPECT_EQ(t.response->index, t.request.index + 1) << "frame " << t.request.index;
            }
        }
        const auto& stats = d->summary.devices.at("10.0.0.2:4001 unit 3");
        EXPECT_EQ(stats.damaged_unanswered, 1u);
        EXPECT_EQ(stats.late_responses, 0u);
        EXPECT_EQ(stats.responses, 2u);
    }
}

// Through a gateway on TCP, the damaged request's timeout ran out before its reply came, and the client's
// good copy waits: the reply answers the copy (the gateway or the device discarded the damaged one), not
// the damaged one late. The copy sent after the damaged one's timeout (to a unit the link had not shown,
// the tester's s7.pcap), or before it with the reply after it. Before, the reply was the damaged request's,
// late, and the good copy a pair.no_response against the device. The damaged request answered at the end
// is the one warned about.
TEST(DamagedRequestAnswered, ThroughAGatewayTheGoodCopyIsAnsweredAfterTheDamagedOneTimedOut) {
    for (const bool unit_seen : {false, true}) {
        SCOPED_TRACE(unit_seen ? "the copy before the timeout, the reply after it"
                               : "the copy after the timeout");
        Conversation c = gateway_conversation();
        if (unit_seen) {
            c.send(true, read3(), 100ms);
            c.send(false, reply3(0), 150ms);
            c.send(true, damaged(read3()), 1000ms);
            c.send(true, read3(), 1900ms);
            c.send(false, reply3(1), 2050ms);
        } else {
            c.send(true, damaged(read3()), 300ms);
            c.send(true, read3(), 1500ms);
            c.send(false, reply3(1), 1550ms);
        }
        c.send(true, damaged(read3()), 4s);
        c.send(false, reply3(2), 4s + 50ms);
        c.send(true, {}, 6s);
        const auto d = decode_pcap(c.file(), gateway_options());
        const std::uint64_t first = unit_seen ? 3 : 1;  // the first damaged request
        expect_one_answered(d->sink, "10.0.0.2:4001 unit 3", first + 3, first + 4,
                            message("10.0.0.2:4001 unit 3", static_cast<int>(first + 3)));
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairLateResponse), 0);
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 0);
        const auto notes = findings_of(d->sink, unanswered);
        ASSERT_EQ(notes.size(), 1u);
        EXPECT_EQ(notes[0]->frames, std::vector<std::uint64_t>{first});
        for (const auto& t : d->sink.transactions) {
            EXPECT_EQ(t.response.has_value(), t.request.index != first) << "frame " << t.request.index;
            if (t.response) {
                EXPECT_EQ(t.response->index, t.request.index + 1) << "frame " << t.request.index;
            }
        }
        const auto& stats = d->summary.devices.at("10.0.0.2:4001 unit 3");
        EXPECT_EQ(stats.timeouts, 0u);
        EXPECT_EQ(stats.late_responses, 0u);
        EXPECT_EQ(stats.damaged_unanswered, 1u);
    }
}

// A damaged request that draws no reply is still the note pair.damaged_request_unanswered, and nothing more:
// at its timeout, before the next request, or at the end of the capture. Nor is a reply whose own CRC fails
// held against the unit (its unit and function bytes may be the damage). The one warned about is the
// damaged request answered in the middle.
TEST(DamagedRequestAnswered, NotWhenNoReplyOrOnlyADamagedOneCame) {
    const auto path = write_temp("damaged_unanswered.txt",
                                 line(0.500, ">", read3()) + line(0.550, "<", reply3(0)) +
                                     line(1.000, ">", damaged(read3())) +  // its timeout runs out
                                     line(3.000, ">", damaged(read3())) +  // the next request ends its wait
                                     line(3.500, ">", damaged(read3())) +  // answered
                                     line(3.550, "<", reply3(1)) +         //
                                     line(4.000, ">", damaged(read3())) +  // answered with a damaged reply
                                     line(4.050, "<", damaged(reply3(2))) +
                                     line(5.000, ">", damaged(read3())));  // the capture ends
    const auto r = decode_serial(path, an::InputFormat::Text);
    const std::string unit3 = "serial " + path + " unit 3";
    expect_one_answered(r->sink, unit3, 5, 6, message(unit3, 5));
    const auto notes = findings_of(r->sink, unanswered);
    ASSERT_EQ(notes.size(), 3u);
    EXPECT_EQ(notes[0]->frames, std::vector<std::uint64_t>{3});
    EXPECT_EQ(notes[1]->frames, std::vector<std::uint64_t>{4});
    EXPECT_EQ(notes[2]->frames, std::vector<std::uint64_t>{9});
    const auto& stats = r->summary.devices.at(unit3);
    EXPECT_EQ(stats.damaged_unanswered, 3u);
    EXPECT_EQ(stats.responses, 3u);
    EXPECT_EQ(stats.findings.at("pair.damaged_request_unanswered"), 3u);
    EXPECT_EQ(stats.findings.at("pair.damaged_request_answered"), 1u);
}

// A reply after the damaged request's timeout: late, and still an answer to a frame the device should have
// discarded.
TEST(DamagedRequestAnswered, ALateReplyIsWarnedAboutToo) {
    const auto path = write_temp("damaged_answered_late.txt",
                                 line(1.000, ">", damaged(read3())) + line(2.500, "<", reply3(1)));
    const auto r = decode_serial(path, an::InputFormat::Text);
    const std::string unit3 = "serial " + path + " unit 3";
    expect_one_answered(r->sink, unit3, 1, 2, message(unit3, 1));
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairLateResponse), 1);
    EXPECT_EQ(r->summary.devices.at(unit3).late_responses, 1u);
}

}  // namespace test_analyzer_damaged_request_answered_test
