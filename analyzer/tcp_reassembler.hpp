#pragma once
// One direction of a TCP connection, put back in order independently of segment boundaries: retransmitted
// and overlapping bytes are delivered once, out-of-order segments wait for the hole to fill, and a hole that
// never fills (lost in the capture) is delivered as a gap of known size so the deframer can resynchronise.
// A retransmission whose bytes differ from the copy already delivered is reported (the first copy is kept:
// a receiver may have kept the other, so the decoded stream may not be the one the device acted on).

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

class TcpReassembler {
  public:
    using DataFn = std::function<void(std::span<const std::uint8_t>, modbus::Timestamp)>;
    using GapFn = std::function<void(std::uint64_t missing, modbus::Timestamp)>;
    // `differing` bytes of a retransmission disagree with what was delivered; the first at stream offset
    // `at`.
    using ConflictFn = std::function<void(std::uint64_t at, std::size_t differing, modbus::Timestamp)>;
    // `bytes` that precede the first byte seen of a stream with no SYN (a capture begun mid-connection whose
    // first segment overtook an earlier one): they cannot go before what was delivered already.
    using BeforeStartFn = std::function<void(std::size_t bytes, modbus::Timestamp)>;

    static constexpr std::size_t default_max_buffered = 1 << 20;
    TcpReassembler(DataFn data, GapFn gap, std::size_t max_buffered = default_max_buffered)
        : data_(std::move(data)), gap_(std::move(gap)), max_buffered_(max_buffered) {}

    // `packet`: the capture's number of the packet that carried the segment (0: none), handed back with its
    // bytes when they are delivered (delivering_packet()), also when they waited behind a hole.
    void segment(std::uint32_t seq, bool syn, std::span<const std::uint8_t> payload, modbus::Timestamp t,
                 std::uint64_t packet = 0);
    // While the data callback runs: the packet whose segment carried the bytes delivered (segment()'s
    // `packet`). Bytes that waited behind a hole are released by a later packet (the peer's acknowledgement,
    // the segment that fills the hole), and were reported at that packet's number.
    std::uint64_t delivering_packet() const noexcept { return delivering_packet_; }
    // A SYN at `seq` opens a new connection on this stream's addresses and ports: the stream has seen
    // another connection (or the middle of one), and this is not that connection's SYN again.
    bool opens_new_connection(std::uint32_t seq) const noexcept { return next_ && syn_at_ != seq; }
    // Whether this connection's SYN was seen: else the stream's first bytes may be the middle of an ADU.
    bool saw_syn() const noexcept { return syn_at_.has_value(); }
    // The peer acknowledged this direction's bytes up to `ack`: bytes before it that the capture never
    // showed (a segment the tap lost, a record cut by the snap length) will not be sent again, so a hole
    // below it is given up. Waiting for it stalled the direction until the end of the capture (or a
    // megabyte later): one lost segment made every later request unanswered. Not at once, though: a tap
    // or mirror port that merges both directions can put the acknowledgement before the segment it
    // acknowledges (modbusBig.pcap, packets 3149 and 3150, 0.7 ms apart), and a hole given up at the
    // acknowledgement lost a reply that the capture holds. The hole is given up when this direction's next
    // segment does not fill it, at an acknowledgement `reordering_wait` or more after the first that
    // covered it, or at flush(); and at once when the acknowledgement covers the whole hole and bytes after
    // it are here already: the hole's bytes would have to come after their own successors, and until
    // then a request pipelined behind a lost one waited, its reply taken for unsolicited.
    void acknowledged(std::uint32_t ack, modbus::Timestamp t);
    // When the peer first acknowledged the bytes a hole acknowledged_unseen() counts lacks: they were sent
    // before it. nullopt when no acknowledged hole waits.
    std::optional<modbus::Timestamp> acknowledged_since() const noexcept {
        return acknowledged_ ? std::optional(acknowledged_at_) : std::nullopt;
    }
    // Gives up the acknowledged hole now, when the peer acknowledged it at or before `t`: the pairing decides
    // at a request's deadline that its reply, sent before then, is not coming.
    void give_up_acknowledged_before(modbus::Timestamp t) {
        if (acknowledged_ && acknowledged_at_ <= t) give_up_acknowledged(t);
    }
    // Whether bytes captured at or before `t` wait behind a hole: a reply sent in time may be among them,
    // delivered with its own time and packet when the hole fills or is given up.
    bool holds_bytes_captured_by(modbus::Timestamp t) const noexcept {
        return std::any_of(pending_.begin(), pending_.end(), [t](const Piece& p) { return p.time <= t; });
    }
    // The stream offset of the next byte to deliver.
    std::uint64_t delivered() const noexcept { return base_; }
    // Bytes the peer acknowledged that the capture has not shown (yet): a hole acknowledged() still waits on.
    std::uint32_t acknowledged_unseen() const noexcept {
        return acknowledged_ && next_ ? *acknowledged_ - *next_ : 0;
    }
    // The `missing` bytes after sequence number `end` (a segment's last captured byte's next) are not in its
    // record: the capture cut it to the snapshot length. When the stream had reached `end`, they are a hole
    // that a whole copy may still fill (a retransmission, a second tap's copy merged in); it is given up, a
    // gap at the cut segment's time, when this direction's next segment does not fill it, when the other
    // direction sends data (peer_spoke), or at flush(): not only when bytes beyond it show the hole, which
    // for a stream's last segment never happened. A segment still waiting behind another hole is left to that
    // hole's handling.
    void cut_by_capture(std::uint32_t end, std::uint32_t missing, modbus::Timestamp t);
    // The other direction sent data: a hole cut_by_capture left is given up (a request cut is answered, its
    // whole copy not coming; a reply cut is followed by the client's next request).
    void peer_spoke() {
        if (cut_) give_up_cut();
    }
    // Whether a hole cut_by_capture left waits, from a segment captured before `t`.
    bool cut_before(modbus::Timestamp t) const noexcept { return cut_ && cut_->time <= t; }
    // While the gap callback runs: whether the gap is a record's bytes past the snapshot length.
    bool gap_is_cut() const noexcept { return cut_gap_; }
    // While the gap callback runs: when the peer first acknowledged the hole's bytes, when it is given up
    // for that (they were sent before then); nullopt for a hole given up otherwise.
    std::optional<modbus::Timestamp> gap_acknowledged_at() const noexcept { return gap_acknowledged_at_; }
    static constexpr modbus::Timestamp reordering_wait{1'000'000'000};
    // A FIN at sequence number `seq` (after its segment's payload): it takes one number of its own, which
    // the peer's acknowledgement covers without any byte having been lost.
    void finished_at(std::uint32_t seq) noexcept { fin_at_ = seq; }
    // Every byte before the FIN has been delivered: the sender sends nothing more on this connection.
    bool finished() const noexcept { return fin_at_ && next_ && *next_ == *fin_at_ && pending_.empty(); }
    // Whether a reset at sequence number `seq` can end this direction's stream: nothing seen yet, or from
    // 64 KiB before the next expected byte to as far past it as bytes may wait for a hole. A receiver takes
    // a reset only within its window (RFC 9293 §3.10.7.3, RFC 5961 §3.2); one far outside is a stray or
    // forged segment, and the connection goes on.
    bool reset_in_window(std::uint32_t seq) const noexcept;
    // End of capture or connection: what is buffered beyond a hole is delivered after a gap.
    void flush(modbus::Timestamp t);
    std::uint64_t retransmitted_bytes() const noexcept { return retransmitted_; }
    void on_conflict(ConflictFn conflict) { conflict_ = std::move(conflict); }
    void on_before_start(BeforeStartFn before_start) { before_start_ = std::move(before_start); }
    // Back to a new reassembler's state (no sequence number seen yet), keeping the callbacks and the
    // storage already grown.
    void reset(std::size_t max_buffered) noexcept;

  private:
    void take_segment(std::uint32_t seq, std::span<const std::uint8_t> payload, modbus::Timestamp t,
                      std::uint64_t packet);
    void give_up_cut();  // a gap at the cut segment's time
    // Bytes that arrived ahead of a hole: arena_[begin, begin + size), to go at stream position `at`, and
    // when and in which packet they arrived (delivered with both: a request that waited behind a lost
    // segment keeps its own time, and a reply captured before the one ahead of it in the stream its own
    // latency; a frame that spans bytes of two times is the deframer's user's to date).
    struct Piece {
        std::uint64_t at;
        std::size_t begin;
        std::size_t size;
        modbus::Timestamp time;
        std::uint64_t packet;
    };
    void deliver(std::span<const std::uint8_t> bytes, modbus::Timestamp t, std::uint64_t packet);
    // Compares bytes retransmitted at stream offset `at` (all before base_) with the ones delivered there,
    // as far back as recent_ reaches.
    void compare_retransmission(std::uint64_t at, std::span<const std::uint8_t> bytes, modbus::Timestamp t);
    void drain(modbus::Timestamp t);
    void skip_to_first_buffered(modbus::Timestamp t);
    void skip(std::uint64_t missing, modbus::Timestamp t);
    void give_up_acknowledged(modbus::Timestamp t);
    void compact();

    DataFn data_;
    GapFn gap_;
    std::size_t max_buffered_;
    std::optional<std::uint32_t> next_;  // next expected sequence number
    std::optional<std::uint32_t> fin_at_;
    std::optional<std::uint32_t> syn_at_;  // the sequence number of this connection's SYN, when seen
    // The furthest acknowledgement past bytes not captured, and when the first one came: the hole waits.
    std::optional<std::uint32_t> acknowledged_;
    modbus::Timestamp acknowledged_at_{0};
    std::uint64_t delivering_packet_ = 0;  // delivering_packet()
    // Pieces waiting for a hole to fill: a heap with the lowest `at` in front. Their bytes share one arena
    // (a segment ahead of a hole used to cost a map node and a vector of its own, and under a fuzzer most
    // segments are). The arena is emptied whenever nothing waits and compacted when mostly dead, so it
    // stays within twice what is buffered (and 4 KiB). The callbacks are handed spans into it: they must
    // not call back into the reassembler.
    std::vector<Piece> pending_;
    std::vector<std::uint8_t> arena_;
    std::vector<std::uint8_t> scratch_;  // compact()'s second arena, kept for its capacity
    std::uint64_t base_ = 0;             // unwrapped stream position of next_
    std::size_t buffered_ = 0;           // bytes of the pieces waiting, duplicates included
    std::uint64_t retransmitted_ = 0;
    ConflictFn conflict_;
    BeforeStartFn before_start_;
    // The last bytes delivered, by stream offset modulo its size: a retransmission is compared with them.
    // Retransmissions repeat the last segment or few; 4 KiB reaches past any Modbus ADU.
    static constexpr std::size_t recent_size = 4096;
    std::array<std::uint8_t, recent_size> recent_{};
    std::uint64_t recent_from_ = 0;  // recent_ holds nothing before this offset (a gap was skipped to it)
    // A record's bytes past the snapshot length, from the stream's next byte (cut_by_capture).
    struct CutHole {
        std::uint32_t end = 0;
        std::uint32_t missing = 0;
        modbus::Timestamp time{0};
    };
    std::optional<CutHole> cut_;
    bool cut_gap_ = false;
    std::optional<modbus::Timestamp> gap_acknowledged_at_;
};

}  // namespace mbscope::analyzer
