#pragma once
// The numbers of the pcapng format (draft-ietf-opsawg-pcapng) that mbscope reads and writes: block types,
// the byte-order magic, option codes. One place for the reader of interfaces (pcapng_interfaces.cpp), the
// reader of a capture's end (pcapng_end.cpp) and the writer (pcapng_writer.cpp).

#include <cstdint>

namespace mbscope::analyzer::pcapng {

inline constexpr std::uint32_t section_header_block = 0x0A0D0D0A;  // the same read either way round
inline constexpr std::uint32_t interface_description_block = 1;
inline constexpr std::uint32_t obsolete_packet_block = 2;  // its interface in 16 bits
inline constexpr std::uint32_t simple_packet_block = 3;    // on interface 0
inline constexpr std::uint32_t interface_statistics_block = 5;
inline constexpr std::uint32_t enhanced_packet_block = 6;
inline constexpr std::uint32_t byte_order_magic = 0x1A2B3C4D;

inline constexpr std::uint16_t shb_userappl = 4;
inline constexpr std::uint16_t if_name = 2, if_tsresol = 9, if_tsoffset = 14;
inline constexpr std::uint16_t isb_endtime = 3, isb_ifdrop = 5, isb_osdrop = 7;

}  // namespace mbscope::analyzer::pcapng
