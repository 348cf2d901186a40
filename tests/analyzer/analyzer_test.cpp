// The analyzer on packets built by the test (raw IPv4 link type): reassembly, pairing and every pairing
// finding, each with a trigger and with its silence on clean traffic.
#include "analyzer/analyzer.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <sstream>

#include "analyzer/packet_parser.hpp"
#include "analyzer/sinks.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_analyzer_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

using mbscope::test::Collect;
using mbscope::test::link_raw;
using mbscope::test::packet;

namespace {

std::vector<std::uint8_t> read_request(std::uint16_t tid, std::uint16_t start = 96, std::uint16_t qty = 3) {
    return mb::encode_tcp(
        tid, 17, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, start, qty)));
}
std::vector<std::uint8_t> read_response(std::uint16_t tid, std::vector<std::uint16_t> values = {555, 0, 100},
                                        std::uint8_t unit = 17) {
    return mb::encode_tcp(
        tid, unit,
        mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, values)));
}

struct Harness {
    Collect sink;
    an::Analyzer analyzer;
    std::uint64_t number = 0;
    std::uint32_t seq[2] = {1000, 5000};
    Harness(an::AnalyzerOptions o = {}) : analyzer(o, sink) {}
    void send(bool to_server, const std::vector<std::uint8_t>& payload, mb::Timestamp t) {
        // Each segment acknowledges everything the other side has sent.
        auto bytes =
            packet(to_server, seq[to_server ? 0 : 1], payload, false, 0x18, 502, seq[to_server ? 1 : 0]);
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
        raw(bytes, t);
    }
    void raw(const std::vector<std::uint8_t>& bytes, mb::Timestamp t, std::uint32_t original_length = 0) {
        an::Packet p;
        p.number = ++number;
        p.time = t;
        p.linktype = link_raw;
        p.data = bytes;
        p.original_length = std::max(original_length, static_cast<std::uint32_t>(bytes.size()));
        analyzer.packet("test", p);
    }
    // The connection opened in the capture (SYN, SYN-ACK): its streams are in step from their first byte,
    // where a capture begun mid-connection judges its first header before taking it (a malformed first ADU
    // is indistinguishable from the tail of one sent before the capture began).
    void open(mb::Timestamp t) {
        raw(packet(true, seq[0] - 1, {}, false, 0x02, 502, 0), t);
        raw(packet(false, seq[1] - 1, {}, false, 0x12, 502, seq[0]), t);
    }
    // `payload` sent, and not captured (the tap lost it): the sender's next bytes come after it.
    void lose(bool to_server, const std::vector<std::uint8_t>& payload) {
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
    }
    // A copy of what was sent from sequence number `at` (a retransmission, a second tap's copy).
    void resend(bool to_server, const std::vector<std::uint8_t>& payload, std::uint32_t at, mb::Timestamp t) {
        raw(packet(to_server, at, payload, false, 0x18, 502, seq[to_server ? 1 : 0]), t);
    }
    // As send, the record cut to the snapshot length: only the payload's first `kept` bytes captured.
    void send_cut(bool to_server, const std::vector<std::uint8_t>& payload, std::size_t kept,
                  mb::Timestamp t) {
        auto bytes =
            packet(to_server, seq[to_server ? 0 : 1], payload, false, 0x18, 502, seq[to_server ? 1 : 0]);
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
        const auto whole = static_cast<std::uint32_t>(bytes.size());
        bytes.resize(bytes.size() - (payload.size() - kept));
        raw(bytes, t, whole);
    }
};

}  // namespace

TEST(PacketParser, EthernetVlanAndTcp) {
    auto ip = packet(true, 7, {1, 2, 3});
    std::vector<std::uint8_t> eth(12, 0xAA);
    eth.insert(eth.end(), {0x81, 0x00, 0x00, 0x05, 0x08, 0x00});  // one 802.1Q tag
    eth.insert(eth.end(), ip.begin(), ip.end());
    an::L4Packet l4;
    ASSERT_EQ(an::parse_packet(1, eth, l4), an::ParseStatus::Ok);
    EXPECT_EQ(l4.destination.port, 502);
    EXPECT_EQ(l4.seq, 7u);
    EXPECT_EQ(l4.payload.size(), 3u);
    EXPECT_EQ(l4.source.to_string(), "10.0.0.1:40000");
    EXPECT_EQ(an::parse_packet(1, std::span(eth).first(20), l4), an::ParseStatus::Malformed);
    EXPECT_EQ(an::parse_packet(147, eth, l4), an::ParseStatus::UnsupportedLink);
}

namespace {

// Wrappers a mirrored packet travels in, built by hand from their RFCs and Cisco's ERSPAN draft.
std::vector<std::uint8_t> with(std::vector<std::uint8_t> head, const std::vector<std::uint8_t>& rest) {
    head.insert(head.end(), rest.begin(), rest.end());
    return head;
}
std::vector<std::uint8_t> ethernet_of(std::uint16_t type, const std::vector<std::uint8_t>& payload) {
    return with({0, 0x11, 0x22, 0x33, 0x44, 0x55, 0, 0x66, 0x77, 0x88, 0x99, 0xAA, std::uint8_t(type >> 8),
                 std::uint8_t(type)},
                payload);
}
// An outer IPv4 header from 192.168.1.1 to 192.168.1.2 carrying `protocol`.
std::vector<std::uint8_t> outer_ip(std::uint8_t protocol, const std::vector<std::uint8_t>& payload) {
    const auto total = static_cast<std::uint16_t>(20 + payload.size());
    return with({0x45,
                 0,
                 std::uint8_t(total >> 8),
                 std::uint8_t(total),
                 0,
                 1,
                 0,
                 0,
                 64,
                 protocol,
                 0,
                 0,
                 192,
                 168,
                 1,
                 1,
                 192,
                 168,
                 1,
                 2},
                payload);
}
std::vector<std::uint8_t> mpls_label(std::uint32_t label, bool bottom) {
    const std::uint32_t word = label << 12 | (bottom ? 0x100u : 0u) | 64u;
    return {std::uint8_t(word >> 24), std::uint8_t(word >> 16), std::uint8_t(word >> 8), std::uint8_t(word)};
}

}  // namespace

// MPLS, GRE (IP, transparent Ethernet bridging, ERSPAN I, II and III), VXLAN and IP in IP carry mirrored
// traffic to a remote analyzer. Their packets decoded to nothing, without a word.
TEST(PacketParser, TunnelsAreDecodedToThePacketInside) {
    const auto ip = packet(true, 7, {1, 2, 3});
    const auto frame = ethernet_of(0x0800, ip);
    const std::vector<std::uint8_t> no_sequence = {}, sequence = {0, 0, 0, 9};
    const auto erspan3 = [&](bool subheader) {
        auto h =
            std::vector<std::uint8_t>{0x20, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, std::uint8_t(subheader ? 1 : 0)};
        if (subheader) h.resize(20, 0xAB);
        return with(h, frame);
    };
    const struct {
        const char* name;
        int link;
        std::vector<std::uint8_t> bytes;
    } cases[] = {
        {"MPLS, two labels", 1,
         ethernet_of(0x8847, with(with(mpls_label(100, false), mpls_label(200, true)), ip))},
        {"Ethernet over MPLS", 1,
         ethernet_of(0x8847, with(with(mpls_label(300, true), {0, 0, 0, 0}), frame))},
        {"GRE, IP", 101, outer_ip(47, with({0, 0, 0x08, 0x00}, ip))},
        {"GRE, Ethernet, key and sequence", 1,
         ethernet_of(0x0800, outer_ip(47, with({0x30, 0, 0x65, 0x58, 0, 0, 0, 5, 0, 0, 0, 1}, frame)))},
        {"GRE, checksum", 101, outer_ip(47, with({0x80, 0, 0x08, 0x00, 0x12, 0x34, 0, 0}, ip))},
        {"ERSPAN I", 101, outer_ip(47, with({0, 0, 0x88, 0xBE}, frame))},
        {"ERSPAN II", 101,
         outer_ip(47, with(with({0x10, 0, 0x88, 0xBE, 0, 0, 0, 9}, {0x10, 0, 0, 1, 0, 0, 0, 0}), frame))},
        {"ERSPAN III", 101, outer_ip(47, with({0x10, 0, 0x22, 0xEB, 0, 0, 0, 9}, erspan3(false)))},
        {"ERSPAN III, platform subheader", 101,
         outer_ip(47, with({0x10, 0, 0x22, 0xEB, 0, 0, 0, 9}, erspan3(true)))},
        {"VXLAN", 101,
         outer_ip(17, with({0xC0, 0x00, 0x12, 0xB5, 0, std::uint8_t(16 + frame.size()), 0, 0, 0x08, 0, 0, 0,
                            0, 0, 0x2A, 0},
                           frame))},
        {"IP in IP", 101, outer_ip(4, ip)},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        an::L4Packet l4;
        ASSERT_EQ(an::parse_packet(c.link, c.bytes, l4), an::ParseStatus::Ok);
        EXPECT_EQ(l4.source.to_string(), "10.0.0.1:40000");
        EXPECT_EQ(l4.destination.to_string(), "10.0.0.2:502");
        EXPECT_EQ(l4.seq, 7u);
        EXPECT_EQ(std::vector<std::uint8_t>(l4.payload.begin(), l4.payload.end()),
                  (std::vector<std::uint8_t>{1, 2, 3}));
        // Every shorter copy (a snap length, a damaged packet) parses within its bytes (AddressSanitizer
        // watches), never to the whole inner packet (a cut VXLAN datagram is the outer one to port 4789).
        for (std::size_t n = 0; n < c.bytes.size() - 3; ++n) {
            const std::vector<std::uint8_t> cut(c.bytes.begin(), c.bytes.begin() + static_cast<long>(n));
            an::L4Packet part;
            if (an::parse_packet(c.link, cut, part) == an::ParseStatus::Ok && part.destination.port == 502) {
                EXPECT_LT(part.payload.size(), 3u) << n;
            }
        }
    }
    // PPTP's GRE (version 1) carries PPP, not a mirrored frame; tunnels nest eight deep at most.
    an::L4Packet l4;
    EXPECT_EQ(
        an::parse_packet(101, outer_ip(47, with({0x30, 0x01, 0x88, 0x0B, 0, 0, 0, 0, 0, 0, 0, 0}, ip)), l4),
        an::ParseStatus::NotIp);
    auto nested = ip;
    for (int i = 0; i < 20; ++i)
        nested = outer_ip(47, with({0, 0, 0x08, 0x00}, nested));
    EXPECT_EQ(an::parse_packet(101, nested, l4), an::ParseStatus::Malformed);
}

// The same tunnels around a whole conversation, decoded by mbscope and by tshark, a decoder nobody here
// wrote: the same ADUs (transaction ids in order), each transaction paired.
TEST(Analyzer, TunnelledConversationsDecodeAsTsharkDecodesThem) {
    if (!mbscope::test::have("tshark")) GTEST_SKIP() << "tshark not installed";
    mbscope::test::Conversation c;
    for (std::uint16_t t = 1; t <= 3; ++t) {
        c.send(true, read_request(t), std::chrono::seconds(t));
        c.send(false, read_response(t), std::chrono::seconds(t) + 2ms);
    }
    const std::vector<std::pair<const char*, std::function<std::vector<std::uint8_t>(const std::vector<std::uint8_t>&)>>>
        tunnels = {
            {"mpls", [](const auto& ip) { return ethernet_of(0x8847, with(mpls_label(16, true), ip)); }},
            {"gre", [](const auto& ip) {
                 return ethernet_of(0x0800, outer_ip(47, with({0x20, 0, 0x65, 0x58, 0, 0, 0, 7}, ethernet_of(0x0800, ip))));
             }},
            {"erspan2", [](const auto& ip) {
                 return ethernet_of(0x0800, outer_ip(47, with(with({0x10, 0, 0x88, 0xBE, 0, 0, 0, 1}, {0x10, 0, 0, 1, 0, 0, 0, 0}),
                                                              ethernet_of(0x0800, ip))));
             }},
            {"vxlan", [](const auto& ip) {
                 const auto inner = ethernet_of(0x0800, ip);
                 return ethernet_of(0x0800, outer_ip(17, with({0xC0, 0x00, 0x12, 0xB5, 0, std::uint8_t(16 + inner.size()), 0, 0,
                                                               0x08, 0, 0, 0, 0, 0, 0x2A, 0},
                                                              inner)));
             }},
            {"geneve", [](const auto& ip) {
                 const auto inner = ethernet_of(0x0800, ip);
                 return ethernet_of(0x0800, outer_ip(17, with({0xC0, 0x00, 0x17, 0xC1, 0, std::uint8_t(16 + inner.size()), 0, 0,
                                                               0x00, 0, 0x65, 0x58, 0, 0, 0x2A, 0},
                                                              inner)));
             }},
            {"pppoe", [](const auto& ip) {
                 return ethernet_of(0x8864, with({0x11, 0, 0x12, 0x34, 0, std::uint8_t(2 + ip.size()), 0x00, 0x21}, ip));
             }},
        };
    for (const auto& [name, wrap] : tunnels) {
        SCOPED_TRACE(name);
        std::vector<mbscope::test::PcapRecord> wrapped;
        for (const auto& r : c.records)
            wrapped.push_back({r.time, wrap(r.data)});
        const auto file = mbscope::test::pcap_file(1, wrapped);
        const auto d = mbscope::test::decode_pcap(file);
        EXPECT_EQ(d->sink.transactions.size(), 3u);
        EXPECT_TRUE(d->sink.findings.empty());
        std::string ours;
        for (const auto& f : d->sink.frames)
            ours += std::to_string(f.frame.transaction_id()) + "\n";
        const auto path = mbscope::test::write_temp(std::string("tunnel_") + name + ".pcap", file);
        EXPECT_EQ(
            mbscope::test::run("tshark -r '" + path + "' -Y mbtcp -T fields -e mbtcp.trans_id 2>/dev/null"),
            ours);
        EXPECT_EQ(ours, "1\n1\n2\n2\n3\n3\n");
    }
}

// Packets whose headers are damaged (an IPv4 header length under 20 bytes, a TCP data offset under 20 bytes,
// a packet shorter than an IPv4 header) were dropped without a word: whatever Modbus they held was gone from
// the report. They are counted in the summary, in text and JSON; packets that are not IP are not.
TEST(Analyzer, PacketsWithDamagedHeadersAreCounted) {
    Harness h;
    auto ihl = packet(true, 1000, read_request(1));
    ihl[0] = 0x44;
    auto offset = packet(true, 1000, read_request(1));
    offset[20 + 12] = 0x30;
    h.raw(ihl, 1s);
    h.raw(offset, 1s);
    h.raw({0x45, 0, 0, 40, 0, 1}, 1s);
    h.raw({0x00, 0x01, 0x08, 0x00}, 1s);  // not IP at all: not counted
    h.send(true, read_request(1), 2s);
    h.send(false, read_response(1), 2s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.analyzer.summary().packets_malformed, 3u);
    EXPECT_EQ(h.sink.transactions.size(), 1u);
    std::ostringstream text;
    an::TextSink(text, true).end(h.analyzer.summary());
    EXPECT_NE(
        text.str().find("not decoded: 3 packets whose link, IP or TCP/UDP header is damaged or cut short"),
        std::string::npos)
        << text.str();
    EXPECT_EQ(an::summary_to_json(h.analyzer.summary())["packets_malformed"], 3);
}

// Modbus/TCP Security runs TLS on port 802: a capture of it decoded to "0 frames" with no word, as a quiet
// line would. Its packets with data are counted and said to be encrypted (not taken for a port to decode).
TEST(Analyzer, ModbusSecurityTrafficIsSaidToBeEncrypted) {
    Harness h;
    const auto hello = mbscope::test::bytes({0x16, 0x03, 0x03, 0x00, 0x05, 0x01, 0x00, 0x00, 0x01, 0x00});
    h.raw(packet(true, 1000, hello, false, 0x18, 802), 1s);
    h.raw(packet(false, 5000, hello, false, 0x18, 802), 1s + 1ms);
    h.raw(packet(true, 1010, {}, false, 0x10, 802), 1s + 2ms);  // an acknowledgement: no data, not counted
    h.analyzer.finish();
    EXPECT_EQ(h.analyzer.summary().modbus_security_packets, 2u);
    EXPECT_TRUE(h.analyzer.summary().modbus_like_ports.empty());
    std::ostringstream text;
    an::TextSink(text, true).end(h.analyzer.summary());
    EXPECT_NE(text.str().find("not decoded: 2 packets on TCP port 802, Modbus/TCP Security: TLS, encrypted"),
              std::string::npos)
        << text.str();
    EXPECT_EQ(an::summary_to_json(h.analyzer.summary())["modbus_security_packets"], 2);
}

// A capture of a link type mbscope does not read (here 802.11) decoded to nothing and exit 0, as a quiet
// line would. It is an input error naming the file and the link type, said once.
TEST(Analyzer, ALinkTypeNotDecodedIsNamed) {
    mbscope::test::Conversation c;
    c.send(true, read_request(1), 1s);
    c.send(false, read_response(1), 1s + 1ms);
    const auto d = mbscope::test::decode_pcap(mbscope::test::pcap_file(105, c.records));
    EXPECT_EQ(d->summary.packets, 2u);
    ASSERT_EQ(d->summary.input_errors.size(), 1u);
    EXPECT_NE(d->summary.input_errors[0].find(": link type 105 is not one mbscope decodes"),
              std::string::npos)
        << d->summary.input_errors[0];
}

TEST(Analyzer, CleanExchangeIsPairedWithLatencyAndNoFinding) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(false, read_response(1), 1s + 2ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_EQ(*h.sink.transactions[0].latency, 2ms);
    EXPECT_TRUE(h.sink.findings.empty());
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").responses, 1u);
}

TEST(Analyzer, AduSplitOverSegmentsAndSeveralPerSegment) {
    Harness h;
    auto a = read_request(1), b = read_request(2);
    std::vector<std::uint8_t> both = a;
    both.insert(both.end(), b.begin(), b.end());
    h.send(true, {both.begin(), both.begin() + 3}, 1s);  // first segment under 8 bytes
    h.send(true, {both.begin() + 3, both.end()}, 1s);
    h.send(false, read_response(1), 1s + 1ms);
    h.send(false, read_response(2), 1s + 2ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.transactions.size(), 2u);
    EXPECT_TRUE(h.sink.findings.empty());
}

// A client using TCP Fast Open sends its first request on the SYN: the request was dropped without a word,
// and its response reported unsolicited.
TEST(Analyzer, ARequestOnASynIsDecoded) {
    Harness h;
    const auto a = read_request(1);
    h.raw(packet(true, 999, a, false, 0x02), 1s);  // SYN with the request: it starts at 1000
    h.seq[0] = 1000 + static_cast<std::uint32_t>(a.size());
    h.send(false, read_response(1), 1s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_TRUE(h.sink.findings.empty());
}

TEST(Analyzer, OutOfOrderAndRetransmittedSegmentsAreReassembled) {
    Harness h;
    auto a = read_request(1);
    h.raw(packet(true, 999, {}, false, 0x02), 1s);                // SYN: the stream starts at 1000
    h.raw(packet(true, 1000 + 5, {a.begin() + 5, a.end()}), 1s);  // second half first
    h.raw(packet(true, 1000, {a.begin(), a.begin() + 5}), 1s);
    h.raw(packet(true, 1000, a), 1s);  // retransmission of everything
    h.seq[0] += static_cast<std::uint32_t>(a.size());
    h.send(false, read_response(1), 1s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.frames.size(), 2u);
    EXPECT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_TRUE(h.sink.findings.empty());
}

TEST(Analyzer, MissingSegmentIsAGapOfKnownSize) {
    Harness h;
    auto a = read_request(1), b = read_request(2), c = read_request(3);
    h.send(true, a, 1s);
    h.lose(true, b);  // b never captured
    h.send(true, c, 1s + 1ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::StreamGap) {
            EXPECT_NE(f.message.find("12 bytes"), std::string::npos) << f.message;
        }
    }
    EXPECT_EQ(h.sink.frames.size(), 2u);
}

// A polling master whose request 2 and response 5 the tap lost (a mirror port drops packets under load).
// The peer's acknowledgement past each hole gives it up once the direction's next segment lies past it:
// before, the reassembler waited for the lost bytes until the end of the capture, and every later request
// went unanswered while its response was unsolicited.
TEST(Analyzer, ALostSegmentCostsOneTransactionNotTheRestOfTheCapture) {
    Harness h;
    for (std::uint16_t i = 1; i <= 10; ++i) {
        const auto t = std::chrono::seconds(i);
        if (i == 2)
            h.lose(true, read_request(i));
        else
            h.send(true, read_request(i), t);
        if (i == 5)
            h.lose(false, read_response(i));
        else
            h.send(false, read_response(i), t + 2ms);
    }
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 2);
    // Response 2: the server acknowledged request 2's bytes, which the capture lacks: not unsolicited.
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 1);
    // Request 5: its reply may be in the hole the client acknowledged, so it is no timeout of the device's.
    EXPECT_EQ(
        h.sink.count(mb::FindingCode::PairNoResponse) + h.sink.count(mb::FindingCode::PairNoResponseAtEnd),
        0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.requests, 9u);
    EXPECT_EQ(device.responses, 8u);  // response 2 answers no request seen
    std::size_t answered = 0;
    for (const auto& t : h.sink.transactions) {
        if (t.response) {
            ++answered;
            EXPECT_EQ(*t.latency, 2ms);  // each delivered at its own packet's time
        }
    }
    EXPECT_EQ(answered, 8u);
}

// The capture began mid-connection and its first request segment overtook the one before it: those bytes
// cannot be decoded before what was already, and are reported as unparsed instead of vanishing.
TEST(Analyzer, BytesBeforeAMidStreamCapturesFirstAreReportedUnparsed) {
    Harness h;
    const auto a = read_request(1), b = read_request(2);
    h.raw(packet(true, 1000 + static_cast<std::uint32_t>(a.size()), b), 1s);  // no SYN: b is seen first
    h.raw(packet(true, 1000, a), 1s + 1ms);
    h.seq[0] = 1000 + static_cast<std::uint32_t>(a.size() + b.size());
    h.send(false, read_response(2), 1s + 3ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, a.size());
    EXPECT_EQ(h.sink.unparsed_records[0].reason, mb::UnparsedReason::BeforeStreamStart);
    EXPECT_EQ(h.sink.unparsed_records[0].packet, 2u);  // the packet that carried them
    EXPECT_EQ(h.analyzer.summary().unparsed_bytes, a.size());
    ASSERT_EQ(h.sink.count(mb::FindingCode::StreamUnparsedBytes), 1);
    EXPECT_EQ(h.sink.transactions.size(), 1u);
}

// Bytes that form no frame are reported when the next frame (or the end) shows where they stop, often a
// later packet: the record and its finding name the packet that carried their first byte and its time.
// Before, they named the packet being read then, seconds later, even one of another connection.
TEST(Analyzer, UnparsedBytesAreReportedAtThePacketThatCarriedThem) {
    Harness h;
    h.open(0s);  // packets 1 and 2: the stream is in step from its first byte
    auto bad = read_request(1);
    bad[4] = 0;
    bad[5] = 0;                                  // MBAP length 0
    h.send(true, bad, 1s);                       // packet 3
    h.send(true, {0xDE, 0xAD, 0xBE, 0xEF}, 2s);  // packet 4: more garbage
    h.send(true, read_request(2), 5s);           // packet 5
    h.send(false, read_response(2), 5s + 10ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, bad.size() + 4);
    EXPECT_EQ(h.sink.unparsed_records[0].packet, 3u);
    EXPECT_EQ(h.sink.unparsed_records[0].time, mb::Timestamp(1s));
    ASSERT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 1);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::TcpLengthInvalid) {
            EXPECT_EQ(f.packet, 3u);
            EXPECT_EQ(f.time, mb::Timestamp(1s));
        }
    EXPECT_EQ(h.sink.transactions.size(), 1u);
}

TEST(Analyzer, NoResponseWithinTimeout) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(true, read_request(2), 5s);  // 4 s later: the first has timed out (3 s)
    h.send(false, read_response(2), 5s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 1u);
}

// A reply after its request's timeout (mb2.pcap: a server that acknowledged nothing for three seconds, then
// answered five requests at once) was "unsolicited", or, with one other request outstanding, a transaction-id
// mismatch with that one. It is late, naming the request it answers; the other request is answered as usual.
// A second copy is unsolicited, and a transaction id used again belongs to its new request.
TEST(Analyzer, AReplyAfterItsRequestTimedOutIsLate) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(true, read_request(2), 4500ms);  // request 1 timed out at 4 s
    h.send(false, read_response(1), 5s);
    h.send(false, read_response(2), 5s + 1ms);
    h.send(false, read_response(1), 5s + 2ms);
    h.send(true, read_request(3), 6s);
    h.send(true, read_request(3), 10s);  // the first 3 timed out at 9 s; its id used again
    h.send(false, read_response(3), 10s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 2);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdMismatch), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairLateResponse) {
            EXPECT_EQ(
                f.message,
                "the reply to frame 1 (FC3 Read Holding Registers 96+3) came 4000 ms after it, past the "
                "3000 ms timeout: the request was reported unanswered");
            EXPECT_EQ(f.frames, (std::vector<std::uint64_t>{1, 3}));
            EXPECT_EQ(mb::info(f.code).severity, mb::Severity::Warning);
        }
    std::size_t answered = 0, late = 0;
    for (const auto& t : h.sink.transactions) {
        answered += t.response.has_value() && !t.late_past;
        if (!t.late_past) continue;
        // The late reply is paired with its request in a transaction of its own, after the timed-out one.
        ++late;
        EXPECT_EQ(t.request.index, 1u);
        ASSERT_TRUE(t.response);
        EXPECT_EQ(t.response->index, 3u);
        EXPECT_EQ(*t.late_past, 3s);
        EXPECT_EQ(t.latency, 4s);
        EXPECT_FALSE(t.timed_out);
        EXPECT_EQ(t.findings, std::vector<mb::FindingCode>{mb::FindingCode::PairLateResponse});
    }
    EXPECT_EQ(answered, 2u);  // requests 2 and the second 3
    EXPECT_EQ(late, 1u);
    // Counted once: request 1 is a timeout and a transaction; its reply is neither a response in time nor
    // another transaction.
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.requests, 4u);
    EXPECT_EQ(device.timeouts, 2u);
    EXPECT_EQ(device.late_responses, 1u);
    EXPECT_EQ(device.responses, 2u);
    EXPECT_EQ(device.latency.max(), 4s);
    EXPECT_EQ(h.analyzer.summary().transactions, 4u);
}

// A finding about a write named the function alone ("FC6 Write Single Register got no response"): which
// register, which value, which range (and for FC43 and FC24 what they read) is what the engineer looks for
// in the device's manual.
TEST(Analyzer, FindingsNameWhatAWriteAsked) {
    Harness h;
    const std::uint16_t values[] = {1, 2};
    const bool coils[] = {true, false, true};
    const auto adu = [](std::uint16_t tid, const mb::Pdu& pdu) {
        return mb::encode_tcp(tid, 17, mb::encode_pdu(pdu));
    };
    h.send(true, adu(1, mb::make_write_single_register(23, 250)), 1s);
    h.send(true, adu(2, mb::make_write_single_coil(7, true)), 1s);
    h.send(true, adu(3, mb::make_write_multiple_registers(96, values)), 1s);
    h.send(true, adu(4, mb::make_write_multiple_coils(10, coils)), 1s);
    h.send(false, mb::encode_tcp(4, 17, mb::encode_pdu(mb::make_exception(15, 2))), 1s + 1ms);
    h.send(true, adu(5, mb::make_read_device_id(1, 0)), 1s);
    h.send(true, adu(6, mb::make_read_fifo_queue(4)), 1s);
    h.analyzer.finish();
    std::vector<std::string> messages;
    for (const auto& f : h.sink.findings)
        messages.push_back(f.message);
    const std::vector<std::string> expected = {
        "exception 2 (Illegal Data Address) to FC15 Write Multiple Coils 10+3",
        "FC6 Write Single Register 23 = 250 unanswered when the capture ended",
        "FC5 Write Single Coil 7 = ON unanswered when the capture ended",
        "FC16 Write Multiple Registers 96+2 unanswered when the capture ended",
        "FC43 Encapsulated Interface Transport, read device identification code 1 object 0 unanswered when "
        "the capture ended",
        "FC24 Read FIFO Queue 4 unanswered when the capture ended",
    };
    EXPECT_EQ(messages, expected);
}

// The summary's functions per device counted decoded requests only: a device asked twice with a malformed
// FC43 request listed "2 requests" and no function.
TEST(Analyzer, ARequestThatCannotBeDecodedIsCountedByItsFunctionCode) {
    Harness h;
    const std::vector<std::uint8_t> too_long = {43, 14, 1, 0,
                                                0xFF};  // read device identification, a byte more
    h.send(true, mb::encode_tcp(1, 17, too_long), 1s);
    h.send(true, read_request(2), 2s);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PduMalformed), 1);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.functions, (std::map<int, std::uint64_t>{{3, 1}, {43, 1}}));
}

// Behind a gateway several devices share one TCP link: a finding line of the text output named the link
// alone ("10.0.0.1:40000 -> 10.0.0.2:502: exception 11 ..."), so which unit the gateway failed to reach was
// left to the transaction line before it. It names the unit, unless its message names the device already.
TEST(Analyzer, AFindingLineNamesTheUnit) {
    Harness h;
    const auto read = mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 2));
    h.send(true, mb::encode_tcp(1, 5, read), 1s);
    h.send(false, mb::encode_tcp(1, 5, mb::encode_pdu(mb::make_exception(3, 0x0B))), 1s + 500ms);
    h.send(true, mb::encode_tcp(2, 6, read), 2s);
    h.send(true, mb::encode_tcp(3, 5, read), 6s);  // past unit 6's timeout
    h.analyzer.finish();
    std::ostringstream text;
    an::TextSink sink(text);
    for (const auto& f : h.sink.findings)
        sink.finding(f);
    const std::string out = text.str();
    EXPECT_NE(out.find("! pair.gateway_target_no_response (error) 10.0.0.1:40000 -> 10.0.0.2:502 unit 5: "
                       "exception 11"),
              std::string::npos)
        << out;
    // The message of a request left unanswered names its device: the line does not say it twice.
    EXPECT_NE(
        out.find("10.0.0.1:40000 -> 10.0.0.2:502: FC3 Read Holding Registers 0+2 to 10.0.0.2:502 unit 6 "
                 "got no response"),
        std::string::npos)
        << out;
    EXPECT_NE(out.find("10.0.0.1:40000 -> 10.0.0.2:502 unit 5: FC3 Read Holding Registers 0+2 unanswered"),
              std::string::npos)
        << out;
}

// "4 exceptions" said that a device refused, not what: the codes tell an address the map lacks (2) from a
// device failure (4) or a gateway that could not reach the device behind it (11). Counted by code, in time
// only (as `exceptions`: a late one is among the timeouts).
TEST(Analyzer, ADevicesExceptionsAreCountedByCode) {
    Harness h;
    const auto exception = [](std::uint16_t tid, std::uint8_t code) {
        return mb::encode_tcp(tid, 17, mb::encode_pdu(mb::make_exception(3, code)));
    };
    h.send(true, read_request(1), 1s);
    h.send(false, exception(1, 11), 1s + 10ms);
    h.send(true, read_request(2), 2s);
    h.send(false, exception(2, 2), 2s + 10ms);
    h.send(true, read_request(3), 3s);
    h.send(false, exception(3, 11), 3s + 10ms);
    h.send(true, read_request(4), 4s);
    h.send(false, exception(4, 4), 9s);  // late
    h.analyzer.finish();
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.exceptions, 3u);
    EXPECT_EQ(device.exception_codes, (std::map<int, std::uint64_t>{{2, 1}, {11, 2}}));
    std::ostringstream text;
    an::TextSink(text, true).end(h.analyzer.summary());
    EXPECT_NE(
        text.str().find("\n    exceptions: 2 Illegal Data Address×1, 11 Gateway Target Device Failed to "
                        "Respond×2\n"),
        std::string::npos)
        << text.str();
    const auto json = an::summary_to_json(h.analyzer.summary())["devices"]["10.0.0.2:502 unit 17"];
    EXPECT_EQ(json["exception_codes"], (nlohmann::json{{"2", 1}, {"11", 2}}));
}

// An exception reply with a byte after its code ("83 06 00", as one device in suricata-verify's modbus.pcap
// sends) is malformed, and still the device's exception 6: counted, named in the transaction and its JSON
// record, as tshark reads it. Before, the code was lost with the PDU and the device had "0 exceptions".
TEST(Analyzer, AnExceptionWithATrailingByteStillCarriesItsCode) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(false, {0x00, 0x01, 0x00, 0x00, 0x00, 0x04, 17, 0x83, 0x06, 0x00}, 1s + 10ms);
    h.analyzer.finish();
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.exceptions, 1u);
    EXPECT_EQ(device.exception_codes, (std::map<int, std::uint64_t>{{6, 1}}));
    EXPECT_EQ(h.sink.count(mb::FindingCode::PduMalformed), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairExceptionResponse), 1);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    const auto& t = h.sink.transactions[0];
    ASSERT_TRUE(t.response.has_value());
    EXPECT_EQ(an::exception_code_of(*t.response), std::optional<std::uint8_t>(6));
    EXPECT_EQ(an::transaction_to_json(t)["exception_code"], 6);
    std::ostringstream text;
    an::TextSink(text).transaction(t);
    EXPECT_NE(text.str().find("-> FC3 exception 6 Server Device Busy, undecodable PDU (trailing bytes"),
              std::string::npos)
        << text.str();
}

// A gateway's exceptions 10 (no path to the unit) and 11 (the unit did not respond) say that the request
// reached no answer: errors, as the unit's timeout is on a line the master drives itself, where before they
// were warnings like any exception and a capture of a gateway that never reached its unit exited 0. An
// exception the device itself answers (2: an address its map lacks) stays a warning.
TEST(Analyzer, AGatewaysExceptionsAreErrors) {
    Harness h;
    const auto exception = [](std::uint16_t tid, std::uint8_t code) {
        return mb::encode_tcp(tid, 17, mb::encode_pdu(mb::make_exception(3, code)));
    };
    const std::pair<std::uint8_t, mb::FindingCode> cases[] = {
        {10, mb::FindingCode::PairGatewayPathUnavailable},
        {11, mb::FindingCode::PairGatewayTargetNoResponse},
        {2, mb::FindingCode::PairExceptionResponse}};
    std::uint16_t tid = 0;
    for (const auto& [code, finding] : cases) {
        ++tid;
        h.send(true, read_request(tid), std::chrono::seconds(tid));
        h.send(false, exception(tid, code), std::chrono::seconds(tid) + 10ms);
    }
    h.analyzer.finish();
    for (const auto& [code, finding] : cases) {
        SCOPED_TRACE(int{code});
        EXPECT_EQ(h.sink.count(finding), 1);
        EXPECT_EQ(mb::info(finding).severity, code == 2 ? mb::Severity::Warning : mb::Severity::Error);
    }
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").exceptions, 3u);  // still exceptions
    // What `mbscope decode` exits with for a capture whose one fault is that exception.
    for (const auto& [code, finding] : cases) {
        mbscope::test::Conversation c;
        c.send(true, read_request(1), 1s);
        c.send(false, exception(1, code), 1s + 10ms);
        const auto path = mbscope::test::write_temp(
            "analyzer_gateway_exception_" + std::to_string(code) + ".pcap", c.file());
        const int status = std::system(
            (std::string(MBSCOPE_BINARY) + " decode --summary '" + path + "' >/dev/null").c_str());
        EXPECT_EQ(WEXITSTATUS(status), code == 2 ? 0 : 1) << "exception " << int{code};
    }
}

// A late exception is what the device answered, and is judged as one; the device's counts keep it among
// the timeouts, not the exceptions of its responses (which it would outnumber).
TEST(Analyzer, ALateExceptionIsAmongTheTimeouts) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(false, mb::encode_tcp(1, 17, mb::encode_pdu(mb::make_exception(3, 2))), 5s);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairExceptionResponse), 1);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.timeouts, 1u);
    EXPECT_EQ(device.late_responses, 1u);
    EXPECT_EQ(device.responses, 0u);
    EXPECT_EQ(device.exceptions, 0u);
}

// Quiet time in a live capture (Analyzer::idle): a silence ends the frame in progress, a request whose
// timeout ran out is unanswered, and the output is flushed; a time already passed changes nothing.
TEST(Analyzer, QuietTimeEndsFramesAndTimesOutRequests) {
    struct Flushes : Collect {
        int flushes = 0;
        void flush() override { ++flushes; }
    };
    Flushes sink;
    an::AnalyzerOptions o;
    o.serial_framing = mb::Framing::Rtu;
    an::Analyzer a(o, sink);
    const auto request = mbscope::test::bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    a.serial("line", request, 10s);
    EXPECT_TRUE(sink.frames.empty());  // a frame ends with t3.5 of silence (4 ms at 9600 baud)
    a.idle(10s + 2ms);
    EXPECT_TRUE(sink.frames.empty());
    a.idle(10s + 5ms);
    ASSERT_EQ(sink.frames.size(), 1u);
    EXPECT_EQ(sink.frames[0].time, 10s);
    a.idle(10s + 900ms);
    EXPECT_EQ(sink.count(mb::FindingCode::PairNoResponse), 0);
    a.idle(11s + 100ms);
    EXPECT_EQ(sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(sink.flushes, 4);
    a.idle(11s);  // earlier than the last: only flushed
    EXPECT_EQ(sink.flushes, 5);

    // Modbus/TCP: the request times out by quiet time alone, as by the next packet's time.
    Harness h;
    h.send(true, read_request(1), 1s);
    h.analyzer.idle(3900ms);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    h.analyzer.idle(4100ms);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
}

// Quiet time in a live capture gives up the head of a frame a silence of t3.5 cut (a reply a USB adapter
// delivered in two reads) no sooner than the deframer would: the tail read 14 ms later still completes it,
// one reply whose CRC holds, paired; a head no tail follows comes out, a reply whose CRC fails, once 100 ms
// of silence have passed.
TEST(Analyzer, QuietTimeWaitsForTheTailOfAFrameASilenceCut) {
    Collect sink;
    an::AnalyzerOptions o;
    o.serial_framing = mb::Framing::Rtu;
    an::Analyzer a(o, sink);
    const auto request = mbscope::test::bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    const auto head = mbscope::test::bytes({0x11, 0x03, 0x06, 0x02, 0x2B});
    const auto tail = mbscope::test::bytes({0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
    a.serial("line", request, 10s);
    a.idle(10s + 5ms);
    ASSERT_EQ(sink.frames.size(), 1u);
    a.serial("line", head, 10s + 20ms);
    a.idle(10s + 30ms);  // t3.5 has passed: the head waits for its tail
    EXPECT_EQ(sink.frames.size(), 1u);
    a.serial("line", tail, 10s + 40ms);
    a.idle(10s + 50ms);
    ASSERT_EQ(sink.frames.size(), 2u);
    EXPECT_TRUE(sink.frames[1].frame.checksum_ok);
    EXPECT_EQ(sink.frames[1].frame.wire_length, 11u);
    EXPECT_TRUE(sink.frames[1].frame.gap_at_t3_5);
    ASSERT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.transactions[0].response.has_value());

    a.serial("line", request, 11s);
    a.serial("line", head, 11s + 20ms);
    a.idle(11s + 110ms);
    EXPECT_EQ(sink.frames.size(), 3u) << "the head waits up to 100 ms";
    a.idle(11s + 125ms);
    ASSERT_EQ(sink.frames.size(), 4u);
    EXPECT_FALSE(sink.frames[3].frame.checksum_ok);
    EXPECT_EQ(sink.frames[3].frame.wire_length, 5u);
    a.finish();
    EXPECT_EQ(sink.count(mb::FindingCode::RtuGapInsideFrame), 1);
    EXPECT_EQ(sink.count(mb::FindingCode::PairNoResponse), 0);
}

TEST(Analyzer, UnansweredAtTheEndOfTheCaptureIsANoteNotATimeout) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 1);
    // The summary agrees with the transaction record: not a timeout.
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.unanswered_at_end, 1u);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_FALSE(h.sink.transactions[0].timed_out);
}

// Timestamps going back (merged captures, a clock step): the latency was reported as -1000 ms and pulled
// the device's minimum below zero.
TEST(Analyzer, AResponseStampedBeforeItsRequestHasNoLatency) {
    Harness h;
    h.send(true, read_request(1), 2s);
    h.send(false, read_response(1), 1s);
    h.send(true, read_request(2), 3s);
    h.send(false, read_response(2), 3s + 10ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairResponseBeforeRequest), 1);
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    EXPECT_FALSE(h.sink.transactions[0].latency.has_value());
    EXPECT_EQ(h.sink.transactions[1].latency, 10ms);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.latency.count(), 1u);
    EXPECT_EQ(device.latency.min(), 10ms);
    EXPECT_EQ(device.responses, 2u);
}

// The capture's clock set back an hour in the middle of a poll (a tap's clock corrected by hand or NTP):
// every request after the step expired at the next packet, its response unsolicited, until the clock caught
// up. The pending deadlines now move back with the clock: a request outstanding across the step keeps the
// wait it had left, one genuinely unanswered after it still times out, and the step is said, once.
TEST(Analyzer, AClockSetBackDoesNotTimeOutEveryRequestAfterIt) {
    for (const bool across : {false, true}) {
        SCOPED_TRACE(across ? "a request outstanding across the step" : "none outstanding");
        Harness h;
        const mb::Timestamp start = 10h;
        for (std::uint16_t i = 0; i < 5; ++i) {
            h.send(true, read_request(i), start + i * 1s);
            h.send(false, read_response(i), start + i * 1s + 20ms);
        }
        h.send(true, {}, start + 9s);  // an acknowledgement, later than every deadline so far
        if (across) h.send(true, read_request(5), start + 10s);
        const mb::Timestamp back = start + 10s + 100ms - 1h;  // the clock is set back an hour
        if (across) h.send(false, read_response(5), back);
        for (std::uint16_t i = 6; i < 11; ++i) {
            h.send(true, read_request(i), back + (i - 5) * 1s);
            h.send(false, read_response(i), back + (i - 5) * 1s + 20ms);
        }
        h.send(true, read_request(11), back + 7s);  // never answered
        h.send(true, read_request(12), back + 20s);
        h.send(false, read_response(12), back + 20s + 20ms);
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseBeforeRequest), across ? 1 : 0);
        EXPECT_EQ(h.analyzer.summary().transactions, across ? 13u : 12u);
        EXPECT_TRUE(h.analyzer.summary().input_errors.empty());
        const auto& errors = h.analyzer.summary().input_notes;
        ASSERT_EQ(errors.size(), 1u);
        // The first packet stamped before the step: the response across it, else the next request.
        EXPECT_NE(errors[0].find(across ? "test: packet 13: the capture's clock goes back 3599900 ms"
                                        : "test: packet 12: the capture's clock goes back 3597900 ms"),
                  std::string::npos)
            << errors[0];
    }
}

// Requests time out by their own framing's timeout (--timeout 3 s over Modbus/TCP, 1 s on a serial line): an
// RTU request behind a Modbus/TCP one, on a gateway's RTU-over-TCP port, waited for the TCP request's later
// deadline, so a reply 1.9 s after it was paired as if in time.
TEST(Analyzer, AShortTimeoutIsNotHeldUpByALongerOneBeforeIt) {
    an::AnalyzerOptions o;
    o.rtu_over_tcp_ports = {5020};
    for (const bool tcp_answered : {true, false}) {
        SCOPED_TRACE(tcp_answered ? "the Modbus/TCP request answered"
                                  : "the Modbus/TCP request still pending");
        Harness h(o);
        const auto rtu_request = mbscope::test::bytes({0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87});
        const auto rtu_response =
            mbscope::test::bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
        h.send(true, read_request(1), 1s);
        h.raw(packet(true, 9000, rtu_request, false, 0x18, 5020, 7000), 1s + 100ms);
        if (tcp_answered) h.send(false, read_response(1), 1s + 200ms);
        h.raw(packet(false, 7000, rtu_response, false, 0x18, 5020, 9008), 3s);  // 1.9 s after its request
        h.send(true, {}, 10s);
        h.analyzer.finish();
        const auto& rtu = h.analyzer.summary().devices.at("10.0.0.2:5020 unit 17");
        EXPECT_EQ(rtu.timeouts, 1u);
        EXPECT_EQ(rtu.responses, 0u);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);  // its request timed out at 2.1 s
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), tcp_answered ? 1 : 2);
    }
}

// A connection reset in the middle of a request, then a new connection on the same addresses and ports: the
// half ADU took the first bytes of the next connection's request, which was lost with it, and its response
// was called unsolicited.
TEST(Analyzer, AResetConnectionsHalfAduDoesNotSwallowTheNextConnectionsRequest) {
    for (const bool reset_seen : {true, false}) {
        Harness h;
        const auto first = read_request(1);
        h.raw(packet(true, 999, {}, false, 0x02), 1s);  // SYN
        h.send(true, {first.begin(), first.begin() + 7}, 1s + 1ms);
        if (reset_seen) h.raw(packet(true, 1007, {}, false, 0x04), 1s + 2ms);  // RST
        h.raw(packet(true, 70000, {}, false, 0x02), 2s);  // a new connection's SYN, another sequence number
        h.raw(packet(false, 90000, {}, false, 0x12, 502, 70001), 2s);  // SYN-ACK
        h.seq[0] = 70001;
        h.seq[1] = 90001;
        h.send(true, read_request(2), 2s + 1ms);
        h.send(false, read_response(2), 2s + 3ms);
        h.analyzer.finish();
        ASSERT_EQ(h.sink.transactions.size(), 1u) << reset_seen;
        EXPECT_EQ(h.sink.transactions[0].request.frame.transaction_id(), 2);
        EXPECT_TRUE(h.sink.transactions[0].response.has_value());
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
        ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
        const auto& cut = h.sink.unparsed_records[0];
        EXPECT_EQ(cut.length, 7u);
        EXPECT_EQ(cut.offset, 0u);
        EXPECT_EQ(cut.reason, mb::UnparsedReason::Truncated);
        EXPECT_EQ(cut.time, 1s + 1ms);  // where the bytes are, though reported when the connection ended
        EXPECT_EQ(cut.packet, 2u);
        EXPECT_EQ(h.analyzer.summary().unparsed_bytes, 7u);
    }
}

// A reset far outside the stream's sequence numbers (a stray or forged segment) does not end the
// connection: a receiver ignores it (RFC 5961 §3.2), and the request it would have cut still pairs with its
// response. It is reported. One at the stream's next sequence number ends it.
TEST(Analyzer, AResetOutsideTheStreamsWindowDoesNotEndTheConnection) {
    Harness h;
    const auto request = read_request(1);
    h.raw(packet(true, 999, {}, false, 0x02), 1s);
    h.send(true, {request.begin(), request.begin() + 7}, 1s + 1ms);
    h.raw(packet(true, 1007 + 0x40000000u, {}, false, 0x04), 1s + 2ms);  // RST, a quarter of the space away
    h.send(true, {request.begin() + 7, request.end()}, 1s + 3ms);
    h.send(false, read_response(1), 1s + 4ms);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_TRUE(h.sink.transactions[0].response.has_value());
    EXPECT_TRUE(h.sink.unparsed_records.empty());
    ASSERT_EQ(h.sink.count(mb::FindingCode::StreamResetOutsideWindow), 1);
    // At the next sequence number: the connection's end, half a request cut by it reported.
    h.send(true, {request.begin(), request.begin() + 5}, 2s);
    h.raw(packet(true, h.seq[0], {}, false, 0x04), 2s + 1ms);
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamResetOutsideWindow), 1);
    ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, 5u);
}

// A SYN sent again (the same sequence number) is the same connection: nothing is cut.
TEST(Analyzer, ARetransmittedSynIsNotANewConnection) {
    Harness h;
    const auto request = read_request(1);
    h.raw(packet(true, 999, {}, false, 0x02), 1s);
    h.send(true, {request.begin(), request.begin() + 7}, 1s + 1ms);
    h.raw(packet(true, 999, {}, false, 0x02), 1s + 2ms);
    h.send(true, {request.begin() + 7, request.end()}, 1s + 3ms);
    h.send(false, read_response(1), 1s + 4ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    EXPECT_TRUE(h.sink.unparsed_records.empty());
    EXPECT_TRUE(h.sink.findings.empty());
}

// A client with requests pipelined, the tap losing the segment of the second: the third waited behind the
// hole until the client's next segment, seconds later, its reply called unsolicited and itself timed out.
// The server's reply acknowledges the hole and the bytes after it, so the hole is given up then: the reply to
// the lost request is unsolicited (its request may be in the lost bytes), the third is paired with its own
// reply, at its own time.
TEST(Analyzer, ARequestPipelinedBehindALostSegmentIsPairedWithItsReply) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.lose(true, read_request(2));  // request 2: not captured
    h.send(true, read_request(3), 1s + 2ms);
    h.send(false, read_response(1), 1s + 10ms);
    h.send(false, read_response(2), 1s + 11ms);
    h.send(false, read_response(3), 1s + 12ms);
    h.send(true, read_request(4), 4s);
    h.send(false, read_response(4), 4s + 10ms);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdMismatch), 0);
    // Once a request after the lost bytes was answered, a reply with another id is a mismatch again.
    h.send(true, read_request(5), 5s);
    h.send(false, read_response(99), 5s + 10ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::PairUnsolicitedResponse) {
            EXPECT_NE(f.message.find("transaction id 2"), std::string::npos) << f.message;
        }
    }
    ASSERT_EQ(h.sink.transactions.size(), 4u);
    const auto& third = h.sink.transactions[1];
    EXPECT_EQ(third.request.frame.transaction_id(), 3);
    EXPECT_EQ(third.request.time, 1s + 2ms);
    ASSERT_TRUE(third.response.has_value());
    EXPECT_EQ(third.latency, 10ms);
}

// (On a connection opened in the capture: on one begun before it, a first reply answers a request sent
// before the capture began, AReplyBeforeAnyRequestOfAConnectionBegunBeforeTheCaptureIsNotUnsolicited.)
TEST(Analyzer, UnsolicitedResponse) {
    Harness h;
    h.open(0s);
    h.send(false, read_response(9), 1s);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
}

// The last response again, transaction id and all, after its request was answered: a device that answered
// twice. Another response with no request waiting is a reply nobody asked for.
TEST(Analyzer, DuplicateResponse) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(false, read_response(1), 1s + 1ms);
    h.send(false, read_response(1), 1s + 2ms);
    h.send(false, read_response(1, {556, 0, 100}), 1s + 3ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairDuplicateResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    EXPECT_EQ(h.sink.transactions.size(), 1u);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairDuplicateResponse) {
            EXPECT_EQ(f.frames.size(), 2u);
        }
}

TEST(Analyzer, TransactionIdMismatch) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(false, read_response(2), 1s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(h.sink.transactions.size(), 1u);
}

// The client sent the id again: it gave up on the first request, which the device never answered. That is
// a timeout like any other, with its finding (an error: the exit code says so), not a timeout only counted.
TEST(Analyzer, TransactionIdDuplicate) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(true, read_request(1), 1s + 1ms);
    h.send(false, read_response(1), 1s + 2ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdDuplicate), 1);
    // Both wait: the reply answers the first, the second is still waiting when the capture ends. Before,
    // the reuse gave the first up as a timeout the device did not cause.
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 1);
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    ASSERT_TRUE(h.sink.transactions[0].response);
    EXPECT_EQ(h.sink.transactions[0].request.index, 1u);
    EXPECT_EQ(h.sink.transactions[0].response->index, 3u);
    EXPECT_EQ(h.sink.transactions[1].request.index, 2u);
    EXPECT_FALSE(h.sink.transactions[1].response);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 0u);
}

namespace {
std::vector<std::uint8_t> write_register(std::uint16_t tid, std::uint16_t address, std::uint16_t value) {
    return mb::encode_tcp(
        tid, 17,
        std::vector<std::uint8_t>{0x06, static_cast<std::uint8_t>(address >> 8),
                                  static_cast<std::uint8_t>(address), static_cast<std::uint8_t>(value >> 8),
                                  static_cast<std::uint8_t>(value)});
}
}  // namespace

// A client that numbers every request alike (ITI's modbus_test.pcap: three FC6 writes to unit 7, all with
// transaction id 504, answered in turn by exact echoes): each reply is its own request's. Before, the reuse
// gave the first two up as timeouts, the first reply was held against the third write as an echo mismatch,
// and the two after it were unsolicited: five errors for a device that did everything right.
TEST(Analyzer, RequestsThatReuseATransactionIdAreAnsweredInTurn) {
    Harness h;
    h.send(true, write_register(504, 4, 2500), 1s);
    h.send(true, write_register(504, 4, 0), 1s + 1ms);
    h.send(true, write_register(504, 5, 14017), 1s + 2ms);
    h.send(false, write_register(504, 4, 2500), 1s + 40ms);
    h.send(false, write_register(504, 4, 0), 1s + 80ms);
    h.send(false, write_register(504, 5, 14017), 1s + 120ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdDuplicate), 2);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
    for (auto code : {mb::FindingCode::PairNoResponse, mb::FindingCode::PairEchoMismatch,
                      mb::FindingCode::PairUnsolicitedResponse, mb::FindingCode::PairNoResponseAtEnd})
        EXPECT_EQ(h.sink.count(code), 0) << mb::to_string(code);
    ASSERT_EQ(h.sink.transactions.size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
        const auto& t = h.sink.transactions[i];
        ASSERT_TRUE(t.response);
        EXPECT_EQ(t.response->index, t.request.index + 3);
        EXPECT_EQ(t.request.pdu->body, t.response->pdu->body);
    }
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.responses, 3u);
    EXPECT_EQ(device.timeouts, 0u);
}

// With the id reused, a reply answers the oldest request it fits (its function, echo and data size), not
// simply the oldest: a client that gave up on a request and asked something else under the same id gets the
// reply to the second, and the first times out as its own.
TEST(Analyzer, AReplyUnderAReusedIdAnswersTheRequestItFits) {
    Harness h;
    h.send(true, read_request(9, 96, 3), 1s);
    h.send(true, read_request(9, 200, 2), 1s + 500ms);
    h.send(false, read_response(9, {7, 8}), 1s + 510ms);
    h.send(true, read_request(10), 5s);
    h.send(false, read_response(10), 5s + 10ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseSizeMismatch), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{1});
        }
    ASSERT_EQ(h.sink.transactions.size(), 3u);
    EXPECT_EQ(h.sink.transactions[0].request.index, 2u);  // answered first
    ASSERT_TRUE(h.sink.transactions[0].response);
    EXPECT_EQ(h.sink.transactions[0].response->index, 3u);
    EXPECT_EQ(h.sink.transactions[1].request.index, 1u);
    EXPECT_TRUE(h.sink.transactions[1].timed_out);
}

// An exception is counted as the device's answer whatever the request was: one that does not decode (the
// very reason a device refuses it) or one for another function. Before, only exceptions to a request that
// decoded, with the same function, reached the summary: ITI's modbus_test_data_part2.pcap showed 121 of the
// 130 exception replies tshark and the transactions list.
TEST(Analyzer, EveryExceptionReplyIsCounted) {
    Harness h;
    h.send(true, mb::encode_tcp(1, 17, std::vector<std::uint8_t>{0x06, 0x00, 0x00}),
           1s);  // FC6 cut short: does not decode
    h.send(false, mb::encode_tcp(1, 17, std::vector<std::uint8_t>{0x86, 0x03}), 1s + 1ms);
    h.send(true, read_request(2), 2s);
    h.send(false, mb::encode_tcp(2, 17, std::vector<std::uint8_t>{0x84, 0x02}),
           2s + 1ms);  // FC4's exception to an FC3 request
    h.analyzer.finish();
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.exceptions, 2u);
    EXPECT_EQ(device.exception_codes.at(3), 1u);
    EXPECT_EQ(device.exception_codes.at(2), 1u);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairExceptionResponse), 2);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairFunctionMismatch), 1);
    bool named = false;
    for (const auto& f : h.sink.findings)
        named |= f.message.find("to FC6 Write Single Register (malformed request)") != std::string::npos;
    EXPECT_TRUE(named) << "the exception names what the malformed request asked for";
}

// A request still waiting when its connection ends (a reset from either side, or the client opening the
// connection again, as a PLC with a fixed source port does after its own timeout) will not be answered:
// given up then, as a timeout with its finding (after the client's own reset, at its next SYN, as the
// client's abort: pair.client_aborted, no timeout). Left waiting, it clashed with the next connection's first
// transaction id as a duplicate, its timeout counted but never reported, and the run passed.
TEST(Analyzer, ARequestWaitingWhenItsConnectionEndsIsGivenUpThen) {
    struct Case {
        int how;  // 0 the client resets, 1 the server resets, 2 the client connects again (reset not seen),
                  // 3 the server closes its side (FIN)
        const char* said;
    };
    for (const Case c : {Case{0, "the client reset the connection before a whole reply came"},
                         Case{1, "before the server reset the connection, 1000.000 ms after it"},
                         Case{2, "before the client opened the connection again, 1100.000 ms after it"},
                         Case{3, "before the server closed the connection, 1000.000 ms after it"}}) {
        Harness h;
        h.raw(packet(true, 999, {}, false, 0x02), 1s);  // SYN
        h.send(true, read_request(1), 1s + 1ms);
        if (c.how == 0) h.raw(packet(true, h.seq[0], {}, false, 0x04), 2s + 1ms);
        if (c.how == 1) h.raw(packet(false, h.seq[1], {}, false, 0x04), 2s + 1ms);
        if (c.how == 3) h.raw(packet(false, h.seq[1], {}, false, 0x11, 502, h.seq[0]), 2s + 1ms);
        h.raw(packet(true, 70000, {}, false, 0x02), 2s + 101ms);  // the same ports, a new connection
        h.raw(packet(false, 90000, {}, false, 0x12, 502, 70001), 2s + 101ms);
        h.seq[0] = 70001;
        h.seq[1] = 90001;
        h.send(true, read_request(1), 2s + 102ms);  // its ids start over
        h.send(false, read_response(1), 2s + 103ms);
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdDuplicate), 0) << c.how;
        const bool client = c.how == 0;
        const auto code = client ? mb::FindingCode::PairClientAborted : mb::FindingCode::PairNoResponse;
        ASSERT_EQ(h.sink.count(code), 1) << c.how;
        for (const auto& f : h.sink.findings)
            if (f.code == code) {
                EXPECT_NE(f.message.find(c.said), std::string::npos) << f.message;
                EXPECT_EQ(f.frames, std::vector<std::uint64_t>{1});
            }
        const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
        EXPECT_EQ(device.timeouts, client ? 0u : 1u) << c.how;
        EXPECT_EQ(device.client_aborted, client ? 1u : 0u) << c.how;
        EXPECT_EQ(device.responses, 1u) << c.how;
        EXPECT_EQ(h.analyzer.summary().errors, client ? 0u : 1u) << c.how;
        ASSERT_EQ(h.sink.transactions.size(), 2u) << c.how;
        EXPECT_EQ(h.sink.transactions[0].timed_out, !client);
        EXPECT_EQ(h.sink.transactions[0].client_aborted, client);
        EXPECT_EQ(h.sink.transactions[0].findings, std::vector<mb::FindingCode>{code});
        EXPECT_TRUE(h.sink.transactions[1].response.has_value());
        EXPECT_TRUE(h.sink.transactions[1].findings.empty());
    }
}

// A link with more requests waiting than the analyzer keeps gives its oldest up: a timeout, reported as one
// (it was counted, with only the overflow warning about the newest request to show for it).
TEST(Analyzer, ARequestGivenUpForRoomIsReportedAsUnanswered) {
    an::AnalyzerOptions o;
    o.max_pending_per_flow = 3;
    Harness h(o);
    for (std::uint16_t tid = 1; tid <= 4; ++tid)
        h.send(true, read_request(tid), 1s + tid * 1ms);
    h.send(false, read_response(4), 1s + 5ms);
    h.send(false, read_response(1), 1s + 6ms);  // its reply after all: late, as any timeout's
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairPendingOverflow), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{1});
            EXPECT_NE(
                f.message.find("before 3 later requests on its link left no room to wait for it, 3.000 ms "
                               "after it"),
                std::string::npos)
                << f.message;
        }
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 1u);
    ASSERT_FALSE(h.sink.transactions.empty());
    EXPECT_TRUE(h.sink.transactions[0].timed_out);
    EXPECT_EQ(h.sink.transactions[0].request.index, 1u);
    EXPECT_EQ(h.sink.transactions[0].findings, std::vector<mb::FindingCode>{mb::FindingCode::PairNoResponse});
}

// A timeout's transaction carries its finding, as an exception's does: a CSV row or a transaction record of
// a request nobody answered must not read as a clean exchange. So does one unanswered at the end.
TEST(Analyzer, AnUnansweredTransactionCarriesItsFinding) {
    Harness h;
    h.send(true, read_request(1), 1s);
    h.send(true, read_request(2), 5s);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    EXPECT_TRUE(h.sink.transactions[0].timed_out);
    EXPECT_EQ(h.sink.transactions[0].findings, std::vector<mb::FindingCode>{mb::FindingCode::PairNoResponse});
    EXPECT_FALSE(h.sink.transactions[1].timed_out);
    EXPECT_EQ(h.sink.transactions[1].findings,
              std::vector<mb::FindingCode>{mb::FindingCode::PairNoResponseAtEnd});
}

TEST(Analyzer, ExceptionIsLinkedToItsRequest) {
    Harness h;
    h.send(true, read_request(1, 200, 1), 1s);
    h.send(false, mb::encode_tcp(1, 17, mb::encode_pdu(mb::make_exception(3, 2))), 1s + 1ms);
    h.analyzer.finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairExceptionResponse), 1);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairExceptionResponse) {
            EXPECT_NE(f.message.find("Illegal Data Address"), std::string::npos);
            EXPECT_EQ(f.frames.size(), 2u);
        }
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").exceptions, 1u);
}

TEST(Analyzer, ResponseSizeFunctionAndUnitMismatches) {
    Harness h;
    h.send(true, read_request(1, 96, 3), 1s);
    h.send(false, read_response(1, {1, 2}), 1s + 1ms);  // two registers for three asked
    h.send(true, read_request(2), 2s);
    h.send(false,
           mb::encode_tcp(2, 17,
                          mb::encode_pdu(mb::make_read_registers_response(
                              mb::FunctionCode::ReadInputRegisters, std::vector<std::uint16_t>{1, 2, 3}))),
           2s + 1ms);
    h.send(true, read_request(3), 3s);
    h.send(false, read_response(3, {1, 2, 3}, 18), 3s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseSizeMismatch), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairFunctionMismatch), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnitMismatch), 1);
    // Paired by its transaction id, the reply naming unit 18 is unit 17's, and so is its finding: no device
    // "unit 18" that nobody asked, holding the error with 0 requests and 0 responses.
    const auto& devices = h.analyzer.summary().devices;
    ASSERT_EQ(devices.size(), 1u);
    const auto& asked = devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(asked.responses, 3u);
    EXPECT_EQ(asked.findings.at("pair.unit_mismatch"), 1u);
}

// --json's frame records keep a PDU's fields in the specification's order, as the JSON lines do (analyzer
// README): a sorted object put "quantity" before "starting_address".
TEST(Analyzer, JsonFieldsKeepTheSpecificationsOrder) {
    Harness h;
    h.send(true, read_request(1, 96, 3), 1s);
    h.analyzer.finish();
    ASSERT_FALSE(h.sink.frames.empty());
    const std::string text = an::frame_to_json(h.sink.frames[0]).dump();
    const auto start = text.find("\"starting_address\"");
    ASSERT_NE(start, std::string::npos) << text;
    EXPECT_LT(start, text.find("\"quantity\"")) << text;
    // The record's own keys stay sorted, as every other record's (and --jsonl's order is its own).
    EXPECT_LT(text.find("\"checksum_ok\""), text.find("\"type\"")) << text;
}

TEST(Analyzer, EchoMismatch) {
    Harness h;
    h.send(true, mb::encode_tcp(1, 17, mb::encode_pdu(mb::make_write_single_register(84, 926))), 1s);
    auto wrong = mb::make_write_single_register(84, 925);
    wrong.direction = mb::Direction::Response;
    h.send(false, mb::encode_tcp(1, 17, mb::encode_pdu(wrong)), 1s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairEchoMismatch), 1);
}

// FC8's counters (sub-functions 0x0B-0x12) return a count, not the request's data (AP §6.8.1): a reply
// with the count is no echo mismatch. One under another sub-function, or a changed echo of sub-function 0x0A
// (clear counters), is. The whole body was compared for every sub-function, an error against a healthy
// device for every counter read.
TEST(Analyzer, Fc8CountersReturnACountAndOnlyEchoingSubFunctionsAreJudgedAsEchoes) {
    const auto diagnostics = [](std::uint16_t sub, std::uint16_t data, mb::Direction direction) {
        const std::uint8_t bytes[] = {static_cast<std::uint8_t>(data >> 8), static_cast<std::uint8_t>(data)};
        auto pdu = mb::make_diagnostics(sub, bytes);
        pdu.direction = direction;
        return mb::encode_pdu(pdu);
    };
    Harness h;
    h.send(true, mb::encode_tcp(1, 17, diagnostics(0x0B, 0, mb::Direction::Request)), 1s);
    h.send(false, mb::encode_tcp(1, 17, diagnostics(0x0B, 42, mb::Direction::Response)), 1s + 1ms);
    h.send(true, mb::encode_tcp(2, 17, diagnostics(0x0C, 0, mb::Direction::Request)), 2s);
    h.send(false, mb::encode_tcp(2, 17, diagnostics(0x0D, 3, mb::Direction::Response)), 2s + 1ms);
    h.send(true, mb::encode_tcp(3, 17, diagnostics(0x0A, 0, mb::Direction::Request)), 3s);
    h.send(false, mb::encode_tcp(3, 17, diagnostics(0x0A, 1, mb::Direction::Response)), 3s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairEchoMismatch), 2);
    std::vector<std::string> messages;
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::PairEchoMismatch) {
            EXPECT_EQ(f.message.find("sub-function 11"), std::string::npos) << f.message;
            messages.push_back(f.message);
        }
    }
    // Each says what differs.
    ASSERT_EQ(messages.size(), 2u);
    EXPECT_NE(
        messages[0].find("the response is not an echo of the request's sub-function: its sub-function is "
                         "13, not 12"),
        std::string::npos)
        << messages[0];
    EXPECT_NE(messages[1].find("the response is not an echo of the request: its data is 00 01, not 00 00"),
              std::string::npos)
        << messages[1];
}

// A capture begun mid-connection whose first client segment is the last 5 bytes of a request ("03 00 00 00
// 01", read of 1 register at 0): taken as in step, they and the next request's first byte read as a header
// of length 256 (unit 3, function 0), which swallowed the next 263 bytes: 22 of 30 replies were
// "unsolicited" errors against a healthy device, and a unit 3 appeared that nobody asked. The stream's
// first header is judged (no SYN was seen): the 5 bytes are unparsed and every later request is paired.
TEST(Analyzer, ACaptureBegunInsideAnAduLosesNoLaterRequest) {
    Harness h;
    const auto tail = read_request(2, 0, 1);
    h.send(true, std::vector<std::uint8_t>(tail.end() - 5, tail.end()), 1s);
    h.send(false, read_response(2, {2}), 1s + 1ms);
    for (std::uint16_t tid = 3; tid < 33; ++tid) {
        h.send(true, read_request(tid, 0, 1), tid * 1s);
        h.send(false, read_response(tid, {tid}), tid * 1s + 1ms);
    }
    h.analyzer.finish();
    ASSERT_FALSE(h.sink.unparsed_records.empty());
    EXPECT_EQ(h.sink.unparsed_records[0].offset, 0u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, 5u);
    EXPECT_EQ(h.sink.unparsed_records[0].reason, mb::UnparsedReason::BeforeFirstHeader);
    EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 0);  // no device's header
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 1);  // the reply to the request cut
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
    const auto& devices = h.analyzer.summary().devices;
    ASSERT_EQ(devices.size(), 1u);
    EXPECT_EQ(devices.begin()->first, "10.0.0.2:502 unit 17");
    EXPECT_EQ(devices.begin()->second.requests, 30u);
    EXPECT_EQ(devices.begin()->second.responses, 30u);
}

// A capture begun between a request and its reply, the connection's opening not in it: the first frame is a
// reply nobody in the capture asked for, whose request went before the capture began; an "unsolicited"
// error held that against the device. With the opening captured, such a reply is unsolicited.
TEST(Analyzer, AReplyBeforeAnyRequestOfAConnectionBegunBeforeTheCaptureIsNotUnsolicited) {
    for (const bool opened : {false, true}) {
        SCOPED_TRACE(opened);
        Harness h;
        if (opened) h.open(0s);
        h.send(false, read_response(1), 1s);
        h.send(true, read_request(2), 2s);
        h.send(false, read_response(2), 2s + 1ms);
        h.send(false, read_response(3), 3s);  // nobody asked: unsolicited either way
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), opened ? 0 : 1);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), opened ? 2 : 1);
    }
}

// A request the tap lost, the server's acknowledgement covering it, then its reply: the hole is given up as
// a gap only at the client's next segment, after the reply, which was "unsolicited" (an error against the
// device for the tap's loss). The acknowledged bytes the capture does not hold may hold its request.
TEST(Analyzer, AReplyToARequestTheTapLostIsNotUnsolicited) {
    Harness h;
    h.open(0s);
    h.send(true, read_request(1), 1s);
    h.send(false, read_response(1), 1s + 1ms);
    h.lose(true, read_request(2));  // request 2: sent, not captured
    h.send(false, read_response(2), 2s + 1ms);
    h.send(true, read_request(3), 2s + 10ms);
    h.send(false, read_response(3), 2s + 11ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    EXPECT_EQ(h.analyzer.summary().transactions, 2u);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
}

// Begun before the capture with two requests in flight: each reply before the capture's first request of
// the link answers a request sent before it began, and is not unsolicited. After a request was captured, a
// reply nobody asked for is (and a reply with another id is a transaction-id mismatch, as before).
TEST(Analyzer, RepliesToRequestsInFlightWhenTheCaptureBeganAreNotTheDevicesFault) {
    Harness h;
    h.send(false, read_response(1, {1}), 1s);
    h.send(false, read_response(2, {2}), 1s + 1ms);
    h.send(true, read_request(3), 2s);
    h.send(false, read_response(3, {3}), 2s + 1ms);
    h.send(false, read_response(4, {4}), 3s);  // nobody asked
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 2);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    ASSERT_TRUE(h.sink.transactions[0].response.has_value());
    EXPECT_EQ(h.sink.transactions[0].response->frame.transaction_id(), 3);
}

// One request the tap lost excuses one reply, not every stray one while the hole waits: the same reply
// again is a duplicate, and a reply to a transaction nobody sent is unsolicited.
TEST(Analyzer, ALostRequestExcusesOneReply) {
    Harness h;
    h.open(0s);
    h.send(true, read_request(1), 1s);
    h.send(false, read_response(1), 1s + 1ms);
    h.lose(true, read_request(2));  // request 2: sent, not captured
    h.send(false, read_response(2), 2s + 1ms);
    h.send(false, read_response(2), 2s + 2ms);
    h.send(false, read_response(9), 2s + 3ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairDuplicateResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 1);
}

// Begun with the last 6 bytes of a read at address 0 ("11 03 00 00 00 0A"): a plausible header of length
// 10 over the next request's bytes, whose PDU does not decode, while a whole request that does starts inside
// it. The 6 bytes are before the first header, and every request is paired.
TEST(Analyzer, ATailThatReadsAsAWholeHeaderYieldsToTheRequestInsideIt) {
    Harness h;
    const auto tail = read_request(1, 0, 10);
    h.send(true, std::vector<std::uint8_t>(tail.end() - 6, tail.end()), 1s);
    for (std::uint16_t tid = 2; tid < 6; ++tid) {
        h.send(true, read_request(tid, 0, 10), tid * 1s);
        h.send(false, read_response(tid, std::vector<std::uint16_t>(10, tid)), tid * 1s + 1ms);
    }
    h.analyzer.finish();
    ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, 6u);
    EXPECT_EQ(h.sink.unparsed_records[0].reason, mb::UnparsedReason::BeforeFirstHeader);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
    EXPECT_EQ(h.analyzer.summary().transactions, 4u);
    EXPECT_EQ(h.analyzer.summary().devices.size(), 1u);
}

// A stream whose opening was captured is read from its first byte, in step: a first header with protocol
// id 1 is still a frame (flagged). Without the opening it may be the tail of an earlier ADU, and is not.
TEST(Analyzer, AStreamWhoseOpeningWasCapturedTakesItsFirstHeader) {
    for (const bool opened : {false, true}) {
        SCOPED_TRACE(opened);
        Harness h;
        if (opened) h.open(0s);
        auto first = read_request(1);
        first[3] = 1;  // protocol id 1
        h.send(true, first, 1s);
        h.send(true, read_request(2), 2s);
        h.send(false, read_response(2), 2s + 1ms);
        h.analyzer.finish();
        EXPECT_EQ(h.sink.frames.size(), opened ? 3u : 2u);
        EXPECT_EQ(h.sink.count(mb::FindingCode::TcpProtocolIdNonzero), opened ? 1 : 0);
        ASSERT_EQ(h.sink.unparsed_records.size(), opened ? 0u : 1u);
        if (!opened) {
            EXPECT_EQ(h.sink.unparsed_records[0].length, first.size());
        }
    }
}

TEST(Analyzer, ProtocolIdAndGarbageBetweenAdus) {
    Harness h;
    h.open(0s);
    auto bad = read_request(1);
    bad[3] = 1;  // protocol id 1
    h.send(true, bad, 1s);
    std::vector<std::uint8_t> junk = {0x00, 0x05, 0x00, 0x00, 0x00, 0x00, 0x11};  // length 0: impossible
    auto good = read_request(2);
    junk.insert(junk.end(), good.begin(), good.end());
    h.send(true, junk, 2s);
    h.send(false, read_response(2), 2s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::TcpProtocolIdNonzero), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 1);
    ASSERT_EQ(h.sink.unparsed_records.size(), 1u);
    EXPECT_EQ(h.sink.unparsed_records[0].length, 7u);
}

TEST(Analyzer, RtuOverUdpIsRecognisedByItsCrc) {
    Collect sink;
    an::Analyzer a({}, sink);
    // MK manual frames (000:356, 000:365) carried in UDP datagrams by a serial gateway.
    const std::vector<std::uint8_t> req = {0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45};
    const std::vector<std::uint8_t> rsp = {0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA};
    auto p1 = packet(true, 0, req, true), p2 = packet(false, 0, rsp, true);
    an::Packet p;
    p.linktype = link_raw;
    p.number = 1;
    p.time = 1s;
    p.data = p1;
    a.packet("test", p);
    p.number = 2;
    p.time = 1s + 5ms;
    p.data = p2;
    a.packet("test", p);
    a.finish();
    ASSERT_EQ(sink.frames.size(), 2u);
    EXPECT_EQ(sink.frames[0].frame.framing, mb::Framing::Rtu);
    EXPECT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.findings.empty());
}

// Modbus/TCP on a port nobody named (--tcp-port) decodes to nothing; the summary says which port held
// whole ADUs so the user can ask for it. Other traffic (HTTP, an RTU frame, an ADU whose length does not fit
// its segment, an ADU cut across segments) is no hint.
TEST(Analyzer, ModbusOnAPortNotDecodedIsNamedInTheSummary) {
    Harness h;
    auto& sink = h.sink;
    auto& a = h.analyzer;
    const auto send = [&](bool to_server, const std::vector<std::uint8_t>& payload, std::uint16_t port,
                          bool udp = false) { h.raw(packet(to_server, 1, payload, udp, 0x18, port), 1s); };
    send(true, read_request(1), 1502);
    send(false, read_response(1), 1502);
    // A server on a port above its client's (40000): the reply's transaction id says which side serves.
    send(true, read_request(7), 45000);
    send(false, read_response(7), 45000);
    send(true, read_request(2), 5020, true);
    const std::string http = "GET / HTTP/1.1\r\nHost: plc\r\n\r\n";
    send(true, std::vector<std::uint8_t>(http.begin(), http.end()), 80);
    send(true, {0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45}, 8080);
    auto longer = read_request(3);
    longer.push_back(0);
    send(true, longer, 8081);
    const auto whole = read_request(4);
    send(true, std::vector<std::uint8_t>(whole.begin(), whole.begin() + 9), 8082);
    a.finish();
    EXPECT_TRUE(sink.frames.empty());
    const auto& ports = a.summary().modbus_like_ports;
    ASSERT_EQ(ports.size(), 3u);
    EXPECT_EQ(ports.at({false, 1502}), 2u);
    EXPECT_EQ(ports.at({false, 45000}), 2u);
    EXPECT_EQ(ports.at({true, 5020}), 1u);

    std::ostringstream text;
    an::TextSink(text, true).end(a.summary());
    EXPECT_NE(text.str().find("hint: 2 TCP packets on port 1502 hold Modbus/TCP ADUs; decode them with "
                              "--tcp-port 1502"),
              std::string::npos)
        << text.str();
    EXPECT_NE(text.str().find("--udp-port 5020"), std::string::npos) << text.str();
    EXPECT_NE(text.str().find("hint: 2 TCP packets on port 45000"), std::string::npos) << text.str();
}

// A retransmitted request whose bytes differ from the first copy (the quantity rewritten): the first copy
// is decoded, once, and the disagreement is a finding naming the stream and where it starts.
TEST(Analyzer, ARetransmissionWithOtherBytesIsAFinding) {
    Harness h;
    auto& sink = h.sink;
    auto& a = h.analyzer;
    const auto send = [&](bool to_server, std::uint32_t seq, const std::vector<std::uint8_t>& payload) {
        h.raw(packet(to_server, seq, payload), 1s);
    };
    const auto request = read_request(1);
    auto forged = request;
    forged.back() ^= 0x7F;  // the quantity's low byte
    send(true, 1, request);
    send(true, 1, forged);
    send(false, 1, read_response(1));
    a.finish();
    EXPECT_EQ(sink.frames.size(), 2u);
    EXPECT_EQ(sink.transactions.size(), 1u);
    ASSERT_EQ(sink.count(mb::FindingCode::StreamRetransmissionConflict), 1);
    for (const auto& f : sink.findings)
        if (f.code == mb::FindingCode::StreamRetransmissionConflict) {
            EXPECT_EQ(
                f.message,
                "a retransmission of the request stream differs from the first copy in 1 byte, the first "
                "at stream offset 11; the first copy was decoded, and the receiver may have kept the other");
        }
}

// Devices in the summary in the order a reader counts: on a multi-drop line unit 2 came after unit 199.
TEST(Summary, DevicesAreInNaturalOrder) {
    an::Summary s;
    for (const char* d : {"serial a unit 10", "serial a unit 2", "serial a unit 199", "serial a unit 1",
                          "10.0.0.10:502 unit 1", "10.0.0.9:502 unit 1", "10.0.0.9:502 unit 01"})
        s.devices[d];
    std::vector<std::string> order;
    for (const auto& [name, stats] : s.devices)
        order.push_back(name);
    EXPECT_EQ(order, (std::vector<std::string>{"10.0.0.9:502 unit 1", "10.0.0.9:502 unit 01",
                                               "10.0.0.10:502 unit 1", "serial a unit 1", "serial a unit 2",
                                               "serial a unit 10", "serial a unit 199"}));
    const an::NaturalOrder less;
    EXPECT_FALSE(less("unit 7", "unit 7"));
    EXPECT_TRUE(less("unit", "unit 7"));
    EXPECT_FALSE(less("unit 7", "unit"));
}

TEST(LatencyHistogram, QuantilesWithinThreePercent) {
    an::LatencyHistogram h;
    for (int i = 1; i <= 1000; ++i)
        h.add(std::chrono::microseconds(i));
    EXPECT_EQ(h.min(), 1us);
    EXPECT_EQ(h.max(), 1000us);
    const double median = std::chrono::duration<double, std::micro>(h.quantile(0.5)).count();
    const double p99 = std::chrono::duration<double, std::micro>(h.quantile(0.99)).count();
    EXPECT_NEAR(median, 500, 500 * 0.02);
    EXPECT_NEAR(p99, 990, 990 * 0.02);
}

// Nearest rank: the p99 of a few latencies, or of a set whose slowest hundredth stands apart, is the tail,
// not the value below it. Rounding the rank down gave the p99 of three latencies as their median.
TEST(LatencyHistogram, QuantilesAreNearestRank) {
    an::LatencyHistogram three;
    for (const auto us : {24, 228, 293})
        three.add(std::chrono::microseconds(us));
    EXPECT_EQ(three.quantile(0.99), 293us);
    using us = std::chrono::duration<double, std::micro>;
    using ms = std::chrono::duration<double, std::milli>;
    EXPECT_NEAR(us(three.quantile(0.5)).count(), 228, 228 * 0.02);
    EXPECT_EQ(three.quantile(0.0), 24us);
    an::LatencyHistogram skewed;  // 95 at 10 ms, 5 at 150 ms: the 99th of 100 is 150 ms
    for (int i = 0; i < 100; ++i)
        skewed.add(std::chrono::milliseconds(i < 95 ? 10 : 150));
    EXPECT_NEAR(ms(skewed.quantile(0.99)).count(), 150, 150 * 0.02);
    EXPECT_NEAR(ms(skewed.quantile(0.95)).count(), 10, 10 * 0.02);
}

// A record cut to the snapshot length (tcpdump -s 64/96, old defaults) holds the first bytes of a reply: its
// MBAP header names the transaction it answers. Answered, its values unknown: not a timeout against the
// device. Before, the cut bytes were a gap found only at the next packet (or never, for the last), and the
// request was "no response".
TEST(Analyzer, AReplyCutByTheSnapshotLengthIsAnAnswerNotATimeout) {
    Harness h;
    h.send(true, read_request(1, 0, 10), 1s);
    h.send_cut(false, read_response(1, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}), 10, 1s + 10ms);  // 10 of 29 bytes
    h.send(true, read_request(2, 0, 1), 1s + 20ms);
    h.send(false, read_response(2, {77}), 1s + 30ms);
    h.send(true, read_request(3, 0, 1), 6s);  // past the first request's timeout
    h.send(false, read_response(3, {78}), 6s + 10ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::PairResponseNotCaptured) {
            EXPECT_EQ(f.frames, std::vector<std::uint64_t>{1});
            EXPECT_NE(f.message.find("holds only 10 of the reply's 29 bytes (a packet cut"),
                      std::string::npos)
                << f.message;
        }
        if (f.code == mb::FindingCode::StreamGap) {
            EXPECT_NE(f.message.find("19 bytes of the response stream were not captured (a packet cut"),
                      std::string::npos)
                << f.message;
        }
    }
    EXPECT_EQ(h.analyzer.summary().packets_cut, 1u);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.responses, 2u);
    EXPECT_EQ(device.replies_not_captured, 1u);
    ASSERT_EQ(h.sink.transactions.size(), 3u);
    EXPECT_TRUE(h.sink.transactions[0].reply_not_captured);
    EXPECT_FALSE(h.sink.transactions[0].timed_out);
}

// The same when the client polls more slowly than the timeout: the cut reply waits in its stream for a
// whole copy until the client speaks again, 5 s later, past the request's 3 s deadline; it answered in
// time all the same. And a cut that keeps only the header up to the unit id (7 bytes) or the length (6)
// still names its transaction. Before, these were timeouts (errors, exit 1) or unanswered at the end.
TEST(Analyzer, AReplyCutByTheSnapshotLengthIsAnAnswerWhenPollingIsSlowerThanTheTimeout) {
    for (const std::size_t kept : {10u, 7u, 6u}) {
        Harness h;
        h.send(true, read_request(1, 0, 10), 1s);
        h.send_cut(false, read_response(1, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}), kept, 1s + 10ms);
        h.send(true, read_request(2, 0, 1), 6s);
        h.send(false, read_response(2, {78}), 6s + 10ms);
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0) << kept;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 0) << kept;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1) << kept;
        const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
        EXPECT_EQ(device.timeouts, 0u) << kept;
        EXPECT_EQ(device.replies_not_captured, 1u) << kept;
        EXPECT_EQ(device.responses, 1u) << kept;
        EXPECT_EQ(h.analyzer.summary().errors, 0u) << kept;
    }
}

// A reply cut after a request timed out is no answer in time: the timeout stands.
TEST(Analyzer, AReplyCutAfterTheTimeoutLeavesTheTimeout) {
    Harness h;
    h.send(true, read_request(1, 0, 10), 1s);
    h.send_cut(false, read_response(1, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}), 10, 5s);
    h.send(true, read_request(2, 0, 1), 9s);
    h.send(false, read_response(2, {78}), 9s + 10ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 1u);
}

// The same cut in the request stream: the reply that answers the cut request is not unsolicited; and a
// transaction whose request and reply are both cut is named once, not left as two runs of unparsed bytes.
TEST(Analyzer, ARequestCutByTheSnapshotLengthLeavesItsReplyNotUnsolicited) {
    Harness h;
    h.send_cut(true, read_request(4, 0, 1), 10, 1s);  // 10 of 12 bytes
    h.send(false, read_response(4, {5}), 1s + 10ms);
    h.send_cut(true, read_request(5, 0, 10), 10, 2s);
    h.send_cut(false, read_response(5, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}), 10, 2s + 10ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 2);
    std::string said;
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::PairRequestNotCaptured) said += f.message + "\n";
    EXPECT_NE(
        said.find("the reply to transaction id 4, whose request the capture holds only in part (10 of its 12 "
                  "bytes, cut to the capture"),
        std::string::npos)
        << said;
    EXPECT_NE(
        said.find("transaction id 5 to unit 17: the capture holds only part of its request (10 of its 12 "
                  "bytes, cut to the snapshot length) and of its reply (10 of its 29 bytes"),
        std::string::npos)
        << said;
    EXPECT_EQ(h.analyzer.summary().packets_cut, 3u);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
}

TEST(PacketParser, TheBytesASnapshotLengthCutAreCounted) {
    const std::vector<std::uint8_t> payload(29, 0x42);
    const auto whole = packet(false, 7, payload);
    an::L4Packet l4;
    ASSERT_EQ(an::parse_packet(link_raw, whole, l4), an::ParseStatus::Ok);
    EXPECT_EQ(l4.payload_cut, 0u);
    an::L4Packet cut;
    ASSERT_EQ(an::parse_packet(link_raw, std::span(whole).first(whole.size() - 19), cut),
              an::ParseStatus::Ok);
    EXPECT_EQ(cut.payload.size(), 10u);
    EXPECT_EQ(cut.payload_cut, 19u);
}

// A cut copy followed by a whole one (a second tap merged in, a retransmission): the whole copy fills the
// hole. Before, the hole was given up at the cut copy and the whole one dropped as a retransmission.
TEST(Analyzer, AWholeCopyAfterACutOneFillsTheHole) {
    Harness h;
    h.send(true, read_request(1, 0, 10), 1s);
    const std::uint32_t at = h.seq[1];
    const auto reply = read_response(1, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9});
    h.send_cut(false, reply, 10, 1s + 10ms);
    h.resend(false, reply, at, 1s + 11ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 0);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    ASSERT_TRUE(h.sink.transactions[0].response);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").responses, 1u);
}

// An IP header whose length is more than its whole record holds (the record's own lengths agree) is no cut
// by the snapshot length: nothing is skipped. Before, the bytes it claimed were skipped as a cut, every
// later segment dropped as old, and the device blamed with timeouts.
TEST(Analyzer, AnIpLengthThatLiesIsNoSnapshotCut) {
    Harness h;
    h.send(true, read_request(1), 1s);
    auto lying = packet(false, h.seq[1], read_response(1), false, 0x18, 502, h.seq[0]);
    h.seq[1] += static_cast<std::uint32_t>(read_response(1).size());
    lying[2] = 0x0F;  // IPv4 total length 0x0FFF, the record whole
    lying[3] = 0xFF;
    h.raw(lying, 1s + 10ms);
    for (int i = 2; i < 6; ++i) {
        h.send(true, read_request(static_cast<std::uint16_t>(i)), std::chrono::seconds(i));
        h.send(false, read_response(static_cast<std::uint16_t>(i)), std::chrono::seconds(i) + 10ms);
    }
    h.analyzer.finish();
    EXPECT_EQ(h.analyzer.summary().packets_cut, 0u);
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").responses, 5u);
}

// Three writes under one transaction id, the first answered after its timeout: its late echo is its own, and
// the other two echoes their own. Before, the late echo went to the second write and each after it shifted by
// one: three echo mismatches against a device that echoed every write exactly.
TEST(Analyzer, ALateReplyUnderAReusedIdIsTheOldestRequests) {
    Harness h;
    h.send(true, write_register(504, 4, 2500), 1s);
    h.send(true, write_register(504, 4, 0), 2s);
    h.send(true, write_register(504, 5, 14017), 3s);
    h.send(false, write_register(504, 4, 2500), 4500ms);
    h.send(false, write_register(504, 4, 0), 4600ms);
    h.send(false, write_register(504, 5, 14017), 4700ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairEchoMismatch), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);  // the first, reported when it timed out
    for (const auto& t : h.sink.transactions)
        if (t.response) {
            EXPECT_EQ(t.request.pdu->body, t.response->pdu->body) << "frame " << t.request.index;
        }
}

// Cut requests from a client that sends the same id and request again, each echoed whole: each echo is the
// reply to its cut request, not "one request answered twice".
TEST(Analyzer, RepliesToCutRequestsUnderOneIdAreNoDuplicates) {
    Harness h;
    for (int i = 1; i <= 3; ++i) {
        h.send_cut(true, write_register(0, 7, 42), 8, std::chrono::seconds(i));
        h.send(false, write_register(0, 7, 42), std::chrono::seconds(i) + 10ms);
    }
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairDuplicateResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairRequestNotCaptured), 3);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
}

// A reply the tap lost whole, the client's acknowledgement covering it, then more polls answered: the
// request's reply may be in the hole, so it is pair.response_not_captured (a warning), not the server's
// timeout (pair.no_response, an error). Before, 22b_lost_reply_then_polling.pcap gave the server a timeout.
TEST(Analyzer, AReplyTheTapLostIsNoTimeoutOfTheServer) {
    Harness h;
    h.open(0s);
    h.send(true, read_request(1), 1s);
    h.lose(false, read_response(1));  // sent, acknowledged, not captured
    h.send(true, {}, 1s + 2ms);       // the client's acknowledgement of it
    for (std::uint16_t tid = 2; tid <= 11; ++tid) {
        h.send(true, read_request(tid), tid * 1s);
        h.send(false, read_response(tid), tid * 1s + 1ms);
    }
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
    EXPECT_EQ(h.analyzer.summary().errors, 0u);
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.timeouts, 0u);
    EXPECT_EQ(device.replies_not_captured, 1u);
    EXPECT_EQ(device.responses, 10u);
}

// The same, the server silent until after the request's timeout: nothing of its stream shows the hole, which
// waited, and the request timed out. Acknowledged before its deadline, the hole is given up then.
TEST(Analyzer, AReplyTheTapLostBeforeASilenceIsNoTimeoutOfTheServer) {
    Harness h;
    h.open(0s);
    h.send(true, read_request(1), 1s);
    h.lose(false, read_response(1));
    h.send(true, {}, 1s + 2ms);
    h.send(true, read_request(2), 6s);
    h.send(false, read_response(2), 6s + 1ms);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
    EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 0u);
    // A request sent after the acknowledgement has no reply in the hole: its silence is a timeout.
    Harness g;
    g.open(0s);
    g.send(true, read_request(1), 1s);
    g.lose(false, read_response(1));
    g.send(true, {}, 1s + 2ms);
    g.send(true, read_request(2), 1s + 500ms);
    g.send(true, read_request(3), 9s);
    g.analyzer.finish();
    EXPECT_EQ(g.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
    EXPECT_EQ(g.sink.count(mb::FindingCode::PairNoResponse), 1);  // request 2
}

// A hole in the middle of a reply: the bytes after it are the rest of that reply, after a gap, not a bad
// MBAP header (tcp.length_invalid, an error against the device). 10_gap_reply.pcap and
// 26_gap_then_reply_same_seg.pcap, whose tail shares a segment with the next reply.
TEST(Analyzer, BytesAfterAGapBeforeTheNextHeaderAreUnparsedNotABadLength) {
    for (const bool next_in_same_segment : {false, true}) {
        Harness h;
        h.open(0s);
        const std::vector<std::uint16_t> ten{0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
        const auto reply = read_response(1, ten);  // 29 bytes
        h.send(true, read_request(1, 0, 10), 1s);
        if (next_in_same_segment) h.send(true, read_request(2), 1s + 1ms);
        h.send(false, {reply.begin(), reply.begin() + 10}, 1s + 2ms);
        h.lose(false, {reply.begin() + 10, reply.begin() + 16});
        std::vector<std::uint8_t> tail(reply.begin() + 16, reply.end());
        if (next_in_same_segment) {
            const auto second = read_response(2);
            tail.insert(tail.end(), second.begin(), second.end());
        }
        h.send(false, tail, 1s + 3ms);
        if (!next_in_same_segment) {
            h.send(true, read_request(2), 2s);
            h.send(false, read_response(2), 2s + 1ms);
        }
        h.send(true, read_request(3), 3s);
        h.send(false, read_response(3), 3s + 1ms);
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 0) << next_in_same_segment;
        EXPECT_EQ(h.analyzer.summary().errors, 0u) << next_in_same_segment;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairResponseNotCaptured), 1);
        ASSERT_EQ(h.sink.unparsed_records.size(), 2u);
        EXPECT_EQ(h.sink.unparsed_records[0].reason, mb::UnparsedReason::Truncated);  // the reply's head
        EXPECT_EQ(h.sink.unparsed_records[1].reason, mb::UnparsedReason::AfterGap);
        EXPECT_EQ(h.sink.unparsed_records[1].length, 13u);
        EXPECT_EQ(h.sink.unparsed_records[1].offset, 16u);
        EXPECT_EQ(h.analyzer.summary().transactions, 3u);
    }
}

// Once in step after a gap, a length no ADU can have is a bad header again.
TEST(Analyzer, ABadLengthAfterAGapAndAFrameIsStillALengthError) {
    Harness h;
    h.open(0s);
    h.send(true, read_request(1), 1s);
    h.lose(true, read_request(2));
    h.send(true, read_request(3), 2s);
    auto bad = read_request(4);
    bad[4] = 0;
    bad[5] = 0;  // MBAP length 0
    h.send(true, bad, 3s);
    h.send(true, read_request(5), 4s);
    h.analyzer.finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::StreamGap), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 1);
}

// Request 2 is captured at 1.0 s ahead of a hole that request 1's retransmission fills at 1.6 s: request 2
// comes out with request 1, stamped 1.0 s as its packet, after requests queued meanwhile with later
// deadlines. Its deadline (4.0 s) was queued behind theirs and passed unseen: its reply at 4.3 s read as
// in time, 3,300 ms with a 3 s timeout and no timeout counted.
TEST(Analyzer, ARequestReleasedFromBehindAHoleTimesOutAtItsOwnDeadline) {
    Harness h;
    h.open(0s);
    const auto r1 = read_request(1), r2 = read_request(2);
    const std::uint32_t at = h.seq[0];
    h.resend(true, r2, at + static_cast<std::uint32_t>(r1.size()), 1s);  // ahead of the hole
    h.resend(true, r1, at, 1s + 600ms);                                  // fills it
    h.seq[0] += static_cast<std::uint32_t>(r1.size() + r2.size());
    h.send(false, read_response(1), 1s + 610ms);
    h.send(false, read_response(2), 4s + 300ms);
    h.analyzer.finish();
    const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
    EXPECT_EQ(device.timeouts, 1u);
    EXPECT_EQ(device.late_responses, 1u);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
}

// The client resets the connection while its request waits, and the server's reply, on its way already,
// comes a millisecond later: it answers the request (tshark pairs them). Before, the request was the
// server's timeout ("before the client reset the connection") and its reply unsolicited. The server's
// stream goes on at the reset: a reply whose first segment came before it and the rest after is one reply
// (restarting the server's stream too cut it into "truncated" bytes and bytes "before the first header").
TEST(Analyzer, AReplyCapturedAfterTheClientsResetStillAnswersItsRequest) {
    for (const bool split : {false, true}) {
        Harness h;
        h.open(0s);
        h.send(true, read_request(1), 1s);
        const auto reply = read_response(1);
        const std::size_t before = split ? 5 : 0;
        if (split)
            h.send(false, std::vector<std::uint8_t>(reply.begin(), reply.begin() + before), 1s + 500us);
        h.raw(packet(true, h.seq[0], {}, false, 0x14, 502, h.seq[1]), 1s + 1ms);  // RST, ACK
        h.send(false,
               std::vector<std::uint8_t>(reply.begin() + static_cast<std::ptrdiff_t>(before), reply.end()),
               1s + 2ms);
        h.raw(packet(true, h.seq[0], {}, false, 0x04, 502, 0), 1s + 3ms);  // RST to the reply
        h.analyzer.finish();
        ASSERT_EQ(h.sink.transactions.size(), 1u) << split;
        EXPECT_TRUE(h.sink.transactions[0].response.has_value()) << split;
        EXPECT_EQ(h.sink.transactions[0].latency, 2ms) << split;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0) << split;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0) << split;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairClientAborted), 0) << split;
        EXPECT_EQ(h.sink.count(mb::FindingCode::StreamUnparsedBytes), 0) << split;
        EXPECT_EQ(h.analyzer.summary().errors, 0u) << split;
        EXPECT_EQ(h.analyzer.summary().unparsed_bytes, 0u) << split;
        EXPECT_EQ(h.analyzer.summary().devices.at("10.0.0.2:502 unit 17").timeouts, 0u) << split;
    }
}

// No reply after the client's reset: the client gave up on the request (pair.client_aborted, a note), no
// timeout of the server's; at its timeout, or at the client's next SYN, whose connection's ids start over.
TEST(Analyzer, ARequestTheClientResetOnIsTheClientsAbortNotATimeout) {
    for (const bool reconnects : {false, true}) {
        Harness h;
        h.open(0s);
        h.send(true, read_request(1), 1s);
        h.raw(packet(true, h.seq[0], {}, false, 0x14, 502, h.seq[1]), 1s + 1ms);
        if (reconnects) {
            h.seq[0] = 70001;
            h.seq[1] = 90001;
            h.open(1s + 500ms);
            h.send(true, read_request(1), 1s + 501ms);
            h.send(false, read_response(1), 1s + 502ms);
        } else {
            h.send(true, read_request(5), 9s);  // a later packet, past the request's timeout
        }
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairClientAborted), 1) << reconnects;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0) << reconnects;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairUnsolicitedResponse), 0) << reconnects;
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairTransactionIdDuplicate), 0) << reconnects;
        const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
        EXPECT_EQ(device.timeouts, 0u);
        EXPECT_EQ(device.client_aborted, 1u);
        EXPECT_EQ(device.responses, reconnects ? 1u : 0u);
    }
}

// Bytes that waited ahead of a hole are the packet's that carried them, at its time: two replies captured
// out of order (43_ooo_replies.pcap) each keep their packet and latency; the tail after a gap and the reply
// sharing its segment, released by the client's next packet, are the segment's packet's.
// Two pipelined requests; the reply to the first is lost on the network, the reply to the second captured
// 50 ms after it and waiting behind that hole; the server sends the lost reply again 3.5 s later, past the
// 3 s timeout. The second request was answered in 50 ms: it was a pair.no_response at its deadline and then
// a reply "50 ms after it, past the 3000 ms timeout". Only the first timed out, and its reply is late. When
// the retransmission runs on over the waiting reply (with other values here), the waiting copy keeps its own
// packet, time and values, and the new copy is the conflict.
TEST(Analyzer, AReplyWaitingBehindAHoleWhenItsRequestsDeadlinePassesWasInTime) {
    for (const bool over_both : {false, true}) {
        SCOPED_TRACE(over_both ? "the retransmission covers both replies"
                               : "the retransmission fills the hole");
        Harness h;
        h.open(0s);
        auto both = read_request(1);
        const auto second = read_request(2);
        both.insert(both.end(), second.begin(), second.end());
        h.send(true, both, 1s);  // packet 3
        const auto r1 = read_response(1), r2 = read_response(2);
        const std::uint32_t r1_at = h.seq[1];
        h.lose(false, r1);
        h.send(false, r2, 1s + 50ms);  // packet 4
        auto again = r1;
        if (over_both) {
            auto other = read_response(2, {9, 9, 9});
            again.insert(again.end(), other.begin(), other.end());
        }
        h.resend(false, again, r1_at, 4s + 500ms);  // packet 5
        h.analyzer.finish();
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
        EXPECT_EQ(h.sink.count(mb::FindingCode::StreamRetransmissionConflict), over_both ? 1 : 0);
        bool answered_in_time = false, late = false;
        for (const auto& t : h.sink.transactions) {
            if (!t.response) continue;
            if (t.request.frame.transaction_id() == 2) {
                answered_in_time = true;
                EXPECT_EQ(t.response->packet, 4u);
                EXPECT_EQ(t.latency, 50ms);
                EXPECT_FALSE(t.late_past);
                const auto adu = t.response->frame.adu();
                EXPECT_EQ(std::vector<std::uint8_t>(adu.begin(), adu.end()), r2);  // the first copy's values
            } else {
                late = true;
                EXPECT_EQ(t.response->packet, 5u);
                EXPECT_EQ(t.latency, 3500ms);
                EXPECT_TRUE(t.late_past);
            }
        }
        EXPECT_TRUE(answered_in_time);
        EXPECT_TRUE(late);
    }
}

TEST(Analyzer, BytesThatWaitedBehindAHoleKeepThePacketThatCarriedThem) {
    {
        Harness h;
        h.open(0s);
        auto both = read_request(1);
        const auto second = read_request(2);
        both.insert(both.end(), second.begin(), second.end());
        h.send(true, both, 1s);  // packet 3
        const auto r1 = read_response(1), r2 = read_response(2);
        h.resend(false, r2, h.seq[1] + static_cast<std::uint32_t>(r1.size()), 1s + 1ms);  // packet 4
        h.send(false, r1, 1s + 2ms);                                                      // packet 5
        h.analyzer.finish();
        ASSERT_EQ(h.sink.transactions.size(), 2u);
        for (const auto& t : h.sink.transactions) {
            ASSERT_TRUE(t.response.has_value());
            const bool first = t.request.frame.transaction_id() == 1;
            EXPECT_EQ(t.response->packet, first ? 5u : 4u);
            EXPECT_EQ(t.latency, first ? 2ms : 1ms);
        }
    }
    {
        Harness h;
        h.open(0s);
        h.send(true, read_request(1, 0, 10), 1s);
        h.send(true, read_request(2), 1s + 1ms);
        const auto reply = read_response(1, std::vector<std::uint16_t>(10, 7));
        h.send(false, {reply.begin(), reply.begin() + 10}, 1s + 2ms);  // packet 5
        h.lose(false, {reply.begin() + 10, reply.begin() + 16});
        std::vector<std::uint8_t> tail(reply.begin() + 16, reply.end());
        const auto second = read_response(2);
        tail.insert(tail.end(), second.begin(), second.end());
        h.send(false, tail, 1s + 3ms);  // packet 6, ahead of the hole until packet 7 acknowledges it
        h.send(true, read_request(3), 2s);
        h.send(false, read_response(3), 2s + 1ms);
        h.analyzer.finish();
        ASSERT_EQ(h.sink.unparsed_records.size(), 2u);
        EXPECT_EQ(h.sink.unparsed_records[1].packet, 6u);
        EXPECT_EQ(h.sink.unparsed_records[1].time, 1s + 3ms);
        bool seen = false;
        for (const auto& t : h.sink.transactions)
            if (t.request.frame.transaction_id() == 2 && t.response) {
                seen = true;
                EXPECT_EQ(t.response->packet, 6u);
                EXPECT_EQ(t.response->time, 1s + 3ms);
            }
        EXPECT_TRUE(seen);
    }
}

// A server sends each reply whole in its own segment, the first with an MBAP length 1 or 2 too long (a
// gateway counting the RTU CRC). Read by the length, reply 1 took reply 2's first byte: answered at 2.01 s
// (1,010 ms) with a bad byte count, 12 bytes formed no frame (tcp.length_invalid) and request 2 went
// unanswered. The segments show what happened: reply 1 is what its segment held, in 10 ms, and its length
// is the server's fault.
TEST(Analyzer, AReplySentWholeWithItsLengthTooLongIsAnsweredInTime) {
    for (const std::uint8_t excess : {1, 2}) {
        Harness h;
        h.open(0s);
        h.send(true, read_request(1), 1s);
        auto reply = read_response(1);  // MBAP length 9
        reply[5] = static_cast<std::uint8_t>(reply[5] + excess);
        h.send(false, reply, 1s + 10ms);  // packet 4
        h.send(true, read_request(2), 2s);
        h.send(false, read_response(2), 2s + 10ms);
        h.analyzer.finish();
        ASSERT_EQ(h.sink.transactions.size(), 2u) << int{excess};
        for (const auto& t : h.sink.transactions) {
            ASSERT_TRUE(t.response) << t.request.frame.transaction_id();
            EXPECT_FALSE(t.timed_out);
            ASSERT_TRUE(t.latency);
            EXPECT_EQ(*t.latency, 10ms) << t.request.frame.transaction_id();
            EXPECT_EQ(t.response->frame.transaction_id(), t.request.frame.transaction_id());
        }
        EXPECT_EQ(h.sink.transactions[0].response->packet, 4u);
        EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthBeyondSegment), 1);
        EXPECT_EQ(h.sink.count(mb::FindingCode::TcpLengthInvalid), 0);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PduByteCountMismatch), 0);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
        EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 0);
        EXPECT_TRUE(h.sink.unparsed_records.empty());
        EXPECT_EQ(h.analyzer.summary().unparsed_bytes, 0u);
        const auto& device = h.analyzer.summary().devices.at("10.0.0.2:502 unit 17");
        EXPECT_EQ(device.responses, 2u);
        EXPECT_EQ(device.timeouts, 0u);
        for (const auto& f : h.sink.findings) {
            if (f.code == mb::FindingCode::TcpLengthBeyondSegment) {
                EXPECT_EQ(f.packet, 4u);
                EXPECT_EQ(f.time, 1s + 10ms);
                EXPECT_EQ(f.message, excess == 1
                                         ? "MBAP length 10, the server's segment held 9 bytes after the "
                                           "first 6 (unit id + PDU): a client reading by the length "
                                           "waits for 1 more byte and takes it from the next reply"
                                         : "MBAP length 11, the server's segment held 9 bytes after the "
                                           "first 6 (unit id + PDU): a client reading by the length "
                                           "waits for 2 more bytes and takes them from the next reply");
            }
        }
    }
}

}  // namespace test_analyzer_analyzer_test
