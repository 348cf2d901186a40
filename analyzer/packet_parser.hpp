#pragma once
// Link, network and transport layers of a captured packet, down to the TCP or UDP payload. Link types:
// Ethernet (with 802.1Q / 802.1ad tags), Linux cooked v1 and v2, raw IPv4/IPv6, BSD null/loopback; inside
// MPLS, PPPoE, GRE (IP, Ethernet, ERSPAN I-III), VXLAN, GENEVE and IP-in-IP tunnels, to the packet they
// carry.
// Parsing never reads outside the packet; a packet it cannot follow says why.

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "analyzer/ip_reassembly.hpp"

namespace mbscope::analyzer {

// Link types that carry no IP (pcap/dlt.h values): the analyzer takes them before parse_packet.
inline constexpr int link_user0 = 147, link_user15 = 162;  // private use: serial bytes, if the user says so
inline constexpr int link_rtac_serial = 250;               // SEL RTAC serial records (rtac_serial.hpp)
inline constexpr int link_upper_pdu = 252;                 // Wireshark exported PDUs (exported_pdu.hpp)

struct Endpoint {
    std::array<std::uint8_t, 16> address{};  // IPv4 in the first 4 bytes
    bool v6 = false;
    std::uint16_t port = 0;
    bool operator==(const Endpoint&) const = default;
    std::string to_string() const;
};

enum class Transport : std::uint8_t { Tcp, Udp };

struct L4Packet {
    Transport transport = Transport::Tcp;
    Endpoint source;
    Endpoint destination;
    std::uint32_t seq = 0;  // TCP only
    std::uint32_t ack = 0;  // TCP only, when has_ack
    bool syn = false, fin = false, rst = false, has_ack = false;
    std::span<const std::uint8_t> payload;
    bool truncated = false;  // the capture holds less than the IP header says (snap length)
    // TCP: the bytes at the end of the payload that the IP header counts and the capture does not hold
    // (the record cut to the snapshot length).
    std::uint32_t payload_cut = 0;
};

enum class ParseStatus : std::uint8_t { Ok, UnsupportedLink, NotIp, NotTcpUdp, Fragment, Malformed };

// A fragment of an IP datagram is ParseStatus::Fragment; with `fragment` given, it is described there for
// IpReassembler (its data pointing into `data`).
ParseStatus parse_packet(int linktype, std::span<const std::uint8_t> data, L4Packet& out,
                         IpFragment* fragment = nullptr) noexcept;
// The transport layer of a reassembled datagram (its payload pointing into `datagram`).
ParseStatus parse_datagram(const IpDatagram& datagram, L4Packet& out) noexcept;

}  // namespace mbscope::analyzer
