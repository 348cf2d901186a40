#include "modbus/transport/exchange.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/rtu_deframer.hpp"

namespace mbscope::modbus::transport {
namespace {

struct Span {
    std::size_t begin = 0, end = 0;  // end == 0: no complete frame
};

Span find_frame(Framing framing, std::span<const std::uint8_t> bytes, bool silence, bool datagram) {
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
                const auto step = rtu_step(bytes.subspan(head), silence);
                if (step.kind == DeframeStep::Kind::Complete) return {head, head + step.length};
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

std::optional<Frame> decode(Framing framing, std::span<const std::uint8_t> bytes) {
    Result<Frame> f = decode_adu(framing, bytes);
    if (!f) return std::nullopt;
    return std::move(f).value();
}

}  // namespace

std::span<const std::uint8_t> Exchange::own_received() const noexcept {
    std::size_t stale = 0;
    for (const auto& f : stale_replies)
        stale += f.wire_length;
    return std::span<const std::uint8_t>(received).subspan(std::min(stale, received.size()));
}

std::size_t ReplyScanner::scan(Exchange& ex, bool silence) {
    std::size_t found_now = 0;
    for (;;) {
        const std::span<const std::uint8_t> rest(ex.received.data() + scan_from_,
                                                 ex.received.size() - scan_from_);
        const Span s = find_frame(framing_, rest, silence, datagram_);
        if (s.end == 0) break;
        auto frame = decode(framing_, rest.subspan(s.begin, s.end - s.begin));
        scan_from_ += s.end;
        // A late reply to one of the requests just before this one (a server that sleeps before an
        // exception, as libmodbus does, answers after the client gave up): kept in `received`, counted,
        // and not taken for this request's reply. Only while nothing else has come: own_received() counts
        // the stale replies off the front.
        if (frame && framing_ == Framing::Tcp && frames_ <= 1 && found_ == 0 && ex.sent.size() >= 7) {
            const auto sent_tid = static_cast<std::uint16_t>((ex.sent[0] << 8) | ex.sent[1]);
            const auto behind = static_cast<std::uint16_t>(sent_tid - frame->transaction_id());
            if (behind >= 1 && behind <= 256) {
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
