#include "analyzer/rtu_over_tcp_probe.hpp"

#include <algorithm>
#include <cstdio>

#include "modbus/adu.hpp"
#include "modbus/function_code.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;

namespace {

enum class At : std::uint8_t { Frame, NoFrame, NeedMore };

// Whether an RTU frame whose CRC holds starts at `at`, its length predicted from its content in the stream's
// direction as the RTU deframer predicts it; its length in `length`.
At frame_at(const std::vector<std::uint8_t>& bytes, std::size_t at, Direction direction,
            std::size_t& length) {
    const std::span<const std::uint8_t> rest(bytes.data() + at, bytes.size() - at);
    if (rest.size() < 2) return At::NeedMore;
    const LengthPrediction p = predict_pdu_length(rest.subspan(1), direction);
    if (p.kind == LengthPrediction::Kind::NeedMore) return At::NeedMore;
    length = 1 + p.length + 2;
    if (p.kind != LengthPrediction::Kind::Known || p.length < 1 || length > max_rtu_adu_length)
        return At::NoFrame;
    if (rest.size() < length) return At::NeedMore;
    return rtu_crc_ok(rest.first(length)) ? At::Frame : At::NoFrame;
}

// What is wrong with the MBAP ADU whose header starts `adu` (which holds at least the header, unit and
// function code, and the whole ADU when its length field is in range): empty when nothing is.
std::string misread(std::span<const std::uint8_t> adu, bool request) {
    const unsigned protocol = (unsigned{adu[2]} << 8) | adu[3];
    const std::size_t length = (std::size_t{adu[4]} << 8) | adu[5];
    const char* stream = request ? "request" : "response";
    char why[96] = "";
    if (protocol != 0) {
        std::snprintf(why, sizeof why, "a %s's protocol id is 0x%04X, not 0", stream, protocol);
    } else if (length < 2 || length > 254) {
        std::snprintf(why, sizeof why, "a %s's length field is %zu, outside 2..254", stream, length);
    } else if (!is_public_function(adu[7] & 0x7F) || (request && (adu[7] & exception_bit))) {
        std::snprintf(why, sizeof why, "a %s's function code is 0x%02X, no public one", stream, adu[7]);
    } else if (adu.size() >= 6 + length) {
        const auto pdu = adu.subspan(7, length - 1);
        const auto decoded = request ? decode_request(pdu) : decode_response(pdu);
        if (!decoded || decoded->violations.contains(FindingCode::PduMalformed) ||
            decoded->violations.contains(FindingCode::PduByteCountMismatch))
            std::snprintf(why, sizeof why, "a %s's PDU (FC%u) does not decode", stream, adu[7] & 0x7Fu);
    }
    return why;
}

// Whether `bytes` open with a whole MBAP ADU: protocol id 0 and a length field in 2..254 that the bytes
// hold. Its function code and PDU are not judged, nor what follows it: a vendor's function (Schneider's
// UMAS on FC90), a malformed request or the first part of the next ADU (pipelining, Nagle) are still
// Modbus/TCP, and are told at once rather than held until the request's timeout.
bool opens_with_mbap_adu(std::span<const std::uint8_t> bytes) {
    if (bytes.size() < 8 || bytes[2] != 0 || bytes[3] != 0) return false;
    const std::size_t length = (std::size_t{bytes[4]} << 8) | bytes[5];
    return length >= 2 && length <= 254 && 6 + length <= bytes.size();
}

}  // namespace

RtuOverTcpProbe::Verdict RtuOverTcpProbe::feed(int side, std::span<const std::uint8_t> bytes,
                                               bool start_unseen) {
    if (verdict_ != Verdict::Undecided || bytes.empty()) return verdict_;
    Side& s = side_[side];
    if (s.bytes.empty()) {
        s.first_chunk = bytes.size();
        s.start_unseen = start_unseen;
    }
    s.bytes.insert(s.bytes.end(), bytes.begin(), bytes.end());
    read_rtu(side);
    read_mbap(side);
    decide();
    return verdict_;
}

void RtuOverTcpProbe::read_rtu(int side) {
    Side& s = side_[side];
    const Direction direction = side == 0 ? Direction::Request : Direction::Response;
    while (!s.failed) {
        std::size_t length = 0;
        const At at = frame_at(s.bytes, s.rtu_end, direction, length);
        if (at != At::Frame && s.frames == 0 && s.rtu_end < s.first_chunk) {
            // A side's first segment that does not start with an RTU frame and opens with a whole MBAP ADU:
            // Modbus/TCP, told at once rather than after more bytes (a reply's wait). (The tail of an RTU
            // frame sent before a capture began could look so, with 00 00 and a length the segment holds
            // at its third byte: such a capture is read as MBAP, as before the probe.)
            if (s.start == 0 && opens_with_mbap_adu({s.bytes.data(), s.first_chunk})) {
                s.failed = true;
                return;
            }
            // A missed stream start: its first segment may end a frame sent before the capture began (once
            // a connection). It does when no frame starts at its first byte and one does right after it;
            // its first byte may also seem to start a frame longer than the bytes at hand, which only a
            // frame after it shows to be none.
            std::size_t after = 0;
            if (s.start_unseen && !skipped_start_ &&
                (at == At::NoFrame || (s.bytes.size() > s.first_chunk &&
                                       frame_at(s.bytes, s.first_chunk, direction, after) == At::Frame))) {
                skipped_start_ = true;
                s.start = s.rtu_end = s.mbap_at = s.first_chunk;
                continue;
            }
        }
        if (at == At::NeedMore) return;
        if (at == At::NoFrame) {
            s.failed = true;
            return;
        }
        if (frames() == 0) {
            first_unit_ = s.bytes[s.rtu_end];
            first_function_ = s.bytes[s.rtu_end + 1];
        }
        s.rtu_end += length;
        s.frame_ends.push_back(s.rtu_end);
        ++s.frames;
    }
}

void RtuOverTcpProbe::read_mbap(int side) {
    Side& s = side_[side];
    // Judged only over what the RTU reading framed: its bytes are the ones both readings claim.
    while (misreading_.empty() && s.mbap_at + 8 <= s.rtu_end) {
        const std::uint8_t* h = s.bytes.data() + s.mbap_at;
        const std::size_t length = (std::size_t{h[4]} << 8) | h[5];
        const std::size_t end = s.mbap_at + 6 + length;
        const std::size_t held = std::min(end, s.rtu_end) - s.mbap_at;
        std::string why = misread({h, held}, side == 0);
        if (why.empty() && end > s.rtu_end) return;  // judged once the RTU reading reaches its end
        if (why.empty() && !std::binary_search(s.frame_ends.begin(), s.frame_ends.end(), end))
            why = std::string("a ") + (side == 0 ? "request" : "response") + "'s length field (" +
                  std::to_string(length) + ") ends it inside an RTU frame";
        if (!why.empty()) {
            misreading_ = std::move(why);
            return;
        }
        s.mbap_at = end;
    }
}

void RtuOverTcpProbe::decide() {
    if (side_[0].failed || side_[1].failed) {
        verdict_ = Verdict::Mbap;
    } else if (frames() >= frames_needed && !misreading_.empty()) {
        verdict_ = Verdict::Rtu;
    } else if (frames() >= frames_ambiguous) {
        verdict_ = Verdict::Mbap;
    } else {
        for (const Side& s : side_)
            if (s.bytes.size() - s.start > max_bytes_per_side) verdict_ = Verdict::Mbap;
    }
    if (verdict_ != Verdict::Undecided) release();
}

RtuOverTcpProbe::Verdict RtuOverTcpProbe::settle() {
    if (verdict_ != Verdict::Undecided) return verdict_;
    verdict_ = settles_as_rtu() ? Verdict::Rtu : Verdict::Mbap;
    release();
    return verdict_;
}

void RtuOverTcpProbe::release() {
    for (Side& s : side_) {  // nothing more is looked at: the memory goes back
        std::vector<std::uint8_t>().swap(s.bytes);
        std::vector<std::size_t>().swap(s.frame_ends);
    }
}

void RtuOverTcpProbe::reset() {
    *this = RtuOverTcpProbe{};
}

}  // namespace mbscope::analyzer
