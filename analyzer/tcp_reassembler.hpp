#pragma once
// One direction of a TCP connection, put back in order independently of segment boundaries: retransmitted
// and overlapping bytes are delivered once, out-of-order segments wait for the hole to fill, and a hole that
// never fills (lost in the capture) is delivered as a gap of known size so the deframer can resynchronise.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

class TcpReassembler {
  public:
    using DataFn = std::function<void(std::span<const std::uint8_t>, modbus::Timestamp)>;
    using GapFn = std::function<void(std::uint64_t missing, modbus::Timestamp)>;

    TcpReassembler(DataFn data, GapFn gap, std::size_t max_buffered = 1 << 20)
        : data_(std::move(data)), gap_(std::move(gap)), max_buffered_(max_buffered) {}

    void segment(std::uint32_t seq, bool syn, std::span<const std::uint8_t> payload, modbus::Timestamp t);
    // End of capture or connection: what is buffered beyond a hole is delivered after a gap.
    void flush(modbus::Timestamp t);
    std::uint64_t retransmitted_bytes() const noexcept { return retransmitted_; }

  private:
    void drain(modbus::Timestamp t);
    void skip_to_first_buffered(modbus::Timestamp t);

    DataFn data_;
    GapFn gap_;
    std::size_t max_buffered_;
    std::optional<std::uint32_t> next_;  // next expected sequence number
    std::map<std::uint64_t, std::vector<std::uint8_t>>
        pending_;             // keyed by offset from next_ at insert time (unwrapped)
    std::uint64_t base_ = 0;  // unwrapped stream position of next_
    std::size_t buffered_ = 0;
    std::uint64_t retransmitted_ = 0;
};

}  // namespace mbscope::analyzer
