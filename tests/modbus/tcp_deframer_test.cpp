#include "modbus/tcp_deframer.hpp"

#include <gtest/gtest.h>

#include "deframer_util.hpp"
#include "modbus/adu.hpp"
#include "test_util.hpp"

namespace test_modbus_tcp_deframer_test {

using namespace mbscope::test;
namespace mb = mbscope::modbus;

namespace {

std::vector<std::vector<std::uint8_t>> sample_adus() {
    return {hex("00 01 00 00 00 06 11 03 00 6B 00 03"), hex("00 01 00 00 00 09 11 03 06 02 2B 00 00 00 64"),
            hex("FF FF 00 00 00 06 01 05 00 AC FF 00"), hex("00 00 00 00 00 03 01 81 02"),
            hex("12 34 00 00 00 0B 01 10 00 01 00 02 04 00 0A 01 02")};
}

mb::DeframeEvents run(const std::vector<std::uint8_t>& data, const std::vector<std::size_t>& sizes,
                      bool passive = false) {
    mb::TcpStreamDeframer d;
    if (passive) d.observe_passively();
    mb::DeframeEvents out;
    std::size_t pos = 0;
    for (auto n : sizes) {
        d.feed({data.data() + pos, n}, out);
        pos += n;
    }
    d.finish(out);
    return out;
}

std::vector<std::uint8_t> concat(const std::vector<std::vector<std::uint8_t>>& parts) {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts)
        out.insert(out.end(), p.begin(), p.end());
    return out;
}

}  // namespace

TEST(TcpStreamDeframer, SeveralAdusPerChunkAndOneAduOverManyChunks) {
    const auto adus = sample_adus();
    const auto data = concat(adus);
    for (const auto& sizes : chunkings(data.size(), 50, 11)) {
        auto events = run(data, sizes);
        expect_every_byte_accounted(events, data.size());
        ASSERT_EQ(frames_bytes(events), adus);
    }
}

TEST(TcpStreamDeframer, FirstSegmentShorterThanEightBytes) {
    // The ADU starts in a 3-byte segment (tshark's entry check needs 8 bytes and misses it).
    const auto adu = hex("00 01 00 00 00 06 11 03 00 6B 00 03");
    auto events = run(adu, {3, 9});
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(std::get<mb::Frame>(events[0]).transaction_id(), 1);
}

TEST(TcpStreamDeframer, ImpossibleLengthResynchronisesOnTheNextHeader) {
    const auto good = sample_adus();
    const auto data =
        concat({good[0], hex("00 02 00 00 00 00 11"), good[1], hex("00 03 00 00 01 2C 11 03"), good[2]});
    auto events = run(data, {data.size()});
    expect_every_byte_accounted(events, data.size());
    EXPECT_EQ(frames_bytes(events), (std::vector{good[0], good[1], good[2]}));
    int bad_headers = 0;
    for (const auto& e : events)
        if (auto* u = std::get_if<mb::Unparsed>(&e))
            bad_headers += u->reason == mb::UnparsedReason::BadHeader;
    EXPECT_EQ(bad_headers, 2);
}

TEST(TcpStreamDeframer, AHeaderWhoseFunctionContradictsItsLengthDoesNotHoldTheStream) {
    // A header of length 1 ("00 00 00 00 00 01 01"), then polls: from its second byte the stream reads as a
    // header of length 257 with function code 1, whose byte count (0) says the PDU has 2 bytes, not 256.
    // Each poll must come out as soon as its segment arrives, not 263 bytes later.
    mb::TcpStreamDeframer d;
    mb::DeframeEvents out;
    d.feed(hex("00 00 00 00 00 01 01"), out);
    for (std::uint8_t tid = 1; tid <= 3; ++tid) {
        const auto poll = concat({{0x00, tid}, hex("00 00 00 06 01 03 00 00 00 02")});
        d.feed(poll, out);
        ASSERT_FALSE(out.empty());
        const auto* frame = std::get_if<mb::Frame>(&out.back());
        ASSERT_NE(frame, nullptr) << "poll " << int{tid} << " held back";
        EXPECT_EQ(frame->transaction_id(), tid);
    }
    d.finish(out);
    ASSERT_EQ(out.size(), 4u);
    const auto& skipped = std::get<mb::Unparsed>(out[0]);
    EXPECT_EQ(skipped.offset, 0u);
    EXPECT_EQ(skipped.length, 7u);
    EXPECT_EQ(skipped.reason, mb::UnparsedReason::BadHeader);
}

TEST(TcpStreamDeframer, ProtocolIdNonZeroInSyncIsAFlaggedFrame) {
    const auto data = hex("00 01 00 01 00 06 11 03 00 6B 00 03");
    auto events = run(data, {data.size()});
    ASSERT_EQ(events.size(), 1u);
    EXPECT_TRUE(std::get<mb::Frame>(events[0]).findings.contains(mb::FindingCode::TcpProtocolIdNonzero));
}

// A read request whose length field says 2 (unit and function) is a frame of 8 bytes whose PDU does not
// decode; its address and quantity ("00 6B 00 03") then start what reads as a header with protocol id 3.
// To a passive observer (the analyzer) that is the stream out of sync, not a frame: the 4 bytes are
// unparsed and the next request is whole. After a frame that decodes, a non-zero protocol id is still a
// (flagged) frame. An endpoint (the slave) reads by the length fields alone, as a device does.
TEST(TcpStreamDeframer, ANonZeroProtocolIdAfterAnAduThatDoesNotDecodeIsResynchronisedOn) {
    const auto good = sample_adus();
    const auto short_length = hex("00 01 00 00 00 02 11 03 00 6B 00 03");
    // Transaction id 2: "00 6B | 00 03 | 00 02" reads as a header of length 2 (1 would be impossible).
    const auto next = hex("00 02 00 00 00 06 11 03 00 6B 00 03");
    const auto data = concat({short_length, next, good[1]});
    for (const std::vector<std::size_t>& sizes :
         {std::vector<std::size_t>{data.size()}, std::vector<std::size_t>{12, 12, data.size() - 24}}) {
        auto events = run(data, sizes, true);
        expect_every_byte_accounted(events, data.size());
        EXPECT_EQ(frames_bytes(events),
                  (std::vector{std::vector<std::uint8_t>(short_length.begin(), short_length.begin() + 8),
                               next, good[1]}));
        for (const auto& e : events) {
            if (const auto* f = std::get_if<mb::Frame>(&e)) {
                EXPECT_FALSE(f->findings.contains(mb::FindingCode::TcpProtocolIdNonzero));
            }
        }
    }
    // After a frame that decodes, though it breaks a rule (a read of quantity 0, as testers send), or one
    // that does not, a non-zero protocol id whose own ADU decodes is still a (flagged) frame.
    for (const auto& before :
         {good[0], hex("00 01 00 00 00 06 11 03 00 00 00 00"), hex("00 01 00 00 00 02 11 03")}) {
        const auto flagged = concat({before, hex("00 02 00 01 00 06 11 03 00 6B 00 03")});
        auto events = run(flagged, {flagged.size()}, true);
        ASSERT_EQ(events.size(), 2u);
        EXPECT_TRUE(std::get<mb::Frame>(events[1]).findings.contains(mb::FindingCode::TcpProtocolIdNonzero));
    }
    const auto endpoint = run(data, {data.size()});
    ASSERT_GE(endpoint.size(), 2u);
    const auto* second = std::get_if<mb::Frame>(&endpoint[1]);
    ASSERT_NE(second, nullptr);
    EXPECT_TRUE(second->findings.contains(mb::FindingCode::TcpProtocolIdNonzero));
}

TEST(TcpStreamDeframer, GapLosesTheFrameInProgressAndResyncs) {
    const auto adus = sample_adus();
    mb::TcpStreamDeframer d;
    mb::DeframeEvents out;
    d.feed(adus[0], out);
    d.feed(std::span(adus[1]).first(5), out);  // the rest of this ADU was never captured
    d.gap(10, out);
    d.feed(adus[2], out);
    d.finish(out);
    ASSERT_EQ(out.size(), 3u);
    EXPECT_EQ(std::get<mb::Unparsed>(out[1]).reason, mb::UnparsedReason::Truncated);
    EXPECT_EQ(std::get<mb::Unparsed>(out[1]).length, 5u);
    const auto& last = std::get<mb::Frame>(out[2]);
    EXPECT_EQ(last.offset, adus[0].size() + 5 + 10);
}

// The bytes after a gap up to the next header are the end of the ADU the gap cut: AfterGap, not a bad
// header (which the analyzer reports as tcp.length_invalid, an error). Once in step, a bad length is one.
TEST(TcpStreamDeframer, BytesAfterAGapBeforeTheNextHeaderAreTheCutAdusEnd) {
    const auto adus = sample_adus();
    mb::TcpStreamDeframer d;
    mb::DeframeEvents out;
    d.feed(std::span(adus[1]).first(5), out);
    d.gap(3, out);
    d.feed(std::span(adus[1]).subspan(8), out);  // the tail of the ADU the gap cut
    d.feed(adus[2], out);
    auto bad = adus[0];
    bad[4] = 0;
    bad[5] = 0;  // MBAP length 0, in step
    d.feed(bad, out);
    d.feed(adus[0], out);
    d.finish(out);
    ASSERT_EQ(out.size(), 5u);
    EXPECT_EQ(std::get<mb::Unparsed>(out[0]).reason, mb::UnparsedReason::Truncated);
    EXPECT_EQ(std::get<mb::Unparsed>(out[1]).reason, mb::UnparsedReason::AfterGap);
    EXPECT_EQ(std::get<mb::Unparsed>(out[1]).length, adus[1].size() - 8);
    EXPECT_TRUE(std::holds_alternative<mb::Frame>(out[2]));
    EXPECT_EQ(std::get<mb::Unparsed>(out[3]).reason, mb::UnparsedReason::BadHeader);
    EXPECT_TRUE(std::holds_alternative<mb::Frame>(out[4]));
}

TEST(TcpStreamDeframer, TruncatedAtEnd) {
    const auto adu = hex("00 01 00 00 00 06 11 03 00");
    auto events = run(adu, {adu.size()});
    expect_every_byte_accounted(events, adu.size());
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::Truncated);
}

TEST(TcpStreamDeframer, LongGarbageKeepsEveryByte) {
    std::vector<std::uint8_t> data(100000, 0xEE);
    const auto adu = sample_adus()[0];
    data.insert(data.end(), adu.begin(), adu.end());
    for (const auto& sizes : chunkings(data.size(), 3, 5)) {
        if (sizes.size() > 20000) continue;  // 1-byte chunks of 100 kB: covered by the short streams
        auto events = run(data, sizes);
        expect_every_byte_accounted(events, data.size());
        ASSERT_EQ(frames_bytes(events).back(), adu);
    }
}

TEST(TcpStreamDeframer, ResetStartsAFreshStreamAtOffsetZero) {
    const auto adus = sample_adus();
    const auto data = concat(adus);
    mb::TcpStreamDeframer d;
    mb::DeframeEvents ignored;
    d.feed(hex("00 01 00 00 FF FF 11"), ignored);  // out of sync, bytes buffered
    d.reset();
    EXPECT_EQ(d.offset(), 0u);
    EXPECT_EQ(d.buffered(), 0u);
    mb::DeframeEvents out;
    d.feed(data, out);
    d.finish(out);
    expect_every_byte_accounted(out, data.size());
    EXPECT_EQ(frames_bytes(out), adus);
}

// A server (often a gateway counting the RTU CRC) sends each reply whole in one segment, its MBAP length 1 or
// 2 too long. Read by the length, the reply took the next reply's first byte, whose rest formed no frame. A
// passive observer sees the segments: the reply is the bytes its segment held, flagged, and the next reply
// is read from its header.
namespace {

// An FC3 reply of 2 registers to unit 1 whose MBAP length is `excess` too long.
std::vector<std::uint8_t> long_reply(std::uint8_t tid, std::uint8_t excess) {
    return concat(
        {{0x00, tid, 0x00, 0x00, 0x00, static_cast<std::uint8_t>(7 + excess)}, hex("01 03 04 00 01 00 02")});
}
std::vector<std::uint8_t> reply(std::uint8_t tid) {
    return long_reply(tid, 0);
}

mb::Timestamp seconds(std::int64_t s) {
    return mb::Timestamp{s * 1'000'000'000};
}

// Feeds each chunk at its own time (chunk i at seconds_at[i], or at i + 1 seconds) and finishes.
mb::DeframeEvents feed_chunks(mb::TcpStreamDeframer& d, const std::vector<std::vector<std::uint8_t>>& chunks,
                              const std::vector<std::int64_t>& seconds_at = {}) {
    mb::DeframeEvents out;
    for (std::size_t i = 0; i < chunks.size(); ++i) {
        d.feed(chunks[i], seconds(i < seconds_at.size() ? seconds_at[i] : static_cast<std::int64_t>(i + 1)),
               out);
    }
    d.finish(out);
    return out;
}

int cut_frames(const mb::DeframeEvents& events) {
    int n = 0;
    for (const auto& e : events) {
        if (const auto* f = std::get_if<mb::Frame>(&e)) {
            n += f->findings.contains(mb::FindingCode::TcpLengthBeyondSegment);
        }
    }
    return n;
}

mb::TcpStreamDeframer passive_deframer(mb::Direction carries) {
    mb::TcpStreamDeframer d;
    d.observe_passively(carries);
    return d;
}

}  // namespace

TEST(TcpStreamDeframer, ALengthTooLongInAWholeSegmentIsCutAtTheSegmentsEnd) {
    for (const std::uint8_t excess : {1, 2}) {
        for (const auto carries : {mb::Direction::Response, mb::Direction::Unknown}) {
            auto d = passive_deframer(carries);
            const auto first = long_reply(1, excess), second = reply(2);
            const auto events = feed_chunks(d, {first, second});
            expect_every_byte_accounted(events, first.size() + second.size());
            ASSERT_EQ(frames_bytes(events), (std::vector{first, second})) << int{excess};
            const auto& cut = std::get<mb::Frame>(events[0]);
            EXPECT_TRUE(cut.findings.contains(mb::FindingCode::TcpLengthBeyondSegment));
            EXPECT_EQ(cut.length_field(), 7 + excess);
            EXPECT_EQ(cut.pdu().size(), 6u);
            // Whole when its own segment came (1 s), not the next (2 s).
            EXPECT_EQ(cut.end, mb::Timestamp{1'000'000'000});
            const auto& next = std::get<mb::Frame>(events[1]);
            EXPECT_TRUE(next.findings.empty());
            EXPECT_EQ(next.transaction_id(), 2);
            EXPECT_EQ(next.end, mb::Timestamp{2'000'000'000});
        }
    }
    // A client's request alike, on a stream carrying requests; the reply above is no request.
    const auto request = hex("00 01 00 00 00 07 01 03 00 00 00 02");
    const auto next_request = hex("00 02 00 00 00 06 01 03 00 00 00 02");
    auto client = passive_deframer(mb::Direction::Request);
    const auto events = feed_chunks(client, {request, next_request});
    expect_every_byte_accounted(events, request.size() + next_request.size());
    EXPECT_EQ(frames_bytes(events), (std::vector{request, next_request}));
    EXPECT_EQ(cut_frames(events), 1);
    auto wrong_way = passive_deframer(mb::Direction::Request);
    EXPECT_EQ(cut_frames(feed_chunks(wrong_way, {long_reply(1, 1), reply(2)})), 0);
}

// The cut frame's time is when its own bytes came: an empty feed between does not move it, and segments fed
// out of their capture order do not put its end before its start.
TEST(TcpStreamDeframer, ACutFramesEndIsItsOwnBytesTime) {
    const auto first = long_reply(1, 1), second = reply(2);
    auto with_empty = passive_deframer(mb::Direction::Response);
    auto events = feed_chunks(with_empty, {first, {}, second});
    ASSERT_EQ(frames_bytes(events), (std::vector{first, second}));
    EXPECT_EQ(std::get<mb::Frame>(events[0]).end, seconds(1));
    EXPECT_EQ(std::get<mb::Frame>(events[1]).end, seconds(3));

    // The cut frame's header and byte count at 5 s (no whole PDU yet, so not cut there), its registers
    // stamped 3 s, the next reply at 4 s.
    const auto split = first.begin() + 9;
    auto out_of_order = passive_deframer(mb::Direction::Response);
    events = feed_chunks(out_of_order, {{first.begin(), split}, {split, first.end()}, second}, {5, 3, 4});
    ASSERT_EQ(frames_bytes(events), (std::vector{first, second}));
    const auto& cut = std::get<mb::Frame>(events[0]);
    EXPECT_TRUE(cut.findings.contains(mb::FindingCode::TcpLengthBeyondSegment));
    EXPECT_EQ(cut.start, seconds(5));
    EXPECT_GE(cut.end, cut.start);
}

// A gateway counting the CRC does so in every reply: each is cut when the next comes, itself too long. The
// last, with no segment after it, is read by its length: truncated at the end.
TEST(TcpStreamDeframer, EveryReplyTooLongIsCutButTheLast) {
    auto d = passive_deframer(mb::Direction::Response);
    const auto r1 = long_reply(1, 2), r2 = long_reply(2, 2), r3 = long_reply(3, 2);
    const auto events = feed_chunks(d, {r1, r2, r3});
    expect_every_byte_accounted(events, r1.size() + r2.size() + r3.size());
    EXPECT_EQ(frames_bytes(events), (std::vector{r1, r2}));
    EXPECT_EQ(cut_frames(events), 2);
    ASSERT_EQ(events.size(), 3u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[2]).reason, mb::UnparsedReason::Truncated);
}

TEST(TcpStreamDeframer, ALegitimatelySplitAduIsNotCut) {
    const auto whole = reply(1), next = reply(2);
    const auto data = concat({whole, next});
    // The header (and unit id) in one segment, the PDU in the next; the PDU split mid-way, its first part
    // ("03 04 00", one byte of the registers) no whole PDU; the header and a register in one segment, then
    // the rest and a whole reply.
    for (const std::size_t split : {std::size_t{6}, std::size_t{7}, std::size_t{10}, std::size_t{11}}) {
        for (const auto carries : {mb::Direction::Response, mb::Direction::Unknown}) {
            auto d = passive_deframer(carries);
            const auto events =
                feed_chunks(d, {{data.begin(), data.begin() + static_cast<std::ptrdiff_t>(split)},
                                {data.begin() + static_cast<std::ptrdiff_t>(split), data.end()}});
            expect_every_byte_accounted(events, data.size());
            EXPECT_EQ(frames_bytes(events), (std::vector{whole, next})) << split;
            EXPECT_EQ(cut_frames(events), 0) << split;
        }
    }
    // A split whose first part does decode whole by itself: an FC7 reply "07 6D" cut after "07", an FC7
    // request. Its next segment starts with "6D", then the next reply's header: no header there.
    const auto fc7 = hex("00 01 00 00 00 03 01 07 6D"), fc7_next = hex("00 02 00 00 00 03 01 07 6D");
    auto d = passive_deframer(mb::Direction::Unknown);
    const auto events = feed_chunks(d, {{fc7.begin(), fc7.end() - 1}, concat({{fc7.back()}, fc7_next})});
    EXPECT_EQ(frames_bytes(events), (std::vector{fc7, fc7_next}));
    EXPECT_EQ(cut_frames(events), 0);
}

// Legitimate streams in every chunking, read passively: never cut.
TEST(TcpStreamDeframer, NoChunkingOfAHealthyStreamIsCut) {
    const auto adus = sample_adus();
    const auto data = concat(adus);
    for (const auto& sizes : chunkings(data.size(), 200, 23)) {
        auto events = run(data, sizes, true);
        expect_every_byte_accounted(events, data.size());
        ASSERT_EQ(frames_bytes(events), adus);
        ASSERT_EQ(cut_frames(events), 0);
    }
}

// Without a segment boundary after the too-long ADU (both in one chunk), or read as an endpoint reads (by the
// lengths alone), the length is followed: the frame takes the next reply's first byte.
TEST(TcpStreamDeframer, ALengthTooLongIsFollowedWithinAChunkAndByAnEndpoint) {
    const auto first = long_reply(1, 1), second = reply(2);
    const auto data = concat({first, second});
    auto one_chunk = passive_deframer(mb::Direction::Response);
    auto endpoint = mb::TcpStreamDeframer{};
    for (const auto& events : {feed_chunks(one_chunk, {data}), feed_chunks(endpoint, {first, second})}) {
        expect_every_byte_accounted(events, data.size());
        EXPECT_EQ(cut_frames(events), 0);
        ASSERT_FALSE(events.empty());
        const auto* frame = std::get_if<mb::Frame>(&events[0]);
        ASSERT_NE(frame, nullptr);
        EXPECT_EQ(frame->length, first.size() + 1);
    }
}

}  // namespace test_modbus_tcp_deframer_test
