// RTU over TCP: a serial gateway's port (--rtu-over-tcp) carries raw RTU frames in the TCP stream. Frames
// are delimited by content and CRC after reassembly, whatever the segment boundaries; bad CRCs are flagged
// and bytes that form no frame are reported. The frames are the MK manual's worked FC3 example (000:356-
// 370): request 11 03 00 60 00 03 07 45, response 11 03 06 02 2B 00 00 00 64 C8 BA.
#include <gtest/gtest.h>

#include "test_packets.hpp"

namespace test_analyzer_rtu_over_tcp_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::decode_pcap;

namespace {

constexpr std::uint16_t gateway = 4001;

const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
const auto response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
const auto request_bad_crc = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x46});  // CRC is 0x4507

struct Conversation : mbscope::test::Conversation {
    Conversation() { server_port = gateway; }
};

an::AnalyzerOptions gateway_options() {
    an::AnalyzerOptions o;
    o.rtu_over_tcp_ports = {gateway};
    return o;
}

}  // namespace

TEST(RtuOverTcp, FramesArePairedAndABadCrcIsFlagged) {
    Conversation c;
    c.send(true, request, 1s);
    c.send(false, response, 1s + 12ms);
    c.send(true, request_bad_crc, 2s);
    c.send(false, response, 2s + 12ms);
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->sink.frames.size(), 4u);
    for (const auto& f : d->sink.frames) {
        EXPECT_EQ(f.frame.framing, mb::Framing::Rtu);
        EXPECT_EQ(f.carrier, an::Carrier::Tcp);
        EXPECT_EQ(f.link, "10.0.0.1:40000 -> 10.0.0.2:4001");
    }
    EXPECT_EQ(d->sink.frames[0].direction, mb::Direction::Request);
    EXPECT_EQ(d->sink.frames[1].direction, mb::Direction::Response);
    EXPECT_FALSE(d->sink.frames[2].frame.checksum_ok);
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.response);
        ASSERT_TRUE(t.latency);
        EXPECT_EQ(*t.latency, 12ms);
        EXPECT_EQ(t.request.frame.unit_id(), 17);
    }
    EXPECT_EQ(d->sink.transactions[1].request.index, 3u);
    ASSERT_EQ(d->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    for (const auto& f : d->sink.findings)
        if (f.code == mb::FindingCode::RtuCrcMismatch) {
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{3});
            EXPECT_EQ(f.message, "CRC 0x4607 received, 0x4507 computed");
        }
    EXPECT_EQ(d->summary.devices.at("10.0.0.2:4001 unit 17").checksum_errors, 1u);
    EXPECT_EQ(d->summary.unparsed_bytes, 0u);
}

// A frame to unit 0 whose CRC fails is no broadcast and names no device through a gateway as on a serial
// line (it stood in the summary as a device "unit 0" with a bad CRC).
TEST(RtuOverTcp, AFrameToUnitZeroWhoseCrcFailsNamesNoDevice) {
    Conversation c;
    c.send(true, request, 1s);
    c.send(false, response, 1s + 12ms);
    c.send(true, bytes({0x00, 0x06, 0x00, 0x01, 0x00, 0x03, 0x98, 0x1A}), 2s);  // CRC 99 DA, damaged
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->summary.devices.size(), 1u);
    EXPECT_EQ(d->summary.devices.count("10.0.0.2:4001 unit 17"), 1u);
    EXPECT_EQ(d->summary.damaged_broadcasts, 1u);
    EXPECT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_EQ(d->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
}

TEST(RtuOverTcp, FramesSplitAcrossSegmentsAreReassembled) {
    Conversation c;
    c.send(true, {request.begin(), request.begin() + 3}, 1s);  // one frame over two segments
    c.send(true, {request.begin() + 3, request.end()}, 1s + 1ms);
    c.send(false, {response.begin(), response.begin() + 5}, 1s + 10ms);
    c.send(false, {response.begin() + 5, response.end()}, 1s + 11ms);
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    ASSERT_TRUE(d->sink.transactions[0].response);
    EXPECT_EQ(d->sink.transactions[0].response->frame.length, 11u);
    EXPECT_TRUE(d->sink.findings.empty());
}

TEST(RtuOverTcp, BytesThatFormNoFrameAreReportedUnparsed) {
    Conversation c;
    c.send(true, request, 1s);
    std::vector<std::uint8_t> noisy = {0xFF, 0xFF};  // unit 255 cannot start a frame (SL §2.2: 1..247)
    noisy.insert(noisy.end(), response.begin(), response.end());
    c.send(false, noisy, 1s + 12ms);
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->sink.unparsed_records.size(), 1u);
    const auto& u = d->sink.unparsed_records[0];
    EXPECT_EQ(u.direction, mb::Direction::Response);
    EXPECT_EQ(u.offset, 0u);
    EXPECT_EQ(u.length, 2u);
    EXPECT_EQ(d->summary.unparsed_bytes, 2u);
    EXPECT_EQ(d->sink.count(mb::FindingCode::StreamUnparsedBytes), 1);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_TRUE(d->sink.transactions[0].response);
    EXPECT_EQ(d->sink.transactions[0].response->frame.offset, 2u);
}

// The client asks again, in a segment of its own, before a reply came: RTU has no transaction id, so it
// waits for each reply and its own timeout ran out, as a master's on a line. The reply answers the retry
// (it was paired with the first request, 512 ms late, and the retry was the timeout).
TEST(RtuOverTcp, AnUnansweredRequestIsReportedWhenTheNextOneComes) {
    Conversation c;
    c.send(true, request, 1s);
    c.send(true, request, 1s + 500ms);  // the gateway's slave never answered the first
    c.send(false, response, 1s + 512ms);
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    EXPECT_FALSE(d->sink.transactions[0].response);
    ASSERT_TRUE(d->sink.transactions[1].response);
    ASSERT_TRUE(d->sink.transactions[1].latency);
    EXPECT_EQ(*d->sink.transactions[1].latency, 12ms);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 1);
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_NE(f.message.find("before the next request"), std::string::npos) << f.message;
        }
    }
}

TEST(RtuOverTcp, TheGatewayPortIsNotDecodedUnlessNamed) {
    Conversation c;
    c.send(true, request, 1s);
    c.send(false, response, 1s + 12ms);
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->summary.packets, 2u);
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_TRUE(d->sink.findings.empty());
}

// A frame whose CRC fails is closed only by later bytes: the next frame from its own side, or the other
// side's turn. It was stamped with the packet (and, for its own side's, the time) of the bytes that closed
// it; it is the packet's that held it, and so are its rtu.crc_mismatch and the frames after it. tshark (-d
// tcp.port==4001,mbrtu) shows each at the packet that holds it.
TEST(RtuOverTcp, AFrameWithABadCrcKeepsThePacketAndTimeItCameIn) {
    const auto unit_1 = bytes({0x01, 0x03, 0x00, 0x00, 0x00, 0x01, 0x84, 0x0A});
    const auto unit_1_reply = bytes({0x01, 0x03, 0x02, 0x00, 0x01, 0x79, 0x84});
    for (const bool answered : {false, true}) {
        SCOPED_TRACE(answered);
        Conversation c;
        c.send(true, request_bad_crc, 300ms);          // packet 1
        if (answered) c.send(false, response, 350ms);  // a slave that does not check the CRC
        c.send(true, unit_1, 5s);                      // packet 2 or 3
        c.send(false, unit_1_reply, 5s + 50ms);
        auto d = decode_pcap(c.file(), gateway_options());
        ASSERT_EQ(d->sink.frames.size(), answered ? 4u : 3u);
        const auto& bad = d->sink.frames[0];
        EXPECT_FALSE(bad.frame.checksum_ok);
        EXPECT_EQ(bad.packet, 1u);
        EXPECT_EQ(bad.time, 300ms);
        const std::uint64_t next = answered ? 3 : 2;
        EXPECT_EQ(d->sink.frames[answered ? 2 : 1].packet, next);
        EXPECT_EQ(d->sink.frames[answered ? 2 : 1].time, 5s);
        if (answered) {
            EXPECT_EQ(d->sink.frames[1].packet, 2u);
            EXPECT_EQ(d->sink.frames[1].time, 350ms);
        }
        ASSERT_EQ(d->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
        for (const auto& f : d->sink.findings) {
            if (f.code == mb::FindingCode::RtuCrcMismatch) {
                EXPECT_EQ(f.packet, 1u);
                EXPECT_EQ(f.time, 300ms);
                EXPECT_EQ(f.frames, std::vector<std::uint64_t>{1});
            }
        }
    }
}

// A damaged reply over two segments, closed by the client's next request: whole at its last byte, the
// packet that holds it, as a frame whose CRC holds is. Bytes that formed no frame are the packet's that held
// their first byte, as on a Modbus/TCP stream (they were the packet's whose bytes showed where they end).
TEST(RtuOverTcp, ADamagedFrameOverTwoSegmentsAndUnparsedBytesKeepTheirPackets) {
    auto damaged = response;
    damaged.back() ^= 0x01;
    Conversation c;
    c.send(true, bytes({0xFF, 0xFF}), 1s);                             // packet 1: no frame
    c.send(true, request, 2s);                                         // packet 2
    c.send(false, {damaged.begin(), damaged.begin() + 5}, 2s + 10ms);  // packet 3
    c.send(false, {damaged.begin() + 5, damaged.end()}, 2s + 11ms);    // packet 4
    c.send(true, request, 3s);                                         // packet 5
    auto d = decode_pcap(c.file(), gateway_options());
    ASSERT_EQ(d->sink.unparsed_records.size(), 1u);
    EXPECT_EQ(d->sink.unparsed_records[0].packet, 1u);
    EXPECT_EQ(d->sink.unparsed_records[0].time, 1s);
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::StreamUnparsedBytes) {
            EXPECT_EQ(f.packet, 1u);
        }
    }
    ASSERT_EQ(d->sink.frames.size(), 3u);
    EXPECT_EQ(d->sink.frames[0].packet, 2u);
    EXPECT_EQ(d->sink.frames[0].time, 2s);
    EXPECT_FALSE(d->sink.frames[1].frame.checksum_ok);
    EXPECT_EQ(d->sink.frames[1].packet, 4u);
    EXPECT_EQ(d->sink.frames[1].time, 2s + 11ms);
    EXPECT_EQ(d->sink.frames[2].packet, 5u);
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::RtuCrcMismatch) {
            EXPECT_EQ(f.packet, 4u);
        }
    }
}

}  // namespace test_analyzer_rtu_over_tcp_test
