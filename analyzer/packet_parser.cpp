#include "analyzer/packet_parser.hpp"

#include <arpa/inet.h>

#include <cstdio>
#include <cstring>

namespace mbscope::analyzer {
namespace {

// libpcap link types (pcap/dlt.h values, kept here to keep the parser independent of libpcap). A file's
// LINKTYPE_RAW (101) reaches us as pcap_datalink()'s DLT_RAW: 12 on most systems, 14 on OpenBSD.
constexpr int link_null = 0, link_ethernet = 1, link_raw_dlt = 12, link_raw_dlt_openbsd = 14, link_raw = 101,
              link_loop = 108, link_sll = 113, link_ipv4 = 228, link_ipv6 = 229, link_sll2 = 276;

std::uint16_t be16(const std::uint8_t* p) {
    return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}
std::uint32_t be32(const std::uint8_t* p) {
    return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

// Tunnels a mirrored copy travels in, decoded down to the packet inside (the outer addresses are the
// tunnel's, not the conversation's): MPLS label stacks (utilities' and carriers' WANs), PPPoE sessions, GRE
// carrying IP or Ethernet (transparent Ethernet bridging, and ERSPAN types I, II and III, remote SPAN),
// VXLAN (UDP 4789), GENEVE (UDP 6081), IP in IP. A packet nests at most max_depth of them.
constexpr int max_depth = 8;
constexpr std::uint16_t vxlan_port = 4789, geneve_port = 6081;

ParseStatus parse_ip(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth);
ParseStatus parse_ethernet(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth);
ParseStatus parse_gre(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth);
ParseStatus by_ethertype(std::uint16_t type, std::span<const std::uint8_t> d, L4Packet& out,
                         IpFragment* fragment, int depth);

// The bytes an IP header counts past the capture's end are the TCP payload's last (a header they cut is
// Malformed): the innermost IP header that says so is the one that counts.
ParseStatus cut_after(ParseStatus status, std::size_t missing, L4Packet& out) noexcept {
    if (status == ParseStatus::Ok && out.transport == Transport::Tcp && missing && !out.payload_cut)
        out.payload_cut = static_cast<std::uint32_t>(missing);
    return status;
}

ParseStatus parse_l4(std::uint8_t protocol, std::span<const std::uint8_t> d, L4Packet& out,
                     IpFragment* fragment, int depth) {
    if (protocol == 47) return parse_gre(d, out, fragment, depth + 1);
    if (protocol == 4 || protocol == 41) return parse_ip(d, out, fragment, depth + 1);  // IPv4, IPv6 in IP
    if (protocol == 6) {
        if (d.size() < 20) return ParseStatus::Malformed;
        const std::size_t header = (d[12] >> 4) * 4u;
        if (header < 20 || header > d.size()) return ParseStatus::Malformed;
        out.transport = Transport::Tcp;
        out.source.port = be16(d.data());
        out.destination.port = be16(d.data() + 2);
        out.seq = be32(d.data() + 4);
        out.ack = be32(d.data() + 8);
        out.has_ack = d[13] & 0x10;
        out.fin = d[13] & 0x01;
        out.syn = d[13] & 0x02;
        out.rst = d[13] & 0x04;
        out.payload = d.subspan(header);
        return ParseStatus::Ok;
    }
    if (protocol == 17) {
        if (d.size() < 8) return ParseStatus::Malformed;
        out.transport = Transport::Udp;
        out.source.port = be16(d.data());
        out.destination.port = be16(d.data() + 2);
        const std::size_t length = be16(d.data() + 4);
        if (length < 8) return ParseStatus::Malformed;
        out.payload = d.subspan(8, std::min(d.size(), length) - 8);
        out.truncated |= length > d.size();
        // VXLAN: flags with the I bit (a valid network identifier), 3 reserved bytes, the identifier and a
        // reserved byte, then an Ethernet frame.
        if (out.destination.port == vxlan_port && out.payload.size() >= 8 && (out.payload[0] & 0x08))
            return parse_ethernet(out.payload.subspan(8), out, fragment, depth + 1);
        // GENEVE (RFC 8926): version 0, the options' length in 4-byte words, flags, the protocol (an
        // EtherType; 0x6558 for Ethernet), the network identifier, then the options.
        if (out.destination.port == geneve_port && out.payload.size() >= 8 && (out.payload[0] >> 6) == 0) {
            const std::size_t header = 8 + (out.payload[0] & 0x3Fu) * 4;
            if (header > out.payload.size()) return ParseStatus::Malformed;
            const std::uint16_t protocol = be16(out.payload.data() + 2);
            const auto inner = out.payload.subspan(header);
            if (protocol == 0x6558) return parse_ethernet(inner, out, fragment, depth + 1);
            return by_ethertype(protocol, inner, out, fragment, depth + 1);
        }
        return ParseStatus::Ok;
    }
    return ParseStatus::NotTcpUdp;
}

// IPv6 extension headers before the transport header: hop-by-hop (0), routing (43), destination options
// (60). `pos` moves past them; false when one runs past the packet.
bool skip_v6_extensions(std::span<const std::uint8_t> d, std::uint8_t& next, std::size_t& pos) {
    while (next == 0 || next == 43 || next == 60) {
        if (pos + 8 > d.size()) return false;
        next = d[pos];
        pos += (d[pos + 1] + 1u) * 8u;
    }
    return pos <= d.size();
}

ParseStatus parse_ip(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth) {
    if (depth > max_depth) return ParseStatus::Malformed;
    if (d.empty()) return ParseStatus::Malformed;
    const int version = d[0] >> 4;
    if (version == 4) {
        if (d.size() < 20) return ParseStatus::Malformed;
        const std::size_t header = (d[0] & 0x0F) * 4u;
        const std::size_t total = be16(d.data() + 2);
        if (header < 20 || header > d.size() || total < header) return ParseStatus::Malformed;
        out.source = Endpoint{};
        out.destination = Endpoint{};
        std::memcpy(out.source.address.data(), d.data() + 12, 4);
        std::memcpy(out.destination.address.data(), d.data() + 16, 4);
        out.truncated = total > d.size();
        const auto payload = d.subspan(header, std::min(d.size(), total) - header);
        if (const std::uint16_t flags = be16(d.data() + 6); (flags & 0x3FFF) != 0) {  // MF or offset set
            if (fragment)
                *fragment = IpFragment{.source = out.source.address,
                                       .destination = out.destination.address,
                                       .id = be16(d.data() + 4),
                                       .protocol = d[9],
                                       .offset = (flags & 0x1FFFu) * 8u,
                                       .more = (flags & 0x2000) != 0,
                                       .data = payload};
            return ParseStatus::Fragment;
        }
        return cut_after(parse_l4(d[9], payload, out, fragment, depth), total - header - payload.size(), out);
    }
    if (version == 6) {
        if (d.size() < 40) return ParseStatus::Malformed;
        out.source = Endpoint{};
        out.destination = Endpoint{};
        out.source.v6 = out.destination.v6 = true;
        std::memcpy(out.source.address.data(), d.data() + 8, 16);
        std::memcpy(out.destination.address.data(), d.data() + 24, 16);
        const std::size_t payload = be16(d.data() + 4);
        out.truncated = 40 + payload > d.size();
        std::uint8_t next = d[6];
        std::size_t pos = 40;
        if (!skip_v6_extensions(d, next, pos)) return ParseStatus::Malformed;
        const std::size_t end = std::min(d.size(), 40 + payload);
        if (pos > end) return ParseStatus::Malformed;
        if (next == 44) {  // fragment header: next header, reserved, offset and M flag, identification
            if (pos + 8 > end) return ParseStatus::Malformed;
            if (fragment)
                *fragment = IpFragment{.source = out.source.address,
                                       .destination = out.destination.address,
                                       .v6 = true,
                                       .id = be32(d.data() + pos + 4),
                                       .protocol = d[pos],
                                       .offset = be16(d.data() + pos + 2) & 0xFFF8u,
                                       .more = (d[pos + 3] & 0x01) != 0,
                                       .data = d.subspan(pos + 8, end - pos - 8)};
            return ParseStatus::Fragment;
        }
        return cut_after(parse_l4(next, d.subspan(pos, end - pos), out, fragment, depth), 40 + payload - end,
                         out);
    }
    return ParseStatus::NotIp;
}

// An MPLS label stack (4 bytes a label, the last with the bottom-of-stack bit), then what the first nibble
// says: IPv4 or IPv6, or 0, a pseudowire control word before an Ethernet frame (Ethernet over MPLS).
ParseStatus parse_mpls(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth) {
    std::size_t pos = 0;
    for (;;) {
        if (pos + 4 > d.size()) return ParseStatus::Malformed;
        const bool bottom = d[pos + 2] & 0x01;
        pos += 4;
        if (bottom) break;
    }
    if (pos >= d.size()) return ParseStatus::Malformed;
    const int nibble = d[pos] >> 4;
    if (nibble == 4 || nibble == 6) return parse_ip(d.subspan(pos), out, fragment, depth);
    if (nibble == 0 && pos + 4 <= d.size()) return parse_ethernet(d.subspan(pos + 4), out, fragment, depth);
    return ParseStatus::NotIp;
}

// A PPPoE session (RFC 2516): version and type, code, session id, length, then the PPP protocol number
// (IPv4 0x0021, IPv6 0x0057), as on DSL links to remote sites.
ParseStatus parse_pppoe(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth) {
    if (d.size() < 8) return ParseStatus::Malformed;
    const std::uint16_t protocol = be16(d.data() + 6);
    if (protocol == 0x0021 || protocol == 0x0057) return parse_ip(d.subspan(8), out, fragment, depth);
    return ParseStatus::NotIp;
}

ParseStatus by_ethertype(std::uint16_t type, std::span<const std::uint8_t> d, L4Packet& out,
                         IpFragment* fragment, int depth) {
    if (type == 0x0800 || type == 0x86DD) return parse_ip(d, out, fragment, depth);
    if (type == 0x8847 || type == 0x8848) return parse_mpls(d, out, fragment, depth + 1);
    if (type == 0x8864) return parse_pppoe(d, out, fragment, depth + 1);
    return ParseStatus::NotIp;
}

ParseStatus parse_ethernet(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth) {
    if (depth > max_depth) return ParseStatus::Malformed;
    if (d.size() < 14) return ParseStatus::Malformed;
    std::size_t pos = 12;
    std::uint16_t type = be16(d.data() + pos);
    while (type == 0x8100 || type == 0x88A8 || type == 0x9100) {  // VLAN tags, possibly stacked
        pos += 4;
        if (pos + 2 > d.size()) return ParseStatus::Malformed;
        type = be16(d.data() + pos);
    }
    return by_ethertype(type, d.subspan(pos + 2), out, fragment, depth);
}

// GRE (RFC 2784, 2890): flags and version, the protocol, then a checksum, key and sequence number when
// their flags say so. Version 1 is PPTP's, which carries PPP, not mirrored frames.
ParseStatus parse_gre(std::span<const std::uint8_t> d, L4Packet& out, IpFragment* fragment, int depth) {
    if (depth > max_depth) return ParseStatus::Malformed;
    if (d.size() < 4) return ParseStatus::Malformed;
    const std::uint16_t flags = be16(d.data());
    if ((flags & 0x0007) != 0 || (flags & 0x4000)) return ParseStatus::NotIp;  // version 1, source routes
    const std::uint16_t protocol = be16(d.data() + 2);
    const bool sequenced = flags & 0x1000;
    std::size_t pos = 4 + ((flags & 0x8000) ? 4u : 0u) + ((flags & 0x2000) ? 4u : 0u) + (sequenced ? 4u : 0u);
    if (pos > d.size()) return ParseStatus::Malformed;
    switch (protocol) {
        case 0x0800:
        case 0x86DD:
            return parse_ip(d.subspan(pos), out, fragment, depth);
        case 0x6558:  // transparent Ethernet bridging
            return parse_ethernet(d.subspan(pos), out, fragment, depth);
        case 0x88BE:  // ERSPAN: type II has a sequence number and an 8-byte header, type I neither
            if (sequenced) pos += 8;
            break;
        case 0x22EB:  // ERSPAN type III: a 12-byte header, and a platform subheader when the O flag says so
            if (pos + 12 > d.size()) return ParseStatus::Malformed;
            pos += (d[pos + 11] & 0x01) ? 20 : 12;
            break;
        default:
            return ParseStatus::NotIp;
    }
    if (pos > d.size()) return ParseStatus::Malformed;
    return parse_ethernet(d.subspan(pos), out, fragment, depth);
}

}  // namespace

std::string Endpoint::to_string() const {
    char buf[64];
    if (!v6) {
        std::snprintf(buf, sizeof buf, "%u.%u.%u.%u:%u", address[0], address[1], address[2], address[3],
                      port);
        return buf;
    }
    // RFC 5952's text (zeros compressed, as tshark and every tool print it): `--map` takes it as printed.
    char text[INET6_ADDRSTRLEN];
    if (!::inet_ntop(AF_INET6, address.data(), text, sizeof text)) return "[?]:" + std::to_string(port);
    return "[" + std::string(text) + "]:" + std::to_string(port);
}

ParseStatus parse_datagram(const IpDatagram& datagram, L4Packet& out) noexcept {
    out = L4Packet{};
    out.source.address = datagram.source;
    out.destination.address = datagram.destination;
    out.source.v6 = out.destination.v6 = datagram.v6;
    const std::span<const std::uint8_t> d(datagram.bytes);
    std::uint8_t next = datagram.protocol;
    std::size_t pos = 0;
    if (datagram.v6 && !skip_v6_extensions(d, next, pos)) return ParseStatus::Malformed;
    return parse_l4(next, d.subspan(pos), out, nullptr, 0);
}

ParseStatus parse_packet(int linktype, std::span<const std::uint8_t> d, L4Packet& out,
                         IpFragment* fragment) noexcept {
    switch (linktype) {
        case link_ethernet:
            return parse_ethernet(d, out, fragment, 0);
        case link_sll:
            if (d.size() < 16) return ParseStatus::Malformed;
            return by_ethertype(be16(d.data() + 14), d.subspan(16), out, fragment, 0);
        case link_sll2:
            if (d.size() < 20) return ParseStatus::Malformed;
            return by_ethertype(be16(d.data()), d.subspan(20), out, fragment, 0);
        case link_raw_dlt:
        case link_raw_dlt_openbsd:
        case link_raw:
        case link_ipv4:
        case link_ipv6:
            return parse_ip(d, out, fragment, 0);
        case link_null:
        case link_loop:
            if (d.size() < 4) return ParseStatus::Malformed;
            // the family word's byte order varies; the IP version decides
            return parse_ip(d.subspan(4), out, fragment, 0);
        default:
            return ParseStatus::UnsupportedLink;
    }
}

}  // namespace mbscope::analyzer
