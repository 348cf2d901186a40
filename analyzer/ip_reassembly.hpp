#pragma once
// IPv4 and IPv6 fragments put back together (RFC 791 §3.2, RFC 8200 §4.5), so that a Modbus ADU in a
// fragmented datagram (a small-MTU tunnel, a gateway's Modbus/UDP) is decoded rather than dropped. The first
// copy of a byte wins, as in the TCP reassembler. A datagram still missing fragments 30 s of capture time
// after its first one arrived (Linux's ipfrag_time), or when the capture ends, is given up and counted.
// Memory is bounded: at most max_datagrams in progress, the oldest given up first.

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <span>
#include <tuple>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

// One fragment as the IP header describes it.
struct IpFragment {
    std::array<std::uint8_t, 16> source{}, destination{};  // IPv4 in the first 4 bytes
    bool v6 = false;
    std::uint32_t id = 0;       // identification (16 bits in IPv4, 32 in IPv6)
    std::uint8_t protocol = 0;  // of the datagram: IPv4's protocol, the fragment header's next header
    std::uint32_t offset = 0;   // in bytes
    bool more = false;          // more fragments follow
    std::span<const std::uint8_t> data;
};

struct IpDatagram {
    std::array<std::uint8_t, 16> source{}, destination{};
    bool v6 = false;
    std::uint8_t protocol = 0;
    std::vector<std::uint8_t> bytes;  // the transport header and payload
};

class IpReassembler {
  public:
    static constexpr std::size_t max_datagrams = 1024;
    static constexpr modbus::Timestamp timeout = std::chrono::seconds(30);

    // The whole datagram when this fragment completes it.
    std::optional<IpDatagram> add(const IpFragment& fragment, modbus::Timestamp time);
    // Gives up what has waited longer than the timeout (everything when at_end).
    void expire(modbus::Timestamp now, bool at_end);

    // Datagrams given up, and the fragments and bytes they had: what the capture holds that was not decoded.
    std::uint64_t incomplete_datagrams() const noexcept { return incomplete_datagrams_; }
    std::uint64_t incomplete_fragments() const noexcept { return incomplete_fragments_; }
    // Fragments that claimed bytes past the largest IP datagram (65,535 bytes): hostile or corrupt.
    std::uint64_t invalid_fragments() const noexcept { return invalid_fragments_; }

  private:
    using Key = std::tuple<bool, std::array<std::uint8_t, 16>, std::array<std::uint8_t, 16>, std::uint32_t,
                           std::uint8_t>;
    struct Partial {
        std::vector<std::uint8_t> bytes;
        std::vector<bool> have;
        std::optional<std::size_t> total;  // known once the last fragment (more = false) is seen
        std::size_t held = 0;              // bytes present
        std::uint64_t fragments = 0;
        modbus::Timestamp first{0};
        std::uint64_t serial = 0;
    };
    void give_up(std::map<Key, Partial>::iterator it);

    std::map<Key, Partial> partials_;
    std::deque<std::pair<Key, std::uint64_t>> order_;  // arrival order of first fragments, for expiry
    std::uint64_t next_serial_ = 0;
    std::uint64_t incomplete_datagrams_ = 0, incomplete_fragments_ = 0, invalid_fragments_ = 0;
};

}  // namespace mbscope::analyzer
