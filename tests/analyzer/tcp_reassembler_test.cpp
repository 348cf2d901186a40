// The analyzer's TCP reassembler alone: what it delivers and declares lost for segments in and out of order,
// retransmitted, overlapping, beyond its buffering bound and across the wrap of the sequence space.
#include "analyzer/tcp_reassembler.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

namespace test_analyzer_tcp_reassembler_test {

namespace mb = mbscope::modbus;
using mbscope::analyzer::TcpReassembler;

namespace {

// What came out: the delivered bytes in order, with each declared hole as that many 0xEE bytes (the test
// streams never hold 0xEE), and the number of calls of each kind.
struct Out {
    std::vector<std::uint8_t> stream;
    int deliveries = 0;
    int gaps = 0;
    std::vector<std::pair<std::uint64_t, std::size_t>> conflicts;  // (stream offset, differing bytes)
};

struct Harness {
    Out out;
    TcpReassembler reassembler;
    explicit Harness(std::size_t max_buffered = 1 << 20)
        : reassembler(
              [this](std::span<const std::uint8_t> b, mb::Timestamp) {
                  out.stream.insert(out.stream.end(), b.begin(), b.end());
                  ++out.deliveries;
              },
              [this](std::uint64_t missing, mb::Timestamp) {
                  out.stream.insert(out.stream.end(), missing, 0xEE);
                  ++out.gaps;
              },
              max_buffered) {
        reassembler.on_conflict([this](std::uint64_t at, std::size_t differing, mb::Timestamp) {
            out.conflicts.emplace_back(at, differing);
        });
    }
    void syn(std::uint32_t isn) { reassembler.segment(isn, true, {}, mb::Timestamp{0}); }
    void flush() { reassembler.flush(mb::Timestamp{0}); }
    // Bytes [from, from + n) of `all`, a stream whose first byte has sequence number `seq`.
    void send(std::uint32_t seq, const std::vector<std::uint8_t>& all, std::size_t from, std::size_t n) {
        reassembler.segment(seq + static_cast<std::uint32_t>(from), false,
                            std::span<const std::uint8_t>(all.data() + from, n), mb::Timestamp{0});
    }
};

std::vector<std::uint8_t> stream_of(std::size_t n) {
    std::vector<std::uint8_t> s(n);
    for (std::size_t i = 0; i < n; ++i)
        s[i] = static_cast<std::uint8_t>(i % 200);
    return s;
}

}  // namespace

TEST(TcpReassembler, InOrderSegmentsAreDeliveredAsTheyCome) {
    Harness h;
    const auto s = stream_of(30);
    h.syn(999);  // SYN: the stream starts at 1000
    h.send(1000, s, 0, 10);
    h.send(1000, s, 10, 20);
    EXPECT_EQ(h.out.stream, s);
    EXPECT_EQ(h.out.deliveries, 2);
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 0u);
}

TEST(TcpReassembler, SegmentsAheadOfAHoleWaitForIt) {
    Harness h;
    const auto s = stream_of(40);
    h.syn(99);
    h.send(100, s, 30, 10);
    h.send(100, s, 10, 20);
    EXPECT_TRUE(h.out.stream.empty());
    h.send(100, s, 0, 10);  // fills the hole: all three go out, in stream order
    EXPECT_EQ(h.out.stream, s);
    EXPECT_EQ(h.out.gaps, 0);
}

TEST(TcpReassembler, RetransmittedAndOverlappingBytesAreDeliveredOnce) {
    Harness h;
    const auto s = stream_of(50);
    h.syn(0);
    h.send(1, s, 0, 20);
    h.send(1, s, 10, 20);  // 10 old bytes, 10 new
    h.send(1, s, 0, 5);    // all old
    h.send(1, s, 40, 10);  // ahead of a hole
    h.send(1, s, 40, 10);  // the same again while it waits
    h.send(1, s, 40, 5);   // and a shorter copy of it
    h.send(1, s, 30, 10);  // the hole
    EXPECT_EQ(h.out.stream, s);
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 10u + 5u + 10u + 5u);
    EXPECT_TRUE(h.out.conflicts.empty());  // honest copies
}

// A retransmission that carries other bytes than the first copy: the first copy is decoded, the new bytes
// past it are delivered, and the disagreement is reported with where it starts and how many bytes differ,
// whether the copies meet in order or while waiting for a hole.
TEST(TcpReassembler, ARetransmissionThatDiffersFromTheFirstCopyIsReported) {
    Harness h;
    const auto s = stream_of(60);
    auto forged = s;
    forged[12] ^= 0xFF;
    forged[15] ^= 0xFF;
    forged[45] ^= 0xFF;
    h.syn(0);
    h.send(1, s, 0, 20);
    h.send(1, forged, 10, 20);  // bytes 12 and 15 disagree; 20..29 are new
    ASSERT_EQ(h.out.conflicts.size(), 1u);
    EXPECT_EQ(h.out.conflicts[0], (std::pair<std::uint64_t, std::size_t>{12, 2}));
    h.send(1, s, 40, 10);       // ahead of a hole
    h.send(1, forged, 40, 10);  // another copy of it, byte 45 changed
    h.send(1, s, 30, 10);       // the hole fills: the first copy goes out, the second is compared
    ASSERT_EQ(h.out.conflicts.size(), 2u);
    EXPECT_EQ(h.out.conflicts[1], (std::pair<std::uint64_t, std::size_t>{45, 1}));
    h.send(1, s, 50, 10);
    EXPECT_EQ(h.out.stream, s);
}

// Offsets of a hole declared lost were never delivered: bytes that arrive for them later are not compared
// with whatever the comparison buffer held there before.
TEST(TcpReassembler, BytesOfALostHoleAreNotComparedWithOldOnes) {
    Harness h(16);
    const auto s = stream_of(100);
    auto other = s;
    for (auto& b : other)
        b ^= 0x55;
    h.syn(0);
    h.send(1, s, 0, 10);
    h.send(1, s, 40, 20);  // past the bound: 10..39 are declared lost
    EXPECT_EQ(h.out.gaps, 1);
    h.send(1, other, 20, 10);  // late bytes of the lost hole
    EXPECT_TRUE(h.out.conflicts.empty());
}

TEST(TcpReassembler, ALongerRetransmissionOfAWaitingSegmentDeliversItsNewBytes) {
    Harness h;
    const auto s = stream_of(30);
    h.syn(0);
    h.send(1, s, 10, 5);
    h.send(1, s, 10, 20);
    h.send(1, s, 0, 10);
    EXPECT_EQ(h.out.stream, s);
}

TEST(TcpReassembler, AHoleThatExceedsTheBufferingBoundIsDeclaredLost) {
    Harness h(100);
    const auto s = stream_of(400);
    h.syn(0);
    h.send(1, s, 0, 10);
    h.send(1, s, 20, 60);  // waits: 60 buffered
    EXPECT_EQ(h.out.gaps, 0);
    h.send(1, s, 80, 60);  // 120 buffered: the hole 10..20 is given up, both pieces go out
    EXPECT_EQ(h.out.gaps, 1);
    std::vector<std::uint8_t> expected(s.begin(), s.begin() + 140);
    std::fill(expected.begin() + 10, expected.begin() + 20, 0xEE);
    EXPECT_EQ(h.out.stream, expected);
    h.send(1, s, 10, 10);  // the lost bytes arrive late: old now
    EXPECT_EQ(h.out.stream.size(), 140u);
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 10u);
}

// The peer acknowledging bytes the capture never showed: they will not be sent again, so the hole below the
// acknowledgement is given up (one lost segment used to hold every later byte of the direction until the end
// of the capture): at once when the acknowledgement covers the whole hole and bytes after it are here (they
// were sent after the hole's); otherwise when the direction's next segment lies past it, at an
// acknowledgement a reordering wait after the first that covered it, or at the end. Bytes not acknowledged
// yet may still come; a FIN's own sequence number, acknowledged, is no lost byte.
// An acknowledgement ahead of the bytes it acknowledges, with nothing after them here yet (a tap merging two
// directions stamps the acknowledgement first, modbusBig.pcap packets 3149 and 3150): the bytes may still
// come, and are waited for. Bytes that arrived behind a hole keep their own time when it is given up.
TEST(TcpReassembler, AnAcknowledgementAheadOfItsBytesWaitsAndLaterBytesKeepTheirTime) {
    Harness h;
    const auto s = stream_of(40);
    h.syn(0);
    h.send(1, s, 0, 10);
    h.reassembler.acknowledged(1 + 20, mb::Timestamp{100});  // 10..20 not here yet
    h.send(1, s, 10, 10);
    EXPECT_EQ(h.out.gaps, 0);
    EXPECT_EQ(h.out.stream.size(), 20u);
    std::vector<mb::Timestamp> times;
    TcpReassembler timed([&times](std::span<const std::uint8_t>, mb::Timestamp t) { times.push_back(t); },
                         [](std::uint64_t, mb::Timestamp) {});
    timed.segment(0, true, {}, mb::Timestamp{0});
    timed.segment(1, false, std::span(s).first(10), mb::Timestamp{1000});
    timed.segment(21, false, std::span(s).subspan(20, 10), mb::Timestamp{2000});  // 10..20 lost
    timed.acknowledged(31, mb::Timestamp{10000});
    EXPECT_EQ(times, (std::vector<mb::Timestamp>{mb::Timestamp{1000}, mb::Timestamp{2000}}));
}

// Bytes that waited ahead of a hole are handed over with the packet that carried them and its time, also
// when they come after bytes of a later packet (captured in the reverse of their stream order): the analyzer
// credited them to the packet that released them, and a reply's latency to that packet's time.
TEST(TcpReassembler, BytesThatWaitedKeepTheirPacketAndTime) {
    const auto s = stream_of(30);
    std::vector<std::pair<std::uint64_t, mb::Timestamp>> seen;
    const TcpReassembler* self = nullptr;
    TcpReassembler r([&seen, &self](std::span<const std::uint8_t>,
                                    mb::Timestamp t) { seen.emplace_back(self->delivering_packet(), t); },
                     [](std::uint64_t, mb::Timestamp) {});
    self = &r;
    r.segment(0, true, {}, mb::Timestamp{0}, 1);
    r.segment(11, false, std::span(s).subspan(10, 10), mb::Timestamp{2000}, 2);  // ahead of 0..10
    r.segment(1, false, std::span(s).first(10), mb::Timestamp{3000}, 3);
    using Seen = std::vector<std::pair<std::uint64_t, mb::Timestamp>>;
    EXPECT_EQ(seen, (Seen{{3, mb::Timestamp{3000}}, {2, mb::Timestamp{2000}}}));
}

// A sender retransmits all it has unacknowledged: one segment that fills the hole and runs on over the bytes
// waiting behind it. Those were delivered with the retransmission's packet and time, and its copy of them
// (differing here) was decoded while the conflict said the first copy was. The waiting bytes keep their own
// packet and time and content; the segment's copy of them is compared, and what lies past them is new.
TEST(TcpReassembler, ARetransmissionOverBytesThatWaitedLeavesThemTheirOwn) {
    const auto s = stream_of(40);
    auto again = s;
    again[22] ^= 0xFF;  // the retransmission's copy of a waiting byte differs
    struct Delivery {
        std::uint64_t packet;
        mb::Timestamp time;
        std::vector<std::uint8_t> bytes;
        bool operator==(const Delivery&) const = default;
    };
    std::vector<Delivery> seen;
    std::vector<std::pair<std::uint64_t, std::size_t>> conflicts;
    const TcpReassembler* self = nullptr;
    TcpReassembler r(
        [&seen, &self](std::span<const std::uint8_t> b, mb::Timestamp t) {
            seen.push_back({self->delivering_packet(), t, {b.begin(), b.end()}});
        },
        [](std::uint64_t, mb::Timestamp) {});
    r.on_conflict(
        [&conflicts](std::uint64_t at, std::size_t n, mb::Timestamp) { conflicts.emplace_back(at, n); });
    self = &r;
    r.segment(0, true, {}, mb::Timestamp{0}, 1);
    r.segment(21, false, std::span(s).subspan(20, 10), mb::Timestamp{2000}, 2);  // ahead of 0..20
    EXPECT_TRUE(r.holds_bytes_captured_by(mb::Timestamp{2000}));
    EXPECT_FALSE(r.holds_bytes_captured_by(mb::Timestamp{1999}));
    r.segment(1, false, std::span(again).first(35), mb::Timestamp{9000}, 3);  // 0..35 in one
    const auto part = [&](std::size_t from, std::size_t n) {
        return std::vector<std::uint8_t>(s.begin() + static_cast<std::ptrdiff_t>(from),
                                         s.begin() + static_cast<std::ptrdiff_t>(from + n));
    };
    const std::vector<Delivery> expected{{3, mb::Timestamp{9000}, part(0, 20)},
                                         {2, mb::Timestamp{2000}, part(20, 10)},
                                         {3, mb::Timestamp{9000}, part(30, 5)}};
    EXPECT_EQ(seen, expected);
    EXPECT_EQ(conflicts, (std::vector<std::pair<std::uint64_t, std::size_t>>{{22, 1}}));
    EXPECT_EQ(r.retransmitted_bytes(), 10u);
    EXPECT_FALSE(r.holds_bytes_captured_by(mb::Timestamp{9000}));
}

TEST(TcpReassembler, AnAcknowledgementPastAHoleGivesItUp) {
    Harness h;
    const auto s = stream_of(100);
    const auto wait = TcpReassembler::reordering_wait;
    const mb::Timestamp t0{0};
    h.syn(0);
    h.send(1, s, 0, 10);
    h.reassembler.acknowledged(11, t0);  // all seen: nothing to give up
    h.send(1, s, 20, 10);                // 10..20 not captured
    h.send(1, s, 40, 10);                // nor 30..40
    h.reassembler.acknowledged(1 + 20, t0);
    EXPECT_EQ(h.out.gaps, 1);
    EXPECT_EQ(h.out.stream.size(), 30u);                // 0..10, the lost 10, 20..30
    h.reassembler.acknowledged(1 + 35, t0 + wait);      // up to 35 only: 35..40 may still come
    h.reassembler.acknowledged(1 + 35, t0 + 2 * wait);  // a wait after the first covering 30..35
    EXPECT_EQ(h.out.gaps, 2);
    EXPECT_EQ(h.out.stream.size(), 35u);
    h.send(1, s, 35, 5);
    std::vector<std::uint8_t> expected(s.begin(), s.begin() + 50);
    std::fill(expected.begin() + 10, expected.begin() + 20, 0xEE);
    std::fill(expected.begin() + 30, expected.begin() + 35, 0xEE);
    EXPECT_EQ(h.out.stream, expected);
    // Nothing waiting and a segment lost at the end: given up when the next one comes, which is in order.
    h.reassembler.acknowledged(1 + 60, t0);
    EXPECT_EQ(h.out.gaps, 2);
    h.send(1, s, 60, 10);
    EXPECT_EQ(h.out.gaps, 3);
    EXPECT_EQ(h.out.stream.size(), 70u);
    EXPECT_EQ(h.out.deliveries, 5);
    // Old and absurd acknowledgements change nothing.
    h.reassembler.acknowledged(1 + 5, t0 + 3 * wait);
    h.reassembler.acknowledged(1 + 70 + (1u << 31), t0 + 3 * wait);
    EXPECT_EQ(h.out.gaps, 3);
    // The FIN after byte 80 takes sequence number 81; its acknowledgement, 82, loses nothing.
    h.send(1, s, 70, 10);
    h.reassembler.finished_at(1 + 80);
    h.reassembler.acknowledged(1 + 81, t0 + 3 * wait);
    h.reassembler.acknowledged(1 + 81, t0 + 5 * wait);
    h.flush();
    EXPECT_EQ(h.out.gaps, 3);
    EXPECT_EQ(h.out.stream.size(), 80u);
}

// A tap or mirror port merging both directions can capture an acknowledgement before the segment it
// acknowledges (modbusBig.pcap: packet 3149 acknowledges the 10-byte reply that is packet 3150, 0.7 ms
// later). The hole waited for nothing: it was given up at the acknowledgement, the reply taken for a
// retransmission of bytes "not captured", and its request reported unanswered.
TEST(TcpReassembler, AnAcknowledgementCapturedBeforeItsBytesWaitsForThem) {
    Harness h;
    const auto s = stream_of(60);
    const auto wait = TcpReassembler::reordering_wait;
    h.syn(0);
    h.send(1, s, 0, 10);
    h.reassembler.acknowledged(1 + 20, mb::Timestamp{0});
    h.send(1, s, 10, 10);  // the bytes acknowledged, captured after the acknowledgement
    h.reassembler.acknowledged(1 + 20, wait);
    EXPECT_EQ(h.out.gaps, 0);
    EXPECT_EQ(h.out.stream, std::vector<std::uint8_t>(s.begin(), s.begin() + 20));
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 0u);
    // Part of an acknowledged range comes late, the rest never: the rest is given up after the wait.
    h.reassembler.acknowledged(1 + 40, 2 * wait);
    h.send(1, s, 20, 12);
    h.reassembler.acknowledged(1 + 40, 3 * wait);
    EXPECT_EQ(h.out.gaps, 1);
    auto expected = std::vector<std::uint8_t>(s.begin(), s.begin() + 40);
    std::fill(expected.begin() + 32, expected.end(), 0xEE);
    EXPECT_EQ(h.out.stream, expected);
    // Acknowledged and never seen before the end: a gap at the end.
    h.send(1, s, 40, 5);
    h.reassembler.acknowledged(1 + 55, 3 * wait);
    EXPECT_EQ(h.out.gaps, 1);
    h.flush();
    EXPECT_EQ(h.out.gaps, 2);
    EXPECT_EQ(h.out.stream.size(), 55u);
}

// A SYN's data (TCP Fast Open) are the stream's first bytes: they were dropped. A server that did not take
// them has them sent again after the handshake, which is then a retransmission of what was delivered.
TEST(TcpReassembler, DataOnASynAreTheStreamsFirstBytes) {
    Harness h;
    const auto s = stream_of(20);
    h.reassembler.segment(99, true, std::span(s).first(12), mb::Timestamp{0});
    EXPECT_EQ(h.out.stream, std::vector<std::uint8_t>(s.begin(), s.begin() + 12));
    h.reassembler.segment(99, true, std::span(s).first(12), mb::Timestamp{0});  // the SYN again
    h.send(100, s, 0, 20);                                                      // sent again, and more
    EXPECT_EQ(h.out.stream, s);
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 12u);
    EXPECT_TRUE(h.out.conflicts.empty());
    EXPECT_EQ(h.out.gaps, 0);
}

// TCP keep-alive probes (RFC 9293 §3.8.4) carry one garbage octet at the sequence number before the next
// (0x00 from BSD and Windows): each was compared with the byte delivered there and reported as a
// retransmission that differs from the first copy. A one-byte retransmission elsewhere is still compared.
TEST(TcpReassembler, AKeepAliveProbeIsNoRetransmission) {
    Harness h;
    const auto s = stream_of(20);  // byte 9 is 9
    h.syn(0);
    h.send(1, s, 0, 10);
    const std::vector<std::uint8_t> garbage = {0x00};
    for (int probe = 0; probe < 3; ++probe)
        h.send(1 + 10 - 1, garbage, 0, 1);  // sequence number 10: the last byte's
    EXPECT_TRUE(h.out.conflicts.empty());
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 0u);
    h.send(1 + 8, garbage, 0, 1);  // two before the next: a retransmission, and it differs
    EXPECT_EQ(h.out.conflicts.size(), 1u);
    h.send(1, s, 10, 10);
    EXPECT_EQ(h.out.stream, s);
}

// A capture begun mid-connection (no SYN) whose first segment overtook an earlier one: the earlier bytes
// precede the first delivered and cannot be put before it. They were counted as retransmitted and vanished;
// they are named, and only bytes delivered before count as retransmitted.
TEST(TcpReassembler, BytesBeforeTheFirstSeenOfAStreamWithoutSynAreNamed) {
    Harness h;
    std::vector<std::size_t> early;
    h.reassembler.on_before_start([&early](std::size_t n, mb::Timestamp) { early.push_back(n); });
    const auto s = stream_of(40);
    h.send(1000, s, 12, 10);  // the first seen: the stream starts here for the reassembler
    h.send(1000, s, 0, 12);   // all before it
    h.send(1000, s, 8, 8);    // 4 before it, 4 delivered already
    h.send(1000, s, 22, 10);
    EXPECT_EQ(early, (std::vector<std::size_t>{12, 4}));
    EXPECT_EQ(h.out.stream, std::vector<std::uint8_t>(s.begin() + 12, s.begin() + 32));
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 4u);
    EXPECT_TRUE(h.out.conflicts.empty());
}

TEST(TcpReassembler, FlushDeclaresEveryHoleAndDeliversWhatFollowsIt) {
    Harness h;
    const auto s = stream_of(100);
    h.syn(0);
    h.send(1, s, 10, 10);
    h.send(1, s, 50, 30);
    h.send(1, s, 90, 10);
    h.flush();
    EXPECT_EQ(h.out.gaps, 3);
    std::vector<std::uint8_t> expected = s;
    std::fill(expected.begin(), expected.begin() + 10, 0xEE);
    std::fill(expected.begin() + 20, expected.begin() + 50, 0xEE);
    std::fill(expected.begin() + 80, expected.begin() + 90, 0xEE);
    EXPECT_EQ(h.out.stream, expected);
}

TEST(TcpReassembler, SequenceNumbersThatWrapAreOneStream) {
    Harness h;
    const auto s = stream_of(64);
    const std::uint32_t isn = 0xFFFFFFF0u;
    h.syn(isn);
    h.send(isn + 1, s, 32, 32);  // past the wrap, ahead of the hole
    h.send(isn + 1, s, 0, 32);   // before and across the wrap
    EXPECT_EQ(h.out.stream, s);
}

TEST(TcpReassembler, ResetForgetsTheConnection) {
    Harness h;
    const auto s = stream_of(40);
    h.syn(0);
    h.send(1, s, 20, 10);  // waiting ahead of a hole
    h.reassembler.reset(1 << 20);
    h.out = Out{};
    h.syn(5000);
    h.send(5001, s, 0, 40);
    h.flush();
    EXPECT_EQ(h.out.stream, s);
    EXPECT_EQ(h.out.gaps, 0);
    EXPECT_EQ(h.reassembler.retransmitted_bytes(), 0u);
}

// Many segments in a shuffled order, with copies and overlaps, some never sent; a bound small enough that
// holes are given up while pieces wait behind others (pieces drained from the middle of what is buffered,
// the storage compacted): every byte comes out once, as sent, or inside a declared hole, in order.
TEST(TcpReassembler, ShuffledSegmentsWithHolesComeOutInOrder) {
    const auto s = stream_of(20000);
    for (unsigned seed = 1; seed <= 20; ++seed) {
        std::mt19937 rng(seed);
        struct Seg {
            std::size_t from, n;
        };
        std::vector<Seg> segs;
        for (std::size_t at = 0; at < s.size();) {
            const std::size_t n = std::min<std::size_t>(s.size() - at, 1 + rng() % 300);
            if (rng() % 20 != 0) segs.push_back({at, n});  // one in twenty never sent
            if (rng() % 5 == 0) segs.push_back({at, std::min(s.size() - at, n + rng() % 50)});  // a copy
            at += n;
        }
        // Out of order within a window of a few segments, as on a real network.
        for (std::size_t i = 0; i + 1 < segs.size(); ++i)
            std::swap(segs[i], segs[std::min(segs.size() - 1, i + rng() % 6)]);
        Harness h(seed % 2 ? 2000 : 1 << 20);
        h.syn(4000000000u);
        for (const Seg& g : segs)
            h.send(4000000001u, s, g.from, g.n);
        h.flush();
        ASSERT_LE(h.out.stream.size(), s.size()) << "seed " << seed;
        for (std::size_t i = 0; i < h.out.stream.size(); ++i)
            ASSERT_TRUE(h.out.stream[i] == s[i] || h.out.stream[i] == 0xEE)
                << "seed " << seed << ", stream position " << i;
        std::size_t furthest = 0;
        for (const Seg& g : segs)
            furthest = std::max(furthest, g.from + g.n);
        EXPECT_EQ(h.out.stream.size(), furthest) << "seed " << seed;
    }
}

}  // namespace test_analyzer_tcp_reassembler_test
