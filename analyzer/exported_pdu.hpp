#pragma once
// Wireshark's exported PDUs (link type 252, LINKTYPE_WIRESHARK_UPPER_PDU): what "File > Export PDUs" and
// `text2pcap -P DISSECTOR` write. Each record is a list of tags, then the PDU itself:
//
//   +----------+----------+---------------+   ...   +----------+----------+----------------+
//   | type (2) | len (2)  | value (len)   |         | 0 (2)    | 0 (2)    | PDU bytes      |
//   +----------+----------+---------------+   ...   +----------+----------+----------------+
//   big-endian; type 12 names the dissector ("mbrtu", "mbtcp"), 20/21 IPv4 and 22/23 IPv6 source and
//   destination, 25/26 source and destination port (4 bytes). Wireshark pads values to 4 bytes and counts
//   the padding in len; text2pcap does not pad. Either way len says where the next tag starts.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "analyzer/packet_parser.hpp"

namespace mbscope::analyzer {

struct ExportedPdu {
    std::string_view dissector;                   // trailing NUL padding removed
    std::optional<Endpoint> source, destination;  // only when the record has both address and port
    std::span<const std::uint8_t> pdu;
};

// nullopt when a tag runs past the record or the end-of-options tag is missing.
std::optional<ExportedPdu> parse_exported_pdu(std::span<const std::uint8_t> record) noexcept;

}  // namespace mbscope::analyzer
