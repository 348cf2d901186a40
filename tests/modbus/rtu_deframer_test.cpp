#include "modbus/rtu_deframer.hpp"

#include <gtest/gtest.h>

#include "deframer_util.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/pdu.hpp"
#include "test_util.hpp"

namespace test_modbus_rtu_deframer_test {

using namespace mbscope::test;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

namespace {

// The MK manual's worked exchange (000:330-484), requests and responses back to back.
const std::vector<const char*> mk_stream = {
    "11 01 00 13 00 15 0E 90",
    "11 01 03 B2 0E 1B DA 92",
    "11 03 00 60 00 03 07 45",
    "11 03 06 02 2B 00 00 00 64 C8 BA",
    "11 05 00 54 FF 00 CF 7A",
    "11 05 00 54 FF 00 CF 7A",
    "11 06 00 54 03 9E 4B D2",
    "11 06 00 54 03 9E 4B D2",
    "11 08 00 00 A5 37 D8 1D",
    "11 08 00 00 A5 37 D8 1D",
    "11 0F 00 13 00 0A 02 CD 00 7E CB",
    "11 0F 00 13 00 0A 26 99",
    "11 10 00 60 00 02 04 00 0A 01 02 01 14",
    "11 10 00 60 00 02 43 46",
    "11 81 02 C0 54",
};

std::vector<std::uint8_t> concat(const std::vector<std::vector<std::uint8_t>>& parts) {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts)
        out.insert(out.end(), p.begin(), p.end());
    return out;
}

std::vector<std::vector<std::uint8_t>> mk_frames() {
    std::vector<std::vector<std::uint8_t>> frames;
    for (auto h : mk_stream)
        frames.push_back(hex(h));
    return frames;
}

mb::DeframeEvents run_untimed(const std::vector<std::uint8_t>& data, const std::vector<std::size_t>& sizes) {
    mb::RtuDeframer d;
    mb::DeframeEvents out;
    std::size_t pos = 0;
    for (auto n : sizes) {
        d.feed({data.data() + pos, n}, out);
        pos += n;
    }
    d.finish(out);
    return out;
}

}  // namespace

TEST(RtuStep, ThreeWayOutcome) {
    using K = mb::DeframeStep::Kind;
    auto full = hex("11 03 00 60 00 03 07 45");
    EXPECT_EQ(mb::rtu_step(full, false, false).kind, K::Complete);
    EXPECT_EQ(mb::rtu_step(full, false, false).length, 8u);
    EXPECT_EQ(mb::rtu_step(std::span(full).first(3), false, false).kind, K::NeedMore);
    auto garbage = hex("FF FF FF FF FF FF FF FF FF FF");
    EXPECT_EQ(mb::rtu_step(garbage, false, false).kind, K::Skip);
}

TEST(RtuStep, FrameNeedsTheCrcCandidateNotJustFourBytes) {
    // A response whose byte count promises more: the stepper waits instead of guessing.
    auto prefix = hex("11 03 06 02 2B 00");
    const auto step = mb::rtu_step(prefix, false, false);
    EXPECT_EQ(step.kind, mb::DeframeStep::Kind::NeedMore);
}

TEST(RtuDeframer, ManualStreamInEveryChunking) {
    // Issue: every chunking (1 byte at a time, random splits) gives the same frames.
    const auto frames = mk_frames();
    const auto data = concat(frames);
    for (const auto& sizes : chunkings(data.size(), 50, 42)) {
        auto events = run_untimed(data, sizes);
        expect_every_byte_accounted(events, data.size());
        ASSERT_EQ(frames_bytes(events), frames);
        for (const auto& e : events)
            EXPECT_TRUE(std::get<mb::Frame>(e).checksum_ok);
    }
}

TEST(RtuDeframer, GarbageBeforeBetweenAndAfterIsReportedNeverLost) {
    const auto frames = mk_frames();
    std::vector<std::vector<std::uint8_t>> parts = {
        hex("FF FE 00 13"), frames[2],   hex("AA"), frames[3], hex("00 00 00 00 00 00 00 00 00"),
        frames[12],         hex("47 11")};
    const auto data = concat(parts);
    for (const auto& sizes : chunkings(data.size(), 30, 7)) {
        auto events = run_untimed(data, sizes);
        expect_every_byte_accounted(events, data.size());
        EXPECT_EQ(frames_bytes(events), (std::vector{frames[2], frames[3], frames[12]}));
        std::uint64_t unparsed = 0;
        for (const auto& e : events)
            if (auto* u = std::get_if<mb::Unparsed>(&e)) unparsed += u->length;
        EXPECT_EQ(unparsed, 4u + 1u + 9u + 2u);
    }
}

TEST(RtuDeframer, FrameWithCorruptedCrcIsFoundBetweenGoodFrames) {
    // MK-ERR-01's corrupted frame 11 03 00 60 00 03 07 46 between two good ones: reported as a frame
    // with a bad CRC (the next frame starts right after its predicted length), not as garbage.
    const auto data = concat(
        {hex("11 03 00 60 00 03 07 45"), hex("11 03 00 60 00 03 07 46"), hex("11 06 00 54 03 9E 4B D2")});
    auto events = run_untimed(data, {data.size()});
    expect_every_byte_accounted(events, data.size());
    ASSERT_EQ(events.size(), 3u);
    const auto& bad = std::get<mb::Frame>(events[1]);
    EXPECT_FALSE(bad.checksum_ok);
    EXPECT_TRUE(bad.findings.contains(mb::FindingCode::RtuCrcMismatch));
    EXPECT_EQ(bad.offset, 8u);
}

TEST(RtuDeframer, TruncatedFrameAtEndIsUnparsed) {
    const auto data = concat({hex("11 03 00 60 00 03 07 45"), hex("11 03 06 02 2B")});
    auto events = run_untimed(data, {data.size()});
    expect_every_byte_accounted(events, data.size());
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[1]).reason, mb::UnparsedReason::Truncated);
}

TEST(RtuDeframer, LongGarbageIsLinearAndAccounted) {
    std::vector<std::uint8_t> data(200000);
    std::mt19937 rng(99);
    for (auto& b : data)
        b = static_cast<std::uint8_t>(rng());
    auto tail = hex("11 03 00 60 00 03 07 45");
    data.insert(data.end(), tail.begin(), tail.end());
    auto events = run_untimed(data, {data.size()});
    expect_every_byte_accounted(events, data.size());
    ASSERT_FALSE(events.empty());
    const auto* last = std::get_if<mb::Frame>(&events.back());
    ASSERT_NE(last, nullptr);
    EXPECT_EQ(std::vector<std::uint8_t>(last->adu().begin(), last->adu().end()), tail);
}

// ---------------------------------------------------------------- timed

namespace {

struct TimedChunk {
    std::vector<std::uint8_t> bytes;
    std::chrono::nanoseconds
        silence_before;  // silence between the previous chunk's end and this chunk's start
};

// Builds chunk timestamps for a 9600 8N1 line (character time 1.0417 ms).
mb::DeframeEvents run_timed(const std::vector<TimedChunk>& chunks, mb::SerialLine line = {}) {
    mb::RtuTimedDeframer d(line);
    mb::DeframeEvents out;
    mb::Timestamp t = 1s;
    const auto ct = line.character_time();
    for (const auto& c : chunks) {
        t += c.silence_before + ct * static_cast<std::int64_t>(c.bytes.size());
        d.advance(t - ct * static_cast<std::int64_t>(c.bytes.size()), out);
        d.feed(c.bytes, t, out);
    }
    d.advance(t + 1s, out);
    d.finish(out);
    return out;
}

}  // namespace

TEST(SerialLine, CharacterTimes) {
    mb::SerialLine l{9600, 8, mb::Parity::None, 1};
    EXPECT_EQ(l.bits_per_character(), 10u);
    EXPECT_EQ(l.character_time(), 1041666ns);
    EXPECT_EQ(l.t3_5(), 3645831ns);
    mb::SerialLine even{9600, 8, mb::Parity::Even, 1};
    EXPECT_EQ(even.bits_per_character(), 11u);  // the 4.01 ms t3.5 of manual-rules.md §0
    const double t35_ms = std::chrono::duration<double, std::milli>(even.t3_5()).count();
    EXPECT_NEAR(t35_ms, 4.01, 0.01);
    mb::SerialLine fast{38400, 8, mb::Parity::Even, 1};
    EXPECT_EQ(fast.t1_5(), 750us);  // SL §2.5.1.1: fixed above 19200 baud
    EXPECT_EQ(fast.t3_5(), 1750us);
}

TEST(RtuTimedDeframer, SilenceSeparatesFrames) {
    auto events =
        run_timed({{hex("11 03 00 60 00 03 07 45"), 0ms}, {hex("11 03 06 02 2B 00 00 00 64 C8 BA"), 10ms}});
    ASSERT_EQ(events.size(), 2u);
    for (const auto& e : events) {
        const auto& f = std::get<mb::Frame>(e);
        EXPECT_TRUE(f.checksum_ok);
        EXPECT_TRUE(f.findings.empty());
        EXPECT_GT(f.end, f.start);
    }
}

TEST(RtuTimedDeframer, GapAboveT15InsideFrameIsFlaggedWithItsSize) {
    // A 3-character gap (3.1 ms at 9600 8N1) inside the FC3 request: shorter than t3.5, so still one frame,
    // and its CRC verifies, but SL §2.5.1.1 says the receiver must discard it.
    auto events = run_timed({{hex("11 03 00 60"), 0ms}, {hex("00 03 07 45"), 3125us}});
    ASSERT_EQ(events.size(), 1u);
    const auto& f = std::get<mb::Frame>(events[0]);
    EXPECT_TRUE(f.checksum_ok);
    EXPECT_TRUE(f.findings.contains(mb::FindingCode::RtuGapInsideFrame));
    EXPECT_NEAR(f.max_gap_chars, 3.0, 0.05);
    EXPECT_EQ(f.gap_before_byte, 4);
}

TEST(RtuTimedDeframer, GapOfOneCharacterIsNotFlagged) {
    auto events = run_timed({{hex("11 03 00 60"), 0ms}, {hex("00 03 07 45"), 1ms}});
    ASSERT_EQ(events.size(), 1u);
    EXPECT_TRUE(std::get<mb::Frame>(events[0]).findings.empty());
}

// A frame joined across a silence of 5 character times after byte `gap_before`: its CRC holds, and the
// silence is inside it, an error still.
void expect_joined(const mb::Frame& f, std::size_t length, std::uint16_t gap_before) {
    EXPECT_TRUE(f.checksum_ok);
    EXPECT_EQ(f.wire_length, length);
    EXPECT_TRUE(f.findings.contains(mb::FindingCode::RtuGapInsideFrame));
    EXPECT_FALSE(f.findings.contains(mb::FindingCode::RtuCrcMismatch));
    EXPECT_TRUE(f.gap_at_t3_5);
    EXPECT_NEAR(f.max_gap_chars, 5.0, 0.05);
    EXPECT_EQ(f.gap_before_byte, gap_before);
}

// MK-RTU-01 (a): the FC3 request split by a 5-character gap. A receiver keeping t3.5 takes two fragments,
// neither a valid frame; the pieces verify together, so the analyzer sees the master's request, cut by a
// silence of t3.5 or more: one frame whose CRC holds, with that silence recorded inside it (an error still).
TEST(RtuTimedDeframer, ARequestCutByASilenceOfT35IsOneFrameWithTheSilenceInside) {
    auto events = run_timed({{hex("11 03 00 60"), 0ms}, {hex("00 03 07 45"), 5208us}});
    expect_every_byte_accounted(events, 8);
    ASSERT_EQ(events.size(), 1u);
    expect_joined(std::get<mb::Frame>(events[0]), 8, 4);
}

// The MK manual's FC3 reply (000:365) cut after its fifth byte by a silence of 5 character times (a USB
// adapter's two reads stamped far apart): its tail "00 00 00 64 C8 BA" was a damaged frame to unit 0 and the
// head a damaged reply, two bad CRCs blaming nobody right. Head and tail verify together: one frame of unit
// 17, its CRC good, the silence recorded inside it as one of t3.5 or more, its times the first and last
// byte's.
TEST(RtuTimedDeframer, AReplyCutByASilenceOfT35IsJoinedByItsCrc) {
    const mb::SerialLine line;
    const auto ct = line.character_time();
    const auto request = hex("11 03 00 60 00 03 07 45");
    const auto head = hex("11 03 06 02 2B");
    const auto tail = hex("00 00 00 64 C8 BA");
    mb::RtuTimedDeframer d(line);
    mb::DeframeEvents out;
    const mb::Timestamp head_end = 1s + 20ms;
    d.feed(request, 1s, out);
    EXPECT_EQ(d.closing_silence(), line.t3_5());
    d.advance(head_end - ct * 5, out);
    d.feed(head, head_end, out);
    const mb::Timestamp tail_end = head_end + ct * 5 + ct * 6;  // 5 characters of silence, then 6 bytes
    d.advance(tail_end - ct * 6, out);
    EXPECT_TRUE(d.holding()) << "the head waits for its tail";
    ASSERT_EQ(out.size(), 1u);
    d.feed(tail, tail_end, out);
    d.advance(tail_end + 10ms, out);
    EXPECT_FALSE(d.holding());
    d.finish(out);
    expect_every_byte_accounted(out, request.size() + head.size() + tail.size());
    ASSERT_EQ(out.size(), 2u);
    EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
    const auto& f = std::get<mb::Frame>(out[1]);
    EXPECT_EQ(frames_bytes(out)[1], hex("11 03 06 02 2B 00 00 00 64 C8 BA"));
    expect_joined(f, 11, 5);
    EXPECT_EQ(f.unit_id(), 0x11);
    EXPECT_EQ(f.offset, 8u);
    EXPECT_FALSE(f.findings.contains(mb::FindingCode::RtuShortSilenceBeforeFrame));
    EXPECT_EQ(f.start, head_end - ct * 4);
    EXPECT_EQ(f.end, tail_end);
    EXPECT_EQ(f.short_silence_before_chars, 0);
    EXPECT_EQ(f.short_silence_after_chars, 0);
}

// Every frame of the MK manual's exchange, cut once at every byte from the second on by a silence of 5
// character times, comes out whole, its CRC good, the silence recorded where it was; chunked a byte at a
// time too. Bytes glued after the tail (the next frame, sent before t3.5) go on as frames of their own.
TEST(RtuTimedDeframer, EveryManualFrameCutOnceIsJoined) {
    const auto frames = mk_frames();
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const auto& frame = frames[i];
        for (std::size_t cut = 2; cut < frame.size(); ++cut) {
            for (const bool bytewise : {false, true}) {
                SCOPED_TRACE(std::string(mk_stream[i]) + " cut at " + std::to_string(cut) +
                             (bytewise ? " bytewise" : ""));
                const std::vector<std::uint8_t> head(frame.begin(), frame.begin() + static_cast<long>(cut));
                std::vector<std::uint8_t> tail(frame.begin() + static_cast<long>(cut), frame.end());
                const auto& next = frames[(i + 1) % frames.size()];
                tail.insert(tail.end(), next.begin(), next.end());  // the next frame glued to the tail
                std::vector<TimedChunk> chunks;
                const auto add = [&](const std::vector<std::uint8_t>& bytes,
                                     std::chrono::nanoseconds before) {
                    if (!bytewise) {
                        chunks.push_back({bytes, before});
                        return;
                    }
                    for (std::size_t b = 0; b < bytes.size(); ++b)
                        chunks.push_back({{bytes[b]}, b == 0 ? before : 0ns});
                };
                add(frames[0], 0ms);
                add(head, 20ms);
                add(tail, 5208us);
                auto events = run_timed(chunks);
                expect_every_byte_accounted(events, frames[0].size() + frame.size() + next.size());
                ASSERT_EQ(frames_bytes(events), (std::vector{frames[0], frame, next}));
                const auto& f = std::get<mb::Frame>(events[1]);
                EXPECT_TRUE(f.checksum_ok);
                EXPECT_TRUE(f.gap_at_t3_5);
                EXPECT_EQ(f.gap_before_byte, cut);
                EXPECT_NEAR(f.max_gap_chars, 5.0, 0.05);
                EXPECT_TRUE(std::get<mb::Frame>(events[2]).checksum_ok);
                EXPECT_FALSE(
                    std::get<mb::Frame>(events[2]).findings.contains(mb::FindingCode::RtuGapInsideFrame));
            }
        }
    }
}

// Only pieces that verify together are joined. A reply cut short (the device stopped), then the master's
// retry, a good frame of its own: the head stays a frame with a bad CRC and the retry a good frame. A head
// whose tail is damaged too: two bad pieces make no frame. A silence longer than a frame is held across
// (hold_limit): the pieces stay apart though they would verify.
TEST(RtuTimedDeframer, PiecesThatDoNotVerifyTogetherAreNotJoined) {
    const auto request = hex("11 03 00 60 00 03 07 45");
    const auto head = hex("11 03 06 02 2B");
    struct Case {
        const char* what;
        std::vector<std::uint8_t> after;
        std::chrono::nanoseconds silence;
        bool after_ok;
    };
    for (const Case& c :
         {Case{"retry", request, 10ms, true}, Case{"damaged tail", hex("00 00 00 64 C8 BB"), 10ms, false},
          Case{"long silence", hex("00 00 00 64 C8 BA"), 150ms, false}}) {
        SCOPED_TRACE(c.what);
        auto events = run_timed({{request, 0ms}, {head, 20ms}, {c.after, c.silence}});
        expect_every_byte_accounted(events, request.size() + head.size() + c.after.size());
        ASSERT_EQ(events.size(), 3u);
        const auto& cut = std::get<mb::Frame>(events[1]);
        EXPECT_FALSE(cut.checksum_ok);
        EXPECT_EQ(cut.offset, 8u);
        EXPECT_EQ(cut.wire_length, head.size());
        EXPECT_FALSE(cut.findings.contains(mb::FindingCode::RtuGapInsideFrame));
        EXPECT_EQ(cut.short_silence_after_chars, 0);
        const auto& after = std::get<mb::Frame>(events[2]);
        EXPECT_EQ(after.checksum_ok, c.after_ok);
        EXPECT_EQ(after.offset, 8u + head.size());
        EXPECT_EQ(after.wire_length, c.after.size());
        EXPECT_TRUE(after.findings.size() == (c.after_ok ? 0u : 1u));
        EXPECT_EQ(after.short_silence_before_chars, 0);
    }
}

// A whole frame that is shorter than another frame its first bytes could start (a one-register FC3 reply
// against an 8-byte request, an FC16 reply against an FC16 request, a one-byte FC1 reply) is ended by t3.5 of
// silence, not waited for as a head: a live reader shows it then.
TEST(RtuTimedDeframer, AHealthyShortFrameIsClosedAtT35) {
    const mb::SerialLine line;
    const std::uint16_t one_register[] = {43};
    const bool one_coil[] = {true};
    const std::vector<std::vector<std::uint8_t>> frames = {
        mb::encode_rtu(0x11, mb::encode_pdu(mb::make_read_registers_response(
                                 mb::FunctionCode::ReadHoldingRegisters, one_register))),
        mb::encode_rtu(0x11, mb::encode_pdu(mb::make_write_multiple_response(
                                 mb::FunctionCode::WriteMultipleRegisters, 0x60, 2))),
        mb::encode_rtu(0x11,
                       mb::encode_pdu(mb::make_read_bits_response(mb::FunctionCode::ReadCoils, one_coil))),
    };
    for (const auto& frame : frames) {
        mb::RtuTimedDeframer d(line);
        mb::DeframeEvents out;
        d.feed(frame, 1s, out);
        EXPECT_EQ(d.closing_silence(), line.t3_5()) << mb::hex_bytes(frame);
        d.advance(1s + line.t3_5(), out);
        EXPECT_FALSE(d.holding()) << mb::hex_bytes(frame);
        ASSERT_EQ(frames_bytes(out), std::vector<std::vector<std::uint8_t>>{frame});
        EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
    }
    // The same bytes with a CRC that fails may be a head: they wait.
    auto damaged = frames[0];
    damaged.back() ^= 0x01;
    mb::RtuTimedDeframer d(line);
    mb::DeframeEvents out;
    d.feed(damaged, 1s, out);
    EXPECT_EQ(d.closing_silence(), 100ms);
}

// A head held for its tail that none completes before finish() or before advance() passes the longest
// silence a frame is joined across comes out as it did before the wait: a frame whose CRC fails (the silence
// ended it), or an unparsed run too short to be a frame. reset() drops it.
TEST(RtuTimedDeframer, AHeadWithNoTailComesOutAsBefore) {
    const mb::SerialLine line;
    const auto request = hex("11 03 00 60 00 03 07 45");
    for (const char* cut : {"11 03 06 02 2B", "11 03 06"}) {
        const auto head = hex(cut);
        const bool frame = head.size() >= 4;
        for (const bool by_advance : {false, true}) {
            SCOPED_TRACE(std::string(cut) + (by_advance ? " advance" : " finish"));
            mb::RtuTimedDeframer d(line);
            mb::DeframeEvents out;
            d.feed(request, 1s, out);
            d.feed(head, 1s + 20ms, out);
            EXPECT_EQ(d.closing_silence(), 100ms) << "bytes that would be held wait as long";
            d.advance(1s + 30ms, out);  // past t3.5: the head is held
            EXPECT_TRUE(d.holding());
            EXPECT_EQ(d.closing_silence(), 100ms);
            ASSERT_EQ(out.size(), 1u);
            if (by_advance) {
                d.advance(1s + 110ms, out);
                EXPECT_EQ(out.size(), 1u) << "held up to 100 ms of silence";
                d.advance(1s + 121ms, out);
                EXPECT_FALSE(d.holding());
                ASSERT_EQ(out.size(), 2u);
            }
            d.finish(out);
            expect_every_byte_accounted(out, request.size() + head.size());
            ASSERT_EQ(out.size(), 2u);
            if (frame) {
                const auto& f = std::get<mb::Frame>(out[1]);
                EXPECT_FALSE(f.checksum_ok);
                EXPECT_EQ(f.offset, 8u);
                EXPECT_EQ(f.wire_length, head.size());
                EXPECT_FALSE(f.findings.contains(mb::FindingCode::RtuGapInsideFrame));
            } else {
                const auto& u = std::get<mb::Unparsed>(out[1]);
                EXPECT_EQ(u.reason, mb::UnparsedReason::TooShort);
                EXPECT_EQ(u.offset, 8u);
                EXPECT_EQ(u.length, head.size());
            }
        }
    }
    // A held head, then bytes that start no tail before the input ends: the head as the silence made it,
    // the bytes after it as the end of the input makes them (truncated).
    mb::RtuTimedDeframer d(line);
    mb::DeframeEvents out;
    d.feed(hex("11 03 06 02 2B"), 1s, out);
    d.feed(hex("11 03 06"), 1s + 20ms, out);
    d.finish(out);
    expect_every_byte_accounted(out, 8);
    ASSERT_EQ(out.size(), 2u);
    EXPECT_FALSE(std::get<mb::Frame>(out[0]).checksum_ok);
    EXPECT_EQ(std::get<mb::Unparsed>(out[1]).reason, mb::UnparsedReason::Truncated);
    // reset() forgets a held head: a tail after it is a stream of its own.
    d.reset(line);
    out.clear();
    d.feed(hex("11 03 06 02 2B"), 1s, out);
    d.advance(1s + 10ms, out);
    EXPECT_TRUE(d.holding());
    d.reset(line);
    EXPECT_FALSE(d.holding());
    d.feed(hex("00 00 00 64 C8 BA"), 1s + 20ms, out);
    d.finish(out);
    expect_every_byte_accounted(out, 6);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_FALSE(std::get<mb::Frame>(out[0]).checksum_ok);
}

// A damaged reply alone between silences (a second device at address 2 answering too, one bit of its byte
// count flipped) is one frame whose CRC fails. Split by content it was a byte of garbage and "03 02 00 99
// 00 07 58 DE", a frame of unit 3 with a bad CRC, that took the fault; the split is kept only for a frame
// whose CRC holds. The tail of a reply cut by a silence made a unit-0 FC7 frame the same way.
TEST(RtuTimedDeframer, ADamagedFrameAloneIsOneFrameNotAPieceOfAnother) {
    for (const auto& run : {hex("02 03 02 00 99 00 07 58 DE"), hex("02 00 07 29 31")}) {
        auto events = run_timed({{hex("02 03 00 20 00 02 C5 F2"), 0ms}, {run, 10ms}});
        ASSERT_EQ(events.size(), 2u);
        const auto& f = std::get<mb::Frame>(events[1]);
        EXPECT_FALSE(f.checksum_ok);
        EXPECT_EQ(f.wire_length, run.size());
        EXPECT_EQ(f.unit_id(), 2);
    }
}

// A line driver's 0x00 as it lets the line go, right after a frame: CRC-16/MODBUS over a frame and its CRC is
// 0, and stays 0 over a 0x00 after them, so the ten bytes "hold" as a frame too, whose PDU has a byte too
// many (pdu.byte_count_mismatch against the device). The frame its content predicts holds: that frame, and
// one stray byte. (The untimed deframer framed it so already.)
TEST(RtuTimedDeframer, AStrayZeroAfterAFrameIsNotPartOfIt) {
    for (const auto& frame : {hex("02 03 04 00 02 00 07 29 31"), hex("03 03 00 30 00 02 C5 E6")}) {
        auto bytes = frame;
        bytes.push_back(0x00);
        auto events = run_timed({{bytes, 0ms}});
        expect_every_byte_accounted(events, bytes.size());
        ASSERT_EQ(events.size(), 2u);
        const auto& f = std::get<mb::Frame>(events[0]);
        EXPECT_TRUE(f.checksum_ok);
        EXPECT_EQ(f.wire_length, frame.size());
        EXPECT_EQ(std::get<mb::Unparsed>(events[1]).length, 1u);
    }
    // A frame whose whole run is the length its content says stays whole (one CRC, no search).
    auto events = run_timed({{hex("11 03 06 02 2B 00 00 00 64 C8 BA"), 0ms}});
    ASSERT_EQ(events.size(), 1u);
    EXPECT_TRUE(std::get<mb::Frame>(events[0]).checksum_ok);
}

// The input ends five bytes into an eleven-byte reply (a log cut off, a capture stopped): the bytes are a
// truncated run, not a frame with a bad CRC whose byte count disagrees. A silence after the same bytes ends
// a frame however short (the device stopped sending): that one is a frame, and its CRC fails.
TEST(RtuTimedDeframer, TheEndOfTheInputCutsAFrameASilenceEndsIt) {
    const auto request = hex("11 03 00 60 00 03 07 45");
    const auto cut = hex("11 03 06 02 2B");
    for (const bool silence : {false, true}) {
        mb::SerialLine line;
        mb::RtuTimedDeframer d(line);
        mb::DeframeEvents out;
        d.feed(request, 1s, out);
        d.feed(cut, 1s + 20ms, out);
        if (silence) d.advance(2s, out);
        d.finish(out);
        expect_every_byte_accounted(out, request.size() + cut.size());
        ASSERT_EQ(out.size(), 2u) << silence;
        EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
        if (silence) {
            const auto& f = std::get<mb::Frame>(out[1]);
            EXPECT_FALSE(f.checksum_ok);
            EXPECT_EQ(f.wire_length, 5u);
        } else {
            const auto& u = std::get<mb::Unparsed>(out[1]);
            EXPECT_EQ(u.reason, mb::UnparsedReason::Truncated);
            EXPECT_EQ(u.offset, 8u);
            EXPECT_EQ(u.length, 5u);
        }
    }
    // A run that does not start a longer frame stays one frame with a bad CRC at the end of the input too.
    mb::RtuTimedDeframer d(mb::SerialLine{});
    mb::DeframeEvents out;
    d.feed(hex("11 03 00 60 00 03 07 46"), 1s, out);
    d.finish(out);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_FALSE(std::get<mb::Frame>(out[0]).checksum_ok);
}

// A request cut after five bytes, "11 03 00 60 00", reads also as a whole reply to FC3 with byte count 0
// and a bad CRC: it was taken for that frame (a reply to nobody, a malformed PDU, a device sending what no
// device sends). No reply to a read carries byte count 0: the bytes are the start of the longer frame, cut
// by the end of the input, in the untimed and the timed deframer alike. A damaged reply of the shorter
// length whose PDU breaks no rule ("11 03 02 00 01": one register) stays a frame whose CRC fails.
TEST(RtuDeframer, AtTheEndBytesThatOnlyAMalformedShorterFrameFitsAreCut) {
    const auto request = hex("11 03 00 60 00 03 07 45");
    struct Case {
        const char* tail;
        bool cut;
    };
    for (const Case c : {Case{"11 03 00 60 00", true}, Case{"11 03 02 00 01 00 00", false}}) {
        SCOPED_TRACE(c.tail);
        const auto tail = hex(c.tail);
        for (const bool timed : {false, true}) {
            mb::DeframeEvents out;
            if (timed) {
                mb::RtuTimedDeframer d(mb::SerialLine{});
                d.feed(request, 1s, out);
                d.feed(tail, 2s, out);
                d.finish(out);
            } else {
                mb::RtuDeframer d;
                d.feed(concat({request, tail}), out);
                d.finish(out);
            }
            expect_every_byte_accounted(out, request.size() + tail.size());
            ASSERT_EQ(out.size(), 2u) << timed;
            EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
            if (c.cut) {
                const auto& u = std::get<mb::Unparsed>(out[1]);
                EXPECT_EQ(u.reason, mb::UnparsedReason::Truncated);
                EXPECT_EQ(u.offset, 8u);
                EXPECT_EQ(u.length, tail.size());
            } else {
                const auto& f = std::get<mb::Frame>(out[1]);
                EXPECT_FALSE(f.checksum_ok);
                EXPECT_EQ(f.wire_length, tail.size());
            }
        }
    }
}

// The same five bytes after a frame in one chunk, then a silence: the silence ends them, a frame however
// short (the device stopped sending), whose CRC fails; only the end of the input cuts them.
TEST(RtuTimedDeframer, BytesASilenceEndsAreAFrameEvenWhereTheEndWouldCutThem) {
    const auto glued = hex("11 03 06 02 2B 00 00 00 64 C8 BA 11 03 00 60 00");
    for (const bool silence : {true, false}) {
        mb::RtuTimedDeframer d(mb::SerialLine{});
        mb::DeframeEvents out;
        d.feed(glued, 1s, out);
        if (silence) d.advance(2s, out);
        d.finish(out);
        expect_every_byte_accounted(out, glued.size());
        ASSERT_EQ(out.size(), 2u) << silence;
        EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
        if (silence) {
            EXPECT_FALSE(std::get<mb::Frame>(out[1]).checksum_ok);
            EXPECT_EQ(std::get<mb::Frame>(out[1]).wire_length, 5u);
        } else {
            EXPECT_EQ(std::get<mb::Unparsed>(out[1]).reason, mb::UnparsedReason::Truncated);
        }
    }
}

TEST(RtuTimedDeframer, FramesGluedInOneChunkAreSplitByContent) {
    // A USB adapter delivered request and response in one read: no silence visible between them.
    auto glued = hex("11 03 00 60 00 03 07 45 11 03 06 02 2B 00 00 00 64 C8 BA");
    auto events = run_timed({{glued, 0ms}});
    ASSERT_EQ(events.size(), 2u);
    EXPECT_TRUE(std::get<mb::Frame>(events[0]).checksum_ok);
    EXPECT_TRUE(std::get<mb::Frame>(events[1]).checksum_ok);
    EXPECT_EQ(std::get<mb::Frame>(events[1]).offset, 8u);
}

TEST(RtuTimedDeframer, SilenceDelimitedRunWithBadCrcIsOneBadFrame) {
    auto events = run_timed({{hex("11 03 00 60 00 03 07 46"), 0ms}, {hex("11 06 00 54 03 9E 4B D2"), 10ms}});
    ASSERT_EQ(events.size(), 2u);
    const auto& bad = std::get<mb::Frame>(events[0]);
    EXPECT_FALSE(bad.checksum_ok);
    EXPECT_EQ(bad.length, 8);
}

TEST(RtuTimedDeframer, ShortNoiseIsUnparsed) {
    auto events = run_timed({{hex("00 FF"), 0ms}, {hex("11 06 00 54 03 9E 4B D2"), 10ms}});
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::TooShort);
}

TEST(RtuTimedDeframer, ChunkingDoesNotChangeFramesWhenSilencesAreKept) {
    const auto frames = mk_frames();
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        std::vector<TimedChunk> chunks;
        for (const auto& f : frames) {
            std::size_t pos = 0;
            bool first = true;
            while (pos < f.size()) {
                const std::size_t n = std::min<std::size_t>(f.size() - pos, 1 + rng() % 5);
                chunks.push_back({{f.begin() + static_cast<std::ptrdiff_t>(pos),
                                   f.begin() + static_cast<std::ptrdiff_t>(pos + n)},
                                  first ? 20ms : 0ms});
                pos += n;
                first = false;
            }
        }
        auto events = run_timed(chunks);
        expect_every_byte_accounted(events, concat(frames).size());
        ASSERT_EQ(frames_bytes(events), frames) << "seed " << seed;
    }
}

TEST(RtuTimedDeframer, LongRunWithoutSilenceIsFramedByContent) {
    std::vector<std::uint8_t> data;
    for (int i = 0; i < 200; ++i) {
        auto f = hex("11 03 00 60 00 03 07 45");
        data.insert(data.end(), f.begin(), f.end());
    }
    auto events = run_timed({{data, 0ms}});
    expect_every_byte_accounted(events, data.size());
    EXPECT_EQ(events.size(), 200u);
}

// A deframer reset in the middle of a stream (a frame half received, skipped bytes pending, a silence
// inside a frame recorded) meets the next stream as a new one: offsets from 0, nothing carried over.
TEST(RtuDeframer, ResetStartsAFreshStreamAtOffsetZero) {
    const auto second = concat({hex("AA"), hex("11 03 00 60 00 03 07 45"), hex("11 03 06 02 2B")});
    mb::DeframeEvents fresh;
    mb::RtuDeframer made;
    made.feed(second, fresh);
    made.finish(fresh);

    mb::RtuDeframer reused;
    mb::DeframeEvents ignored;
    reused.feed(hex("FF FE 11 03 06 02"), ignored);  // skipped bytes pending and half a frame buffered
    reused.reset();
    EXPECT_EQ(reused.bytes_in(), 0u);
    mb::DeframeEvents out;
    reused.feed(second, out);
    reused.finish(out);
    expect_every_byte_accounted(out, second.size());
    EXPECT_EQ(pieces(out).size(), pieces(fresh).size());
    EXPECT_EQ(frames_bytes(out), frames_bytes(fresh));
}

TEST(RtuTimedDeframer, ResetStartsAFreshStreamAtOffsetZero) {
    using namespace std::chrono_literals;
    const mb::SerialLine line{};
    const auto ct = line.character_time();
    mb::RtuTimedDeframer d(mb::SerialLine{1200, 8, mb::Parity::None, 1});
    mb::DeframeEvents ignored;
    d.feed(hex("11 03 00"), mb::Timestamp{5s}, ignored);
    d.feed(hex("60 00"), mb::Timestamp{5s + 20ms}, ignored);  // a silence inside the frame, recorded
    d.reset(line);
    EXPECT_EQ(d.line().baud, line.baud);

    const auto frame = hex("11 03 00 60 00 03 07 45");
    mb::DeframeEvents out;
    const mb::Timestamp end{1s};
    d.feed(frame, end, out);
    d.advance(end + 1s, out);
    d.finish(out);
    ASSERT_EQ(out.size(), 1u);
    const auto& f = std::get<mb::Frame>(out[0]);
    EXPECT_EQ(f.offset, 0u);
    EXPECT_TRUE(f.checksum_ok);
    EXPECT_TRUE(f.findings.empty()) << "the silence recorded before the reset is not this frame's";
    EXPECT_EQ(f.start, end - ct * 7);  // this line's character time, not the one before the reset
}

}  // namespace test_modbus_rtu_deframer_test
