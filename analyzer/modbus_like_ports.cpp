#include "analyzer/modbus_like_ports.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/function_code.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::analyzer {
namespace {

std::array<std::uint8_t, 19> endpoint_key(const Endpoint& e) {
    std::array<std::uint8_t, 19> k{};
    std::copy(e.address.begin(), e.address.end(), k.begin());
    k[16] = e.v6 ? 1 : 0;
    k[17] = static_cast<std::uint8_t>(e.port >> 8);
    k[18] = static_cast<std::uint8_t>(e.port);
    return k;
}

bool whole_mbap_adu(std::span<const std::uint8_t> p) {
    if (p.size() < 8 || p[2] != 0 || p[3] != 0) return false;
    const std::size_t length = (std::size_t{p[4]} << 8) | p[5];
    return length >= 2 && length <= 254 && p.size() == 6 + length && modbus::is_public_function(p[7] & 0x7F);
}

// Whether the payload is one RTU ADU with a valid CRC whose length a request's content predicts (bit 0) or a
// response's (bit 1): the lengths the RTU deframer predicts, without the deframer's search for a frame. (The
// CRC last: every packet on a port not decoded comes here.)
unsigned whole_rtu_adu(std::span<const std::uint8_t> p) {
    if (p.size() < 4 || p.size() > modbus::max_rtu_adu_length) return 0;
    unsigned fits = 0;
    for (const auto d : {modbus::Direction::Request, modbus::Direction::Response}) {
        const auto predicted = modbus::predict_pdu_length(p.subspan(1, p.size() - 3), d);
        if (predicted.kind == modbus::LengthPrediction::Kind::Known && predicted.length + 3 == p.size())
            fits |= d == modbus::Direction::Request ? 1u : 2u;
    }
    return fits != 0 && modbus::rtu_crc_ok(p) ? fits : 0;
}

}  // namespace

void ModbusLikePorts::note(const L4Packet& l4) {
    const auto p = l4.payload;
    const bool mbap = whole_mbap_adu(p);
    const unsigned rtu = whole_rtu_adu(p);
    const bool udp = l4.transport == Transport::Udp;
    auto source = endpoint_key(l4.source), destination = endpoint_key(l4.destination);
    const bool source_first = source < destination;
    const Key key = source_first ? Key{source, destination} : Key{destination, source};
    auto it = conversations_.find(key);
    if (!mbap && !rtu) {
        // Other data ends a run of RTU frames; an acknowledgement without data says nothing.
        if (it != conversations_.end() && !p.empty()) it->second.rtu_run = 0;
        return;
    }
    if (it == conversations_.end()) {
        if (conversations_.size() >= max_conversations) {
            // Past the bound an RTU frame is no hint: a run of them needs its conversation.
            if (mbap) ++overflow_[{udp, std::min(l4.source.port, l4.destination.port)}];
            return;
        }
        Conversation c;
        c.udp = udp;
        c.port[0] = source_first ? l4.source.port : l4.destination.port;
        c.port[1] = source_first ? l4.destination.port : l4.source.port;
        it = conversations_.emplace(key, c).first;
    }
    Conversation& c = it->second;
    const int from = source_first ? 0 : 1;
    if (rtu) {
        ++c.rtu_packets;
        c.also_mbap += mbap;
        c.longest_rtu_run = std::max(c.longest_rtu_run, ++c.rtu_run);
        if (rtu == 1) ++c.rtu_requests_to[1 - from];
        if (rtu == 2) ++c.rtu_responses_from[from];
    } else {
        c.rtu_run = 0;
    }
    if (!mbap) return;
    const std::int32_t tid = (std::int32_t{p[0]} << 8) | p[1];
    ++c.packets;
    if (c.last_tid[1 - from] == tid) ++c.replies_from[from];
    c.last_tid[from] = tid;
}

std::uint16_t ModbusLikePorts::server_port(const Conversation& c) {
    std::uint16_t server = std::min(c.port[0], c.port[1]);
    if (c.rtu()) {
        const std::uint64_t side0 = c.rtu_requests_to[0] + c.rtu_responses_from[0];
        const std::uint64_t side1 = c.rtu_requests_to[1] + c.rtu_responses_from[1];
        if (side0 != side1) server = side0 > side1 ? c.port[0] : c.port[1];
    } else if (c.replies_from[0] != c.replies_from[1]) {
        server = c.replies_from[0] > c.replies_from[1] ? c.port[0] : c.port[1];
    }
    return server;
}

std::map<std::pair<bool, std::uint16_t>, std::uint64_t> ModbusLikePorts::tally() const {
    auto ports = overflow_;
    for (const auto& [key, c] : conversations_) {
        // An RTU conversation's MBAP-shaped packets are its RTU frames read the wrong way; others, if any,
        // still count.
        const std::uint64_t packets = c.rtu() ? c.packets - c.also_mbap : c.packets;
        if (packets) ports[{c.udp, server_port(c)}] += packets;
    }
    return ports;
}

std::map<std::pair<bool, std::uint16_t>, std::uint64_t> ModbusLikePorts::rtu_tally() const {
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> ports;
    for (const auto& [key, c] : conversations_)
        if (c.rtu()) ports[{c.udp, server_port(c)}] += c.rtu_packets;
    return ports;
}

}  // namespace mbscope::analyzer
