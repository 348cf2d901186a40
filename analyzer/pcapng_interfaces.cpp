#include "analyzer/pcapng_interfaces.hpp"

#include <pcap/dlt.h>

#include <algorithm>

namespace mbscope::analyzer {

namespace {
constexpr std::uint32_t section_header_block = 0x0A0D0D0A;  // the same read either way round
constexpr std::uint32_t interface_description_block = 1;
constexpr std::uint32_t byte_order_magic = 0x1A2B3C4D;
constexpr std::uint32_t minimum_block = 12;  // type, total length, total length again
constexpr std::uint32_t minimum_interface_block = 20;
constexpr std::uint16_t linktype_raw = 101;  // pcapng's (and classic pcap's) raw IP
}  // namespace

std::uint32_t PcapngInterfacePatch::u32(std::size_t at) const noexcept {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i)
        v |= static_cast<std::uint32_t>(header_[at + i]) << (big_endian_ ? 8 * (3 - i) : 8 * i);
    return v;
}

// Type and total length known (and a section's byte order): where the block ends, and how much more of its
// header is wanted.
void PcapngInterfacePatch::begin_block() noexcept {
    const std::uint32_t length = u32(4);
    if (length < minimum_block || length % 4 != 0) {
        state_ = State::Off;
        return;
    }
    state_ = State::Blocks;
    end_ = block_ + length;
    wanted_ =
        u32(0) == interface_description_block && length >= minimum_interface_block ? interface_header : seen_;
}

// Both bytes of an interface's link type seen: LINKTYPE_RAW written as DLT_RAW, in the section's byte order.
void PcapngInterfacePatch::link_type(std::uint8_t& second) noexcept {
    const std::uint16_t first_byte = header_[link_type_at];
    const std::uint16_t second_byte = header_[link_type_at + 1];
    const auto type = static_cast<std::uint16_t>(big_endian_ ? first_byte << 8 | second_byte
                                                             : second_byte << 8 | first_byte);
    if (type != linktype_raw || link_type_first_ == nullptr) return;
    constexpr std::uint16_t dlt = DLT_RAW;
    *link_type_first_ = static_cast<std::uint8_t>(big_endian_ ? dlt >> 8 : dlt);
    second = static_cast<std::uint8_t>(big_endian_ ? dlt : dlt >> 8);
}

void PcapngInterfacePatch::header_byte(std::uint8_t& byte) noexcept {
    header_[seen_] = byte;
    const std::uint8_t index = seen_++;
    if (state_ == State::Start) {
        if (seen_ == 4 && u32(0) != section_header_block)
            state_ = State::Off;  // classic pcap, or not a capture
        if (seen_ < block_header) return;
    }
    if (seen_ == block_header) {
        if (u32(0) == section_header_block)
            wanted_ = section_header;  // its length is read in the byte order that follows it
        else
            begin_block();
        return;
    }
    if (seen_ == section_header && wanted_ == section_header) {  // a new section: its byte order
        big_endian_ = false;
        if (u32(8) != byte_order_magic) big_endian_ = true;
        if (u32(8) != byte_order_magic) {
            state_ = State::Off;
            return;
        }
        begin_block();
        return;
    }
    if (wanted_ != interface_header) return;
    // An interface block long enough to hold its link type and snapshot length.
    if (index == link_type_at) link_type_first_ = &byte;
    if (index == link_type_at + 1) link_type(byte);
    if (index >= snaplen_at) byte = 0;
}

void PcapngInterfacePatch::pass(std::span<std::uint8_t> bytes) noexcept {
    // A link type's first byte passed last time is changed only if these bytes follow it in memory.
    if (wants_next_byte() && bytes.data() != link_type_first_ + 1) link_type_first_ = nullptr;
    std::size_t i = 0;
    while (i < bytes.size() && state_ != State::Off) {
        const std::uint64_t at = position_ + i;
        if (seen_ < wanted_) {
            header_byte(bytes[i]);
            ++i;
            continue;
        }
        if (at < end_) {  // the rest of the block: nothing to change
            i += static_cast<std::size_t>(std::min<std::uint64_t>(end_ - at, bytes.size() - i));
            continue;
        }
        block_ = end_;  // the next block's header starts here
        seen_ = 0;
        wanted_ = block_header;
    }
    position_ += bytes.size();
}

}  // namespace mbscope::analyzer
