#include "modbus/tcp_deframer.hpp"

#include <algorithm>
#include <cstring>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::modbus {
namespace {

using Kind = DeframeStep::Kind;

std::size_t length_field(std::span<const std::uint8_t> b) noexcept {
    return static_cast<std::size_t>((b[4] << 8) | b[5]);
}

// Lengths the deframer follows: the specification's 2..254, and up to 257 as real devices send (frame.hpp).
bool length_ok(std::size_t len) noexcept {
    return len >= 2 && len <= max_frame_bytes - 6;
}

// A header plausible enough to resynchronise on, looked at with the bytes available.
bool plausible_header(std::span<const std::uint8_t> b) noexcept {
    if (b.size() < 6) return false;
    if (b[2] != 0 || b[3] != 0 || !length_ok(length_field(b))) return false;
    if (b.size() >= 8) {
        const std::uint8_t fc = b[7] & 0x7F;
        if (fc == 0) return false;
    }
    return true;
}

// Whether the PDU bytes seen so far can start a PDU of `length` bytes in either direction. An incomplete
// candidate header is only waited for while this holds: a length of 257 read from the middle of a stream
// ("00 00 | 01 01") would otherwise hold back the next 263 bytes, and every request in them would be
// decoded only after its response had already been called unsolicited. FC8's data is left open: the
// diagnostics sub-functions carry data of any length.
bool length_consistent(std::span<const std::uint8_t> prefix, std::size_t length) noexcept {
    if (prefix.empty() || (prefix[0] & 0x7F) == 0x08) return true;
    for (const Direction direction : {Direction::Request, Direction::Response}) {
        const LengthPrediction p = predict_pdu_length(prefix, direction);
        if (p.kind != LengthPrediction::Kind::Known || p.length == length) return true;
    }
    return false;
}

bool plausible_pdu(std::span<const std::uint8_t> pdu) noexcept {
    auto request = decode_request(pdu);
    if (request && request->violations.empty()) return true;
    auto response = decode_response(pdu);
    return response && response->violations.empty();
}

// Whether a PDU decodes cleanly and whole (no rule broken, no byte missing or left over) in `direction`, or
// in either when it is Unknown.
bool clean_pdu(std::span<const std::uint8_t> pdu, Direction direction) noexcept {
    if (direction == Direction::Unknown) return plausible_pdu(pdu);
    auto decoded = direction == Direction::Request ? decode_request(pdu) : decode_response(pdu);
    return decoded && decoded->violations.empty();
}

// How many bytes an MBAP length may count beyond an ADU sent whole in one segment, for the ADU to be cut at
// the segment's end: 2, a gateway counting the RTU CRC; 1, one counting a byte of its own (the unit id
// twice, say). No more, because up to 2 a legitimately split ADU cannot pass for one: its next segment
// starts with its last 1 or 2 bytes, then the next ADU's header, and read as a header these bytes take
// their length field from the next ADU's protocol id (2 bytes missing) or from its low byte and the high
// byte of the next length (1 missing), 0 either way, a length no ADU has. From 3 on, the length field would
// be the next ADU's length or transaction id, anything: only the decoding would tell the two readings apart.
constexpr std::size_t max_length_excess = 2;

}  // namespace

DeframeStep tcp_step(std::span<const std::uint8_t> buf, bool at_end, bool in_sync) noexcept {
    if (buf.size() < 6) {
        if (!at_end) return {Kind::NeedMore, 6};
        return {Kind::Skip, buf.size(), true, UnparsedReason::Truncated};
    }
    if (in_sync && length_ok(length_field(buf))) {
        const std::size_t total = 6 + length_field(buf);
        if (buf.size() >= total) return {Kind::Complete, total};
        if (!at_end) return {Kind::NeedMore, total};
        return {Kind::Skip, buf.size(), true, UnparsedReason::Truncated};
    }
    // Out of sync (or an impossible length): find the next offset where a header is plausible and, once
    // its ADU is complete, the PDU decodes cleanly in one direction. Garbage that merely looks like a
    // header is skipped like any other garbage.
    for (std::size_t j = in_sync ? 1 : 0; j + 6 <= buf.size(); ++j) {
        const auto at = buf.subspan(j);
        if (!plausible_header(at)) continue;
        const std::size_t total = 6 + length_field(at);
        if (at.size() < total) {
            // The PDU's bytes so far (none while the unit id is the last byte there is).
            const auto pdu_so_far = at.size() > 7 ? at.subspan(7) : std::span<const std::uint8_t>{};
            if (at_end || !length_consistent(pdu_so_far, total - 7)) continue;
            if (j == 0) return {Kind::NeedMore, total};
            return {Kind::Skip, j, true, UnparsedReason::BadHeader};
        }
        if (!plausible_pdu(at.subspan(7, total - 7))) continue;
        if (j == 0) return {Kind::Complete, total};
        return {Kind::Skip, j, true, UnparsedReason::BadHeader};
    }
    if (at_end) return {Kind::Skip, buf.size(), true, UnparsedReason::BadHeader};
    // Keep the last 5 bytes: a header may start there.
    const std::size_t keep = 5;
    if (buf.size() > keep) return {Kind::Skip, buf.size() - keep, true, UnparsedReason::BadHeader};
    return {Kind::NeedMore, buf.size() + 1};
}

void TcpStreamDeframer::flush_unparsed(DeframeEvents& out) {
    if (pending_.length == 0) return;
    out.emplace_back(pending_);
    pending_ = Unparsed{};
}

namespace {
// Whether a PDU decodes as a Modbus function's, in either direction, other rule violations or not (a read
// of quantity 0 is a frame a tester sends on purpose, not a stream out of sync).
bool decodes(std::span<const std::uint8_t> pdu) noexcept {
    for (const bool request : {true, false}) {
        const auto decoded = request ? decode_request(pdu) : decode_response(pdu);
        if (decoded && !decoded->violations.contains(FindingCode::PduUnknownFunction)) return true;
    }
    return false;
}
}  // namespace

bool TcpStreamDeframer::last_frame_decodes() const noexcept {
    return last_pdu_size_ == 0 || decodes({last_pdu_.data(), last_pdu_size_});
}

// After a frame that did not decode, a header with a non-zero protocol id is taken for one only when its
// PDU decodes (waited for while the bytes so far can start a PDU of its length): otherwise it is the rest
// of that frame.
bool TcpStreamDeframer::trusted_header(std::span<const std::uint8_t> rest) const noexcept {
    if (rest.size() < 6 || (rest[2] == 0 && rest[3] == 0) || last_frame_decodes()) return true;
    if (!length_ok(length_field(rest))) return false;
    const std::size_t total = 6 + length_field(rest);
    if (rest.size() < total) {
        const auto pdu_so_far = rest.size() > 7 ? rest.subspan(7) : std::span<const std::uint8_t>{};
        return length_consistent(pdu_so_far, total - 7);
    }
    return decodes(rest.subspan(7, total - 7));
}

// rest[0, held): the bytes buffered when the chunk rest[held...) came, the front of an ADU read in step by
// its length, which reaches past them.
bool TcpStreamDeframer::cut_at_segment_end(std::span<const std::uint8_t> rest,
                                           std::size_t held) const noexcept {
    if (held < 8 || rest.size() <= held || !length_ok(length_field(rest))) return false;
    const std::size_t total = 6 + length_field(rest);
    if (total <= held || total - held > max_length_excess) return false;
    // The bytes held, a PDU by themselves: a PDU cut mid-way (a read reply's first registers) is truncated.
    if (!clean_pdu(rest.subspan(7, held - 7), carries_)) return false;
    // The next chunk starts with a header, and its ADU is whole in it (or is cut the same way again).
    const auto next = rest.subspan(held);
    if (next.size() < 8 || !plausible_header(next)) return false;
    const std::size_t next_total = 6 + length_field(next);
    if (next.size() >= next_total) return clean_pdu(next.subspan(7, next_total - 7), carries_);
    return next_total - next.size() <= max_length_excess && clean_pdu(next.subspan(7), carries_);
}

DeframeStep TcpStreamDeframer::unaligned_step(std::span<const std::uint8_t> rest,
                                              bool at_end) const noexcept {
    if (rest.size() < 8 && !at_end) return {Kind::NeedMore, 8};  // the header with its function code
    // A capture holds whole packets, and a client sends an ADU in one segment: the first bytes are nearly
    // always a header. So a plausible one whose ADU is here whole is taken, whether its PDU decodes or not
    // (a malformed first ADU is the device's, as tshark reads it); one whose ADU would reach past what is
    // here is waited for only while the bytes so far can start a PDU of its length.
    if (rest.size() >= 8 && plausible_header(rest)) {
        const std::size_t total = 6 + length_field(rest);
        if (rest.size() >= total) {
            // Unless its PDU does not decode cleanly and a whole frame that does starts inside it: the
            // tail "11 03 00 00 00 0A" of a read reads as a header of length 10 over the next request.
            if (plausible_pdu(rest.subspan(7, total - 7))) return {Kind::Complete, total};
            for (std::size_t j = 1; j < total && j + 8 <= rest.size(); ++j) {
                const auto at = rest.subspan(j);
                if (!plausible_header(at)) continue;
                const std::size_t whole = 6 + length_field(at);
                if (whole <= at.size() && plausible_pdu(at.subspan(7, whole - 7)))
                    return {Kind::Skip, j, true, UnparsedReason::BadHeader};
            }
            return {Kind::Complete, total};
        }
        if (!at_end && length_consistent(rest.subspan(7), total - 7)) return {Kind::NeedMore, total};
    }
    return tcp_step(rest, at_end, false);
}

void TcpStreamDeframer::run(bool at_end, DeframeEvents& out) {
    while (head_ < buf_.size()) {
        const std::span<const std::uint8_t> rest(buf_.data() + head_, buf_.size() - head_);
        // A non-zero protocol id after an ADU that does not decode is, unless it makes a frame that
        // does, that ADU's own bytes, not a header.
        // (Once bytes were skipped, the first header is searched for as after a gap.)
        const bool unaligned = unaligned_ && in_sync_;
        const bool by_length = !unaligned && in_sync_ && (!passive_ || trusted_header(rest));
        DeframeStep step = unaligned ? unaligned_step(rest, at_end) : tcp_step(rest, at_end, by_length);
        // An ADU read by its length across the start of the chunk just fed, whose length is too long: the
        // bytes before the chunk are the frame (see the header).
        bool cut = false;
        if (passive_ && by_length && step.kind != Kind::Skip && chunk_start_ != no_chunk &&
            head_ < chunk_start_ && step.length > chunk_start_ - head_ &&
            cut_at_segment_end(rest, chunk_start_ - head_)) {
            step = {Kind::Complete, chunk_start_ - head_};
            cut = true;
        }
        if (step.kind == Kind::NeedMore) break;
        // Every byte before the first frame of a stream begun before the capture: one run, one reason.
        // So is every byte after a gap before the next frame: the tail of the ADU the hole cut.
        const UnparsedReason reason = !unaligned_  ? step.reason
                                      : after_gap_ ? UnparsedReason::AfterGap
                                                   : UnparsedReason::BeforeFirstHeader;
        if (step.kind == Kind::Skip) {
            if (pending_.length != 0 && pending_.reason != reason) flush_unparsed(out);
            if (pending_.length == 0) {
                pending_.offset = base_;
                pending_.reason = reason;
                pending_.time = first_;
            }
            pending_.length += static_cast<std::uint32_t>(step.length);
            in_sync_ = false;
        } else {
            flush_unparsed(out);
            Frame& frame = std::get<Frame>(out.emplace_back(std::in_place_type<Frame>, Frame::Unfilled{}));
            frame.framing = Framing::Tcp;
            frame.offset = base_;
            frame.length = static_cast<std::uint16_t>(step.length);
            frame.wire_length = frame.length;
            std::memcpy(frame.bytes.data(), rest.data(), step.length);
            frame.start = first_;
            // A cut frame's last byte came before the chunk; never before its first (segments fed out of
            // their capture order).
            frame.end = cut ? std::max(first_, held_until_) : last_;
            if (frame.protocol_id() != 0) frame.findings.add(FindingCode::TcpProtocolIdNonzero);
            if (frame.length_field() > max_pdu_length + 1) frame.findings.add(FindingCode::TcpLengthInvalid);
            if (cut) frame.findings.add(FindingCode::TcpLengthBeyondSegment);
            if (passive_) {
                last_pdu_size_ = step.length - 7;
                std::memcpy(last_pdu_.data(), rest.data() + 7, last_pdu_size_);
            }
            in_sync_ = true;
            unaligned_ = false;
            after_gap_ = false;
        }
        head_ += step.length;
        base_ += step.length;
        first_ = last_;
    }
    if (at_end) flush_unparsed(out);
    if (head_ > 4096 && head_ * 2 > buf_.size()) {
        buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(head_));
        head_ = 0;
    }
}

void TcpStreamDeframer::feed(std::span<const std::uint8_t> bytes, Timestamp received, DeframeEvents& out) {
    // Nothing new to read; and its time would pass for the held bytes' (held_until_).
    if (bytes.empty()) return;
    if (head_ == buf_.size()) {
        buf_.clear();
        head_ = 0;
        first_ = received;
    }
    held_until_ = last_;
    last_ = received;
    chunk_start_ = buf_.size();
    buf_.insert(buf_.end(), bytes.begin(), bytes.end());
    run(false, out);
    chunk_start_ = no_chunk;
}

void TcpStreamDeframer::gap(std::uint64_t missing, DeframeEvents& out) {
    // What is buffered can never complete: report it, then skip the hole.
    if (head_ < buf_.size()) {
        flush_unparsed(out);
        out.emplace_back(Unparsed{base_, static_cast<std::uint32_t>(buf_.size() - head_),
                                  UnparsedReason::Truncated, first_});
        base_ += buf_.size() - head_;
    }
    flush_unparsed(out);
    buf_.clear();
    head_ = 0;
    base_ += missing;
    // As at a mid-stream start: a segment after a hole most often starts with a header (a client sends an
    // ADU a segment), taken when plausible; else the bytes up to the next header are the cut ADU's end.
    // Searched for as out of step, they were a "bad header" (tcp.length_invalid, an error held against the
    // device) for the tap's loss.
    in_sync_ = true;
    unaligned_ = true;
    after_gap_ = true;
    last_pdu_size_ = 0;
}

void TcpStreamDeframer::reset() noexcept {
    buf_.clear();
    head_ = 0;
    base_ = 0;
    in_sync_ = true;
    unaligned_ = false;
    after_gap_ = false;
    last_pdu_size_ = 0;
    last_ = Timestamp{0};
    first_ = Timestamp{0};
    held_until_ = Timestamp{0};
    chunk_start_ = no_chunk;
    pending_ = Unparsed{};
}

void TcpStreamDeframer::finish(DeframeEvents& out) {
    run(true, out);
    buf_.clear();
    head_ = 0;
}

}  // namespace mbscope::modbus
