#pragma once
// ASCII deframing (SL §2.5.2; MK manual 000:304-309): a frame starts at ':' and ends at CR LF; a pause of
// more than the inter-character timeout (1 s, 000:304) inside a frame abandons it. Characters outside
// ':' ... CR LF, an unfinished frame cut by a new ':', bad characters and odd lengths become Unparsed
// records; lower-case hex and a wrong LRC still give a Frame, with findings.

#include <array>
#include <chrono>
#include <cstdint>
#include <span>

#include "modbus/frame.hpp"
#include "modbus/serial_line.hpp"

namespace mbscope::modbus {

class AsciiDeframer {
  public:
    struct Options {
        std::chrono::nanoseconds inter_char_timeout = std::chrono::seconds(1);
        // One character's time on the line (SerialLine::character_time): a chunk's time is its last
        // character's, and the first came this much earlier per character after it; at 300 baud a chunk of
        // 32 characters took a second to arrive without any pause in it. Zero: characters arrive at once.
        std::chrono::nanoseconds character_time{0};
    };
    AsciiDeframer() noexcept = default;
    explicit AsciiDeframer(Options options) noexcept : options_(options) {}

    // `received` is the time of the chunk's last character; zero means untimed (no timeout check).
    void feed(std::span<const std::uint8_t> chars, Timestamp received, DeframeEvents& out);
    void feed(std::span<const std::uint8_t> chars, DeframeEvents& out) { feed(chars, Timestamp{0}, out); }
    void finish(DeframeEvents& out);
    std::size_t buffered() const noexcept { return frame_length_; }  // characters of an incomplete frame

  private:
    void abandon(UnparsedReason reason, DeframeEvents& out);
    Unparsed frame_unparsed(
        UnparsedReason reason) const;  // the frame held so far, as characters that formed none
    void complete(Timestamp end, DeframeEvents& out);  // the LF, arriving at `end`, ends the frame
    // the next `count` characters are noise, the first of them arriving `at`
    void add_noise(std::size_t count, Timestamp at, DeframeEvents& out);
    void start_frame(Timestamp at);                  // the next character, a ':', starts a frame
    void append(std::span<const std::uint8_t> run);  // the next characters belong to the frame
    void flush_noise(DeframeEvents& out);

    Options options_{};
    // ':' onwards. The protocol bounds a frame, so its buffer lives in the deframer: no allocation per frame
    // or per deframer (one character past the longest frame is held before it is abandoned as too long).
    std::array<std::uint8_t, max_ascii_frame_length + 1> frame_{};
    std::size_t frame_length_ = 0;
    std::uint64_t frame_offset_ = 0;
    Timestamp frame_start_{0};
    std::uint64_t offset_ = 0;  // stream offset of the next character
    Timestamp last_{0};
    bool has_last_ = false;
    Unparsed noise_{};  // characters outside frames, merged
};

}  // namespace mbscope::modbus
