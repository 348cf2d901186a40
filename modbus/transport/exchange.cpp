#include "modbus/transport/exchange.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/checksum.hpp"
#include "modbus/pdu.hpp"
#include "modbus/rtu_deframer.hpp"

namespace mbscope::modbus::transport {
namespace {

struct Span {
    std::size_t begin = 0, end = 0;  // end == 0: no complete frame
};

// An RTU reply's length as its function code and byte count say (address, PDU, CRC), once the bytes so
// far tell it.
std::optional<std::size_t> rtu_reply_length(std::span<const std::uint8_t> b) noexcept {
    if (b.size() < 2) return std::nullopt;
    const LengthPrediction p = predict_pdu_length(b.subspan(1), Direction::Response);
    if (p.kind != LengthPrediction::Kind::Known) return std::nullopt;
    return 1 + p.length + 2;
}

bool crc_ok(std::span<const std::uint8_t> frame) noexcept {
    const std::size_t n = frame.size() - 2;
    return crc16(frame.first(n)) == static_cast<std::uint16_t>(frame[n] | (frame[n + 1] << 8));
}

// The bytes here are replies. The RTU deframer, which serves either direction, takes the first length whose
// CRC checks; inside a longer reply a request's length may check too ("01 01 04 62 F2 02 58 45" is the
// start of a read-coils reply and a whole FC1 request): a reply's own length, when its bytes say it and
// their CRC checks, is preferred, and waited for while the line is not silent.
Span find_frame(Framing framing, std::span<const std::uint8_t> bytes, bool silence, bool datagram,
                std::optional<std::size_t> echo_length = std::nullopt) {
    switch (framing) {
        case Framing::Tcp: {
            if (datagram) return {0, bytes.size()};
            if (bytes.size() < 6) return {};
            const std::size_t total = 6u + ((std::size_t{bytes[4]} << 8) | bytes[5]);
            return bytes.size() >= total ? Span{0, total} : Span{};
        }
        case Framing::Ascii: {
            for (std::size_t i = 0; i < bytes.size(); ++i) {
                if (bytes[i] != ':') continue;
                for (std::size_t j = i + 1; j + 1 < bytes.size(); ++j)
                    if (bytes[j] == '\r' && bytes[j + 1] == '\n') return {i, j + 2};
                return {};
            }
            return {};
        }
        case Framing::Rtu: {
            std::size_t head = 0;
            while (head < bytes.size()) {
                // Diagnostics answers with the request's length (AP §6.8: sub-function 00 echoes any data,
                // the others a word for the request's word), which its own bytes do not tell: taken first
                // when its checksum holds there (a shorter prefix whose CRC happens to hold, or the two data
                // bytes most sub-functions carry, cut a correct echo of 00's three data bytes "C1 83 57").
                if (echo_length && bytes.size() - head >= *echo_length && bytes.size() - head >= 2 &&
                    bytes[head + 1] == 0x08 && crc_ok(bytes.subspan(head, *echo_length)))
                    return {head, head + *echo_length};
                const auto step = rtu_step(bytes.subspan(head), silence, false);
                if (step.kind == DeframeStep::Kind::Complete) {
                    const auto want = rtu_reply_length(bytes.subspan(head));
                    if (want && *want > step.length && *want <= max_frame_bytes) {
                        if (head + *want <= bytes.size()) {
                            if (crc_ok(bytes.subspan(head, *want))) return {head, head + *want};
                        } else if (!silence) {
                            return {};  // the rest of the reply is on its way
                        }
                    }
                    return {head, head + step.length};
                }
                if (step.kind == DeframeStep::Kind::NeedMore) break;
                head += step.length ? step.length : 1;
            }
            // Ended by silence without a frame the content explains: all of it is the answer, as a receiver
            // timing the line would take it.
            if (silence && bytes.size() >= 4) return {0, bytes.size()};
            return {};
        }
    }
    return {};
}

// An RTU Diagnostics request: its reply is as long as it is (find_frame).
std::optional<std::size_t> diagnostics_reply_length(Framing framing, std::span<const std::uint8_t> sent) {
    if (framing == Framing::Rtu && sent.size() >= 4 && sent[1] == 0x08) return sent.size();
    return std::nullopt;
}

std::optional<Frame> decode(Framing framing, std::span<const std::uint8_t> bytes) {
    Result<Frame> f = decode_adu(framing, bytes);
    if (!f) return std::nullopt;
    return std::move(f).value();
}

std::uint16_t word_at(std::span<const std::uint8_t> b, std::size_t i) noexcept {
    return static_cast<std::uint16_t>((b[i] << 8) | b[i + 1]);
}

bool same_bytes(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b, std::size_t from,
                std::size_t to) noexcept {
    return a.size() >= to && b.size() >= to && std::equal(a.begin() + from, a.begin() + to, b.begin() + from);
}

}  // namespace

bool could_answer(std::uint8_t unit, std::span<const std::uint8_t> request, const Frame& reply) noexcept {
    const auto p = reply.pdu();
    if (request.empty() || p.empty()) return false;
    if (unit != 0 && reply.unit_id() != unit) return false;
    const std::uint8_t fc = request[0];
    if (p[0] == (fc | 0x80)) return p.size() == 2;
    if (p[0] != fc) return false;
    const auto read_reply = [&](std::size_t bytes_per_item, std::size_t per_byte) {
        if (request.size() < 5) return true;
        const std::size_t count =
            (std::size_t{word_at(request, 3)} * bytes_per_item + per_byte - 1) / per_byte;
        return p.size() >= 2 && p[1] == count && p.size() == 2 + count;
    };
    switch (fc) {
        case 1:
        case 2:
            return read_reply(1, 8);  // a bit each, packed
        case 3:
        case 4:
        case 23:
            return read_reply(2, 1);  // FC23: the read half's quantity
        case 5:
        case 6:
            return p.size() == 5 && same_bytes(p, request, 1, 3);  // the address echoed
        case 15:
        case 16:
            return p.size() == 5 && same_bytes(p, request, 1, 5);  // address and quantity
        case 22:
            return p.size() == 7 && same_bytes(p, request, 1, 3);  // the address echoed
        case 8:
            return p.size() >= 3 && same_bytes(p, request, 1, 3);  // the sub-function echoed
        case 43:
            return p.size() >= 2 && same_bytes(p, request, 1, 2);  // the MEI type echoed
        default:
            return true;
    }
}

bool could_draw_same_reply(const OwedRequest& owed, std::uint8_t unit,
                           std::span<const std::uint8_t> pdu) noexcept {
    return !owed.pdu.empty() && !pdu.empty() && (owed.pdu[0] & 0x7F) == (pdu[0] & 0x7F) &&
           (owed.unit == unit || owed.unit == 0 || unit == 0);
}

bool OwedRequests::owes_reply() const noexcept {
    return std::any_of(owed_.begin(), owed_.end(), [](const OwedRequest& o) { return o.reply_due; });
}

bool OwedRequests::owes_reply_like(std::uint8_t unit, std::span<const std::uint8_t> pdu) const noexcept {
    return std::any_of(owed_.begin(), owed_.end(), [&](const OwedRequest& o) {
        return o.reply_due && could_draw_same_reply(o, unit, pdu);
    });
}

bool OwedRequests::after(const Exchange& ex, std::uint8_t unit, std::span<const std::uint8_t> pdu,
                         std::vector<SettledRequest>* settled, bool reply_due) {
    for (const auto& stale : ex.stale_replies) {
        auto request = settle(stale);
        if (request && settled) settled->push_back({std::move(*request), stale});
    }
    // Anything that came for this request, whole or not, means the device got to it.
    if (!ex.own_received().empty()) {
        owed_.clear();
        return false;
    }
    if (ex.closed || pdu.empty()) return false;
    if (owed_.size() == kept) {
        // The oldest request no reply was due to goes first: a target slower than the wait sees several
        // probes it must not answer (waited for briefly) within one due reply's delay.
        const auto silent =
            std::find_if(owed_.begin(), owed_.end(), [](const OwedRequest& o) { return !o.reply_due; });
        owed_.erase(silent != owed_.end() ? silent : owed_.begin());
    }
    owed_.push_back({unit, std::vector<std::uint8_t>(pdu.begin(), pdu.end()), ex.sent, reply_due,
                     std::chrono::steady_clock::now()});
    return true;
}

std::size_t OwedRequests::after_tcp(const Exchange& ex, std::vector<SettledRequest>* settled) {
    for (const auto& stale : ex.stale_replies) {
        auto request = settle(stale);
        if (request && settled) settled->push_back({std::move(*request), stale});
    }
    if (ex.closed) {
        owed_.clear();  // the connection is gone, and the replies it owed with it
        return 0;
    }
    const auto requests = frames_in(Framing::Tcp, ex.sent);
    const auto answered = transaction_ids(ex.own_received());
    // One request and anything back: its reply, right or wrong (a wrong id is for the rules to fail).
    if (requests.size() == 1 && !ex.own_received().empty()) return owed_.size();
    for (const auto& request : requests) {
        if (std::find(answered.begin(), answered.end(), request.transaction_id()) != answered.end()) continue;
        const auto pdu = request.pdu();
        const bool due = request.protocol_id() == 0 && decode_request(pdu).has_value();
        if (owed_.size() == kept_tcp) owed_.erase(owed_.begin());
        owed_.push_back({request.unit_id(), std::vector<std::uint8_t>(pdu.begin(), pdu.end()),
                         std::vector<std::uint8_t>(request.adu().begin(), request.adu().end()), due,
                         std::chrono::steady_clock::now()});
    }
    return owed_.size();
}

std::optional<OwedRequest> OwedRequests::settle(const Frame& late) {
    if (late.framing == Framing::Tcp) {
        // The transaction id says which request it answers; none owed carries it: no owed request's.
        const auto answered = std::find_if(owed_.begin(), owed_.end(), [&](const OwedRequest& o) {
            const auto ids = transaction_ids(o.sent);
            return !ids.empty() && ids.front() == late.transaction_id();
        });
        if (answered == owed_.end()) return std::nullopt;
        OwedRequest request = std::move(*answered);
        owed_.erase(answered);
        return request;
    }
    auto answered = std::find_if(owed_.begin(), owed_.end(), [&](const OwedRequest& o) {
        return o.reply_due && could_answer(o.unit, o.pdu, late);
    });
    if (answered == owed_.end())
        answered = std::find_if(owed_.begin(), owed_.end(),
                                [&](const OwedRequest& o) { return could_answer(o.unit, o.pdu, late); });
    if (answered == owed_.end()) return std::nullopt;
    OwedRequest request = std::move(*answered);
    owed_.erase(answered);
    return request;
}

std::vector<std::uint8_t> OwedRequests::settle_frames(Framing framing, std::span<const std::uint8_t> bytes,
                                                      std::vector<SettledRequest>& settled) {
    std::vector<std::uint8_t> rest;
    std::size_t kept_from = 0;  // bytes before a settling frame and after the last one are the rest
    for (const auto& frame : frames_in(framing, bytes)) {
        if (!frame.checksum_ok) continue;
        auto request = settle(frame);
        if (!request) continue;
        rest.insert(rest.end(), bytes.begin() + static_cast<std::ptrdiff_t>(kept_from),
                    bytes.begin() + static_cast<std::ptrdiff_t>(frame.offset));
        kept_from = frame.offset + frame.wire_length;
        settled.push_back({std::move(*request), frame});
    }
    rest.insert(rest.end(), bytes.begin() + static_cast<std::ptrdiff_t>(kept_from), bytes.end());
    return rest;
}

std::vector<Frame> frames_in(Framing framing, std::span<const std::uint8_t> bytes) {
    std::vector<Frame> out;
    std::size_t at = 0;
    while (!bytes.empty()) {
        // The bytes are all there is: the line is silent after them.
        const Span s = find_frame(framing, bytes, true, false);
        if (s.end == 0) break;
        if (auto f = decode(framing, bytes.subspan(s.begin, s.end - s.begin))) {
            f->offset = at + s.begin;
            out.push_back(std::move(*f));
        }
        bytes = bytes.subspan(s.end);
        at += s.end;
    }
    return out;
}

std::vector<std::uint16_t> transaction_ids(std::span<const std::uint8_t> bytes) {
    std::vector<std::uint16_t> ids;
    while (bytes.size() >= 7) {
        ids.push_back(word_at(bytes, 0));
        const std::size_t total = 6u + ((std::size_t{bytes[4]} << 8) | bytes[5]);
        if (total > bytes.size()) break;
        bytes = bytes.subspan(total);
    }
    return ids;
}

std::span<const std::uint8_t> Exchange::own_received() const noexcept {
    std::size_t stale = 0;
    for (const auto& f : stale_replies)
        stale += f.wire_length;
    return std::span<const std::uint8_t>(received).subspan(std::min(stale, received.size()));
}

namespace {

bool same_frame(const Frame& a, const Frame& b) {
    return a.checksum_ok == b.checksum_ok && std::ranges::equal(a.adu(), b.adu());
}

}  // namespace

// Frames are compared decoded: an ASCII frame's adu() is its binary form, not its characters.
bool repeats_reply(const Frame& reply, std::span<const std::uint8_t> later) {
    // The bytes are all there is: the line is silent after them.
    const Span s =
        find_frame(reply.framing, later, true, false,
                   reply.framing == Framing::Rtu ? std::optional(reply.wire_length) : std::nullopt);
    if (s.end == 0 || s.begin != 0) return false;
    const auto again = decode(reply.framing, later.first(s.end));
    return again && same_frame(*again, reply);
}

bool repeats_response(const Exchange& ex) {
    // No room for the response and a copy of it (every exchange of a well-behaved device): nothing to decode.
    if (!ex.response || ex.own_received().size() < 2 * ex.response->wire_length) return false;
    // Frame by frame, as the scanner found them, up to the response: the copy must follow it.
    auto own = ex.own_received();
    while (!own.empty()) {
        const Span s = find_frame(ex.response->framing, own, true, false,
                                  diagnostics_reply_length(ex.response->framing, ex.sent));
        if (s.end == 0) return false;
        const auto f = decode(ex.response->framing, own.subspan(s.begin, s.end - s.begin));
        own = own.subspan(s.end);
        if (f && same_frame(*f, *ex.response)) return repeats_reply(*ex.response, own);
    }
    return false;
}

bool ReplyScanner::late_over_tcp(const Exchange& ex, const Frame& frame) const {
    const auto own = transaction_ids(ex.sent);
    if (own.empty()) return false;  // no request to tell it from
    const auto id = frame.transaction_id();
    if (std::find(own.begin(), own.end(), id) != own.end()) return false;
    // Just behind the one request awaited: the client's own ids count up, and this is an earlier one's.
    const auto behind = static_cast<std::uint16_t>(own.front() - id);
    if (frames_ <= 1 && behind >= 1 && behind <= stale_transaction_window) return true;
    return std::any_of(owed_.begin(), owed_.end(), [&](const OwedRequest& o) {
        const auto ids = transaction_ids(o.sent);
        return !ids.empty() && ids.front() == id;
    });
}

std::size_t ReplyScanner::scan(Exchange& ex, bool silence) {
    std::size_t found_now = 0;
    const auto echo_length = diagnostics_reply_length(framing_, ex.sent);
    for (;;) {
        const std::span<const std::uint8_t> rest(ex.received.data() + scan_from_,
                                                 ex.received.size() - scan_from_);
        const Span s = find_frame(framing_, rest, silence, datagram_, echo_length);
        if (s.end == 0) break;
        auto frame = decode(framing_, rest.subspan(s.begin, s.end - s.begin));
        scan_from_ += s.end;
        // A late reply to one of the requests just before this one (a server that sleeps before an
        // exception, as libmodbus does, answers after the client gave up): kept in `received`, counted,
        // and not taken for this request's reply. Only while nothing else has come: own_received() counts
        // the stale replies off the front.
        if (frame && framing_ == Framing::Tcp && found_ == 0 && late_over_tcp(ex, *frame)) {
            ex.stale_replies.push_back(std::move(*frame));
            continue;
        }
        // RTU and ASCII: a reply that could answer only an earlier request. One that could answer both stays
        // this request's: content cannot tell them apart (the conformance session waits out such a late
        // reply before it sends a request of the same shape).
        // Only a frame right where the last one ended: own_received() counts the stale replies off the front.
        if (frame && framing_ != Framing::Tcp && !owed_.empty() && frames_ <= 1 && found_ == 0 &&
            s.begin == 0 && frame->checksum_ok) {
            // The request decodes whatever its checksum: a device that skips the check answers it.
            const auto own = decode(framing_, ex.sent);
            const bool mine = own && could_answer(own->unit_id(), own->pdu(), *frame);
            const bool theirs = std::any_of(owed_.begin(), owed_.end(), [&](const OwedRequest& o) {
                return could_answer(o.unit, o.pdu, *frame);
            });
            if (!mine && theirs) {
                ex.stale_replies.push_back(std::move(*frame));
                continue;
            }
        }
        if (!ex.response) ex.response = frame;
        ++found_;
        ++found_now;
        if (datagram_ || silence) break;
    }
    return found_now;
}

}  // namespace mbscope::modbus::transport
