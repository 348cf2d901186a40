// The client's reply framing without a socket (modbus/transport/exchange.hpp): where a response ends and
// which frames are late replies to earlier requests (Modbus/TCP by transaction id, RTU and ASCII by what
// they answer).
#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "modbus/transport/exchange.hpp"

namespace test_transport_exchange_test {

using namespace mbscope::modbus;
using transport::Exchange;
using transport::ReplyScanner;

namespace {

const std::vector<std::uint8_t> read_pdu{0x03, 0x00, 0x00, 0x00, 0x01};
const std::vector<std::uint8_t> reply_pdu{0x03, 0x02, 0x12, 0x34};

void append(Exchange& ex, const std::vector<std::uint8_t>& bytes) {
    ex.received.insert(ex.received.end(), bytes.begin(), bytes.end());
}

// A list owing the FC3 read of read_pdu to unit 0x11, given up with nothing back.
transport::OwedRequests owing_a_read() {
    transport::OwedRequests owed;
    Exchange silent;
    silent.sent = encode_rtu(0x11, read_pdu);
    EXPECT_TRUE(owed.after(silent, 0x11, read_pdu));
    return owed;
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

// A read-coils reply whose first 8 bytes are also a whole FC1 request with a valid CRC ("01 01 04 62 F2 02"
// and its CRC 58 45): the reply's own length (its byte count says 9 bytes) is the frame, waited for while
// the line is not silent. Taking the first length whose CRC checks cut a correct slave's reply into a
// malformed one (reply.malformed against the reference slave in the network fuzzer).
TEST(ReplyScanner, RtuTakesAReplysOwnLengthOverARequestShapedPrefix) {
    const std::vector<std::uint8_t> reply{0x01, 0x01, 0x04, 0x62, 0xF2, 0x02, 0x58, 0x45, 0x00};
    Exchange ex;
    ex.sent = {0x01, 0x01, 0x00, 0x00, 0x00, 0x20, 0x3D, 0xD2};
    append(ex, std::vector<std::uint8_t>(reply.begin(), reply.begin() + 8));
    ReplyScanner scanner(Framing::Rtu, false, 1);
    EXPECT_EQ(scanner.scan(ex, false), 0u);
    append(ex, std::vector<std::uint8_t>(reply.begin() + 8, reply.end()));
    EXPECT_EQ(scanner.scan(ex, false), 1u);
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_EQ(ex.response->wire_length, 9u);
    EXPECT_TRUE(ex.response->checksum_ok);
    const auto frames = transport::frames_in(Framing::Rtu, reply);
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].wire_length, 9u);
    // Cut at the prefix and silent after it: the 8 bytes are what came.
    Exchange cut;
    append(cut, std::vector<std::uint8_t>(reply.begin(), reply.begin() + 8));
    ReplyScanner by_silence(Framing::Rtu, false, 1);
    EXPECT_EQ(by_silence.scan(cut, true), 1u);
    EXPECT_EQ(cut.response->wire_length, 8u);
}

// Diagnostics 00 echoes its request, data of any length: "01 08 00 00 C1 83 57" and its CRC. Its own bytes
// do not say its length, and its first four with "C1 83" are a frame whose CRC holds: the reply was cut
// there (or at the two data bytes most sub-functions carry) and a correct slave's echo failed as
// reply.checksum in the network fuzzer. The request's length is the frame, and a copy of it a copy.
TEST(ReplyScanner, RtuDiagnosticsReplyIsAsLongAsItsRequest) {
    const std::vector<std::uint8_t> echo{0x01, 0x08, 0x00, 0x00, 0xC1, 0x83, 0x57, 0x7B, 0xBA};
    for (const bool silence : {false, true}) {
        Exchange ex;
        ex.sent = echo;
        append(ex, echo);
        ReplyScanner scanner(Framing::Rtu, false, 1);
        EXPECT_EQ(scanner.scan(ex, silence), 1u);
        ASSERT_TRUE(ex.response.has_value());
        EXPECT_EQ(ex.response->wire_length, echo.size());
        EXPECT_TRUE(ex.response->checksum_ok);
        EXPECT_FALSE(transport::repeats_response(ex));
        append(ex, echo);
        EXPECT_TRUE(transport::repeats_response(ex));
    }
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

// ---- late replies over RTU and ASCII, which carry no transaction id

namespace {

Frame rtu_reply(std::uint8_t unit, const std::vector<std::uint8_t>& pdu) {
    return *decode_rtu(encode_rtu(unit, pdu));
}

}  // namespace

// A reply sent twice: the same bytes again (transaction id and checksum too), after a late reply set aside
// or not; a reply followed by anything else, or by another request's reply of the same shape, is not.
TEST(RepeatsReply, OnlyTheSameBytesAgainAreTheReplyTwice) {
    for (const Framing framing : {Framing::Tcp, Framing::Rtu, Framing::Ascii}) {
        SCOPED_TRACE(std::string(to_string(framing)));
        const auto frame_of = [&](std::uint16_t tid, const std::vector<std::uint8_t>& pdu) {
            return encode_adu(framing, tid, 1, pdu);
        };
        const auto reply = frame_of(10, reply_pdu);
        const auto scanned = [&](const std::vector<std::vector<std::uint8_t>>& parts) {
            Exchange ex;
            ex.sent = frame_of(10, read_pdu);
            for (const auto& p : parts)
                append(ex, p);
            ReplyScanner(framing, false, 1).scan(ex, true);
            return ex;
        };
        const auto twice = scanned({reply, reply});
        ASSERT_TRUE(twice.response.has_value());
        EXPECT_TRUE(transport::repeats_response(twice));
        EXPECT_TRUE(transport::repeats_reply(*twice.response, reply));
        EXPECT_FALSE(transport::repeats_response(scanned({reply})));
        EXPECT_FALSE(transport::repeats_response(scanned({reply, {0xDE, 0xAD}})));
        // Cut short, the copy is not the reply again.
        EXPECT_FALSE(transport::repeats_reply(*twice.response, std::span(reply).first(reply.size() - 1)));
        // Another value in the same shape (over Modbus/TCP, another transaction too).
        EXPECT_FALSE(transport::repeats_response(scanned({reply, frame_of(11, {0x03, 0x02, 0x12, 0x35})})));
        if (framing == Framing::Tcp) {
            // A late reply set aside first: the copy is counted from the request's own reply.
            const auto late = frame_of(9, reply_pdu);
            const auto after_late = scanned({late, reply, reply});
            ASSERT_EQ(after_late.stale_replies.size(), 1u);
            EXPECT_TRUE(transport::repeats_response(after_late));
            EXPECT_FALSE(transport::repeats_response(scanned({late, reply})));
        }
    }
}

TEST(CouldAnswer, TheShapeEachFunctionGivesItsResponse) {
    using transport::could_answer;
    const std::vector<std::uint8_t> read_coils{0x01, 0x00, 0x13, 0x00, 0x0A};  // 10 coils: 2 bytes
    EXPECT_TRUE(could_answer(0x11, read_coils, rtu_reply(0x11, {0x01, 0x02, 0xCD, 0x01})));
    EXPECT_FALSE(could_answer(0x11, read_coils, rtu_reply(0x11, {0x01, 0x01, 0xCD})));
    EXPECT_FALSE(could_answer(0x12, read_coils, rtu_reply(0x11, {0x01, 0x02, 0xCD, 0x01})));
    EXPECT_TRUE(could_answer(0x11, read_coils, rtu_reply(0x11, {0x81, 0x02})));
    EXPECT_FALSE(could_answer(0x11, read_coils, rtu_reply(0x11, {0x83, 0x02})));
    // A broadcast's reply (a fault in itself) may carry any unit id.
    EXPECT_TRUE(could_answer(0x00, read_coils, rtu_reply(0x07, {0x01, 0x02, 0xCD, 0x01})));

    const std::vector<std::uint8_t> read_two{0x03, 0x00, 0x6B, 0x00, 0x02};
    EXPECT_TRUE(could_answer(0x11, read_two, rtu_reply(0x11, {0x03, 0x04, 0, 1, 0, 2})));
    EXPECT_FALSE(could_answer(0x11, read_two, rtu_reply(0x11, {0x03, 0x02, 0, 1})));
    EXPECT_FALSE(could_answer(0x11, read_two, rtu_reply(0x11, {0x04, 0x04, 0, 1, 0, 2})));

    const std::vector<std::uint8_t> write_one{0x06, 0x00, 0x01, 0x00, 0x03};
    EXPECT_TRUE(could_answer(0x11, write_one, rtu_reply(0x11, write_one)));
    EXPECT_FALSE(could_answer(0x11, write_one, rtu_reply(0x11, {0x06, 0x00, 0x02, 0x00, 0x03})));
    const std::vector<std::uint8_t> write_many{0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0, 0x0A, 0x01, 0x02};
    EXPECT_TRUE(could_answer(0x11, write_many, rtu_reply(0x11, {0x10, 0x00, 0x01, 0x00, 0x02})));
    EXPECT_FALSE(could_answer(0x11, write_many, rtu_reply(0x11, {0x10, 0x00, 0x01, 0x00, 0x03})));
    const std::vector<std::uint8_t> echo{0x08, 0x00, 0x00, 0xA5, 0x37};
    EXPECT_TRUE(could_answer(0x11, echo, rtu_reply(0x11, echo)));
    EXPECT_FALSE(could_answer(0x11, echo, rtu_reply(0x11, {0x08, 0x00, 0x0A, 0x00, 0x00})));
    // Functions whose response repeats nothing of the request: the function code is all there is.
    EXPECT_TRUE(
        could_answer(0x11, std::vector<std::uint8_t>{0x11}, rtu_reply(0x11, {0x11, 0x02, 0x11, 0xFF})));
    EXPECT_FALSE(could_answer(0x11, {}, rtu_reply(0x11, {0x11, 0x02, 0x11, 0xFF})));
}

// A device slower than the client's timeout: its reply to the FC3 request given up arrives while the FC4
// request after it waits. It answers only the owed request, so it is set aside, and FC4's own reply after it
// is the response.
TEST(ReplyScanner, RtuLateReplyOnlyAnOwedRequestExplainsIsSetAside) {
    const std::vector<transport::OwedRequest> owed{{0x11, read_pdu, {}}};
    const std::vector<std::uint8_t> read_input{0x04, 0x00, 0x00, 0x00, 0x01};
    const std::vector<std::uint8_t> input_reply{0x04, 0x02, 0x56, 0x78};
    Exchange ex;
    ex.sent = encode_rtu(0x11, read_input);
    append(ex, encode_rtu(0x11, reply_pdu));
    ReplyScanner scanner(Framing::Rtu, false, 1, owed);
    EXPECT_EQ(scanner.scan(ex, false), 0u);
    ASSERT_EQ(ex.stale_replies.size(), 1u);
    EXPECT_FALSE(ex.response.has_value());
    append(ex, encode_rtu(0x11, input_reply));
    EXPECT_EQ(scanner.scan(ex, false), 1u);
    ASSERT_TRUE(ex.response.has_value());
    EXPECT_EQ(ex.response->pdu()[0], 0x04);
    EXPECT_EQ(ex.own_received().size(), encode_rtu(0x11, input_reply).size());

    // The same in ASCII.
    Exchange text;
    const auto request = encode_ascii(0x11, read_input);
    text.sent.assign(request.begin(), request.end());
    const auto late = encode_ascii(0x11, reply_pdu);
    text.received.assign(late.begin(), late.end());
    ReplyScanner ascii(Framing::Ascii, false, 1, owed);
    EXPECT_EQ(ascii.scan(text, false), 0u);
    EXPECT_EQ(text.stale_replies.size(), 1u);
}

// What content cannot settle stays the request's: a reply either request could draw (the session waits
// such a late reply out before sending), one that answers neither (for the rules to judge), one with a bad
// CRC.
TEST(ReplyScanner, RtuReplyTheRequestCouldDrawIsNeverSetAside) {
    const std::vector<transport::OwedRequest> owed{{0x11, read_pdu, {}}};
    const auto scan = [&](const std::vector<std::uint8_t>& request_pdu, std::vector<std::uint8_t> reply) {
        Exchange ex;
        ex.sent = encode_rtu(0x11, request_pdu);
        ex.received = std::move(reply);
        ReplyScanner scanner(Framing::Rtu, false, 1, owed);
        EXPECT_EQ(scanner.scan(ex, true), 1u);
        EXPECT_TRUE(ex.stale_replies.empty());
        return ex;
    };
    const std::vector<std::uint8_t> other_address{0x03, 0x00, 0x07, 0x00, 0x01};
    EXPECT_TRUE(scan(other_address, encode_rtu(0x11, reply_pdu)).response->checksum_ok);
    const std::vector<std::uint8_t> write{0x06, 0x00, 0x01, 0x00, 0x03};
    EXPECT_EQ(scan(write, encode_rtu(0x11, std::vector<std::uint8_t>{0x05, 0x00, 0x01, 0xFF, 0x00}))
                  .response->pdu()[0],
              0x05);
    auto bad_crc = encode_rtu(0x11, reply_pdu);
    bad_crc.back() ^= 0xFF;
    EXPECT_FALSE(scan(write, bad_crc).response->checksum_ok);
    // Not after bytes that are no frame: what came for the request is counted from the first set aside.
    Exchange noisy;
    const auto request = encode_ascii(0x11, write);
    noisy.sent.assign(request.begin(), request.end());
    const auto late = "x" + encode_ascii(0x11, reply_pdu);
    noisy.received.assign(late.begin(), late.end());
    ReplyScanner after_noise(Framing::Ascii, false, 1, owed);
    EXPECT_EQ(after_noise.scan(noisy, false), 1u);
    EXPECT_TRUE(noisy.stale_replies.empty());
    // Without an owed request nothing is set aside.
    Exchange ex;
    ex.sent = encode_rtu(0x11, write);
    ex.received = encode_rtu(0x11, reply_pdu);
    ReplyScanner scanner(Framing::Rtu, false, 1);
    EXPECT_EQ(scanner.scan(ex, true), 1u);
    EXPECT_TRUE(ex.stale_replies.empty());
}

// Bytes found waiting before a request (a late reply and whatever else came) split into their frames.
TEST(FramesIn, SplitsWhatArrivedUnaskedIntoFrames) {
    auto bytes = encode_rtu(0x11, reply_pdu);
    const auto second = encode_rtu(0x11, std::vector<std::uint8_t>{0x06, 0x00, 0x01, 0x00, 0x03});
    bytes.insert(bytes.end(), second.begin(), second.end());
    const auto rtu = transport::frames_in(Framing::Rtu, bytes);
    ASSERT_EQ(rtu.size(), 2u);
    EXPECT_EQ(rtu[1].pdu()[0], 0x06);
    EXPECT_EQ(rtu[0].offset, 0u);
    EXPECT_EQ(rtu[1].offset, bytes.size() - second.size());  // where each begins in the bytes
    const auto text = encode_ascii(0x11, reply_pdu) + "noise" + encode_ascii(0x11, reply_pdu);
    EXPECT_EQ(
        transport::frames_in(Framing::Ascii, std::vector<std::uint8_t>(text.begin(), text.end())).size(), 2u);
    EXPECT_TRUE(transport::frames_in(Framing::Rtu, {}).empty());
}

// The session's and the reply target's bookkeeping of requests given up: the last four that got nothing,
// cleared by anything that comes for a later one, each settled by the late reply that could answer it.
TEST(OwedRequests, KeepsTheLastFourUnansweredUntilAReplyComes) {
    transport::OwedRequests owed;
    const auto read_at = [](std::uint8_t address) {
        return std::vector<std::uint8_t>{0x03, 0x00, address, 0x00, 0x01};
    };
    Exchange silent;
    for (std::uint8_t a = 0; a < 6; ++a)
        EXPECT_TRUE(owed.after(silent, 0x11, read_at(a)));
    ASSERT_EQ(owed.list().size(), 4u);
    EXPECT_EQ(owed.list().front().pdu, read_at(2));
    EXPECT_FALSE(owed.after(silent, 0x11, {}));  // bytes that are no request are owed nothing
    Exchange closed;
    closed.closed = true;
    EXPECT_FALSE(owed.after(closed, 0x11, read_at(9)));

    // A late reply settles the oldest request it could answer, and says which it was.
    const auto settled = owed.settle(*decode_rtu(encode_rtu(0x11, reply_pdu)));
    ASSERT_TRUE(settled);
    EXPECT_EQ(settled->pdu, read_at(2));
    ASSERT_EQ(owed.list().size(), 3u);
    EXPECT_EQ(owed.list().front().pdu, read_at(3));
    EXPECT_FALSE(owed.settle(*decode_rtu(encode_rtu(0x12, reply_pdu))));  // another unit's: answers none
    EXPECT_EQ(owed.list().size(), 3u);

    // Anything that came for a later request: the device got that far, nothing before it is owed.
    Exchange answered;
    answered.received = {0x11};
    EXPECT_FALSE(owed.after(answered, 0x11, read_at(7)));
    EXPECT_TRUE(owed.empty());
}

// Probes the rules want unanswered (waited for briefly) can outnumber the list within one due reply's delay:
// they go first, so that the due reply is still recognised when it comes.
TEST(OwedRequests, ARequestDueAReplyOutlastsTheSilentOnes) {
    auto owed = owing_a_read();
    Exchange silent;
    const std::vector<std::uint8_t> bad_checksum_read{0x03, 0x00, 0x09, 0x00, 0x01};
    for (int i = 0; i < 6; ++i)
        ASSERT_TRUE(owed.after(silent, 0x11, bad_checksum_read, nullptr, false));
    ASSERT_EQ(owed.list().size(), 4u);
    EXPECT_EQ(owed.list().front().pdu, read_pdu);
    EXPECT_TRUE(owed.list().front().reply_due);
    // A reply both could draw is the due request's, though the others are owed too.
    const auto settled = owed.settle(*decode_rtu(encode_rtu(0x11, reply_pdu)));
    ASSERT_TRUE(settled);
    EXPECT_TRUE(settled->reply_due);
    EXPECT_EQ(owed.list().size(), 3u);
}

// A request owes a reply like another's when a reply due to an owed one could be drawn by it too: the same
// function or its exception, the same unit or a broadcast. Owed requests that want no reply owe none.
TEST(OwedRequests, OwesAReplyLikeARequestOfTheSameShape) {
    auto owed = owing_a_read();
    Exchange silent;
    const std::vector<std::uint8_t> write{0x06, 0x00, 0x00, 0x00, 0x01};
    ASSERT_TRUE(owed.after(silent, 0, write, nullptr, false));  // a broadcast: no reply due
    EXPECT_TRUE(owed.owes_reply_like(0x11, read_pdu));
    EXPECT_TRUE(owed.owes_reply_like(0x11, std::vector<std::uint8_t>{0x83}));  // draws exception 83 too
    EXPECT_TRUE(owed.owes_reply_like(0, read_pdu));
    EXPECT_FALSE(owed.owes_reply_like(0x12, read_pdu));
    EXPECT_FALSE(owed.owes_reply_like(0x11, std::vector<std::uint8_t>{0x04, 0x00, 0x00, 0x00, 0x01}));
    EXPECT_FALSE(owed.owes_reply_like(0x11, write));  // the owed write was a broadcast's
    EXPECT_FALSE(owed.owes_reply_like(0x11, std::vector<std::uint8_t>{}));
    owed.clear();
    EXPECT_FALSE(owed.owes_reply_like(0x11, read_pdu));
}

// A late reply that comes during a later exchange (set aside there) settles its request, which the caller
// gets back with the bytes it sent, to judge the reply as that request's.
TEST(OwedRequests, AStaleReplySettlesItsRequestWithTheBytesItSent) {
    transport::OwedRequests owed;
    Exchange given_up;
    given_up.sent = encode_rtu(0x11, read_pdu);
    ASSERT_TRUE(owed.after(given_up, 0x11, read_pdu));
    EXPECT_EQ(owed.list().front().sent, given_up.sent);

    Exchange later;
    later.sent = encode_rtu(0x11, std::vector<std::uint8_t>{0x04, 0x00, 0x00, 0x00, 0x01});
    const auto stale = encode_rtu(0x11, reply_pdu);
    append(later, stale);
    later.stale_replies.push_back(*decode_rtu(stale));
    std::vector<transport::SettledRequest> settled;
    EXPECT_TRUE(owed.after(later, 0x11, std::vector<std::uint8_t>{0x04, 0x00, 0x00, 0x00, 0x01}, &settled));
    ASSERT_EQ(settled.size(), 1u);
    EXPECT_EQ(settled[0].request.sent, given_up.sent);
    EXPECT_EQ(settled[0].reply.pdu()[0], 0x03);
    ASSERT_EQ(owed.list().size(), 1u);  // the later request, nothing came for it
    EXPECT_EQ(owed.list().front().pdu[0], 0x04);
}

// Bytes found waiting with no request out: frames with a good checksum that answer an owed request settle
// it; noise, a frame with a bad checksum and a frame no owed request explains are the rest, in order.
TEST(OwedRequests, SettleFramesTakesOutTheLateRepliesAndKeepsTheRest) {
    auto owed = owing_a_read();
    Exchange silent;
    const std::vector<std::uint8_t> write_pdu{0x06, 0x00, 0x01, 0x00, 0x03};
    silent.sent = encode_rtu(0x11, write_pdu);
    ASSERT_TRUE(owed.after(silent, 0x11, write_pdu));

    auto bad = encode_rtu(0x11, reply_pdu);
    bad.back() ^= 0xFF;
    const auto unexplained = encode_rtu(0x11, std::vector<std::uint8_t>{0x01, 0x01, 0x01});
    const auto late_read = encode_rtu(0x11, reply_pdu);
    const auto late_write = encode_rtu(0x11, write_pdu);
    std::vector<std::uint8_t> bytes = bad;
    for (const auto* part : {&late_read, &unexplained, &late_write})
        bytes.insert(bytes.end(), part->begin(), part->end());

    std::vector<transport::SettledRequest> settled;
    const auto rest = owed.settle_frames(Framing::Rtu, bytes, settled);
    ASSERT_EQ(settled.size(), 2u);
    EXPECT_EQ(settled[0].request.pdu, read_pdu);
    EXPECT_EQ(settled[1].request.pdu, write_pdu);
    std::vector<std::uint8_t> expected_rest = bad;
    expected_rest.insert(expected_rest.end(), unexplained.begin(), unexplained.end());
    EXPECT_EQ(rest, expected_rest);
    EXPECT_TRUE(owed.empty());

    // ASCII: offsets are in characters.
    transport::OwedRequests ascii_owed;
    Exchange ascii_silent;
    ascii_silent.sent = {':'};
    ASSERT_TRUE(ascii_owed.after(ascii_silent, 0x11, read_pdu));
    const std::string text = "junk" + encode_ascii(0x11, reply_pdu) + "tail";
    settled.clear();
    const auto ascii_rest = ascii_owed.settle_frames(
        Framing::Ascii, std::vector<std::uint8_t>(text.begin(), text.end()), settled);
    ASSERT_EQ(settled.size(), 1u);
    EXPECT_EQ(std::string(ascii_rest.begin(), ascii_rest.end()), "junktail");
}

}  // namespace test_transport_exchange_test
