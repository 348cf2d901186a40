// IP fragments: a Modbus ADU in a fragmented datagram was dropped without a word (the parser answered
// "fragment" and the analyzer moved on). Fragments are reassembled now, in any order and with duplicates; a
// datagram that never completes is counted in the summary.
#include "analyzer/ip_reassembly.hpp"

#include <gtest/gtest.h>

#include <sstream>

#include "analyzer/packet_parser.hpp"
#include "analyzer/sinks.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_packets.hpp"

namespace test_analyzer_ip_reassembly_test {

using namespace mbscope::test;
using namespace std::chrono_literals;

namespace {

std::vector<std::uint8_t> read_request(std::uint16_t tid) {
    return mb::encode_tcp(
        tid, 17, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0x6B, 3)));
}

std::vector<std::uint8_t> read_response(std::uint16_t tid) {
    const std::uint16_t values[] = {0x022B, 0, 0x64};
    return mb::encode_tcp(
        tid, 17,
        mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, values)));
}

// An IPv4 packet (20-byte header, as packet() builds it) cut into fragments at the given transport-data
// offsets (multiples of 8), each a packet of its own.
std::vector<std::vector<std::uint8_t>> fragments_v4(const std::vector<std::uint8_t>& ip,
                                                    const std::vector<std::size_t>& cuts, std::uint16_t id) {
    const std::span<const std::uint8_t> data(ip.begin() + 20, ip.end());
    std::vector<std::size_t> at = cuts;
    at.insert(at.begin(), 0);
    at.push_back(data.size());
    std::vector<std::vector<std::uint8_t>> out;
    for (std::size_t i = 0; i + 1 < at.size(); ++i) {
        std::vector<std::uint8_t> f(ip.begin(), ip.begin() + 20);
        const std::size_t total = 20 + at[i + 1] - at[i];
        const std::uint16_t flags =
            static_cast<std::uint16_t>((i + 2 < at.size() ? 0x2000 : 0) | (at[i] / 8));
        f[2] = static_cast<std::uint8_t>(total >> 8);
        f[3] = static_cast<std::uint8_t>(total);
        f[4] = static_cast<std::uint8_t>(id >> 8);
        f[5] = static_cast<std::uint8_t>(id);
        f[6] = static_cast<std::uint8_t>(flags >> 8);
        f[7] = static_cast<std::uint8_t>(flags);
        f.insert(f.end(), data.begin() + static_cast<std::ptrdiff_t>(at[i]),
                 data.begin() + static_cast<std::ptrdiff_t>(at[i + 1]));
        out.push_back(std::move(f));
    }
    return out;
}

// An IPv6 fragment from 2001:db8::1 to 2001:db8::2 carrying `data` of the datagram at `offset`.
std::vector<std::uint8_t> fragment_v6(std::uint8_t next, std::uint32_t id, std::size_t offset, bool more,
                                      std::span<const std::uint8_t> data, bool to_server = true) {
    std::vector<std::uint8_t> p = {0x60, 0, 0, 0, 0, 0, 44, 64};
    const std::size_t payload = 8 + data.size();
    p[4] = static_cast<std::uint8_t>(payload >> 8);
    p[5] = static_cast<std::uint8_t>(payload);
    std::vector<std::uint8_t> a = {0x20, 0x01, 0x0d, 0xb8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
    std::vector<std::uint8_t> b = a;
    b[15] = 2;
    const auto& src = to_server ? a : b;
    const auto& dst = to_server ? b : a;
    p.insert(p.end(), src.begin(), src.end());
    p.insert(p.end(), dst.begin(), dst.end());
    const std::uint16_t off = static_cast<std::uint16_t>(offset | (more ? 1 : 0));
    for (const int b : {int{next}, 0, off >> 8, off & 0xFF, int(id >> 24), int(id >> 16 & 0xFF),
                        int(id >> 8 & 0xFF), int(id & 0xFF)})
        p.push_back(static_cast<std::uint8_t>(b));
    p.insert(p.end(), data.begin(), data.end());
    return p;
}

// UDP header (ports 40000 → 502 or back) and payload, as an IPv6 datagram's transport data.
std::vector<std::uint8_t> udp(const std::vector<std::uint8_t>& payload, bool to_server) {
    const std::size_t len = 8 + payload.size();
    const std::uint16_t sport = to_server ? 40000 : 502, dport = to_server ? 502 : 40000;
    std::vector<std::uint8_t> d;
    for (const int b :
         {sport >> 8, sport & 0xFF, dport >> 8, dport & 0xFF, int(len >> 8), int(len & 0xFF), 0, 0})
        d.push_back(static_cast<std::uint8_t>(b));
    d.insert(d.end(), payload.begin(), payload.end());
    return d;
}

std::string text_summary(const an::Summary& s) {
    std::ostringstream out;
    an::TextSink sink(out);
    sink.end(s);
    return out.str();
}

}  // namespace

TEST(IpReassembly, TcpSegmentInFragmentsOutOfOrderAndDuplicatedIsDecoded) {
    Conversation c;
    const auto request = read_request(1);
    auto pieces = fragments_v4(packet(true, 1000, request, false, 0x18, 502, 5000), {8, 24}, 0x1234);
    ASSERT_EQ(pieces.size(), 3u);
    c.records.push_back({1s, pieces[2]});
    c.records.push_back({1s, pieces[0]});
    c.records.push_back({1s, pieces[0]});  // a duplicate
    c.records.push_back({1s + 1ms, pieces[1]});
    c.seq[0] += static_cast<std::uint32_t>(request.size());
    c.send(false, read_response(1), 1s + 3ms);
    const auto d = decode_pcap(c.file());
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_EQ(d->sink.transactions[0].latency, 2ms);  // from the fragment that completed the request
    EXPECT_TRUE(d->sink.findings.empty());
    EXPECT_EQ(d->summary.ip_datagrams_incomplete, 0u);
    EXPECT_EQ(text_summary(d->summary).find("not decoded"), std::string::npos);
}

TEST(IpReassembly, Ipv6UdpDatagramInTwoFragments) {
    std::vector<PcapRecord> records;
    const auto request = udp(read_request(7), true), response = udp(read_response(7), false);
    records.push_back({1s, fragment_v6(17, 99, 8, false, std::span(request).subspan(8), true)});
    records.push_back({1s, fragment_v6(17, 99, 0, true, std::span(request).first(8), true)});
    records.push_back({1s + 1ms, fragment_v6(17, 5, 0, true, std::span(response).first(16), false)});
    records.push_back({1s + 1ms, fragment_v6(17, 5, 16, false, std::span(response).subspan(16), false)});
    const auto d = decode_pcap(pcap_file(link_raw, records));
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_EQ(d->sink.transactions[0].request.frame.transaction_id(), 7);
    EXPECT_TRUE(d->sink.transactions[0].response.has_value());
    EXPECT_TRUE(d->sink.findings.empty());
}

TEST(IpReassembly, ADatagramMissingAFragmentIsCountedNotDropped) {
    Conversation c;
    const auto pieces = fragments_v4(packet(true, 1000, read_request(1), false, 0x18, 502, 5000), {16}, 7);
    c.records.push_back({1s, pieces[0]});  // the second fragment was never captured
    const auto d = decode_pcap(c.file());
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_EQ(d->summary.ip_datagrams_incomplete, 1u);
    EXPECT_EQ(d->summary.ip_fragments_incomplete, 1u);
    EXPECT_NE(
        text_summary(d->summary).find("not decoded: 1 IP datagrams missing fragments (1 fragments captured)"),
        std::string::npos)
        << text_summary(d->summary);
}

TEST(IpReassembly, GivesUpAfterTheTimeoutAndBoundsWhatItHolds) {
    an::IpReassembler r;
    const std::vector<std::uint8_t> eight(8, 0xAB);
    an::IpFragment f;
    f.more = true;
    f.data = eight;
    f.id = 1;
    EXPECT_FALSE(r.add(f, 0s));
    r.expire(29s, false);
    EXPECT_EQ(r.incomplete_datagrams(), 0u);
    r.expire(31s, false);
    EXPECT_EQ(r.incomplete_datagrams(), 1u);
    // More datagrams in progress than it holds: the oldest are given up, one per newcomer.
    for (std::uint32_t id = 0; id < an::IpReassembler::max_datagrams + 10; ++id) {
        f.id = 1000 + id;
        EXPECT_FALSE(r.add(f, 40s));
    }
    EXPECT_EQ(r.incomplete_datagrams(), 11u);
    r.expire(41s, true);
    EXPECT_EQ(r.incomplete_datagrams(), 1u + an::IpReassembler::max_datagrams + 10);
    // A fragment reaching past 65,535 bytes is refused, not allocated.
    f.offset = 65528 + 8;
    EXPECT_FALSE(r.add(f, 50s));
    EXPECT_EQ(r.invalid_fragments(), 1u);
    // The last fragment says where the datagram ends; bytes a fragment claimed past it are not its own.
    an::IpFragment a, b;
    a.id = b.id = 77;
    const std::vector<std::uint8_t> sixteen(16, 0x11), tail(4, 0x22);
    a.more = true;
    a.data = sixteen;
    b.offset = 8;
    b.data = tail;
    EXPECT_FALSE(r.add(a, 60s));
    const auto whole = r.add(b, 60s);
    ASSERT_TRUE(whole);
    EXPECT_EQ(whole->bytes, (std::vector<std::uint8_t>{0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x11,
                                                       0x11, 0x11, 0x11}));
}

}  // namespace test_analyzer_ip_reassembly_test
