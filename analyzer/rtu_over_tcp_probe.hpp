#pragma once
// Tells a TCP connection decoded as Modbus/TCP (port 502, a --tcp-port) that in fact carries raw RTU frames,
// as a serial gateway in transparent mode sends them, from one that carries MBAP ADUs. Read as MBAP, RTU
// bytes make up transactions and devices: the request 01 03 00 00 00 02 C4 0B is transaction 0x0103,
// protocol 0, length 2, unit 196, FC11, a well-formed request of a unit that does not exist.
//
// The heuristic, per connection, over each direction's bytes from the first captured (requests client to
// server, responses back):
//   - RTU reading: back-to-back ADUs whose lengths are predicted from their content as the RTU deframer
//     predicts them (predict_pdu_length, in the stream's own direction), each ending in a valid CRC-16. A
//     byte that starts no such frame, or a CRC that fails, ends the reading: the connection is MBAP. On a
//     stream whose start the capture missed, the first segment of one direction (never both: a client of a
//     gateway waits for each reply, so at most one frame is in flight when a capture begins) may be the end
//     of a frame sent before the capture; the reading then starts after it.
//   - MBAP reading of the same bytes, judged only over what the RTU reading framed: a header whose protocol
//     id is not 0, a length field outside 2..254 or ending its ADU inside an RTU frame, a function code that
//     is no public one, or a PDU that does not decode in the stream's direction is a misreading.
//   A side's first segment that does not start with an RTU frame and is whole, well-formed MBAP ADUs is
//   Modbus/TCP at once (a genuine stream is told at its first packet, not held until more bytes show
//   where the RTU reading's predicted frame would end).
//   RTU when the RTU reading holds over at least 3 frames (both directions counted) and the MBAP reading
//   misreads somewhere in them; MBAP when the RTU reading fails, when 8 frames read both ways (each reading
//   consistent: Modbus/TCP is what the port is for), or when a direction's bytes pass 2 KiB undecided.
//   A connection that ends, or goes quiet for the request timeout, undecided (settle): RTU from 1 frame
//   whose MBAP reading failed (a poll and its reply, from a client that connects for each poll or polls
//   slowly; a first poll unanswered), else MBAP. Quiet time does not settle a connection whose bytes are
//   all RTU frames so far while its MBAP reading holds (an FC3 request of 2 registers reads as an FC11
//   one): its next bytes or its end do.
//
// False positives: an MBAP stream is taken for RTU only if its first bytes read as 3 back-to-back RTU
// frames whose CRCs all hold (1 when it ends or goes quiet first). For bytes not built to match, each CRC
// holds with probability 2^-16, so less than 2^-48 per connection (2^-16 for one that ends after one), times
// the two start positions a missed stream start allows; and even then the MBAP reading must fail as well,
// which it does not for a genuine Modbus/TCP stream. An MBAP stream built so that every ADU ends in the CRC
// of its other bytes (the last register written chosen to be it) reads consistently both ways and stays
// MBAP.
// False negatives: a connection that ends after frames whose MBAP reading holds, a capture of requests whose
// MBAP reading is consistent (FC3 of 2 registers reads as an FC11 request, and only the replies, protocol id
// 0x0400 and up, give it away), or RTU bytes damaged before the third frame: read as MBAP.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace mbscope::analyzer {

class RtuOverTcpProbe {
  public:
    enum class Verdict : std::uint8_t { Undecided = 0, Mbap = 1, Rtu = 2 };

    static constexpr std::uint32_t frames_needed = 3;         // RTU frames before an MBAP misreading counts
    static constexpr std::uint32_t frames_needed_at_end = 1;  // the same when no more bytes will be read
    static constexpr std::uint32_t frames_ambiguous = 8;      // frames read both ways: MBAP, the port's own
    static constexpr std::size_t max_bytes_per_side = 2048;   // eight RTU ADUs of the largest (SL §2.5.1)

    // One direction's next stream bytes (side 0: client to server, requests; 1: responses). start_unseen:
    // the capture missed the stream's start (no SYN), so its first bytes may end a frame sent before.
    // Returns the verdict so far; once decided it no longer changes and later bytes are not looked at.
    Verdict feed(int side, std::span<const std::uint8_t> bytes, bool start_unseen);
    Verdict verdict() const noexcept { return verdict_; }
    // Every byte read so far is RTU frames with valid CRCs, one at least: a connection the quiet time must
    // not settle (a gateway's first poll unanswered, the next one a poll period later), though the MBAP
    // reading has not yet failed (an FC3 request of 2 registers reads as an FC11 one).
    bool rtu_reading_holds() const noexcept { return !side_[0].failed && !side_[1].failed && frames() > 0; }
    // What settle() would say now is RTU.
    bool settles_as_rtu() const noexcept {
        return rtu_reading_holds() && frames() >= frames_needed_at_end && !misreading_.empty();
    }
    // No more bytes will be read (the connection ended, or went quiet for the request timeout): a verdict
    // from what was read, RTU or MBAP.
    Verdict settle();
    // For the finding's message: the RTU frames read, the first one's unit and function code, and what the
    // MBAP reading got wrong.
    std::uint32_t frames() const noexcept { return side_[0].frames + side_[1].frames; }
    std::uint8_t first_unit() const noexcept { return first_unit_; }
    std::uint8_t first_function() const noexcept { return first_function_; }
    const std::string& mbap_misreading() const noexcept { return misreading_; }
    // Back to a new probe's state (a new connection on the same addresses and ports).
    void reset();

  private:
    struct Side {
        std::vector<std::uint8_t> bytes;
        std::size_t first_chunk = 0;  // length of the first bytes fed, 0 before any
        bool start_unseen = false;
        std::size_t start = 0;    // where both readings begin
        std::size_t rtu_end = 0;  // end of the last RTU frame whose CRC holds
        std::vector<std::size_t> frame_ends;
        std::size_t mbap_at = 0;  // the next MBAP header to judge
        std::uint32_t frames = 0;
        bool failed = false;
    };
    void read_rtu(int side);
    void read_mbap(int side);
    void decide();
    void release();

    Side side_[2];
    bool skipped_start_ = false;  // one side's first segment was taken for the end of an earlier frame
    std::uint8_t first_unit_ = 0, first_function_ = 0;
    std::string misreading_;
    Verdict verdict_ = Verdict::Undecided;
};

}  // namespace mbscope::analyzer
