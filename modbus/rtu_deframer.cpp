#include "modbus/rtu_deframer.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::modbus {
namespace {

using Kind = DeframeStep::Kind;

// The ADU lengths a frame starting at the front of a buffer can have: one per direction whose length its
// first bytes tell, ascending, and how many bytes a direction needs before it can tell. Called at every byte
// position of a stream without frames, so it is kept small enough to travel in a register and without an
// array (a fuzzing build's AddressSanitizer gives a function a poisoned stack frame for a local it cannot
// keep in registers, which cost more than the deframing itself).
struct Candidates {
    std::uint16_t shorter = 0;
    std::uint16_t longer = 0;
    std::uint16_t count = 0;
    std::uint16_t need = 0;  // >0: a direction needs this many ADU bytes before its length is known

    std::size_t length(std::size_t i) const noexcept { return i == 0 ? shorter : longer; }
};

// buf from `offset` on. Not span::subspan: with its checks for a count, a fuzzing build does not inline it,
// and its caller then keeps the span in a poisoned stack frame.
std::span<const std::uint8_t> from(std::span<const std::uint8_t> buf, std::size_t offset) noexcept {
    return {buf.data() + offset, buf.size() - offset};
}

Candidates candidates(std::span<const std::uint8_t> buf) noexcept {
    Candidates c;
    const auto pdu = from(buf, 1);
    for (std::uint8_t d = 0; d < 2; ++d) {
        const LengthPrediction p = predict_pdu_length(pdu, d == 0 ? Direction::Request : Direction::Response);
        if (p.kind == LengthPrediction::Kind::Known) {
            const std::size_t adu = 1 + p.length + 2;
            if (p.length < 1 || adu > max_rtu_adu_length) continue;
            // Not std::min and std::max: their reference parameters leave a fuzzing build's AddressSanitizer
            // stack slots to poison here.
            if (c.count == 0) {
                c.shorter = static_cast<std::uint16_t>(adu);
                c.count = 1;
            } else if (adu < c.shorter) {
                c.longer = c.shorter;
                c.shorter = static_cast<std::uint16_t>(adu);
                c.count = 2;
            } else if (adu > c.shorter) {
                c.longer = static_cast<std::uint16_t>(adu);
                c.count = 2;
            }
        } else if (p.kind == LengthPrediction::Kind::NeedMore && 1 + p.length > c.need) {
            c.need = static_cast<std::uint16_t>(1 + p.length);
        }
    }
    return c;
}

enum class Probe : std::uint8_t { Yes, No, NeedMore };
struct ProbeResult {
    Probe probe = Probe::No;
    std::uint16_t need = 0;  // NeedMore: the bytes needed from the probe's start
};

// Does a CRC-valid frame start at the front of buf? (no recursion: used to confirm a bad-CRC frame)
ProbeResult probe_valid(std::span<const std::uint8_t> buf, bool at_end) noexcept {
    if (buf.size() < 4) return {at_end ? Probe::No : Probe::NeedMore, 4};
    const Candidates c = candidates(buf);
    bool pending = c.need > buf.size();
    std::uint16_t need = c.need;
    for (std::size_t i = 0; i < c.count; ++i) {
        if (buf.size() < c.length(i)) {
            pending = true;
            if (c.length(i) > need) need = static_cast<std::uint16_t>(c.length(i));
            continue;
        }
        if (rtu_crc_ok(buf.first(c.length(i)))) return {Probe::Yes, 0};
    }
    if (pending && !at_end) return {Probe::NeedMore, need};
    return {Probe::No, 0};
}

bool plausible_start(std::span<const std::uint8_t> buf) noexcept {
    return buf[0] <= 247 && is_public_function(buf[1] & 0x7F);
}

// At the end of the input, a plausible start whose predicted length runs past the end is a truncated frame,
// unless a valid frame starts inside it (then only the bytes before that one are lost). Kept out of
// rtu_step, which runs at every byte position: there, a fuzzing build left one of this loop's calls of
// span::size() out of line, which kept buf in a poisoned stack frame for every call.
DeframeStep skip_at_end(std::span<const std::uint8_t> buf, Candidates c) noexcept {
    bool runs_past_end = c.need > buf.size();
    for (std::size_t i = 0; i < c.count; ++i)
        runs_past_end |= c.length(i) > buf.size();
    if (!runs_past_end) return {Kind::Skip, 1, true, UnparsedReason::Garbage};
    std::size_t valid_at = buf.size();
    for (std::size_t j = 1; j + 4 <= buf.size() && valid_at == buf.size(); ++j) {
        if (probe_valid(from(buf, j), true).probe == Probe::Yes) valid_at = j;
    }
    return {Kind::Skip, valid_at, true, UnparsedReason::Truncated};
}

// At the end of the input, bytes that fill the shorter candidate exactly while the longer runs past the end:
// a frame damaged in its CRC, or the first bytes of a longer one cut by the end of the input. FC3's
// "11 03 00 60 00" is a request to read 96 cut after five bytes, and a reply with byte count 0, which no
// reply to a read carries. Damaged when they decode as a PDU that breaks no rule either way; else cut. Out of
// rtu_step's hot path, as skip_at_end.
bool cut_rather_than_damaged(std::span<const std::uint8_t> buf, Candidates c) noexcept {
    const bool longer_runs_past = c.need > buf.size() || (c.count == 2 && c.longer > buf.size());
    if (!longer_runs_past || buf.size() < 4) return false;
    const std::span<const std::uint8_t> pdu(buf.data() + 1, buf.size() - 3);
    const auto request = decode_request(pdu);
    const auto response = decode_response(pdu);
    return !(request && request->violations.empty()) && !(response && response->violations.empty());
}

// A run between silences whose CRC holds as a whole, though its content says a frame ends sooner, where a CRC
// holds too: that frame and bytes after it (a driver's 0x00 as it releases the line keeps the CRC of any
// frame before it valid, as CRC-16/MODBUS's residue is 0), not one frame of the whole run with trailing bytes
// held against the device. Most runs are one frame of the predicted length: no second CRC for them.
bool valid_frame_inside(std::span<const std::uint8_t> run) noexcept {
    const Candidates c = candidates(run);
    for (std::size_t i = 0; i < c.count; ++i)
        if (c.length(i) == run.size()) return false;
    for (std::size_t i = 0; i < c.count; ++i)
        if (c.length(i) < run.size() && rtu_crc_ok(run.first(c.length(i)))) return true;
    return false;
}

}  // namespace

DeframeStep rtu_step(std::span<const std::uint8_t> buf, bool at_end, bool input_ended) noexcept {
    if (buf.size() < 4) {
        if (!at_end) return {Kind::NeedMore, 4};
        return {Kind::Skip, buf.size(), true, UnparsedReason::Truncated};
    }
    const Candidates c = candidates(buf);
    if (c.count == 0 && c.need == 0) return {Kind::Skip, 1, true, UnparsedReason::UnknownFunction};
    for (std::size_t i = 0; i < c.count; ++i) {
        const std::size_t len = c.length(i);
        if (buf.size() < len) {
            if (!at_end) return {Kind::NeedMore, len};
            continue;
        }
        if (rtu_crc_ok(buf.first(len))) return {Kind::Complete, len, true};
    }
    if (c.need > buf.size() && !at_end) return {Kind::NeedMore, c.need};

    // No candidate verifies: a frame with a corrupted CRC is recognised when a valid frame follows it
    // immediately, or when it fills the input exactly.
    if (plausible_start(buf)) {
        for (std::size_t i = 0; i < c.count; ++i) {
            const std::size_t len = c.length(i);
            if (buf.size() < len) continue;
            if (len == buf.size() && at_end && !(input_ended && cut_rather_than_damaged(buf, c)))
                return {Kind::Complete, len, false};
            const ProbeResult after = probe_valid(from(buf, len), at_end);
            switch (after.probe) {
                case Probe::Yes:
                    return {Kind::Complete, len, false};
                case Probe::NeedMore:
                    return {Kind::NeedMore, len + after.need};
                case Probe::No:
                    break;
            }
        }
    }
    if (at_end && plausible_start(buf)) return skip_at_end(buf, c);
    return {Kind::Skip, 1, true, UnparsedReason::Garbage};
}

// ---------------------------------------------------------------- untimed

void RtuDeframer::flush_unparsed(DeframeEvents& out) {
    if (pending_.length == 0) return;
    out.emplace_back(pending_);
    pending_ = Unparsed{};
}

void RtuDeframer::run(bool at_end, DeframeEvents& out) {
    while (head_ < buf_.size()) {
        const std::span<const std::uint8_t> rest(buf_.data() + head_, buf_.size() - head_);
        const DeframeStep step = rtu_step(rest, at_end, at_end);
        if (step.kind == Kind::NeedMore) break;
        if (step.kind == Kind::Skip) {
            if (pending_.length != 0 && pending_.reason != step.reason) flush_unparsed(out);
            if (pending_.length == 0) {
                pending_.offset = base_;
                pending_.reason = step.reason;
                if (rest.size() >= 2) pending_.head = {rest[0], rest[1]};
            }
            pending_.length += static_cast<std::uint32_t>(step.length);
        } else {
            flush_unparsed(out);
            Frame& frame = std::get<Frame>(out.emplace_back(std::in_place_type<Frame>, Frame::Unfilled{}));
            detail::fill_rtu_frame(rest.first(step.length), frame);
            frame.offset = base_;
        }
        head_ += step.length;
        base_ += step.length;
    }
    if (at_end) flush_unparsed(out);
    // Compact: keep the buffer small without moving bytes on every call.
    if (head_ > 4096 && head_ * 2 > buf_.size()) {
        buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(head_));
        head_ = 0;
    }
}

void RtuDeframer::feed(std::span<const std::uint8_t> bytes, DeframeEvents& out) {
    if (head_ == buf_.size()) {
        buf_.clear();
        head_ = 0;
    }
    buf_.insert(buf_.end(), bytes.begin(), bytes.end());
    run(false, out);
}

void RtuDeframer::finish(DeframeEvents& out) {
    run(true, out);
    buf_.clear();
    head_ = 0;
}

void RtuDeframer::reset() noexcept {
    buf_.clear();
    head_ = 0;
    base_ = 0;
    pending_ = Unparsed{};
}

// ---------------------------------------------------------------- timed

void RtuTimedDeframer::reset(SerialLine line) noexcept {
    line_ = line;
    seg_.clear();
    times_.clear();
    gaps_.clear();
    seg_offset_ = 0;
    held_ = 0;
    last_end_ = Timestamp{0};
    has_last_ = false;
}

Timestamp RtuTimedDeframer::hold_limit() const noexcept {
    // A host's reads of a USB adapter are some tens of ms apart at worst (a latency timer of 16 ms, a clock
    // of 15.6 ms); a slow line's t3.5 is itself that long. A longer silence ends what was sent.
    return std::max<Timestamp>(std::chrono::milliseconds(100), line_.t3_5() * 4);
}

Timestamp RtuTimedDeframer::closing_silence() const noexcept {
    if (held_ != 0 && seg_.size() == held_) return hold_limit();
    // Bytes not yet ended by a silence that would be held at it: they wait as long. Bytes that verify whole
    // are a frame, which that silence ends, not a head: a 7-byte FC3 reply reads as the front of an 8-byte
    // request by its length alone, and a live reader showed it only after the longer wait. (A frame that
    // verifies among other bytes is not looked for here; it only comes out later.)
    const std::span<const std::uint8_t> run(seg_.data(), seg_.size());
    if (held_ == 0 && may_be_head(0, run.size()) && !(run.size() >= 4 && rtu_crc_ok(run)))
        return hold_limit();
    return line_.t3_5();
}

void RtuTimedDeframer::emit_frame(std::size_t begin, std::size_t length, DeframeEvents& out) {
    Frame& frame = std::get<Frame>(out.emplace_back(std::in_place_type<Frame>, Frame::Unfilled{}));
    detail::fill_rtu_frame({seg_.data() + begin, length}, frame);
    frame.offset = seg_offset_ + begin;
    frame.start = times_[begin];
    frame.end = times_[begin + length - 1];
    for (const Gap& g : gaps_) {
        // A silence right before the frame, after other bytes of the run: the frame came too soon. (The
        // silence after a held head ended a run: at a frame's edge it is no short silence.)
        if (!g.t3_5 && g.before_offset == frame.offset) frame.short_silence_before_chars = g.chars;
        if (!g.t3_5 && g.before_offset == frame.offset + length) frame.short_silence_after_chars = g.chars;
        if (g.before_offset <= frame.offset || g.before_offset >= frame.offset + length) continue;
        // The silence of t3.5 or more that a joined frame holds is its longest, whatever the other measured.
        if (g.t3_5 ? !frame.gap_at_t3_5 || g.chars > frame.max_gap_chars
                   : !frame.gap_at_t3_5 && g.chars > frame.max_gap_chars) {
            frame.max_gap_chars = g.chars;
            frame.gap_before_byte = static_cast<std::uint16_t>(g.before_offset - frame.offset);
            frame.gap_at_t3_5 = g.t3_5;
        }
    }
    if (frame.max_gap_chars > 0 || frame.gap_at_t3_5) frame.findings.add(FindingCode::RtuGapInsideFrame);
    if (frame.short_silence_before_chars > 0) frame.findings.add(FindingCode::RtuShortSilenceBeforeFrame);
}

void RtuTimedDeframer::emit_unparsed(std::size_t begin, std::size_t length, UnparsedReason reason,
                                     DeframeEvents& out) {
    Unparsed& u = std::get<Unparsed>(out.emplace_back(
        Unparsed{seg_offset_ + begin, static_cast<std::uint32_t>(length), reason, times_[begin]}));
    if (begin + 1 < seg_.size()) u.head = {seg_[begin], seg_[begin + 1]};
}

bool RtuTimedDeframer::close_run(std::size_t begin, std::size_t n, SegmentEnd end, DeframeEvents& out) {
    const std::span<const std::uint8_t> run(seg_.data() + begin, n);
    if (n >= 4 && n <= max_rtu_adu_length && rtu_crc_ok(run) && !valid_frame_inside(run)) {
        emit_frame(begin, n, out);
        return true;
    }
    // Split by content. Keep the result only if it finds at least one frame whose CRC holds; otherwise the
    // silence-delimited run is one frame with a bad CRC (or too short to be one): a damaged reply split by
    // content was a byte of garbage and a made-up frame of another unit, which took the fault. The pieces go
    // straight into `out` and are taken back when no frame verified (they are then unparsed runs and damaged
    // frames only, cheap to drop): no list of its own to build and copy from.
    const std::size_t mark = out.size();
    std::size_t pos = 0;
    bool any_frame = false;
    bool cut = false;  // the run's first bytes ask for a frame longer than the rest of the input
    std::size_t run_begin = 0;
    std::size_t run_length = 0;
    UnparsedReason run_reason{};
    auto flush_run = [&] {
        if (run_length) emit_unparsed(begin + run_begin, run_length, run_reason, out);
        run_length = 0;
    };
    while (pos < n) {
        const DeframeStep step = rtu_step(from(run, pos), true, end == SegmentEnd::Input);
        if (step.kind == Kind::Complete) {
            flush_run();
            emit_frame(begin + pos, step.length, out);
            any_frame |= step.checksum_ok;
            pos += step.length;
        } else {
            const std::size_t len = std::max<std::size_t>(step.length, 1);
            cut |= pos == 0 && step.reason == UnparsedReason::Truncated;
            if (run_length && run_reason != step.reason) flush_run();
            if (!run_length) {
                run_begin = pos;
                run_reason = step.reason;
            }
            run_length += len;
            pos += len;
        }
    }
    flush_run();
    if (!any_frame && !(end == SegmentEnd::Input && cut)) {
        out.erase(out.begin() + static_cast<std::ptrdiff_t>(mark), out.end());
        if (n >= 4 && n <= max_rtu_adu_length)
            emit_frame(begin, n, out);
        else
            emit_unparsed(begin, n, n < 4 ? UnparsedReason::TooShort : UnparsedReason::TooLong, out);
    }
    return any_frame;
}

bool RtuTimedDeframer::may_be_head(std::size_t begin, std::size_t n) const noexcept {
    // Two bytes at least: a unit and a function code that says what follows. Shorter than a whole frame.
    if (n < 2 || n >= max_rtu_adu_length) return false;
    const std::span<const std::uint8_t> head(seg_.data() + begin, n);
    if (!plausible_start(head)) return false;
    if (n < 4) return true;  // no frame is that short
    const Candidates c = candidates(head);
    return c.need > n || (c.count != 0 && c.length(c.count - 1) > n);
}

std::size_t RtuTimedDeframer::resolve_head(DeframeEvents& out) {
    const std::size_t h = held_;
    held_ = 0;
    const std::span<const std::uint8_t> all(seg_.data(), seg_.size());
    // Joined when the head and the first bytes after it, as many as their content asks for, verify, and the
    // bytes after the head do not begin a frame of their own that verifies. The lengths are told from the
    // joined bytes: a head of two or three bytes has not reached its byte count yet. At most two CRCs over at
    // most 256 bytes and one probe, once per held head: bounded work per run.
    if (all.size() > h && probe_valid(from(all, h), true).probe != Probe::Yes) {
        const Candidates c = candidates(all);
        for (std::size_t i = 0; i < c.count; ++i) {
            const std::size_t len = c.length(i);
            if (len > h && len <= all.size() && rtu_crc_ok(all.first(len))) {
                emit_frame(0, len, out);
                return len;
            }
        }
    }
    // No tail came, or it did not complete the head: the head is what the silence after it made it.
    close_run(0, h, SegmentEnd::Silence, out);
    return h;
}

void RtuTimedDeframer::close_segment(SegmentEnd end, DeframeEvents& out) {
    const std::size_t n = seg_.size();
    // A head held at the silence before these bytes is joined to them or given up first; what follows the
    // frame it makes goes through the same rules as any run.
    std::size_t consumed = held_ != 0 ? resolve_head(out) : 0;
    if (end != SegmentEnd::Open && consumed < n) {
        const std::size_t mark = out.size();
        const bool verified = close_run(consumed, n - consumed, end, out);
        // A run ended by a silence, in which no frame verifies, that starts a frame longer than itself: the
        // head of a frame the silence cut, maybe. Held (its pieces taken back) until the next run ends.
        if (end == SegmentEnd::Silence && !verified && may_be_head(consumed, n - consumed)) {
            out.erase(out.begin() + static_cast<std::ptrdiff_t>(mark), out.end());
            held_ = n - consumed;
        } else {
            consumed = n;
        }
    } else if (end == SegmentEnd::Open) {
        // A long run without silence: frame its front by content, keep the tail for more bytes.
        std::size_t pos = consumed;
        while (n - pos > 2 * max_rtu_adu_length) {
            const DeframeStep step = rtu_step({seg_.data() + pos, n - pos}, false, false);
            if (step.kind == Kind::NeedMore) break;
            if (step.kind == Kind::Complete)
                emit_frame(pos, step.length, out);
            else
                emit_unparsed(pos, step.length, step.reason, out);
            pos += step.length;
        }
        consumed = pos;
    }
    drop_front(consumed);
}

void RtuTimedDeframer::drop_front(std::size_t consumed) noexcept {
    if (consumed == 0) return;
    seg_.erase(seg_.begin(), seg_.begin() + static_cast<std::ptrdiff_t>(consumed));
    times_.erase(times_.begin(), times_.begin() + static_cast<std::ptrdiff_t>(consumed));
    seg_offset_ += consumed;
    std::erase_if(gaps_, [&](const Gap& g) { return g.before_offset < seg_offset_; });
}

bool RtuTimedDeframer::head_may_join() const noexcept {
    const std::span<const std::uint8_t> all(seg_.data(), seg_.size());
    const Candidates c = candidates(all);
    if (c.need > all.size()) return true;  // the lengths are not known yet
    for (std::size_t i = 0; i < c.count; ++i) {
        const std::size_t len = c.length(i);
        if (len > held_ && (len > all.size() || rtu_crc_ok(all.first(len)))) return true;
    }
    return false;
}

void RtuTimedDeframer::feed(std::span<const std::uint8_t> bytes, Timestamp received, DeframeEvents& out) {
    if (bytes.empty()) return;
    const auto ct = line_.character_time();
    const std::size_t n = bytes.size();
    Timestamp first_end = received - ct * static_cast<std::int64_t>(n - 1);
    if (has_last_) {
        if (first_end < last_end_ + ct) first_end = last_end_ + ct;  // coarse timestamps: no overlap
        const auto silence = first_end - ct - last_end_;
        const float chars = static_cast<float>(static_cast<double>(silence.count()) / ct.count());
        // The silence ends the bytes since the last one (a head held before them is resolved with them).
        if (silence >= line_.t3_5() && seg_.size() > held_) close_segment(SegmentEnd::Silence, out);
        if (held_ != 0 && seg_.size() == held_) {
            // These bytes are the first after a held head: the silence is inside the frame if they complete
            // it. After a silence too long for that, the head is given up first.
            if (silence > hold_limit())
                close_segment(SegmentEnd::Silence, out);
            else
                gaps_.push_back({seg_offset_ + held_, chars, true});
        } else if (silence > line_.t1_5() && !seg_.empty()) {
            gaps_.push_back({seg_offset_ + seg_.size(), chars, false});
        }
    }
    // Grown once per chunk, not a byte at a time (a capacity check per byte and per time stamp).
    const std::size_t old = seg_.size();
    seg_.insert(seg_.end(), bytes.begin(), bytes.end());
    times_.resize(old + n);
    for (std::size_t i = 0; i < n; ++i)
        times_[old + i] = first_end + ct * static_cast<std::int64_t>(i);
    last_end_ = times_.back();
    has_last_ = true;
    // A held head that these bytes cannot complete is given up as soon as they tell (every length its content
    // asks for is here and none verifies), not when their run ends: a damaged one-register reply, held so,
    // would come out only after the next request's run, which a reader's clock (a request's timeout) may
    // have passed.
    if (held_ != 0 && seg_.size() > held_ && !head_may_join()) {
        const std::size_t h = held_;
        held_ = 0;
        close_run(0, h, SegmentEnd::Silence, out);
        drop_front(h);
    }
    if (seg_.size() > 4 * max_rtu_adu_length) close_segment(SegmentEnd::Open, out);
}

void RtuTimedDeframer::advance(Timestamp now, DeframeEvents& out) {
    if (!has_last_ || seg_.empty()) return;
    const auto quiet = now - last_end_;
    if (seg_.size() > held_ && quiet >= line_.t3_5()) close_segment(SegmentEnd::Silence, out);
    // A head held for its tail, and none has come within the longest silence a frame is joined across.
    if (held_ != 0 && seg_.size() == held_ && quiet > hold_limit()) close_segment(SegmentEnd::Silence, out);
}

void RtuTimedDeframer::finish(DeframeEvents& out) {
    close_segment(SegmentEnd::Input, out);
}

}  // namespace mbscope::modbus
