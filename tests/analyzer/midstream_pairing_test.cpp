// Pairing on a Modbus/TCP connection the capture joined after it opened (no SYN), with requests pipelined:
// replies to requests sent before the capture began may still come after the capture's first request, and
// are neither that request's reply (with another id) nor unsolicited.
#include <gtest/gtest.h>

#include "test_packets.hpp"

namespace test_analyzer_midstream_pairing_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Conversation;
using mbscope::test::decode_pcap;
using mbscope::test::packet;

namespace {

std::vector<std::uint8_t> read_request(std::uint16_t tid, std::uint8_t unit, std::uint8_t quantity) {
    return bytes({tid >> 8, tid & 0xFF, 0, 0, 0, 6, unit, 3, 0, 0, 0, quantity});
}
// A reply to read_request: `quantity` registers, each holding the unit's number.
std::vector<std::uint8_t> read_reply(std::uint16_t tid, std::uint8_t unit, std::uint8_t quantity) {
    std::vector<std::uint8_t> b =
        bytes({tid >> 8, tid & 0xFF, 0, 0, 0, 3 + 2 * quantity, unit, 3, 2 * quantity});
    for (int i = 0; i < quantity; ++i)
        b.insert(b.end(), {0, unit});
    return b;
}

// The connection opened in the capture: the client's SYN and the server's SYN-ACK.
void open(Conversation& c, mb::Timestamp t) {
    c.records.push_back({t, packet(true, c.seq[0] - 1, {}, false, 0x02, 502, 0)});
    c.records.push_back({t, packet(false, c.seq[1] - 1, {}, false, 0x12, 502, c.seq[0])});
}

}  // namespace

// The client sent id 10 (unit 1, one register) before the capture began; the capture holds request 11 (unit
// 2, three registers), then reply 10, then reply 11, as tshark pairs them. Reply 10 was paired with request
// 11: a transaction-id mismatch, a unit mismatch and a size mismatch, unit 1's value shown as unit 2's, and
// reply 11 unsolicited. Also across the ids' wrap (65535 before 0).
TEST(MidstreamPairing, AReplyToARequestPipelinedBeforeTheCaptureIsNotTheCapturedRequestsReply) {
    for (const auto& [before, first] : {std::pair<std::uint16_t, std::uint16_t>{10, 11}, {65535, 0}}) {
        SCOPED_TRACE(first);
        Conversation c;
        c.send(true, read_request(first, 2, 3), 10ms);
        c.send(false, read_reply(before, 1, 1), 50ms);
        c.send(false, read_reply(first, 2, 3), 90ms);
        const auto d = decode_pcap(c.file());
        ASSERT_EQ(d->sink.findings.size(), 1u);
        const auto& f = d->sink.findings[0];
        EXPECT_EQ(f.code, mb::FindingCode::PairRequestNotCaptured);
        EXPECT_EQ(f.packet, 2u);
        EXPECT_EQ(f.time, 50ms);
        EXPECT_EQ(f.frames, std::vector<std::uint64_t>{2});
        EXPECT_EQ(f.device.str(), "10.0.0.2:502 unit 1");
        EXPECT_NE(f.message.find("transaction id " + std::to_string(before)), std::string::npos) << f.message;
        EXPECT_EQ(d->summary.errors, 0u);
        ASSERT_EQ(d->sink.transactions.size(), 1u);
        const auto& t = d->sink.transactions[0];
        EXPECT_EQ(t.request.frame.transaction_id(), first);
        ASSERT_TRUE(t.response.has_value());
        EXPECT_EQ(t.response->frame.transaction_id(), first);
        EXPECT_EQ(t.response->packet, 3u);
        ASSERT_TRUE(t.latency.has_value());
        EXPECT_EQ(*t.latency, 80ms);
        EXPECT_TRUE(t.findings.empty());
        EXPECT_EQ(d->summary.devices.at("10.0.0.2:502 unit 2").responses, 1u);
        EXPECT_EQ(d->summary.devices.count("10.0.0.2:502 unit 1"), 1u);
        EXPECT_EQ(d->summary.devices.at("10.0.0.2:502 unit 1").responses, 0u);
    }
}

// Two captured requests wait (11 to unit 2, 12 to unit 3) when reply 10 comes: it was unsolicited, an
// error; each captured request is paired with its own reply.
TEST(MidstreamPairing, AReplyBeforeTheCapturedRequestsWhileSeveralWaitIsNotUnsolicited) {
    Conversation c;
    c.send(true, read_request(11, 2, 3), 10ms);
    c.send(true, read_request(12, 3, 2), 20ms);
    c.send(false, read_reply(10, 1, 1), 50ms);
    c.send(false, read_reply(11, 2, 3), 90ms);
    c.send(false, read_reply(12, 3, 2), 100ms);
    const auto d = decode_pcap(c.file());
    ASSERT_EQ(d->sink.findings.size(), 1u);
    EXPECT_EQ(d->sink.findings[0].code, mb::FindingCode::PairRequestNotCaptured);
    EXPECT_EQ(d->sink.findings[0].packet, 3u);
    EXPECT_EQ(d->summary.errors, 0u);
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.response.has_value());
        EXPECT_EQ(t.response->frame.transaction_id(), t.request.frame.transaction_id());
        EXPECT_EQ(t.response->frame.unit_id(), t.request.frame.unit_id());
    }
}

// What stays a transaction-id mismatch: a reply with an earlier id once a reply answered a captured request
// (a server answers in turn: those sent before the capture were answered before it), the same id excused a
// second time (a request is answered once), an id after the captured request's
// (Analyzer.TransactionIdMismatch), and any of it on a connection whose opening the capture holds (nothing
// went before it).
TEST(MidstreamPairing, AWrongIdInsideTheCapturedConversationIsStillAMismatch) {
    {
        SCOPED_TRACE("after a reply answered a captured request");
        Conversation c;
        c.send(true, read_request(11, 2, 3), 10ms);
        c.send(false, read_reply(11, 2, 3), 20ms);
        c.send(true, read_request(12, 2, 3), 30ms);
        c.send(false, read_reply(10, 2, 3), 40ms);
        const auto d = decode_pcap(c.file());
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairRequestNotCaptured), 0);
        EXPECT_EQ(d->sink.transactions.size(), 2u);
    }
    {
        SCOPED_TRACE("the same earlier id again");
        Conversation c;
        c.send(true, read_request(11, 2, 3), 10ms);
        c.send(false, read_reply(10, 1, 1), 20ms);
        c.send(false, read_reply(10, 2, 3), 30ms);
        const auto d = decode_pcap(c.file());
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairRequestNotCaptured), 1);
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
    }
    {
        SCOPED_TRACE("a connection opened in the capture");
        Conversation c;
        open(c, 0s);
        c.send(true, read_request(11, 2, 3), 10ms);
        c.send(false, read_reply(10, 2, 3), 50ms);
        const auto d = decode_pcap(c.file());
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
        EXPECT_EQ(d->sink.count(mb::FindingCode::PairRequestNotCaptured), 0);
    }
}

// ModbusTCP.pcap (ITI), connection from port 57184: the capture's first request of the link is id 0, and
// one segment brings replies 31998, 31999 and 32000 to requests sent before it (a client whose ids started
// over), then replies 0 and 1. 31998 is far from the id before 0, so it was paired with request 0 (a
// transaction-id and a size mismatch), 31999 and 32000 were unsolicited, and request 1 got reply 0 (a
// function mismatch): eight errors against a device that answered everything. A reply that fits none of the
// waiting requests is one sent before the capture, and so are those whose ids follow it, fitting or not.
TEST(MidstreamPairing, RepliesInFlightWithIdsFarFromTheFirstCapturedAreNotItsReplies) {
    Conversation c;
    c.send(true, read_request(0, 1, 2), 10ms);
    auto early = read_reply(31998, 1, 99);
    for (const auto& reply : {read_reply(31999, 1, 2), read_reply(32000, 1, 20)})
        early.insert(early.end(), reply.begin(), reply.end());
    c.send(false, early, 11ms);
    c.send(true, read_request(1, 1, 3), 12ms);
    auto replies = read_reply(0, 1, 2);
    const auto second = read_reply(1, 1, 3);
    replies.insert(replies.end(), second.begin(), second.end());
    c.send(false, replies, 60ms);
    const auto d = decode_pcap(c.file());
    EXPECT_EQ(d->summary.findings, (std::map<std::string, std::uint64_t>{{"pair.request_not_captured", 3}}));
    EXPECT_EQ(d->summary.errors, 0u);
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.response.has_value());
        EXPECT_EQ(t.response->frame.transaction_id(), t.request.frame.transaction_id());
    }
    std::string said;
    for (const auto& f : d->sink.findings)
        said += f.message + "\n";
    EXPECT_NE(
        said.find("transaction id 31998 comes before any reply to a request the capture holds, and fits "
                  "none of the requests waiting"),
        std::string::npos)
        << said;
    EXPECT_NE(said.find("transaction id 31999 comes before any reply to a request the capture holds, its id "
                        "next after that of 31998"),
              std::string::npos)
        << said;
}

// A device that answers every request with transaction id 0 (a firmware bug some have), polled with ids
// 100 to 104 a second apart, each reply fitting its request (unit, function, size): over a connection the
// capture joined after it opened, and over UDP. Each reply is its request's, with a wrong id: five
// transaction-id mismatches and five responses. (The first reply was excused as answering a request sent
// before the capture, every later one was unsolicited and every request a timeout: the device's bug never
// named.)
TEST(MidstreamPairing, ADeviceThatAlwaysAnswersWithIdZeroIsAMismatchEveryTime) {
    for (const bool udp : {false, true}) {
        SCOPED_TRACE(udp ? "Modbus/UDP" : "Modbus/TCP, no SYN");
        Conversation c;
        for (std::uint16_t i = 0; i < 5; ++i) {
            const auto at = 1s + 1s * i;
            // a value of its own in each: the same bytes again are a reply answered twice
            const auto reply = bytes({0, 0, 0, 0, 0, 5, 1, 3, 2, 0, 40 + i});
            if (udp) {
                c.records.push_back({at, packet(true, 0, read_request(100 + i, 1, 1), true)});
                c.records.push_back({at + 20ms, packet(false, 0, reply, true)});
            } else {
                c.send(true, read_request(100 + i, 1, 1), at);
                c.send(false, reply, at + 20ms);
            }
        }
        const auto d = decode_pcap(c.file());
        EXPECT_EQ(d->summary.findings,
                  (std::map<std::string, std::uint64_t>{{"pair.transaction_id_mismatch", 5}}));
        // (no ASSERT here: one transport failing must not hide the other's result)
        EXPECT_EQ(d->sink.transactions.size(), 5u);
        for (const auto& t : d->sink.transactions) {
            EXPECT_TRUE(t.response.has_value());
            if (t.response) {
                EXPECT_EQ(t.response->frame.transaction_id(), 0u);
            }
            EXPECT_EQ(t.latency, std::optional<mb::Timestamp>(20ms));
        }
        const auto& stats = d->summary.devices.at("10.0.0.2:502 unit 1");
        EXPECT_EQ(stats.requests, 5u);
        EXPECT_EQ(stats.responses, 5u);
        EXPECT_EQ(stats.timeouts, 0u);
    }
}

}  // namespace test_analyzer_midstream_pairing_test
