#include "modbus/ascii_deframer.hpp"

#include "modbus/adu.hpp"

namespace mbscope::modbus {

void AsciiDeframer::flush_noise(DeframeEvents& out) {
    if (noise_.length == 0) return;
    out.emplace_back(noise_);
    noise_ = Unparsed{};
}

void AsciiDeframer::add_noise(std::uint64_t offset, DeframeEvents& out) {
    if (noise_.length != 0 && noise_.offset + noise_.length != offset) flush_noise(out);
    if (noise_.length == 0) {
        noise_.offset = offset;
        noise_.reason = UnparsedReason::NoStart;
        noise_.time = last_;
    }
    ++noise_.length;
}

void AsciiDeframer::abandon(UnparsedReason reason, DeframeEvents& out) {
    if (frame_.empty()) return;
    flush_noise(out);
    out.emplace_back(
        Unparsed{frame_offset_, static_cast<std::uint32_t>(frame_.size()), reason, frame_start_});
    frame_.clear();
}

void AsciiDeframer::complete(DeframeEvents& out) {
    flush_noise(out);
    Frame frame;
    frame.offset = frame_offset_;
    frame.wire_length = static_cast<std::uint32_t>(frame_.size());
    frame.start = frame_start_;
    frame.end = last_;
    auto r = detail::ascii_hex_to_frame({frame_.data() + 1, frame_.size() - 3}, frame);
    if (r) {
        out.emplace_back(frame);
    } else {
        UnparsedReason reason = UnparsedReason::BadCharacter;
        if (r.error().code == ErrorCode::OddHexLength) reason = UnparsedReason::OddLength;
        if (r.error().code == ErrorCode::Truncated) reason = UnparsedReason::TooShort;
        if (r.error().code == ErrorCode::TooLong) reason = UnparsedReason::TooLong;
        out.emplace_back(
            Unparsed{frame_offset_, static_cast<std::uint32_t>(frame_.size()), reason, frame_start_});
    }
    frame_.clear();
}

void AsciiDeframer::feed(std::span<const std::uint8_t> chars, Timestamp received, DeframeEvents& out) {
    if (chars.empty()) return;
    const bool timed = received.count() != 0;
    if (timed && has_last_ && !frame_.empty() && received - last_ > options_.inter_char_timeout)
        abandon(UnparsedReason::Timeout, out);
    if (timed) {
        last_ = received;
        has_last_ = true;
    }
    for (std::uint8_t c : chars) {
        const std::uint64_t at = offset_++;
        if (c == ':') {
            abandon(UnparsedReason::MissingEnd, out);  // a frame in progress never saw its CR LF
            // Room for the longest frame once, rather than growing a character at a time (ten
            // reallocations on the way to 513 characters for each deframer made).
            if (frame_.capacity() == 0) frame_.reserve(max_ascii_frame_length + 1);
            frame_.push_back(c);
            frame_offset_ = at;
            frame_start_ = last_;
            continue;
        }
        if (frame_.empty()) {
            add_noise(at, out);
            continue;
        }
        const bool after_cr = frame_.back() == '\r';
        frame_.push_back(c);
        if (after_cr) {
            if (c == '\n') {
                complete(out);
            } else {
                frame_.pop_back();
                abandon(UnparsedReason::MissingEnd, out);
                add_noise(at, out);
            }
            continue;
        }
        if (frame_.size() > max_ascii_frame_length) abandon(UnparsedReason::TooLong, out);
    }
}

void AsciiDeframer::finish(DeframeEvents& out) {
    abandon(UnparsedReason::Truncated, out);
    flush_noise(out);
}

}  // namespace mbscope::modbus
