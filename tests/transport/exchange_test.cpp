// The client's reply framing without a socket (modbus/transport/exchange.hpp): where a response ends and
// which Modbus/TCP frames are late replies to earlier requests.
#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "modbus/transport/exchange.hpp"

using namespace mbscope::modbus;
using transport::Exchange;
using transport::ReplyScanner;

namespace {

const std::vector<std::uint8_t> read_pdu{0x03, 0x00, 0x00, 0x00, 0x01};
const std::vector<std::uint8_t> reply_pdu{0x03, 0x02, 0x12, 0x34};

void append(Exchange& ex, const std::vector<std::uint8_t>& bytes) {
    ex.received.insert(ex.received.end(), bytes.begin(), bytes.end());
}

}  // namespace

TEST(ReplyScanner, ALateReplyBeforeTheOwnIsSetAside) {
    Exchange ex;
    ex.sent = encode_tcp(10, 1, read_pdu);
    append(ex, encode_tcp(9, 1, reply_pdu));
    append(ex, encode_tcp(10, 1, reply_pdu));
    ReplyScanner scanner(Framing::Tcp, false, 1);
    EXPECT_EQ(scanner.scan(ex, false), 1u);
    EXPECT_TRUE(scanner.complete());
    ASSERT_EQ(ex.stale_replies.size(), 1u);
    EXPECT_EQ(ex.stale_replies[0].transaction_id(), 9);
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_EQ(ex.response->transaction_id(), 10);
    EXPECT_EQ(ex.own_received().size(), encode_tcp(10, 1, reply_pdu).size());
}

TEST(ReplyScanner, AFrameAfterOneThatDoesNotDecodeIsNotSetAside) {
    // An MBAP header of length 0 is a frame by its length and no frame by its content. It came for this
    // request, so a late-looking reply after it is not set aside (own_received(), the stale replies counted
    // off the front, would otherwise cut the header and keep the reply); it becomes the response, the first
    // frame that decodes, for the oracle to find its transaction id wrong.
    Exchange ex;
    ex.sent = encode_tcp(10, 1, read_pdu);
    append(ex, {0x00, 0x0A, 0x00, 0x00, 0x00, 0x00});
    append(ex, encode_tcp(9, 1, reply_pdu));
    ReplyScanner scanner(Framing::Tcp, false, 1);
    EXPECT_EQ(scanner.scan(ex, false), 2u);
    EXPECT_TRUE(ex.stale_replies.empty());
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_EQ(ex.response->transaction_id(), 9);
    EXPECT_EQ(ex.own_received().size(), ex.received.size());
}

TEST(ReplyScanner, RtuEndsAtTheCrcOrAtASilence) {
    Exchange ex;
    ex.sent = encode_rtu(0x11, read_pdu);
    const auto reply = encode_rtu(0x11, reply_pdu);
    append(ex, std::vector<std::uint8_t>(reply.begin(), reply.begin() + 3));
    ReplyScanner scanner(Framing::Rtu, false, 1);
    EXPECT_EQ(scanner.scan(ex, false), 0u);
    append(ex, std::vector<std::uint8_t>(reply.begin() + 3, reply.end()));
    EXPECT_EQ(scanner.scan(ex, false), 1u);
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_TRUE(ex.response->checksum_ok);

    // Bytes no length prediction explains end at the silence, all of them one answer.
    Exchange garbage;
    append(garbage, {0x11, 0x63, 0x01, 0x02, 0x03});
    ReplyScanner by_silence(Framing::Rtu, false, 1);
    EXPECT_EQ(by_silence.scan(garbage, false), 0u);
    EXPECT_EQ(by_silence.scan(garbage, true), 1u);
    ASSERT_TRUE(garbage.response.has_value());
    EXPECT_EQ(garbage.response->wire_length, 5u);
}

TEST(ReplyScanner, AsciiEndsAtCrLf) {
    Exchange ex;
    const auto text = encode_ascii(0x11, reply_pdu);
    append(ex, std::vector<std::uint8_t>(text.begin(), text.end() - 1));
    ReplyScanner scanner(Framing::Ascii, false, 1);
    EXPECT_EQ(scanner.scan(ex, false), 0u);
    append(ex, {'\n'});
    EXPECT_EQ(scanner.scan(ex, false), 1u);
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_TRUE(ex.response->checksum_ok);
}
