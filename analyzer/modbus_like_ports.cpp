#include "analyzer/modbus_like_ports.hpp"

#include <algorithm>

#include "modbus/function_code.hpp"

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

}  // namespace

void ModbusLikePorts::note(const L4Packet& l4) {
    const auto p = l4.payload;
    if (p.size() < 8 || p[2] != 0 || p[3] != 0) return;
    const std::size_t length = (std::size_t{p[4]} << 8) | p[5];
    if (length < 2 || length > 254 || p.size() != 6 + length || !modbus::is_public_function(p[7] & 0x7F))
        return;
    const bool udp = l4.transport == Transport::Udp;
    auto source = endpoint_key(l4.source), destination = endpoint_key(l4.destination);
    const bool source_first = source < destination;
    const Key key = source_first ? Key{source, destination} : Key{destination, source};
    auto it = conversations_.find(key);
    if (it == conversations_.end()) {
        if (conversations_.size() >= max_conversations) {
            ++overflow_[{udp, std::min(l4.source.port, l4.destination.port)}];
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
    const std::int32_t tid = (std::int32_t{p[0]} << 8) | p[1];
    ++c.packets;
    if (c.last_tid[1 - from] == tid) ++c.replies_from[from];
    c.last_tid[from] = tid;
}

std::map<std::pair<bool, std::uint16_t>, std::uint64_t> ModbusLikePorts::tally() const {
    auto ports = overflow_;
    for (const auto& [key, c] : conversations_) {
        std::uint16_t server = std::min(c.port[0], c.port[1]);
        if (c.replies_from[0] != c.replies_from[1])
            server = c.replies_from[0] > c.replies_from[1] ? c.port[0] : c.port[1];
        ports[{c.udp, server}] += c.packets;
    }
    return ports;
}

}  // namespace mbscope::analyzer
