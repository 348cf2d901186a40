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
    std::vector<std::uint8_t> sent;       // the bytes written, as on the wire
    std::vector<std::uint8_t> received;   // every byte read before the exchange ended
    std::optional<Frame> response;        // the first frame found in `received`
    std::chrono::nanoseconds elapsed{0};  // from the last byte written to the end of the response
    // From the last byte written to the first byte of the reply to this request (the first byte read when
    // only late replies to earlier requests came).
    std::chrono::nanoseconds first_byte{0};
    bool timed_out = false;  // nothing complete arrived in time
    bool closed = false;     // the peer closed the connection
    // Serial lines: the longest time between two reads while a frame was still incomplete (a pause inside a
    // frame, as this host saw it: its scheduler and a USB adapter's buffering move such times), and how many
    // bytes of that frame had come before it. Zero: every frame came in one read or without a pause.
    std::chrono::nanoseconds longest_pause{0};
    std::size_t pause_after = 0;
    // Late replies to earlier requests, read and set aside: over Modbus/TCP by transaction id, over RTU and
    // ASCII by what they answer (see OwedRequest).
    std::vector<Frame> stale_replies;

    // `received` without the stale replies, which come first (a frame is set aside only before this
    // request's own reply, and before anything else that came): what came for this request.
    std::span<const std::uint8_t> own_received() const noexcept;
};

// Whether `later`, bytes that came after `reply` on the same link, begins with `reply` again, byte for byte:
// the request answered twice (a device sending its transmit buffer again). A device answers a request
// once (SL §2.1; MK-MS-01, 000:246-248: exactly one reply). Over Modbus/TCP the copy carries the same
// transaction id, over RTU and ASCII the same checksum: no other request's reply looks like this.
bool repeats_reply(const Frame& reply, std::span<const std::uint8_t> later);
// Whether what came for `ex` holds its response twice in a row (repeats_reply within one exchange).
bool repeats_response(const Exchange& ex);

// Over Modbus/TCP a reply whose transaction id is this many or fewer before the request's is a late reply to
// an earlier request (ReplyScanner sets it aside); one further behind is taken for the request's own, unless
// it carries the id of an owed request (OwedRequests::after_tcp).
constexpr std::uint16_t stale_transaction_window = 256;

// The transaction ids of the MBAP frames in `bytes` (several requests written at once), in order, one after
// another by their length fields: the last one's too when its length claims more bytes than follow (a
// request whose length is wrong on purpose still has its id); none when `bytes` hold no MBAP header and unit.
std::vector<std::uint16_t> transaction_ids(std::span<const std::uint8_t> bytes);

// A request sent earlier whose reply did not come in time. RTU and ASCII carry no transaction id: a reply
// that comes after its request was given up, while the next request waits, can be told from that request's
// own only by what it answers. Over Modbus/TCP its transaction id (in `sent`) tells it.
struct OwedRequest {
    std::uint8_t unit = 0;  // 0: a broadcast, whose reply (a fault in itself) may carry any unit id
    std::vector<std::uint8_t> pdu;
    std::vector<std::uint8_t> sent;  // the bytes as written: a late reply is judged against them
    // False where the rules want no reply (a broadcast, a bad checksum): a late reply that a request due one
    // could also draw is taken as that request's.
    bool reply_due = true;
    std::chrono::steady_clock::time_point given_up{};  // when the exchange ended without it
};

// A late reply and the owed request it answers.
struct SettledRequest {
    OwedRequest request;
    Frame reply;
};

// Whether `reply` has the shape of an answer to `request_pdu` sent to `unit`: the unit id, the request's
// function code or its exception, and where a response repeats or implies them, the request's byte count,
// address, quantity or sub-function. Not whether the answer is right (the rules judge that).
bool could_answer(std::uint8_t unit, std::span<const std::uint8_t> request_pdu, const Frame& reply) noexcept;

// Whether a request to `unit` of `pdu` could draw the same reply as `owed`: the same function, or one whose
// exception shares its code (a request of function 0x84 draws the exception 84 that function 04's can), to
// the same unit or with a broadcast on either side. Content cannot tell such replies apart; only timing can.
bool could_draw_same_reply(const OwedRequest& owed, std::uint8_t unit,
                           std::span<const std::uint8_t> pdu) noexcept;

// The requests a client over RTU or ASCII may still hear from: the last four given up with nothing back
// (when more were, those due a reply are kept before those the rules want unanswered).
// Anything that comes for a later request clears them (a device answers in order: what it still owed would
// have come first); a late reply settles the oldest request it could answer.
// Over Modbus/TCP (after_tcp()), the last stale_transaction_window requests given up with nothing back,
// whatever came for later ones (ids tell the replies apart): a reply carrying one of their transaction ids is
// that request's, however far its id is from the current request's (a conformance rule's own ids 0, 0x1234,
// 0xFFFF: the reply to tid 284 taken as the answer to tid 0 failed tcp.tid_echo.0 for a device that was
// only slower than the timeout).
class OwedRequests {
  public:
    // After an exchange of a request to `unit` of `pdu` (empty: bytes that are no request): its stale
    // replies settle what they answer (each appended to `settled` when given, with the request it
    // answers); true when the request is owed now. `reply_due`: see OwedRequest.
    bool after(const Exchange& ex, std::uint8_t unit, std::span<const std::uint8_t> pdu,
               std::vector<SettledRequest>* settled = nullptr, bool reply_due = true);
    // Modbus/TCP: after an exchange of the MBAP requests in ex.sent (several when pipelined): its stale
    // replies settle the requests whose transaction ids they carry (appended to `settled` when given); each
    // request that drew no frame of its own is owed now (one request that drew anything was answered, by
    // whatever id), due a reply when its protocol id is 0 and its PDU is a request that decodes. A closed
    // connection carries no reply: every request owed is given up. Returns how many are owed now.
    std::size_t after_tcp(const Exchange& ex, std::vector<SettledRequest>* settled = nullptr);
    // The oldest owed request due a reply that `late` could answer, else the oldest other; taken off the
    // list. None when it answers none. A Modbus/TCP frame answers the request whose transaction id it
    // carries, nothing else.
    std::optional<OwedRequest> settle(const Frame& late);
    // `bytes` that came with no request waiting for them: each whole frame in them with a good checksum
    // that could answer an owed request settles it (appended to `settled`); returns the other bytes, in
    // order.
    std::vector<std::uint8_t> settle_frames(Framing framing, std::span<const std::uint8_t> bytes,
                                            std::vector<SettledRequest>& settled);
    // Whether an owed request due a reply could draw the same reply as a request to `unit` of `pdu`
    // (could_draw_same_reply): should that reply come late, only its timing tells it from the request's own,
    // so a client waits it out before sending the request.
    bool owes_reply_like(std::uint8_t unit, std::span<const std::uint8_t> pdu) const noexcept;
    // Whether any owed request is due a reply (one the rules want unanswered may never get one).
    bool owes_reply() const noexcept;
    std::span<const OwedRequest> list() const noexcept { return owed_; }
    bool empty() const noexcept { return owed_.empty(); }
    void clear() noexcept { owed_.clear(); }
    // When the newest owed request was given up; only when not empty.
    std::chrono::steady_clock::time_point newest_given_up() const noexcept { return owed_.back().given_up; }

    // Waits for an owed reply that hear nothing, in a row, after which a client takes the device as one that
    // drops replies rather than one that sends them late, and waits no more until a late reply shows again:
    // a silent device would otherwise cost a timeout twice for each request of the same shape.
    static constexpr unsigned quiet_waits_kept = 3;

  private:
    static constexpr std::size_t kept = 4;
    static constexpr std::size_t kept_tcp = stale_transaction_window;
    std::vector<OwedRequest> owed_;
};

// The whole frames in bytes that arrived with no request waiting (a late reply found before the next
// request went out), in order, each frame's `offset` where it begins in `bytes`; bytes that form none are
// left out.
std::vector<Frame> frames_in(Framing framing, std::span<const std::uint8_t> bytes);

// Finds the frames in an exchange's `received` as bytes are appended to it.
class ReplyScanner {
  public:
    // `datagram`: each read is one whole message (UDP). `frames`: how many frames the caller waits for
    // (0: as many as come). `owed`: RTU and ASCII, earlier requests whose replies may still come (kept by
    // the caller for the scanner's lifetime).
    ReplyScanner(Framing framing, bool datagram, std::size_t frames,
                 std::span<const OwedRequest> owed = {}) noexcept
        : framing_(framing), datagram_(datagram), frames_(frames), owed_(owed) {}

    // Looks at the bytes of ex.received not yet framed. `silence`: the line has been quiet long enough to
    // end an RTU frame. A late reply to an earlier request, when nothing else came before it, is set aside
    // in ex.stale_replies: over Modbus/TCP a reply whose transaction id is none of the requests' in
    // ex.sent and is within the stale_transaction_window before the request's (one request awaited) or is
    // an owed request's (any number awaited); over RTU and ASCII a frame with a good checksum that
    // could answer an owed request and could not answer this one. Otherwise the first frame becomes
    // ex.response (nullopt when its bytes do not decode). Returns how many frames (not set aside) this call
    // found.
    std::size_t scan(Exchange& ex, bool silence);

    // Frames found so far, not counting those set aside.
    std::size_t found() const noexcept { return found_; }
    // How many bytes of ex.received the frames found (and set aside) so far span: the bytes past it are a
    // frame still coming.
    std::size_t framed() const noexcept { return scan_from_; }
    // Whether the exchange is complete: the frames waited for have come.
    bool complete() const noexcept { return frames_ != 0 && found_ >= frames_; }

  private:
    // Modbus/TCP: whether `frame` answers an earlier request rather than one of those in ex.sent.
    bool late_over_tcp(const Exchange& ex, const Frame& frame) const;

    Framing framing_;
    bool datagram_;
    std::size_t frames_;
    std::span<const OwedRequest> owed_;
    std::size_t scan_from_ = 0;
    std::size_t found_ = 0;
};

}  // namespace mbscope::modbus::transport
