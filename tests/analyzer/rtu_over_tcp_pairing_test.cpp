// Pairing on RTU over TCP (--rtu-over-tcp): a gateway queues the requests of a connection and answers them
// in turn, so requests a client writes at once (in one segment) are pipelined and do not end each other's
// wait; a request in a segment of its own does end the wait of those before it, as a master's next request
// does on a serial line (RTU has no transaction id: a client waits for each reply, or gave up on it). And a
// reply the tap lost in part, in bytes the client acknowledged, is the capture's loss
// (pair.response_not_captured), not the device's timeout, as over Modbus/TCP.
#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "test_packets.hpp"

namespace test_analyzer_rtu_over_tcp_pairing_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::Conversation;
using mbscope::test::decode_pcap;

namespace {

constexpr std::uint16_t gateway = 4001;
constexpr const char* server = "10.0.0.2:4001";

std::vector<std::uint8_t> rtu(std::uint8_t unit, const std::vector<std::uint8_t>& pdu) {
    return mb::encode_rtu(unit, pdu);
}
std::vector<std::uint8_t> read_holding(std::uint8_t unit, std::uint8_t start, std::uint8_t quantity) {
    return rtu(unit, {0x03, 0x00, start, 0x00, quantity});
}
std::vector<std::uint8_t> concat(std::vector<std::uint8_t> a, const std::vector<std::uint8_t>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}
// Modbus/TCP: an MBAP header (transaction id, protocol 0, length) in front of unit and PDU.
std::vector<std::uint8_t> mbap(std::uint8_t tid, std::uint8_t unit, const std::vector<std::uint8_t>& pdu) {
    return mb::encode_tcp(tid, unit, pdu);
}

Conversation gateway_conversation() {
    Conversation c;
    c.server_port = gateway;
    return c;
}
an::AnalyzerOptions gateway_options() {
    an::AnalyzerOptions o;
    o.rtu_over_tcp_ports = {gateway};
    return o;
}
std::string device(int unit) {
    return std::string(server) + " unit " + std::to_string(unit);
}

}  // namespace

// The client writes reads of units 1 and 2 at once: in one segment, or one write whose second request
// straddles two segments; the gateway answers unit 1 after 40 ms, then unit 2. Both answered, nothing to
// report. (It was pair.no_response, "got no response before the next request", against unit 1, its reply
// "late, the master moved on after 0 ms", exit 1.)
TEST(RtuOverTcpPairing, PipelinedRequestsAreAnsweredInTurn) {
    for (const bool one_segment : {true, false}) {
        SCOPED_TRACE(one_segment ? "in one segment" : "one write across two segments");
        Conversation c = gateway_conversation();
        const auto both = concat(read_holding(1, 0, 1), read_holding(2, 0, 1));
        if (one_segment) {
            c.send(true, both, 10ms);
        } else {
            c.send(true, {both.begin(), both.begin() + 11}, 10ms);
            c.send(true, {both.begin() + 11, both.end()}, 10ms);
        }
        c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 50ms);
        c.send(false, rtu(2, {0x03, 0x02, 0x00, 0x02}), 90ms);
        c.send(true, {}, 5s);  // well past every timeout
        const auto d = decode_pcap(c.file(), gateway_options());
        EXPECT_TRUE(d->sink.findings.empty());
        EXPECT_EQ(d->summary.errors, 0u);
        ASSERT_EQ(d->sink.transactions.size(), 2u);
        for (int unit = 1; unit <= 2; ++unit) {
            const auto& t = d->sink.transactions[static_cast<std::size_t>(unit - 1)];
            EXPECT_EQ(t.request.frame.unit_id(), unit);
            ASSERT_TRUE(t.response);
            EXPECT_EQ(t.response->frame.unit_id(), unit);
            EXPECT_FALSE(t.late_past);
            ASSERT_TRUE(t.latency);
            EXPECT_EQ(*t.latency, 40ms * unit);
            const auto& stats = d->summary.devices.at(device(unit));
            EXPECT_EQ(stats.requests, 1u);
            EXPECT_EQ(stats.responses, 1u);
            EXPECT_EQ(stats.timeouts, 0u);
            EXPECT_EQ(stats.late_responses, 0u);
        }
    }
}

// The same reads in segments of their own, 1 ms apart: nothing shows the client pipelined, and a client of
// a gateway without transaction ids waits for each reply, so the second request ends the first one's wait
// as on a serial line, and the first reply is its late one.
TEST(RtuOverTcpPairing, RequestsInSegmentsOfTheirOwnArePairedAsOnALine) {
    Conversation c = gateway_conversation();
    c.send(true, read_holding(1, 0, 1), 10ms);
    c.send(true, read_holding(2, 0, 1), 11ms);
    c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 50ms);
    c.send(false, rtu(2, {0x03, 0x02, 0x00, 0x02}), 90ms);
    c.send(true, {}, 5s);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->summary.findings,
              (std::map<std::string, std::uint64_t>{{"pair.late_response", 1}, {"pair.no_response", 1}}));
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_EQ(f.message, "request to 10.0.0.2:4001 unit 1 got no response before the next request");
        }
    }
    const auto& unit1 = d->summary.devices.at(device(1));
    EXPECT_EQ(unit1.timeouts, 1u);
    EXPECT_EQ(unit1.late_responses, 1u);
    const auto& unit2 = d->summary.devices.at(device(2));
    EXPECT_EQ(unit2.responses, 1u);
    EXPECT_EQ(unit2.timeouts, 0u);
}

// A master polls unit 1 through a gateway that does not queue, every 500 ms, alternating registers 0 and
// 100 (replies of one size), and gives each reply 300 ms, less than the analyzer's 1 s; the reply to the
// request at 2.0 s is lost on the line. That request is the timeout, and every later reply keeps its own
// request. (Each waited to its own timeout: the reply at 2.53 s answered the request at 2.0 s, and every
// later one the request before its own, register 100's values shown as register 0's, with no finding.)
TEST(RtuOverTcpPairing, ALostReplyInSteadyPollingIsATimeoutAndTheLaterRepliesKeepTheirOwnRequests) {
    Conversation c = gateway_conversation();
    for (std::uint8_t i = 0; i < 6; ++i) {
        const std::uint8_t start = i % 2 == 0 ? 0 : 100;
        const auto at = 1s + 500ms * i;
        c.send(true, read_holding(1, start, 2), at);
        if (i != 2) {
            c.send(false, rtu(1, {0x03, 0x04, 0x00, start, 0x00, i}), at + 30ms);
        }
    }
    c.send(true, {}, 5s);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->summary.findings, (std::map<std::string, std::uint64_t>{{"pair.no_response", 1}}));
    EXPECT_EQ(d->summary.errors, 1u);
    ASSERT_EQ(d->sink.transactions.size(), 6u);
    for (std::size_t i = 0; i < 6; ++i) {
        SCOPED_TRACE(i);
        const auto& t = d->sink.transactions[i];
        EXPECT_EQ(t.request.time, 1s + 500ms * static_cast<int>(i));
        EXPECT_EQ(t.response.has_value(), i != 2);
        if (t.response) {
            // the reply carries the request's start register and the poll's number
            EXPECT_EQ(t.response->frame.pdu()[3], t.request.frame.pdu()[2]);
            EXPECT_EQ(t.response->frame.pdu()[5], i);
            ASSERT_TRUE(t.latency);
            EXPECT_EQ(*t.latency, 30ms);
        }
    }
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_EQ(f.time, 2s);
            EXPECT_EQ(f.message, "request to 10.0.0.2:4001 unit 1 got no response before the next request");
        }
    }
    const auto& stats = d->summary.devices.at(device(1));
    EXPECT_EQ(stats.requests, 6u);
    EXPECT_EQ(stats.responses, 5u);
    EXPECT_EQ(stats.timeouts, 1u);
    EXPECT_EQ(stats.late_responses, 0u);
}

// Two reads of one unit, of different sizes, pipelined: each reply is paired with the request it fits, in
// turn, not the first with the second request (a size mismatch) and the second unsolicited.
TEST(RtuOverTcpPairing, PipelinedRequestsToOneUnitKeepTheirOwnReplies) {
    Conversation c = gateway_conversation();
    c.send(true, concat(read_holding(1, 0, 1), read_holding(1, 10, 2)), 10ms);
    c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 30ms);
    c.send(false, rtu(1, {0x03, 0x04, 0x00, 0x0A, 0x00, 0x0B}), 50ms);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_TRUE(d->sink.findings.empty());
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    ASSERT_TRUE(d->sink.transactions[0].response);
    EXPECT_EQ(d->sink.transactions[0].response->frame.length, 7u);
    ASSERT_TRUE(d->sink.transactions[1].response);
    EXPECT_EQ(d->sink.transactions[1].response->frame.length, 9u);
    const auto& stats = d->summary.devices.at(device(1));
    EXPECT_EQ(stats.responses, 2u);
    EXPECT_EQ(stats.timeouts, 0u);
}

// A gateway with a port per line may answer a later request first: a reply answers the request of its unit.
TEST(RtuOverTcpPairing, AReplyAnswersTheRequestOfItsUnit) {
    Conversation c = gateway_conversation();
    c.send(true, concat(read_holding(1, 0, 1), read_holding(2, 0, 1)), 10ms);
    c.send(false, rtu(2, {0x03, 0x02, 0x00, 0x02}), 30ms);
    c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 60ms);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_TRUE(d->sink.findings.empty());
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.response);
        EXPECT_EQ(t.response->frame.unit_id(), t.request.frame.unit_id());
    }
}

// On a serial line a request given up takes no late reply in another unit's slot once another exchange has
// completed (the line carried it since); through a gateway with a port per line it does: unit 1's line may
// answer after unit 2's exchange on another port, while unit 3 is asked, and its reply is unit 1's late one.
TEST(RtuOverTcpPairing, ALateReplyAfterAnotherUnitsExchangeIsStillLate) {
    Conversation c = gateway_conversation();
    c.send(true, read_holding(1, 0, 1), 10ms);
    c.send(true, read_holding(2, 0, 1), 1200ms);
    c.send(false, rtu(2, {0x03, 0x02, 0x00, 0x02}), 1250ms);
    c.send(true, read_holding(3, 0, 1), 1280ms);
    c.send(false, rtu(1, {0x03, 0x02, 0x00, 0x01}), 1300ms);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->summary.findings,
              (std::map<std::string, std::uint64_t>{
                  {"pair.late_response", 1}, {"pair.no_response", 1}, {"pair.no_response_at_end", 1}}));
    const auto& unit1 = d->summary.devices.at(device(1));
    EXPECT_EQ(unit1.timeouts, 1u);
    EXPECT_EQ(unit1.late_responses, 1u);
    EXPECT_EQ(d->summary.devices.at(device(2)).responses, 1u);
}

// A queued request still times out by the response timeout (the serial one, 1 s): unit 1's, which the
// gateway never answered, while unit 2's reply came.
TEST(RtuOverTcpPairing, AQueuedRequestStillTimesOut) {
    Conversation c = gateway_conversation();
    c.send(true, concat(read_holding(1, 0, 1), read_holding(2, 0, 1)), 10ms);
    c.send(false, rtu(2, {0x03, 0x02, 0x00, 0x02}), 50ms);
    c.send(true, {}, 5s);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(d->summary.errors, 1u);
    EXPECT_EQ(d->sink.findings.size(), 1u);
    for (const auto& f : d->sink.findings) {
        if (f.code == mb::FindingCode::PairNoResponse) {
            EXPECT_EQ(
                f.message,
                "FC3 Read Holding Registers 0+1 to 10.0.0.2:4001 unit 1 got no response within 1000 ms");
        }
    }
    EXPECT_EQ(d->summary.devices.at(device(1)).timeouts, 1u);
    EXPECT_EQ(d->summary.devices.at(device(2)).responses, 1u);
    EXPECT_EQ(d->summary.devices.at(device(2)).timeouts, 0u);
}

// A request whose CRC failed and, in the same segment, the client's good copy of it: the gateway discards the
// first, and its one reply answers the good copy, not the oldest request that it fits (which left the good
// copy a timeout against the device).
TEST(RtuOverTcpPairing, AReplyAnswersTheGoodCopyOfADamagedRequest) {
    Conversation c = gateway_conversation();
    auto damaged = rtu(3, {0x06, 0x00, 0x01, 0x00, 0x03});
    damaged.back() ^= 0x12;
    c.send(true, concat(damaged, rtu(3, {0x06, 0x00, 0x01, 0x00, 0x03})), 1s);
    c.send(false, rtu(3, {0x06, 0x00, 0x01, 0x00, 0x03}), 1s + 50ms);
    c.send(true, {}, 5s);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->summary.findings, (std::map<std::string, std::uint64_t>{
                                       {"pair.damaged_request_unanswered", 1}, {"rtu.crc_mismatch", 1}}));
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    for (const auto& t : d->sink.transactions) {
        EXPECT_EQ(t.response.has_value(), t.request.frame.checksum_ok);
        EXPECT_EQ(t.discarded, !t.request.frame.checksum_ok);
    }
    const auto& stats = d->summary.devices.at(device(3));
    EXPECT_EQ(stats.responses, 1u);
    EXPECT_EQ(stats.timeouts, 0u);
    EXPECT_EQ(stats.damaged_unanswered, 1u);
}

// The tap captured the first 4 bytes of unit 4's reply (04 03 04 00) and lost the rest, which the client
// acknowledged; then unit 5 is asked and answers. Over Modbus/TCP that is pair.response_not_captured, a
// warning; RTU over TCP gives the same verdict and the same counts (it was pair.no_response against unit 4,
// an error, exit 1).
TEST(RtuOverTcpPairing, AReplyTheTapLostInPartIsNotATimeout) {
    for (const bool rtu_over_tcp : {false, true}) {
        SCOPED_TRACE(rtu_over_tcp ? "RTU over TCP" : "Modbus/TCP");
        Conversation c;
        c.server_port = rtu_over_tcp ? gateway : 502;
        const std::vector<std::uint8_t> read4 = {0x03, 0x00, 0x00, 0x00, 0x02},
                                        reply4 = {0x03, 0x04, 0, 4, 0, 4};
        const std::vector<std::uint8_t> read5 = {0x03, 0x00, 0x00, 0x00, 0x01}, reply5 = {0x03, 0x02, 0, 5};
        const auto request4 = rtu_over_tcp ? rtu(4, read4) : mbap(1, 4, read4);
        const auto response4 = rtu_over_tcp ? rtu(4, reply4) : mbap(1, 4, reply4);
        c.send(true, request4, 1500ms);
        c.send(false, {response4.begin(), response4.begin() + 4}, 1550ms);
        c.lose(false, {response4.begin() + 4, response4.end()});
        c.send(true, {}, 1560ms);  // the client acknowledges the whole reply
        c.send(true, rtu_over_tcp ? rtu(5, read5) : mbap(2, 5, read5), 1700ms);
        c.send(false, rtu_over_tcp ? rtu(5, reply5) : mbap(2, 5, reply5), 1750ms);
        c.send(true, {}, 1800ms);
        an::AnalyzerOptions o;
        if (rtu_over_tcp) {
            o.rtu_over_tcp_ports = {gateway};
        }
        const auto d = decode_pcap(c.file(), o);
        EXPECT_EQ(d->summary.errors, 0u);
        EXPECT_EQ(d->summary.findings,
                  (std::map<std::string, std::uint64_t>{
                      {"pair.response_not_captured", 1}, {"stream.gap", 1}, {"stream.unparsed_bytes", 1}}));
        const std::string at = rtu_over_tcp ? "10.0.0.2:4001" : "10.0.0.2:502";
        const auto& unit4 = d->summary.devices.at(at + " unit 4");
        EXPECT_EQ(unit4.requests, 1u);
        EXPECT_EQ(unit4.responses, 0u);
        EXPECT_EQ(unit4.timeouts, 0u);
        EXPECT_EQ(unit4.unanswered_at_end, 0u);
        EXPECT_EQ(unit4.replies_not_captured, 1u);
        const auto& unit5 = d->summary.devices.at(at + " unit 5");
        EXPECT_EQ(unit5.responses, 1u);
        EXPECT_EQ(unit5.timeouts, 0u);
        ASSERT_EQ(d->sink.transactions.size(), 2u);
        for (const auto& t : d->sink.transactions) {
            EXPECT_EQ(t.reply_not_captured, t.request.frame.unit_id() == 4);
            EXPECT_EQ(t.response.has_value(), t.request.frame.unit_id() == 5);
        }
        if (rtu_over_tcp) {
            for (const auto& f : d->sink.findings) {
                if (f.code == mb::FindingCode::PairResponseNotCaptured) {
                    EXPECT_EQ(f.message,
                              "FC3 Read Holding Registers 0+2 to 10.0.0.2:4001 unit 4 was answered, but the "
                              "capture "
                              "holds only the first 4 bytes of the reply (unit 4, function code 3), the rest "
                              "among 5 "
                              "bytes of the response stream it lacks: its values are unknown");
                }
            }
        }
    }
}

// The same 4 bytes with nothing missing after them (the gateway sent them, then the next reply whole): a
// broken reply, and the request to unit 4 timed out, an error against the device.
TEST(RtuOverTcpPairing, ACutReplyWithNoHoleAfterItIsNoExcuse) {
    Conversation c = gateway_conversation();
    const auto response4 = rtu(4, {0x03, 0x04, 0, 4, 0, 4});
    c.send(true, read_holding(4, 0, 2), 1500ms);
    c.send(false, {response4.begin(), response4.begin() + 4}, 1550ms);
    c.send(true, read_holding(5, 0, 1), 1700ms);
    c.send(false, rtu(5, {0x03, 0x02, 0, 5}), 1750ms);
    c.send(true, {}, 5s);
    const auto d = decode_pcap(c.file(), gateway_options());
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairResponseNotCaptured), 0);
    EXPECT_EQ(d->summary.devices.at(device(4)).timeouts, 1u);
    EXPECT_EQ(d->summary.devices.at(device(4)).replies_not_captured, 0u);
    EXPECT_EQ(d->summary.devices.at(device(5)).responses, 1u);
}

}  // namespace test_analyzer_rtu_over_tcp_pairing_test
