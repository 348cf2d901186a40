#pragma once
// One request and what came back for it, and how the bytes that come back become frames: the part of the
// client that reads no socket, so that what any slave sends can be fed to it from a fuzzer's input (the
// `client_reply` target) exactly as the client meets it.
//
// A response ends, per framing, where the framing says: Modbus/TCP at the MBAP length, a UDP datagram,
// RTU when the bytes form a CRC-valid frame of the predicted length or, failing that, at a silence of
// t3.5 (serial) or the client's settle time (serial over TCP), ASCII at CR LF.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::modbus::transport {

struct Exchange {
    std::vector<std::uint8_t> sent;          // the bytes written, as on the wire
    std::vector<std::uint8_t> received;      // every byte read before the exchange ended
    std::optional<Frame> response;           // the first frame found in `received`
    std::chrono::nanoseconds elapsed{0};     // from the last byte written to the end of the response
    std::chrono::nanoseconds first_byte{0};  // from the last byte written to the first byte read
    bool timed_out = false;                  // nothing complete arrived in time
    bool closed = false;                     // the peer closed the connection
    std::vector<Frame> stale_replies;  // Modbus/TCP: late replies to earlier requests, read and set aside

    // `received` without the stale replies, which come first (a frame is set aside only before this
    // request's own reply, and before anything else that came): what came for this request.
    std::span<const std::uint8_t> own_received() const noexcept;
};

// Finds the frames in an exchange's `received` as bytes are appended to it.
class ReplyScanner {
  public:
    // `datagram`: each read is one whole message (UDP). `frames`: how many frames the caller waits for
    // (0: as many as come).
    ReplyScanner(Framing framing, bool datagram, std::size_t frames) noexcept
        : framing_(framing), datagram_(datagram), frames_(frames) {}

    // Looks at the bytes of ex.received not yet framed. `silence`: the line has been quiet long enough to
    // end an RTU frame. A Modbus/TCP reply whose transaction id is one of the 256 before the request's is
    // a late reply to an earlier request: when nothing else came before it, it is set aside in
    // ex.stale_replies; otherwise the first frame becomes ex.response (nullopt when its bytes do not
    // decode). Returns how many frames (not set aside) this call found.
    std::size_t scan(Exchange& ex, bool silence);

    // Frames found so far, not counting those set aside.
    std::size_t found() const noexcept { return found_; }
    // Whether the exchange is complete: the frames waited for have come.
    bool complete() const noexcept { return frames_ != 0 && found_ >= frames_; }

  private:
    Framing framing_;
    bool datagram_;
    std::size_t frames_;
    std::size_t scan_from_ = 0;
    std::size_t found_ = 0;
};

}  // namespace mbscope::modbus::transport
