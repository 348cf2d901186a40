// A Modbus/TCP client whose own port is 502 too (some PLCs and gateways bind it for their outgoing
// connections): the ports no longer say which end is the server. Before, every segment was taken for one
// sent to the server, so the server's replies were decoded as requests from a second "client", a phantom
// device 10.0.0.1:502 with malformed requests. The SYN says who the client is; without it, the end that
// speaks first.
#include <gtest/gtest.h>

#include "analyzer/analyzer.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_packets.hpp"

namespace test_analyzer_both_server_ports_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace mbscope::test;

namespace {

// Segments between 10.0.0.1:502 and 10.0.0.2:502, each acknowledging what the other end sent.
struct BothOn502 {
    Collect sink;
    an::Analyzer analyzer{an::AnalyzerOptions{}, sink};
    std::uint64_t number = 0;
    std::uint32_t seq[2] = {1000, 5000};  // sent by 10.0.0.1, by 10.0.0.2
    // `from_first`: sent by 10.0.0.1.
    void send(bool from_first, const std::vector<std::uint8_t>& payload, std::uint8_t flags = 0x18) {
        const int me = from_first ? 0 : 1;
        const bool syn = flags & 0x02;
        const auto p = packet(from_first, syn ? seq[me] - 1 : seq[me], payload, false, flags, 502,
                              (flags & 0x10) ? seq[1 - me] : 0, 502);
        seq[me] += static_cast<std::uint32_t>(payload.size());
        an::Packet record;
        record.number = ++number;
        record.time = mb::Timestamp(static_cast<std::int64_t>(number) * 1'000'000);
        record.linktype = link_raw;
        record.data = p;
        record.original_length = static_cast<std::uint32_t>(p.size());
        analyzer.packet("both-502", record);
    }
    void finish() { analyzer.finish(); }
};

std::vector<std::uint8_t> read_request(std::uint16_t tid) {
    return mb::encode_tcp(
        tid, 1, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 2)));
}
std::vector<std::uint8_t> read_response(std::uint16_t tid) {
    const std::vector<std::uint16_t> values{7, 8};
    return mb::encode_tcp(
        tid, 1,
        mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, values)));
}

// Every exchange paired, no finding, one device: the server's.
void expect_one_server(const BothOn502& c, const std::string& server, std::size_t exchanges) {
    ASSERT_EQ(c.sink.transactions.size(), exchanges);
    for (const auto& t : c.sink.transactions) {
        EXPECT_TRUE(t.response.has_value());
        EXPECT_EQ(t.request.device.str(), server + " unit 1");
    }
    for (const auto& f : c.sink.findings)
        ADD_FAILURE() << f.message;
    EXPECT_EQ(c.analyzer.summary().devices.size(), 1u);
    EXPECT_EQ(c.analyzer.summary().devices.count(server + " unit 1"), 1u);
}

}  // namespace

TEST(BothServerPorts, TheSynSaysWhoTheClientIs) {
    for (const bool first_is_client : {true, false}) {
        SCOPED_TRACE(first_is_client);
        BothOn502 c;
        c.send(first_is_client, {}, 0x02);   // SYN
        c.send(!first_is_client, {}, 0x12);  // SYN-ACK
        c.send(first_is_client, {}, 0x10);   // ACK
        for (std::uint16_t tid = 1; tid <= 3; ++tid) {
            c.send(first_is_client, read_request(tid));
            c.send(!first_is_client, read_response(tid));
        }
        c.finish();
        expect_one_server(c, first_is_client ? "10.0.0.2:502" : "10.0.0.1:502", 3);
    }
}

// Without the SYN (a capture begun mid-connection) the first to send an ADU is the client; an ACK or a
// keepalive probe (one byte the server's stack sends again) before it tells nothing.
TEST(BothServerPorts, WithoutTheSynTheFirstToSpeakIsTheClient) {
    for (const bool first_is_client : {true, false}) {
        SCOPED_TRACE(first_is_client);
        BothOn502 c;
        c.send(!first_is_client, {}, 0x10);      // the server's ACK of something before the capture
        c.send(!first_is_client, {0x00}, 0x10);  // its keepalive probe: one byte it sent before
        for (std::uint16_t tid = 1; tid <= 3; ++tid) {
            c.send(first_is_client, read_request(tid));
            c.send(!first_is_client, read_response(tid));
        }
        c.finish();
        expect_one_server(c, first_is_client ? "10.0.0.2:502" : "10.0.0.1:502", 3);
    }
}

}  // namespace test_analyzer_both_server_ports_test
