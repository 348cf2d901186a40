#include "analyzer/pcapng_snaplen.hpp"

#include <algorithm>

namespace mbscope::analyzer {

namespace {
constexpr std::uint32_t section_header_block = 0x0A0D0D0A;  // the same read either way round
constexpr std::uint32_t interface_description_block = 1;
constexpr std::uint32_t byte_order_magic = 0x1A2B3C4D;
constexpr std::uint32_t minimum_block = 12;  // type, total length, total length again
constexpr std::uint32_t minimum_interface_block = 20;
}  // namespace

std::uint32_t PcapngSnaplenPatch::u32(std::size_t at) const noexcept {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i)
        v |= static_cast<std::uint32_t>(header_[at + i]) << (big_endian_ ? 8 * (3 - i) : 8 * i);
    return v;
}

void PcapngSnaplenPatch::header_byte(std::uint8_t& byte) noexcept {
    header_[seen_] = byte;
    // Bytes 12-15 are wanted only of an interface block long enough to hold them: its snapshot length.
    if (seen_ >= 12) byte = 0;
    ++seen_;
    if (seen_ == 4 && state_ == State::Start) {
        if (u32(0) != section_header_block) state_ = State::Off;  // classic pcap, or not a capture
        return;
    }
    if (seen_ != 12) return;
    const std::uint32_t type = u32(0);
    if (type == section_header_block) {  // a new section: its byte order
        big_endian_ = false;
        if (u32(8) != byte_order_magic) big_endian_ = true;
        if (u32(8) != byte_order_magic) {
            state_ = State::Off;
            return;
        }
    }
    const std::uint32_t length = u32(4);
    if (length < minimum_block || length % 4 != 0) {
        state_ = State::Off;
        return;
    }
    state_ = State::Blocks;
    end_ = block_ + length;
    wanted_ = type == interface_description_block && length >= minimum_interface_block ? 16 : 12;
}

void PcapngSnaplenPatch::pass(std::span<std::uint8_t> bytes) noexcept {
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
        wanted_ = 12;
    }
    position_ += bytes.size();
}

}  // namespace mbscope::analyzer
