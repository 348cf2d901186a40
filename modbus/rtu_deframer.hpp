#pragma once
// RTU deframing, with and without timing (SL §2.5.1.1).
//
// Without timing (raw dumps), a frame's end is predicted from its content: function code and byte count
// give the candidate lengths for a request and for a response, and the CRC confirms one. When no candidate
// verifies, the stepper checks whether a valid frame starts right after a candidate; if so the candidate is
// a frame whose CRC is wrong (reported as such), otherwise it slides by one byte. Every position costs a
// bounded amount of work (at most four CRCs over at most 256 bytes), so long garbage is linear in its size.
//
// With timing, a silence of t3.5 ends a frame and a silence above t1.5 inside a frame is recorded. A run of
// bytes between two t3.5 silences whose CRC fails is split by content (USB adapters deliver several frames
// glued in one chunk, timestamps are then unreliable); if no split verifies it is one frame with a bad CRC.
//
// Unless it is the head of a frame cut in two by a silence of t3.5 or more: a USB adapter delivers a frame in
// two reads whose host timestamps are far apart, or a device pauses in the middle of its frame. A run in
// which no frame verifies, whose content (unit, function code, byte count) asks for more bytes than it holds,
// is held until the next run ends: when the head and the first bytes of that run, as many as the head's
// content asks for, verify by their CRC, they are one frame, with the silence inside it recorded as one of
// t3.5 or more (Frame::gap_at_t3_5; a receiver keeping t3.5 took two frames whose CRCs both fail, and that
// stays an error). Otherwise the head is what it was without the wait: a frame with a bad CRC, or an unparsed
// run. A head is held across a silence of at most max(100 ms, 4 x t3.5) (hold_limit), and joined with one run
// only (a frame cut twice stays in pieces); the wait delays its output by one run. A run in which a frame
// verifies is never held, and one that begins with a frame that verifies is never taken as a tail: two
// frames that each verify are never joined, nor two bad pieces that do not verify together.

#include <cstdint>
#include <span>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/serial_line.hpp"

namespace mbscope::modbus {

// One step over the front of buf (see DeframeStep). at_end: no more bytes will come, because a silence
// ended them or (input_ended) the input did: bytes that only a malformed frame shorter than the one they
// begin fits exactly are then that frame cut by the end, where a silence makes them a damaged frame.
DeframeStep rtu_step(std::span<const std::uint8_t> buf, bool at_end, bool input_ended) noexcept;

class RtuDeframer {
  public:
    // Feed bytes in any chunking; complete frames and unparsed runs are appended to out.
    void feed(std::span<const std::uint8_t> bytes, DeframeEvents& out);
    // End of input: whatever is buffered becomes frames or unparsed records.
    void finish(DeframeEvents& out);
    std::uint64_t bytes_in() const noexcept { return base_ + (buf_.size() - head_); }
    // Stream offset of the first byte in no event yet: a run of unparsed bytes still gathering starts there.
    std::uint64_t unreported() const noexcept { return pending_.length != 0 ? pending_.offset : base_; }
    // Stream offset of the first byte held for a frame not yet whole.
    std::uint64_t held_from() const noexcept { return base_; }
    // Back to a new deframer's state at stream offset 0, keeping the buffer's capacity.
    void reset() noexcept;

  private:
    void run(bool at_end, DeframeEvents& out);
    void flush_unparsed(DeframeEvents& out);

    std::vector<std::uint8_t> buf_;
    std::size_t head_ = 0;
    std::uint64_t base_ = 0;  // stream offset of buf_[head_]
    Unparsed pending_{};      // consecutive skipped bytes are reported as one record
};

class RtuTimedDeframer {
  public:
    explicit RtuTimedDeframer(SerialLine line) noexcept : line_(line) {}

    // `received` is the time at which the last byte of the chunk ended; the bytes before it are taken
    // to have arrived back to back, one character time apart.
    void feed(std::span<const std::uint8_t> bytes, Timestamp received, DeframeEvents& out);
    // Time has passed with no byte: closes the current frame once t3.5 of silence has elapsed.
    void advance(Timestamp now, DeframeEvents& out);
    // The input ends (not the line: no silence followed its last byte). Unlike a silence, which ends a
    // frame however short (a device that stopped sending), the end of the input cuts one: bytes whose
    // content asks for more than the input holds are an unparsed run, truncated, not a frame with a bad CRC.
    void finish(DeframeEvents& out);
    const SerialLine& line() const noexcept { return line_; }
    // Bytes are held for a frame not yet ended by a silence (or by finish), or as the head of a frame cut by
    // a silence, waiting for its tail.
    bool holding() const noexcept { return !seg_.empty(); }
    // The silence after the last byte past which what is held is given up by advance(): t3.5, or for a head
    // that waits for its tail (held, or about to be at that silence) the longest silence a frame is joined
    // across. For a caller that ends frames itself when the line is quiet (advance with a time past any).
    Timestamp closing_silence() const noexcept;
    // Back to a new deframer's state for `line`, keeping the buffers' capacity.
    void reset(SerialLine line) noexcept;

  private:
    struct Gap {
        std::uint64_t before_offset;  // stream offset of the byte after the silence
        float chars;
        bool t3_5;  // the silence after a held head: it ended a run, and is inside a frame only if joined
    };
    // What ends the bytes held: nothing yet (a long run: its front is framed, the tail kept), a silence of
    // t3.5, or the end of the input.
    enum class SegmentEnd : std::uint8_t { Open, Silence, Input };
    void close_segment(SegmentEnd end, DeframeEvents& out);
    // Frames seg_[begin, begin + n), ended by a silence or by the input; whether a frame whose CRC holds is
    // among what it emitted.
    bool close_run(std::size_t begin, std::size_t n, SegmentEnd end, DeframeEvents& out);
    // seg_[begin, begin + n) in which no frame verified: may it be the head of a frame a silence cut?
    bool may_be_head(std::size_t begin, std::size_t n) const noexcept;
    // The head held at seg_'s front meets the bytes after it: emits the joined frame, or the head alone as
    // it was; returns the bytes emitted.
    std::size_t resolve_head(DeframeEvents& out);
    // Whether the bytes after a held head may still complete it: the lengths its content asks for are not
    // all here yet, or one of them verifies.
    bool head_may_join() const noexcept;
    // Drops the first `consumed` bytes of seg_, emitted.
    void drop_front(std::size_t consumed) noexcept;
    Timestamp hold_limit() const noexcept;
    void emit_frame(std::size_t begin, std::size_t length, DeframeEvents& out);  // CRC status from the bytes
    void emit_unparsed(std::size_t begin, std::size_t length, UnparsedReason reason, DeframeEvents& out);

    SerialLine line_;
    std::vector<std::uint8_t> seg_;  // bytes since the last t3.5 silence
    std::vector<Timestamp> times_;   // end time of each byte in seg_
    std::vector<Gap> gaps_;          // silences above t1.5 inside seg_
    std::uint64_t seg_offset_ = 0;   // stream offset of seg_[0]
    std::size_t held_ = 0;           // bytes at seg_'s front held as the head of a frame a silence cut
    Timestamp last_end_{0};
    bool has_last_ = false;
};

}  // namespace mbscope::modbus
