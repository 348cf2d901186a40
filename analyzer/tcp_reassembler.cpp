#include "analyzer/tcp_reassembler.hpp"

#include <algorithm>
#include <utility>

namespace mbscope::analyzer {
namespace {

// std::push_heap / pop_heap build a max-heap: "later first" as its order puts the lowest position in front.
constexpr auto later = [](const auto& a, const auto& b) noexcept { return a.at > b.at; };

}  // namespace

void TcpReassembler::reset(std::size_t max_buffered) noexcept {
    max_buffered_ = max_buffered;
    next_.reset();
    fin_at_.reset();
    syn_at_.reset();
    acknowledged_.reset();
    delivering_packet_ = 0;
    pending_.clear();
    arena_.clear();
    base_ = 0;
    buffered_ = 0;
    retransmitted_ = 0;
    recent_from_ = 0;
    cut_.reset();
    gap_acknowledged_at_.reset();
}

bool TcpReassembler::reset_in_window(std::uint32_t seq) const noexcept {
    if (!next_) return true;
    const std::int64_t rel = static_cast<std::int32_t>(seq - *next_);  // wrap-aware, as segment() is
    constexpr std::int64_t slack = 65536;
    return rel >= -slack && rel <= static_cast<std::int64_t>(max_buffered_) + slack;
}

void TcpReassembler::segment(std::uint32_t seq, bool syn, std::span<const std::uint8_t> payload,
                             modbus::Timestamp t, std::uint64_t packet) {
    if (syn) {
        if (next_ && syn_at_ == seq) return;  // the SYN again (and its data): the stream has moved past it
        syn_at_ = seq;
        next_ = seq + 1;
        // Data on a SYN (TCP Fast Open) are the stream's first bytes; they were dropped without a word. A
        // server that does not take them has them sent again after the handshake: a retransmission then.
        if (!payload.empty()) {
            deliver(payload, t, packet);
            drain(t);
        }
        return;
    }
    if (!next_) next_ = seq;  // capture started mid-connection
    if (payload.empty()) return;
    if (!cut_) return take_segment(seq, payload, t, packet);
    // A record was cut at the next byte: this segment fills the hole from its start (a whole copy), lies
    // before it (nothing to do with it), or lies beyond it, and then the hole's bytes are not coming.
    const auto rel = static_cast<std::int32_t>(seq - *next_);
    if (rel > 0) give_up_cut();
    take_segment(seq, payload, t, packet);
    if (!cut_) return;
    const auto filled = static_cast<std::uint32_t>(*next_ - cut_->end);
    if (filled >= cut_->missing)
        cut_.reset();
    else if (filled > 0)  // a copy cut again, shorter: the rest of the hole waits
        cut_ = CutHole{*next_, cut_->missing - filled, cut_->time};
}

void TcpReassembler::take_segment(std::uint32_t seq, std::span<const std::uint8_t> payload,
                                  modbus::Timestamp t, std::uint64_t packet) {
    // A keep-alive probe (RFC 9293 §3.8.4): one garbage octet at the sequence number before the next, sent
    // to make the peer acknowledge. Its byte is not the stream's (BSD and Windows send 0x00): taken for a
    // retransmission, every probe was a retransmission conflict.
    if (payload.size() == 1 && static_cast<std::uint32_t>(seq + 1) == *next_ && base_ > 0) return;
    // Past an acknowledged hole: the direction moved on without the acknowledged bytes.
    if (acknowledged_ && static_cast<std::int32_t>(seq - *next_) > 0) give_up_acknowledged(t);
    // Position relative to the next expected byte, wrap-aware (RFC 793 sequence space).
    const auto rel = static_cast<std::int32_t>(seq - *next_);
    if (rel < 0) {
        const auto overlap = static_cast<std::size_t>(-static_cast<std::int64_t>(rel));
        // base_ counts delivered bytes since the first seen. Bytes before that one were never delivered:
        // not a retransmission (it used to count them as one, and they vanished without a word).
        std::size_t early = 0;
        if (overlap > base_) {
            early = std::min(overlap - static_cast<std::size_t>(base_), payload.size());
            if (before_start_) before_start_(early, t);
        }
        const std::size_t old = std::min(overlap, payload.size());  // [early, old): delivered before
        if (old > early) {
            compare_retransmission(base_ + early - overlap, payload.subspan(early, old - early), t);
            retransmitted_ += old - early;
        }
        if (overlap >= payload.size()) return;
        payload = payload.subspan(overlap);
    } else if (rel > 0) {
        // Ahead of a hole: wait. A retransmission of a piece still waiting is kept as a piece of its own
        // (the heap cannot find the first by position); when drained its bytes count as retransmitted.
        pending_.push_back(
            {base_ + static_cast<std::uint64_t>(rel), arena_.size(), payload.size(), t, packet});
        arena_.insert(arena_.end(), payload.begin(), payload.end());
        std::push_heap(pending_.begin(), pending_.end(), later);
        buffered_ += payload.size();
        if (buffered_ > max_buffered_) skip_to_first_buffered(t);  // the hole will not fill: give it up
        return;
    }
    // A segment that fills a hole and runs on over bytes waiting behind it (a sender retransmitting all it
    // has unacknowledged): its bytes up to the first waiting piece are new, the waiting ones are delivered
    // from their own packet and time, and the segment's copy of them is a retransmission. Delivered whole,
    // the waiting bytes took the new packet's time (a reply captured 50 ms after its request got the
    // retransmission's 900 ms) and the new copy's content, said to be the first copy's.
    while (!pending_.empty() && pending_.front().at < base_ + payload.size()) {
        const auto fresh = static_cast<std::size_t>(pending_.front().at - base_);  // drain() left at > base_
        deliver(payload.first(fresh), t, packet);
        const std::uint64_t resumed_at = base_;
        drain(t);
        const auto rest = payload.subspan(fresh);
        const auto again = static_cast<std::size_t>(std::min<std::uint64_t>(base_ - resumed_at, rest.size()));
        compare_retransmission(resumed_at, rest.first(again), t);
        retransmitted_ += again;
        payload = rest.subspan(again);
        if (payload.empty()) return;
    }
    deliver(payload, t, packet);
    drain(t);
}

void TcpReassembler::deliver(std::span<const std::uint8_t> bytes, modbus::Timestamp t, std::uint64_t packet) {
    delivering_packet_ = packet;
    data_(bytes, t);
    // Kept for comparison: the last recent_size bytes, each at its offset modulo the size.
    const auto kept = bytes.last(std::min(bytes.size(), recent_size));
    std::uint64_t at = base_ + (bytes.size() - kept.size());
    for (std::size_t done = 0; done < kept.size();) {
        const std::size_t slot = static_cast<std::size_t>(at % recent_size);
        const std::size_t n = std::min(kept.size() - done, recent_size - slot);
        std::copy_n(kept.begin() + static_cast<std::ptrdiff_t>(done), n,
                    recent_.begin() + static_cast<std::ptrdiff_t>(slot));
        done += n;
        at += n;
    }
    *next_ += static_cast<std::uint32_t>(bytes.size());
    base_ += bytes.size();
}

void TcpReassembler::compare_retransmission(std::uint64_t at, std::span<const std::uint8_t> bytes,
                                            modbus::Timestamp t) {
    if (!conflict_) return;
    const std::uint64_t oldest = std::max(recent_from_, base_ > recent_size ? base_ - recent_size : 0);
    std::size_t differing = 0;
    std::uint64_t first = 0;
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        const std::uint64_t position = at + i;
        if (position < oldest) continue;
        if (recent_[static_cast<std::size_t>(position % recent_size)] != bytes[i] && differing++ == 0)
            first = position;
    }
    if (differing) conflict_(first, differing, t);
}

void TcpReassembler::drain(modbus::Timestamp t) {
    while (!pending_.empty() && pending_.front().at <= base_) {
        std::pop_heap(pending_.begin(), pending_.end(), later);
        const Piece piece = pending_.back();
        pending_.pop_back();
        buffered_ -= piece.size;
        const std::uint64_t skip = base_ - piece.at;
        compare_retransmission(piece.at,
                               {arena_.data() + piece.begin,
                                static_cast<std::size_t>(std::min<std::uint64_t>(skip, piece.size))},
                               t);
        if (skip >= piece.size) {
            retransmitted_ += piece.size;
            continue;
        }
        retransmitted_ += skip;
        // The arena does not move during the call: only segment() and drain() add or compact.
        const std::span<const std::uint8_t> rest(arena_.data() + piece.begin + skip,
                                                 piece.size - static_cast<std::size_t>(skip));
        deliver(rest, piece.time, piece.packet);
    }
    if (pending_.empty())
        arena_.clear();
    else if (arena_.size() > 2 * buffered_ + 4096)
        compact();
    if (acknowledged_ && static_cast<std::int32_t>(*acknowledged_ - *next_) <= 0)
        acknowledged_.reset();  // the acknowledged bytes came after all
}

void TcpReassembler::compact() {
    scratch_.clear();
    for (Piece& piece : pending_) {
        const auto from = arena_.begin() + static_cast<std::ptrdiff_t>(piece.begin);
        piece.begin = scratch_.size();
        scratch_.insert(scratch_.end(), from, from + static_cast<std::ptrdiff_t>(piece.size));
    }
    arena_.swap(scratch_);
}

void TcpReassembler::skip_to_first_buffered(modbus::Timestamp t) {
    if (pending_.empty()) return;
    skip(pending_.front().at - base_, t);
}

void TcpReassembler::skip(std::uint64_t missing, modbus::Timestamp t) {
    gap_(missing, t);
    *next_ += static_cast<std::uint32_t>(missing);
    base_ += missing;
    recent_from_ = base_;
    drain(t);
}

void TcpReassembler::cut_by_capture(std::uint32_t end, std::uint32_t missing, modbus::Timestamp t) {
    if (!next_ || missing == 0 || *next_ != end) return;
    if (cut_) give_up_cut();  // an earlier hole the stream has not moved past: not coming either
    if (*next_ == end) cut_ = CutHole{end, missing, t};
}

void TcpReassembler::give_up_cut() {
    const auto c = *std::exchange(cut_, std::nullopt);
    if (*next_ != c.end) return;
    // Bytes already waiting from past the cut (a copy of them captured whole) are not lost.
    std::uint64_t lost = c.missing;
    if (!pending_.empty()) lost = std::min<std::uint64_t>(lost, pending_.front().at - base_);
    if (!lost) return;
    cut_gap_ = true;
    skip(lost, c.time);  // at the cut segment's time
    cut_gap_ = false;
}

void TcpReassembler::acknowledged(std::uint32_t ack, modbus::Timestamp t) {
    if (!next_) return;
    if (fin_at_ && static_cast<std::int32_t>(ack - *fin_at_) > 0) ack = *fin_at_;
    // Wrap-aware; an acknowledgement more than 1 GiB ahead is no acknowledgement of this stream (a
    // mid-stream capture's first segments, a port reused by another connection).
    auto rel = static_cast<std::int32_t>(ack - *next_);
    if (rel <= 0 || rel > (1 << 30)) return;
    // A hole the acknowledgement covers whole, with bytes after it here already: those came after the
    // hole's bytes were sent, so the hole's were not captured (a tap's drop), not merely stamped late.
    // Given up at once, hole by hole, as far as bytes after it are here (what lies beyond may still come).
    while (rel > 0 && !pending_.empty() && static_cast<std::uint64_t>(rel) >= pending_.front().at - base_) {
        gap_acknowledged_at_ = acknowledged_ ? std::min(acknowledged_at_, t) : t;
        skip_to_first_buffered(t);
        gap_acknowledged_at_.reset();
        rel = static_cast<std::int32_t>(ack - *next_);
    }
    if (rel <= 0) return;
    if (!acknowledged_) {  // the acknowledged bytes may still come, a little late in the capture
        acknowledged_ = ack;
        acknowledged_at_ = t;
        return;
    }
    if (static_cast<std::int32_t>(ack - *acknowledged_) > 0) acknowledged_ = ack;
    if (t - acknowledged_at_ >= reordering_wait) give_up_acknowledged(t);
}

// Every hole below the acknowledgement, each declared a gap (bytes waiting between them are delivered).
void TcpReassembler::give_up_acknowledged(modbus::Timestamp t) {
    const std::uint32_t ack = *acknowledged_;
    acknowledged_.reset();
    if (cut_) give_up_cut();  // named for what it is, before the holes after it
    gap_acknowledged_at_ = acknowledged_at_;
    for (auto rel = static_cast<std::int32_t>(ack - *next_); rel > 0;
         rel = static_cast<std::int32_t>(ack - *next_)) {
        std::uint64_t missing = static_cast<std::uint64_t>(rel);
        if (!pending_.empty()) missing = std::min(missing, pending_.front().at - base_);
        if (missing == 0) break;  // drain() leaves no piece at base_; kept from looping all the same
        skip(missing, t);
    }
    gap_acknowledged_at_.reset();
}

void TcpReassembler::flush(modbus::Timestamp t) {
    if (cut_) give_up_cut();
    if (acknowledged_) give_up_acknowledged(t);
    while (!pending_.empty())
        skip_to_first_buffered(t);
}

}  // namespace mbscope::analyzer
