#include "modbus/ascii_deframer.hpp"

#include <algorithm>
#include <cstring>

#include "modbus/adu.hpp"
#include "modbus/hex.hpp"

namespace mbscope::modbus {

void AsciiDeframer::flush_noise(DeframeEvents& out) {
    if (noise_.length == 0) return;
    out.emplace_back(noise_);
    noise_ = Unparsed{};
}

void AsciiDeframer::add_noise(std::size_t count, Timestamp at, DeframeEvents& out) {
    if (noise_.length != 0 && noise_.offset + noise_.length != offset_) flush_noise(out);
    if (noise_.length == 0) {
        noise_.offset = offset_;
        noise_.reason = UnparsedReason::NoStart;
        noise_.time = at;
    }
    noise_.length += static_cast<std::uint32_t>(count);
    offset_ += count;
}

void AsciiDeframer::start_frame(Timestamp at) {
    frame_[0] = ':';
    frame_length_ = 1;
    frame_offset_ = offset_++;
    frame_start_ = at;
}

void AsciiDeframer::append(std::span<const std::uint8_t> run) {
    // The caller never hands more than the room left (feed's `limit`).
    std::copy(run.begin(), run.end(), frame_.begin() + static_cast<std::ptrdiff_t>(frame_length_));
    frame_length_ += run.size();
    offset_ += run.size();
}

Unparsed AsciiDeframer::frame_unparsed(UnparsedReason reason) const {
    Unparsed u{frame_offset_, static_cast<std::uint32_t>(frame_length_), reason, frame_start_};
    // The unit and function code its first four digits spell, if they are digits: a reply that noise
    // damaged, or that the end of a capture cut, is still known to have begun.
    if (frame_length_ >= 5) {
        int digits[4];
        for (std::size_t k = 0; k < 4; ++k)
            digits[k] = hex_digit(frame_[1 + k]);
        if (std::all_of(std::begin(digits), std::end(digits), [](int d) { return d >= 0; }))
            u.head = {static_cast<std::uint8_t>(digits[0] << 4 | digits[1]),
                      static_cast<std::uint8_t>(digits[2] << 4 | digits[3])};
    }
    return u;
}

void AsciiDeframer::abandon(UnparsedReason reason, DeframeEvents& out) {
    if (frame_length_ == 0) return;
    flush_noise(out);
    out.emplace_back(frame_unparsed(reason));
    frame_length_ = 0;
}

void AsciiDeframer::complete(Timestamp end, DeframeEvents& out) {
    flush_noise(out);
    // Decoded in place (a frame made and copied in was two passes over its 336 bytes), replaced when the
    // characters do not decode.
    Frame& frame = std::get<Frame>(out.emplace_back(std::in_place_type<Frame>, Frame::Unfilled{}));
    frame.offset = frame_offset_;
    frame.wire_length = static_cast<std::uint32_t>(frame_length_);
    frame.start = frame_start_;
    frame.end = end;
    auto r = detail::ascii_hex_to_frame({frame_.data() + 1, frame_length_ - 3}, frame);
    if (!r) {
        UnparsedReason reason = UnparsedReason::BadCharacter;
        if (r.error().code == ErrorCode::OddHexLength) reason = UnparsedReason::OddLength;
        if (r.error().code == ErrorCode::Truncated) reason = UnparsedReason::TooShort;
        if (r.error().code == ErrorCode::TooLong) reason = UnparsedReason::TooLong;
        out.back() = frame_unparsed(reason);
    }
    frame_length_ = 0;
}

void AsciiDeframer::feed(std::span<const std::uint8_t> chars, Timestamp received, DeframeEvents& out) {
    if (chars.empty()) return;
    const bool timed = received.count() != 0;
    const std::uint8_t* const p = chars.data();
    const std::size_t n = chars.size();
    // When character i arrived: `received` is the last one's time, and each came one character time after
    // the one before it (untimed: zero, as every time here).
    const auto at = [&](std::size_t i) {
        return timed ? received - options_.character_time * static_cast<std::int64_t>(n - 1 - i) : received;
    };
    // The pause is from the last character before this chunk to its first (SL §2.5.2.1's inter-character
    // timeout, 1 s on the MK instruments, 000:304), not to its last.
    if (timed && has_last_ && frame_length_ != 0 && at(0) - last_ > options_.inter_char_timeout)
        abandon(UnparsedReason::Timeout, out);
    if (timed) {
        last_ = received;
        has_last_ = true;
    }
    // Runs of characters are taken whole: noise up to the next ':', a frame's body up to the next ':' or CR
    // (found by memchr), so the work per character is a copy, not a branch per character.
    std::size_t i = 0;
    while (i < n) {
        if (p[i] == ':') {
            abandon(UnparsedReason::MissingEnd, out);  // a frame in progress never saw its CR LF
            start_frame(at(i));
            ++i;
            continue;
        }
        if (frame_length_ == 0) {  // noise, up to the next ':'
            const auto* colon = static_cast<const std::uint8_t*>(std::memchr(p + i, ':', n - i));
            const std::size_t stop = colon ? static_cast<std::size_t>(colon - p) : n;
            add_noise(stop - i, at(i), out);
            i = stop;
            continue;
        }
        if (frame_[frame_length_ - 1] == '\r') {
            if (p[i] == '\n') {
                frame_[frame_length_++] = '\n';  // room: a frame holding its CR is not too long yet
                ++offset_;
                complete(at(i), out);
            } else {
                abandon(UnparsedReason::MissingEnd, out);
                add_noise(1, at(i), out);
            }
            ++i;
            continue;
        }
        // The frame's body: up to the next ':' (handled above), up to and with a CR, or up to the character
        // that makes it one longer than the longest frame.
        const std::size_t limit = std::min(n - i, max_ascii_frame_length + 1 - frame_length_);
        const auto* colon = static_cast<const std::uint8_t*>(std::memchr(p + i, ':', limit));
        const std::size_t body_end = colon ? static_cast<std::size_t>(colon - p) : i + limit;
        const auto* cr = static_cast<const std::uint8_t*>(std::memchr(p + i, '\r', body_end - i));
        const std::size_t stop = cr ? static_cast<std::size_t>(cr - p) + 1 : body_end;
        append({p + i, p + stop});
        i = stop;
        if (frame_length_ > max_ascii_frame_length) abandon(UnparsedReason::TooLong, out);
    }
}

void AsciiDeframer::finish(DeframeEvents& out) {
    abandon(UnparsedReason::Truncated, out);
    flush_noise(out);
}

}  // namespace mbscope::modbus
