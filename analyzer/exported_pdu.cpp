#include "analyzer/exported_pdu.hpp"

#include <algorithm>

namespace mbscope::analyzer {
namespace {

// Tag types, epan/exported_pdu.h
constexpr std::uint16_t tag_end_of_options = 0, tag_dissector_name = 12, tag_ipv4_source = 20,
                        tag_ipv4_destination = 21, tag_ipv6_source = 22, tag_ipv6_destination = 23,
                        tag_source_port = 25, tag_destination_port = 26;

std::uint16_t be16(const std::uint8_t* p) noexcept {
    return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}

struct Address {
    std::optional<Endpoint> endpoint;  // address seen; port filled in when its tag comes
    bool port = false;
};

void set_address(Address& a, std::span<const std::uint8_t> value, bool v6) noexcept {
    if (value.size() < (v6 ? 16u : 4u)) return;
    if (!a.endpoint) a.endpoint = Endpoint{};
    a.endpoint->v6 = v6;
    std::copy_n(value.begin(), v6 ? 16 : 4, a.endpoint->address.begin());
}

void set_port(Address& a, std::span<const std::uint8_t> value) noexcept {
    if (value.size() < 4) return;  // a 32-bit value holding a 16-bit port
    if (!a.endpoint) a.endpoint = Endpoint{};
    a.endpoint->port = be16(value.data() + 2);
    a.port = true;
}

}  // namespace

std::optional<ExportedPdu> parse_exported_pdu(std::span<const std::uint8_t> record) noexcept {
    ExportedPdu out;
    Address source, destination;
    bool source_address = false, destination_address = false;
    std::size_t pos = 0;
    for (;;) {
        if (record.size() - pos < 4) return std::nullopt;
        const std::uint16_t type = be16(record.data() + pos), length = be16(record.data() + pos + 2);
        pos += 4;
        if (type == tag_end_of_options) break;
        if (record.size() - pos < length) return std::nullopt;
        const auto value = record.subspan(pos, length);
        pos += length;
        switch (type) {
            case tag_dissector_name: {
                std::string_view name(reinterpret_cast<const char*>(value.data()), value.size());
                out.dissector = name.substr(0, name.find('\0'));
                break;
            }
            case tag_ipv4_source:
            case tag_ipv6_source:
                set_address(source, value, type == tag_ipv6_source);
                source_address = true;
                break;
            case tag_ipv4_destination:
            case tag_ipv6_destination:
                set_address(destination, value, type == tag_ipv6_destination);
                destination_address = true;
                break;
            case tag_source_port:
                set_port(source, value);
                break;
            case tag_destination_port:
                set_port(destination, value);
                break;
            default:
                break;  // tags that say nothing about Modbus
        }
    }
    if (source_address && destination_address && source.port && destination.port) {
        out.source = source.endpoint;
        out.destination = destination.endpoint;
    }
    out.pdu = record.subspan(pos);
    return out;
}

}  // namespace mbscope::analyzer
