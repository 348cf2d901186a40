#include "analyzer/pcapng_interfaces.hpp"

#include <pcap/dlt.h>

#include "analyzer/pcapng_format.hpp"

#include <algorithm>
#include <utility>

namespace mbscope::analyzer {

namespace {
using namespace pcapng;
constexpr std::uint8_t local_use_bit = 0x80;  // of a block type's most significant byte
constexpr std::uint32_t minimum_block = 12;   // type, total length, total length again
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
    const std::uint32_t type = u32(0);
    wanted_ =
        type == interface_description_block && length >= minimum_interface_block ? interface_header : seen_;
    if (type == simple_packet_block)
        packet_on(0);
    else if (keeping_ && (type == obsolete_packet_block || type == enhanced_packet_block))
        wanted_ = packet_header;  // every block is at least that long
}

// A packet block's interface known: hidden from libpcap when it is on an interface of another link type
// than the one kept. An interface the section has not described is left to libpcap to refuse.
void PcapngInterfacePatch::packet_on(std::uint32_t interface) noexcept {
    if (!keeping_ || interface >= interfaces_.size() || interfaces_[interface] == kept_) return;
    if (block_first_ != nullptr) block_first_[big_endian_ ? 0 : 3] |= local_use_bit;
}

// Both bytes of an interface's link type seen: LINKTYPE_RAW written as DLT_RAW, in the section's byte order;
// with keep_only, another of the file's link types written as the kept one.
void PcapngInterfacePatch::link_type(std::uint8_t& second) {
    const std::uint16_t first_byte = header_[link_type_at];
    const std::uint16_t second_byte = header_[link_type_at + 1];
    auto type = static_cast<std::uint16_t>(big_endian_ ? first_byte << 8 | second_byte
                                                       : second_byte << 8 | first_byte);
    if (type == linktype_raw) type = DLT_RAW;
    interfaces_.push_back(type);
    if (link_types_.size() < most_link_types &&
        std::find(link_types_.begin(), link_types_.end(), type) == link_types_.end())
        link_types_.push_back(type);
    std::uint16_t written = type;
    if (keeping_ && type != kept_ && std::find(known_.begin(), known_.end(), type) != known_.end())
        written = kept_;
    if (!first_written_)
        first_written_ = written;
    else if (written != *first_written_ && !refused_at_)
        refused_at_ = block_;
    const std::uint16_t as_found = big_endian_ ? std::uint16_t(first_byte << 8 | second_byte)
                                               : std::uint16_t(second_byte << 8 | first_byte);
    if (written == as_found || link_type_first_ == nullptr) return;
    *link_type_first_ = static_cast<std::uint8_t>(big_endian_ ? written >> 8 : written);
    second = static_cast<std::uint8_t>(big_endian_ ? written : written >> 8);
}

void PcapngInterfacePatch::keep_only(std::uint16_t kept, std::vector<std::uint16_t> known) {
    keeping_ = true;
    kept_ = kept;
    known_ = std::move(known);
}

std::size_t PcapngInterfacePatch::bytes_wanted() const noexcept {
    if (state_ != State::Blocks || seen_ == 0 || seen_ >= wanted_) return 0;
    if (wanted_ == interface_header) return seen_ == link_type_at + 1 ? 1 : 0;
    // A block's type is known from its first four bytes, a packet block's interface from its twelfth.
    if (keeping_ && (wanted_ == block_header || wanted_ == packet_header)) return packet_header - seen_;
    return 0;
}

void PcapngInterfacePatch::header_byte(std::uint8_t& byte) {
    header_[seen_] = byte;
    if (seen_ == 0) block_first_ = &byte;
    const std::uint8_t index = seen_++;
    if (state_ == State::Start) {
        if (seen_ == 4 && u32(0) != section_header_block)
            state_ = State::Off;  // classic pcap, or not a capture
        if (seen_ < block_header) return;
    }
    if (seen_ == block_header) {
        section_header_ = u32(0) == section_header_block;
        if (section_header_)
            wanted_ = section_header;  // its length is read in the byte order that follows it
        else
            begin_block();
        return;
    }
    if (seen_ == section_header && section_header_) {  // a new section: its byte order
        section_header_ = false;
        big_endian_ = false;
        if (u32(8) != byte_order_magic) big_endian_ = true;
        if (u32(8) != byte_order_magic) {
            state_ = State::Off;
            return;
        }
        interfaces_.clear();  // a section numbers its interfaces from 0
        begin_block();
        return;
    }
    if (wanted_ == packet_header) {
        if (seen_ == packet_header) {
            const bool obsolete = u32(0) == obsolete_packet_block;  // its 16-bit interface first
            packet_on(obsolete ? (big_endian_ ? u32(interface_at) >> 16 : u32(interface_at) & 0xFFFF)
                               : u32(interface_at));
        }
        return;
    }
    if (wanted_ != interface_header) return;
    // An interface block long enough to hold its link type and snapshot length.
    if (index == link_type_at) link_type_first_ = &byte;
    if (index == link_type_at + 1) link_type(byte);
    if (index >= snaplen_at) byte = 0;
}

void PcapngInterfacePatch::pass(std::span<std::uint8_t> bytes) {
    // A header's first bytes, passed before, are changed only if these bytes follow them in memory.
    if (bytes.data() != next_in_memory_) block_first_ = link_type_first_ = nullptr;
    next_in_memory_ = bytes.data() + bytes.size();
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
