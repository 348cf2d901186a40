#pragma once
// Modbus/TCP ADUs on ports nobody asked to decode: which server port to suggest (--tcp-port, --udp-port).
// A packet that repeats the transaction id the other side of its conversation sent last is a reply, and
// its source port is the server's; a conversation with no such evidence (one direction captured, or a
// client that uses one transaction id for everything) falls back to the lower port, since clients usually
// take theirs from the ephemeral range.
// A serial gateway in transparent mode sends raw RTU frames instead: a conversation whose packets held three
// or more whole RTU ADUs with valid CRCs in a row is told apart, and its port suggested for --rtu-over-tcp.
// Its requests may parse as MBAP ADUs as well (01 03 00 00 00 02 C4 0B: length 2, unit 196, FC11), which
// then are no evidence of Modbus/TCP. Three in a row, as for a decoded port's connections
// (rtu_over_tcp_probe.hpp): a payload of other traffic is one RTU ADU with a valid CRC by chance with
// probability 2^-16 at most, so three in a row about 2^-48.
#include <array>
#include <cstdint>
#include <map>
#include <utility>

#include "analyzer/packet_parser.hpp"

namespace mbscope::analyzer {

class ModbusLikePorts {
  public:
    // A packet on no decoded port: counted when its payload is exactly one plausible Modbus/TCP ADU, or one
    // RTU ADU with a valid CRC.
    void note(const L4Packet& l4);
    // Packets per (UDP?, server port), every conversation's packets under the port judged its server's:
    // Modbus/TCP ADUs, of conversations not found to carry RTU.
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> tally() const;
    // The same for the conversations that carried RTU frames (three in a row or more): their RTU packets.
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> rtu_tally() const;

  private:
    // The two endpoints of a conversation in a fixed order (the lesser first), and the transport.
    using Key = std::pair<std::array<std::uint8_t, 19>, std::array<std::uint8_t, 19>>;
    struct Conversation {
        bool udp = false;
        std::uint16_t port[2] = {0, 0};  // the first and second endpoint's ports
        std::uint64_t packets = 0;
        std::uint64_t replies_from[2] = {0, 0};
        std::int32_t last_tid[2] = {-1, -1};  // the transaction id each side sent last, -1 before any
        // RTU: packets holding one RTU ADU with a valid CRC, the run of them going on (a packet with other
        // data ends it) and the longest; and per side, those whose length only a request's (0) or only a
        // response's (1) content predicts, which tell the server (the request's receiver).
        std::uint64_t rtu_packets = 0, also_mbap = 0;
        std::uint32_t rtu_run = 0, longest_rtu_run = 0;
        std::uint64_t rtu_requests_to[2] = {0, 0}, rtu_responses_from[2] = {0, 0};
        bool rtu() const { return longest_rtu_run >= 3; }
    };
    // The server port of a conversation: the side the evidence names, else the lower port.
    static std::uint16_t server_port(const Conversation& c);
    // Past this many conversations a packet is counted under its lower port at once: the hint is not worth
    // unbounded memory on a capture of a whole plant network.
    static constexpr std::size_t max_conversations = 4096;

    std::map<Key, Conversation> conversations_;
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> overflow_;
};

}  // namespace mbscope::analyzer
