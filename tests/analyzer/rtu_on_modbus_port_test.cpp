// A serial gateway in transparent mode sends raw RTU frames over TCP. Decoded as Modbus/TCP (port 502
// without --rtu-over-tcp), they read as MBAP headers: the request 01 03 00 00 00 02 C4 0B was transaction
// 0x0103, protocol 0, length 2, unit 196, FC11, and a device "unit 196" answered with protocol id 0x0400.
// The frames are those of no2play/trafficsim's modbus_rtu_only.pcap (../shared/captures, RTU over UDP),
// whose reply carries F0 1C where its CRC is DA 3E (CRC-16/MODBUS of 01 03 04 00 0A 00 14, worked out by
// hand with the SL §6.2.2 procedure): the reply here carries the right one.
#include <gtest/gtest.h>

#include <dirent.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "analyzer/sinks.hpp"
#include "test_packets.hpp"

namespace test_analyzer_rtu_on_modbus_port_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Conversation;
using mbscope::test::decode_pcap;

namespace {

const auto request = bytes({0x01, 0x03, 0x00, 0x00, 0x00, 0x02, 0xC4, 0x0B});
const auto response = bytes({0x01, 0x03, 0x04, 0x00, 0x0A, 0x00, 0x14, 0xDA, 0x3E});

// Three reads a second apart, each answered 20 ms later, through a gateway on `port`.
Conversation three_rtu_reads(std::uint16_t port = 502) {
    Conversation c;
    c.server_port = port;
    for (int i = 1; i <= 3; ++i) {
        c.send(true, request, std::chrono::seconds(i));
        c.send(false, response, std::chrono::seconds(i) + 20ms);
    }
    return c;
}

bool has_rtu_framing_finding(const mbscope::test::Decoded& d) {
    return d.sink.count(mb::FindingCode::TcpRtuFraming) != 0;
}

}  // namespace

TEST(RtuOnModbusPort, RtuFramesOnPort502AreAFindingAndMakeUpNoDevice) {
    auto d = decode_pcap(three_rtu_reads().file());
    ASSERT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    for (const auto& f : d->sink.findings)
        if (f.code == mb::FindingCode::TcpRtuFraming) {
            EXPECT_EQ(f.link, "10.0.0.1:40000 -> 10.0.0.2:502");
            EXPECT_EQ(f.packet, 3u);  // the second request: the third frame
            EXPECT_TRUE(f.device.empty());
            EXPECT_NE(f.message.find("--rtu-over-tcp 502"), std::string::npos) << f.message;
            EXPECT_NE(f.message.find("protocol id is 0x0400"), std::string::npos) << f.message;
        }
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_TRUE(d->sink.transactions.empty());
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.rtu_over_tcp_connections, (std::map<std::uint16_t, std::uint64_t>{{502, 1}}));
    // No byte dropped without a word: each direction's 24 and 27 bytes, one run each.
    EXPECT_EQ(d->summary.unparsed_bytes, 3u * (8 + 9));
    ASSERT_EQ(d->sink.unparsed_records.size(), 2u);
    for (const auto& u : d->sink.unparsed_records) {
        EXPECT_EQ(u.reason, mb::UnparsedReason::RtuOverTcp);
        EXPECT_EQ(u.offset, 0u);
        EXPECT_EQ(u.length, u.direction == mb::Direction::Request ? 24u : 27u);
        EXPECT_EQ(u.packet, u.direction == mb::Direction::Request ? 1u : 2u);
    }
    std::ostringstream text;
    an::TextSink(text, true).end(d->summary);
    EXPECT_NE(text.str().find("hint: 1 TCP connection to port 502 carried RTU frames, not Modbus/TCP: looks "
                              "like RTU over TCP (a serial gateway), not decoded; decode them with "
                              "--rtu-over-tcp 502"),
              std::string::npos)
        << text.str();
    const auto json = an::summary_to_json(d->summary);
    EXPECT_EQ(json["rtu_over_tcp_connections"][0]["port"], 502);
    EXPECT_EQ(json["rtu_over_tcp_connections"][0]["connections"], 1);
}

// A client that polls once and goes quiet (or connects for each poll): a request and its reply are told
// once the request's timeout has passed without a third frame, when another connection's packet comes. That
// connection, Modbus/TCP, is decoded as ever.
TEST(RtuOnModbusPort, APollAndItsReplyAreToldWhenTheConnectionGoesQuiet) {
    Conversation c;
    c.send(true, request, 1s);
    c.send(false, response, 1s + 20ms);
    const auto mbap_request = bytes({0, 1, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1});
    const auto mbap_response = bytes({0, 1, 0, 0, 0, 5, 1, 3, 2, 0, 7});
    c.records.push_back({10s, mbscope::test::packet(true, 1, mbap_request, false, 0x18, 502, 1, 40001)});
    c.records.push_back(
        {10s + 2ms, mbscope::test::packet(false, 1, mbap_response, false, 0x18, 502, 13, 40001)});
    auto d = decode_pcap(c.file());
    ASSERT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    for (const auto& f : d->sink.findings)
        if (f.code == mb::FindingCode::TcpRtuFraming) {
            EXPECT_EQ(f.link, "10.0.0.1:40000 -> 10.0.0.2:502");
            EXPECT_EQ(f.packet, 2u);
            EXPECT_EQ(f.time, 1s + 20ms);
        }
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_EQ(d->sink.transactions[0].request.link, "10.0.0.1:40001 -> 10.0.0.2:502");
    ASSERT_EQ(d->summary.devices.size(), 1u);
    EXPECT_EQ(d->summary.devices.at("10.0.0.2:502 unit 1").requests, 1u);
    EXPECT_EQ(d->summary.unparsed_bytes, 8u + 9u);
}

// A gateway whose first poll went unanswered, the next ones coming after the request's timeout: the first
// request, read as MBAP, is a consistent FC11 request to unit 196, so the quiet time does not settle the
// connection (it was settled as MBAP on that one frame and made up units for good); the replies tell it.
TEST(RtuOnModbusPort, AFirstPollUnansweredDoesNotSettleTheConnectionAsMbap) {
    Conversation c;
    c.send(true, request, 1s);
    for (int i = 5; i <= 7; ++i) {
        c.send(true, request, std::chrono::seconds(i));
        c.send(false, response, std::chrono::seconds(i) + 20ms);
    }
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 4u * 8 + 3u * 9);
}

// One poll whose MBAP reading fails (FC3 of 10 registers: a function code 0xCD), unanswered, the connection
// then quiet: one RTU frame whose CRC holds and no MBAP reading is enough.
TEST(RtuOnModbusPort, OneFrameThatIsNoMbapAduIsToldWhenTheConnectionGoesQuiet) {
    Conversation c;
    c.send(true, bytes({0x01, 0x03, 0x00, 0x00, 0x00, 0x0A, 0xC5, 0xCD}), 1s);
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 8u);
}

// A Modbus/TCP connection whose first request is a vendor's function (Schneider's UMAS, FC90) is told at
// its first packet: its request is the capture's first frame, as before the probe, not held behind another
// connection's transaction until its reply.
TEST(RtuOnModbusPort, AVendorFunctionIsModbusTcpAtItsFirstPacket) {
    Conversation c;
    c.send(true, bytes({0x00, 0x01, 0x00, 0x00, 0x00, 0x04, 0x01, 0x5A, 0x00, 0x02}), 1s);
    c.records.push_back(
        {1s + 10ms, mbscope::test::packet(true, 1, bytes({0, 7, 0, 0, 0, 6, 1, 3, 0, 0, 0, 2}), false, 0x18,
                                          502, 1, 40001)});
    c.records.push_back(
        {1s + 20ms, mbscope::test::packet(false, 1, bytes({0, 7, 0, 0, 0, 7, 1, 3, 4, 0, 10, 0, 20}), false,
                                          0x18, 502, 13, 40001)});
    c.send(false, bytes({0x00, 0x01, 0x00, 0x00, 0x00, 0x04, 0x01, 0x5A, 0x00, 0xFE}), 1s + 50ms);
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 0);
    ASSERT_EQ(d->sink.frames.size(), 4u);
    EXPECT_EQ(d->sink.frames[0].time, 1s);
    EXPECT_EQ(d->sink.frames[0].packet, 1u);
    EXPECT_EQ(d->sink.transactions.size(), 2u);
}

// The client resets a connection found to carry RTU frames while a poll waits; the gateway's reply comes
// after the reset in the capture. The server's stream goes on as RTU: the reply is one more RTU frame not
// decoded, not bytes "before the first header" of a connection begun before the capture.
TEST(RtuOnModbusPort, AClientResetKeepsTheServersStreamRtu) {
    Conversation c = three_rtu_reads();
    c.send(true, request, 4s);
    c.records.push_back({4s + 5ms, mbscope::test::packet(true, c.seq[0], {}, false, 0x14, 502, c.seq[1])});
    c.send(false, response, 4s + 20ms);
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 4u * (8 + 9));
    for (const auto& u : d->sink.unparsed_records)
        EXPECT_EQ(u.reason, mb::UnparsedReason::RtuOverTcp) << u.offset;
}

// What `mbscope decode` says when nothing but such a connection was read: no frame decoded (exit 2), and
// the option that decodes it.
TEST(RtuOnModbusPort, DecodeNamesTheOptionWhenNothingElseWasRead) {
    const auto path = mbscope::test::write_temp("rtu_on_modbus_port.pcap", three_rtu_reads().file());
    const auto [code, out] = mbscope::test::run_command(
        std::string(MBSCOPE_BINARY) + " decode --summary --no-progress '" + path + "' 2>&1");
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(
        out.find("RTU frames over TCP, not Modbus/TCP (a serial gateway): decode with --rtu-over-tcp 502"),
        std::string::npos)
        << out;
    const auto [told, decoded] =
        mbscope::test::run_command(std::string(MBSCOPE_BINARY) +
                                   " decode --summary --no-progress --rtu-over-tcp 502 '" + path + "' 2>&1");
    EXPECT_EQ(told, 0) << decoded;
    EXPECT_NE(decoded.find("10.0.0.2:502 unit 1: 3 requests, 3 responses"), std::string::npos) << decoded;
}

// The same on a port the user gave as Modbus/TCP (--tcp-port), and whatever the MBAP reading of the first
// frame: the MK manual's FC3 example (000:356-370) reads as protocol id 0x0060 at once.
TEST(RtuOnModbusPort, RtuFramesOnATcpPortAreAFindingToo) {
    Conversation c;
    c.server_port = 5020;
    for (int i = 1; i <= 2; ++i) {
        c.send(true, bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45}), std::chrono::seconds(i));
        c.send(false, bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA}),
               std::chrono::seconds(i) + 12ms);
    }
    an::AnalyzerOptions options;
    options.tcp_ports = {5020};
    auto d = decode_pcap(c.file(), options);
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 2u * (8 + 11));
}

TEST(RtuOnModbusPort, TheSameCaptureWithRtuOverTcpDecodesAsBefore) {
    an::AnalyzerOptions options;
    options.rtu_over_tcp_ports = {502};
    auto d = decode_pcap(three_rtu_reads().file(), options);
    EXPECT_FALSE(has_rtu_framing_finding(*d));
    EXPECT_TRUE(d->sink.findings.empty());
    ASSERT_EQ(d->sink.transactions.size(), 3u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.response);
        EXPECT_EQ(t.request.frame.framing, mb::Framing::Rtu);
        EXPECT_EQ(t.request.frame.unit_id(), 1);
    }
    ASSERT_EQ(d->summary.devices.size(), 1u);
    EXPECT_EQ(d->summary.devices.count("10.0.0.2:502 unit 1"), 1u);
    EXPECT_TRUE(d->summary.rtu_over_tcp_connections.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 0u);
}

// A capture begun inside a reply (no SYN, its first bytes the last four of a reply) still tells RTU.
TEST(RtuOnModbusPort, ACaptureBegunInsideAFrameStillTellsRtu) {
    Conversation c;
    c.send(false, {response.end() - 4, response.end()}, 500ms);
    for (int i = 1; i <= 2; ++i) {
        c.send(true, request, std::chrono::seconds(i));
        c.send(false, response, std::chrono::seconds(i) + 20ms);
    }
    auto d = decode_pcap(c.file());
    EXPECT_EQ(d->sink.count(mb::FindingCode::TcpRtuFraming), 1);
    EXPECT_TRUE(d->summary.devices.empty());
    EXPECT_EQ(d->summary.unparsed_bytes, 4u + 2u * (8 + 9));
}

// A Modbus/TCP client whose FC16 requests each end in the CRC-16 of their other bytes (the last register
// written is that CRC, the transaction id's low byte 0x10 and unit 8 making an RTU reading predict FC16 of
// byte count 8, the ADU's 17 bytes): every request reads as an RTU frame whose CRC holds, and as a
// consistent MBAP ADU too. Modbus/TCP it stays, every request decoded. CRCs worked out by hand (SL §6.2.2).
TEST(RtuOnModbusPort, MbapAdusThatEndInAValidCrcAreNotTakenForRtu) {
    const std::vector<std::vector<std::uint8_t>> requests = {
        bytes({0x00, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x00, 0x00, 0x02, 0x04, 0x00, 0x64, 0x17,
               0x14}),
        bytes({0x01, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x02, 0x00, 0x02, 0x04, 0x00, 0x65, 0x16,
               0x36}),
        bytes({0x02, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x04, 0x00, 0x02, 0x04, 0x00, 0x66, 0x15,
               0x50}),
        bytes({0x03, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x06, 0x00, 0x02, 0x04, 0x00, 0x67, 0x14,
               0x72}),
        bytes({0x04, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x08, 0x00, 0x02, 0x04, 0x00, 0x68, 0x12,
               0x5A}),
        bytes({0x05, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x0A, 0x00, 0x02, 0x04, 0x00, 0x69, 0x13,
               0x78}),
        bytes({0x06, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x0C, 0x00, 0x02, 0x04, 0x00, 0x6A, 0x10,
               0x1E}),
        bytes({0x07, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x0E, 0x00, 0x02, 0x04, 0x00, 0x6B, 0x11,
               0x3C}),
        bytes({0x08, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x10, 0x00, 0x02, 0x04, 0x00, 0x6C, 0x1C,
               0x44}),
        bytes({0x09, 0x10, 0x00, 0x00, 0x00, 0x0B, 0x08, 0x10, 0x01, 0x12, 0x00, 0x02, 0x04, 0x00, 0x6D, 0x1D,
               0x66}),
    };
    for (const bool replies : {false, true}) {
        SCOPED_TRACE(replies ? "with the replies" : "requests alone (one direction captured)");
        Conversation c;
        for (std::size_t i = 0; i < requests.size(); ++i) {
            const auto at = std::chrono::milliseconds(100 * static_cast<int>(i + 1));
            c.send(true, requests[i], at);
            if (!replies) continue;
            // The echo of transaction id, unit, function, address and quantity.
            auto reply = std::vector<std::uint8_t>(requests[i].begin(), requests[i].begin() + 12);
            reply[5] = 0x06;
            c.send(false, reply, at + 5ms);
        }
        auto d = decode_pcap(c.file());
        EXPECT_FALSE(has_rtu_framing_finding(*d));
        ASSERT_EQ(d->sink.frames.size(), replies ? 20u : 10u);
        for (const auto& f : d->sink.frames) {
            EXPECT_EQ(f.frame.framing, mb::Framing::Tcp);
            EXPECT_EQ(f.frame.unit_id(), 8);
        }
        EXPECT_EQ(d->sink.frames[0].packet, 1u);
        ASSERT_EQ(d->sink.transactions.size(), 10u);
        for (const auto& t : d->sink.transactions)
            EXPECT_EQ(t.response.has_value(), replies);
        EXPECT_TRUE(d->summary.rtu_over_tcp_connections.empty());
        EXPECT_EQ(d->summary.unparsed_bytes, 0u);
    }
}

// A port nobody named: RTU frames are no Modbus/TCP ADUs to decode with --tcp-port (the requests parse as
// such, see above), but a gateway's port to decode with --rtu-over-tcp.
TEST(RtuOnModbusPort, RtuFramesOnAPortNotDecodedAreHintedAsRtuOverTcp) {
    auto d = decode_pcap(three_rtu_reads(4001).file());
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_TRUE(d->summary.modbus_like_ports.empty());
    EXPECT_EQ(d->summary.rtu_like_ports,
              (std::map<std::pair<bool, std::uint16_t>, std::uint64_t>{{{false, 4001}, 6}}));
    std::ostringstream text;
    an::TextSink(text, true).end(d->summary);
    EXPECT_NE(text.str().find("hint: 6 TCP packets on port 4001 hold RTU frames with valid CRCs, not "
                              "Modbus/TCP: looks like RTU over TCP (a serial gateway); decode them with "
                              "--rtu-over-tcp 4001"),
              std::string::npos)
        << text.str();
    EXPECT_EQ(text.str().find("--tcp-port"), std::string::npos) << text.str();
    const auto json = an::summary_to_json(d->summary);
    EXPECT_EQ(json["rtu_like_ports"][0]["port"], 4001);
    EXPECT_EQ(json["rtu_like_ports"][0]["transport"], "tcp");
}

// One or two RTU frames on a port not named are no hint (a payload of other traffic ends in a valid CRC of
// its other bytes once in 65,536): three in a row are.
TEST(RtuOnModbusPort, FewerThanThreeRtuFramesInARowAreNoHint) {
    Conversation c;
    c.server_port = 4001;
    c.send(true, request, 1s);
    c.send(false, response, 1s + 20ms);
    c.send(true, bytes({'h', 'e', 'l', 'l', 'o'}), 2s);
    c.send(false, response, 2s + 20ms);
    auto d = decode_pcap(c.file());
    EXPECT_TRUE(d->summary.rtu_like_ports.empty());
}

// Every capture bundled with the sources and beside them (../shared/captures) is Modbus/TCP, or RTU over
// UDP, whose datagrams' CRCs tell it: none is taken for RTU over TCP.
TEST(RtuOnModbusPort, NoBundledCaptureIsTakenForRtuOverTcp) {
    const std::string root = MBSCOPE_SOURCE_DIR;
    std::vector<std::string> files;
    for (const std::string& dir : {root + "/captures", root + "/../shared/captures"}) {
        std::vector<std::string> dirs = {dir};
        while (!dirs.empty()) {
            const std::string here = dirs.back();
            dirs.pop_back();
            DIR* d = opendir(here.c_str());
            if (!d) continue;
            while (const dirent* e = readdir(d)) {
                const std::string name = e->d_name;
                if (name == "." || name == "..") continue;
                const std::string path = here + "/" + name;
                if (e->d_type == DT_DIR)
                    dirs.push_back(path);
                else if (name.ends_with(".pcap") || name.ends_with(".pcapng"))
                    files.push_back(path);
            }
            closedir(d);
        }
    }
    ASSERT_GE(files.size(), 18u) << "../shared/captures beside the checkout";
    for (const auto& file : files) {
        SCOPED_TRACE(file);
        const auto [code, out] = mbscope::test::run_command(std::string(MBSCOPE_BINARY) +
                                                            " decode --jsonl --no-progress '" + file + "'");
        EXPECT_NE(out.find("\"type\":\"summary\""), std::string::npos);
        EXPECT_EQ(out.find("tcp.rtu_framing"), std::string::npos);
        EXPECT_EQ(out.find("rtu_over_tcp_connections"), std::string::npos);
        EXPECT_EQ(out.find("rtu_like_ports"), std::string::npos);
        EXPECT_EQ(out.find("rtu_over_tcp\""), std::string::npos);  // no unparsed record of that reason
    }
}

}  // namespace test_analyzer_rtu_on_modbus_port_test
