#pragma once
// Modbus/TCP ADUs on ports nobody asked to decode: which server port to suggest (--tcp-port, --udp-port).
// A packet that repeats the transaction id the other side of its conversation sent last is a reply, and
// its source port is the server's; a conversation with no such evidence (one direction captured, or a
// client that uses one transaction id for everything) falls back to the lower port, since clients usually
// take theirs from the ephemeral range.
#include <array>
#include <cstdint>
#include <map>
#include <utility>

#include "analyzer/packet_parser.hpp"

namespace mbscope::analyzer {

class ModbusLikePorts {
  public:
    // A packet on no decoded port: counted when its payload is exactly one plausible Modbus/TCP ADU.
    void note(const L4Packet& l4);
    // Packets per (UDP?, server port), every conversation's packets under the port judged its server's.
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> tally() const;

  private:
    // The two endpoints of a conversation in a fixed order (the lesser first), and the transport.
    using Key = std::pair<std::array<std::uint8_t, 19>, std::array<std::uint8_t, 19>>;
    struct Conversation {
        bool udp = false;
        std::uint16_t port[2] = {0, 0};  // the first and second endpoint's ports
        std::uint64_t packets = 0;
        std::uint64_t replies_from[2] = {0, 0};
        std::int32_t last_tid[2] = {-1, -1};  // the transaction id each side sent last, -1 before any
    };
    // Past this many conversations a packet is counted under its lower port at once: the hint is not worth
    // unbounded memory on a capture of a whole plant network.
    static constexpr std::size_t max_conversations = 4096;

    std::map<Key, Conversation> conversations_;
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> overflow_;
};

}  // namespace mbscope::analyzer
