#include "analyzer/tcp_reassembler.hpp"

namespace mbscope::analyzer {

void TcpReassembler::segment(std::uint32_t seq, bool syn, std::span<const std::uint8_t> payload,
                             modbus::Timestamp t) {
    if (syn) {
        next_ = seq + 1;
        payload = {};  // data on a SYN is legal but never used by Modbus clients
        return;
    }
    if (!next_) next_ = seq;  // capture started mid-connection
    if (payload.empty()) return;
    // Position relative to the next expected byte, wrap-aware (RFC 793 sequence space).
    const auto rel = static_cast<std::int32_t>(seq - *next_);
    if (rel < 0) {
        const auto overlap = static_cast<std::size_t>(-static_cast<std::int64_t>(rel));
        if (overlap >= payload.size()) {
            retransmitted_ += payload.size();
            return;
        }
        retransmitted_ += overlap;
        payload = payload.subspan(overlap);
    } else if (rel > 0) {
        const std::uint64_t at = base_ + static_cast<std::uint64_t>(rel);
        auto& slot = pending_[at];
        if (slot.size() < payload.size()) {
            buffered_ += payload.size() - slot.size();
            slot.assign(payload.begin(), payload.end());
        }
        if (buffered_ > max_buffered_) skip_to_first_buffered(t);  // the hole will not fill: give it up
        return;
    }
    data_(payload, t);
    *next_ += static_cast<std::uint32_t>(payload.size());
    base_ += payload.size();
    drain(t);
}

void TcpReassembler::drain(modbus::Timestamp t) {
    while (!pending_.empty()) {
        auto it = pending_.begin();
        if (it->first > base_) return;
        std::vector<std::uint8_t> bytes = std::move(it->second);
        const std::uint64_t at = it->first;
        buffered_ -= bytes.size();
        pending_.erase(it);
        const std::uint64_t skip = base_ - at;
        if (skip >= bytes.size()) {
            retransmitted_ += bytes.size();
            continue;
        }
        retransmitted_ += skip;
        std::span<const std::uint8_t> rest(bytes.data() + skip, bytes.size() - skip);
        data_(rest, t);
        *next_ += static_cast<std::uint32_t>(rest.size());
        base_ += rest.size();
    }
}

void TcpReassembler::skip_to_first_buffered(modbus::Timestamp t) {
    if (pending_.empty()) return;
    const std::uint64_t missing = pending_.begin()->first - base_;
    gap_(missing, t);
    *next_ += static_cast<std::uint32_t>(missing);
    base_ += missing;
    drain(t);
}

void TcpReassembler::flush(modbus::Timestamp t) {
    while (!pending_.empty())
        skip_to_first_buffered(t);
}

}  // namespace mbscope::analyzer
