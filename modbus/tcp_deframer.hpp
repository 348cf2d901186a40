#pragma once
// Modbus/TCP over a byte stream (one direction of one connection): several ADUs in one chunk, one ADU over
// many chunks. The MBAP length field delimits each ADU (TCP §3.1.3). A length outside 2..254 cannot be
// trusted: the bytes are reported as unparsed and the deframer resynchronises on the next plausible MBAP
// header (protocol id 0, length 2..254, function code 1..127). While in sync, a header with a non-zero
// protocol id is still a frame (flagged tcp.protocol_id_nonzero) so the analyzer can say what it was.
// A passive observer (observe_passively(): the analyzer) goes further: right after an ADU whose PDU does
// not decode, a length field too short for its PDU ("length 2" on a 12-byte read request) puts the rest of
// that ADU in front of the next header, where it reads as a header with a non-zero protocol id; unless that
// header's own ADU decodes, the stream is out of sync there, and resynchronises. It also reads an MBAP
// length 1 or 2 too long (a gateway counting the RTU CRC in it) where the segments show it: an ADU left
// incomplete at the end of one chunk (one feed(): one segment's bytes as the analyzer feeds them) whose
// bytes so far make a PDU that decodes cleanly and whole in the direction the stream carries, followed by a
// chunk that starts with a plausible header (protocol id 0) whose ADU is whole in it and decodes cleanly
// (or is cut the same way again: such a gateway does it in every reply), is the held bytes, a frame flagged
// tcp.length_beyond_segment, and the next chunk read from its header. Read by the length, the frame took
// the next ADU's first byte, whose rest formed no frame: a 1 s "latency", a bad byte count and a lost
// reply. Within one chunk, or an ADU whose bytes so far do not decode whole, the length is followed. An
// endpoint (the slave, a client) reads the stream as a device does, by the length fields alone.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::modbus {

// One step over the front of buf. in_sync: the previous bytes ended a frame (or this is the stream start).
DeframeStep tcp_step(std::span<const std::uint8_t> buf, bool at_end, bool in_sync) noexcept;

class TcpStreamDeframer {
  public:
    void feed(std::span<const std::uint8_t> bytes, Timestamp received, DeframeEvents& out);
    void feed(std::span<const std::uint8_t> bytes, DeframeEvents& out) { feed(bytes, Timestamp{0}, out); }
    // `missing` bytes of the stream were never captured: the frame in progress is lost. The bytes after the
    // hole are read as a mid-stream start's are (start_unaligned): they may be the end of an ADU whose
    // header was before or in the hole, and what comes before the next header is unparsed (AfterGap), not
    // a bad header. Once a frame is found the stream is in step again, and a bad length is a bad length.
    void gap(std::uint64_t missing, DeframeEvents& out);
    void finish(DeframeEvents& out);
    std::uint64_t offset() const noexcept { return base_ + (buf_.size() - head_); }
    std::size_t buffered() const noexcept { return buf_.size() - head_; }  // bytes of an incomplete frame
    // The stream offset of the first byte no event has reported yet: unparsed bytes still gathering, or
    // the buffered ones.
    std::uint64_t unreported() const noexcept { return pending_.length != 0 ? pending_.offset : base_; }
    // Those bytes, valid until the next call (a frame cut by a gap: its MBAP header still names it).
    std::span<const std::uint8_t> incomplete() const noexcept { return {buf_.data() + head_, buffered()}; }
    // Back to a new deframer's state at stream offset 0, keeping the buffer's capacity (and the mode).
    void reset() noexcept;
    // Reads the stream as a passive observer (the analyzer), see above. `carries`: the direction of the PDUs
    // on the stream (the analyzer's client-to-server stream carries requests), which an ADU cut at a
    // segment's end must decode in; Unknown: either.
    void observe_passively(Direction carries = Direction::Unknown) noexcept {
        passive_ = true;
        carries_ = carries;
    }
    // The stream's start was not seen (a capture begun mid-connection, no SYN): its first bytes may be the
    // end of an ADU sent before the capture began. The first header is taken only when it is plausible
    // (protocol id 0, a function code, a length in range) and its ADU is here whole (and, when its PDU does
    // not decode cleanly, no whole frame that does starts inside it) or its bytes so far can start a PDU of
    // that length; else the deframer resynchronises as after a gap. Taken as in sync, the tail
    // "03 00 00 00 01" of a request and the next request's first byte read as a header of length 256,
    // which swallowed the next 263 bytes of requests. Call before the first bytes are fed.
    void start_unaligned() noexcept { unaligned_ = true; }

  private:
    void run(bool at_end, DeframeEvents& out);
    // Whether the bytes buffered before the chunk that starts at rest[held] are an ADU whose MBAP length is
    // too long, sent whole (see above).
    bool cut_at_segment_end(std::span<const std::uint8_t> rest, std::size_t held) const noexcept;
    void flush_unparsed(DeframeEvents& out);

    std::vector<std::uint8_t> buf_;
    std::size_t head_ = 0;
    std::uint64_t base_ = 0;
    bool in_sync_ = true;
    bool passive_ = false;
    Direction carries_ = Direction::Unknown;
    // While feed() runs: where in buf_ the chunk fed starts (none outside it), and when the bytes before it
    // came.
    static constexpr std::size_t no_chunk = static_cast<std::size_t>(-1);
    std::size_t chunk_start_ = no_chunk;
    Timestamp held_until_{0};
    bool unaligned_ = false;  // start_unaligned() or gap(), until the first frame
    bool after_gap_ = false;  // unaligned_ since a gap, not the stream's start
    DeframeStep unaligned_step(std::span<const std::uint8_t> rest, bool at_end) const noexcept;
    // The PDU of the last frame, judged only when the next header's protocol id is not 0.
    std::array<std::uint8_t, max_frame_bytes> last_pdu_{};
    std::size_t last_pdu_size_ = 0;
    bool last_frame_decodes() const noexcept;
    bool trusted_header(std::span<const std::uint8_t> rest) const noexcept;
    Timestamp last_{0};
    Timestamp first_{0};  // time of the chunk that held the first buffered byte
    Unparsed pending_{};
};

}  // namespace mbscope::modbus
