#include "analyzer/pcapng_end.hpp"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <vector>

#include "analyzer/pcapng_format.hpp"

namespace mbscope::analyzer {

namespace {

using namespace pcapng;
constexpr std::uint32_t largest_block_read = 1 << 20;  // interface and statistics blocks are small
constexpr int blocks_walked = 4096;                    // interfaces at the start, statistics at the end

class Reader {
  public:
    explicit Reader(const std::string& path) : in_(path, std::ios::binary) {
        if (in_) {
            in_.seekg(0, std::ios::end);
            size_ = static_cast<std::uint64_t>(in_.tellg());
        }
    }
    std::uint64_t size() const { return size_; }
    bool read(std::uint64_t at, std::size_t n, std::vector<std::uint8_t>& out) {
        if (!in_ || at > size_ || n > size_ - at) return false;
        out.resize(n);
        in_.seekg(static_cast<std::streamoff>(at));
        return static_cast<bool>(
            in_.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(n)));
    }

  private:
    std::ifstream in_;
    std::uint64_t size_ = 0;
};

struct Section {
    bool big_endian = false;
    std::uint32_t u32(const std::vector<std::uint8_t>& b, std::size_t at) const {
        std::uint32_t v = 0;
        for (int i = 0; i < 4; ++i)
            v |= std::uint32_t{b[at + static_cast<std::size_t>(big_endian ? 3 - i : i)]} << (8 * i);
        return v;
    }
    std::uint16_t u16(const std::vector<std::uint8_t>& b, std::size_t at) const {
        return static_cast<std::uint16_t>(big_endian ? b[at] << 8 | b[at + 1] : b[at] | b[at + 1] << 8);
    }
};

// Each option of a block whose options start at `from` and end before its trailing length.
template <typename F>
void each_option(const Section& s, const std::vector<std::uint8_t>& block, std::size_t from, F f) {
    const std::size_t end = block.size() - 4;
    for (std::size_t at = from; at + 4 <= end;) {
        const std::uint16_t code = s.u16(block, at), length = s.u16(block, at + 2);
        if (code == 0 || at + 4 + length > end) return;
        f(code, at + 4, length);
        at += 4 + ((length + 3u) & ~3u);
    }
}

// Ticks of 10^-v s (or 2^-v s with the high bit set) in nanoseconds; nullopt past what a Timestamp holds.
std::optional<modbus::Timestamp> in_nanoseconds(std::uint64_t ticks, std::uint8_t resolution) {
    constexpr auto most = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
    const unsigned v = resolution & 0x7F;
    if (resolution & 0x80) {
        const long double ns = std::ldexp(static_cast<long double>(ticks) * 1e9L, -static_cast<int>(v));
        if (!(ns < static_cast<long double>(most))) return std::nullopt;
        return modbus::Timestamp(static_cast<std::int64_t>(ns));
    }
    if (v > 28) return std::nullopt;
    std::uint64_t scale = 1;
    for (unsigned i = 0; i < (v > 9 ? v - 9 : 9 - v); ++i)
        scale *= 10;  // at most 10^19
    if (v > 9) return modbus::Timestamp(static_cast<std::int64_t>(ticks / scale));
    if (ticks > most / scale) return std::nullopt;
    return modbus::Timestamp(static_cast<std::int64_t>(ticks * scale));
}

}  // namespace

std::optional<modbus::Timestamp> pcapng_capture_end(const std::string& path, modbus::Timestamp last_packet,
                                                    std::uint64_t* dropped) {
    Reader file(path);
    std::vector<std::uint8_t> b;
    if (!file.read(0, 12, b)) return std::nullopt;
    Section s;
    s.big_endian = s.u32(b, 8) != byte_order_magic;
    if (s.u32(b, 0) != section_header_block || s.u32(b, 8) != byte_order_magic) return std::nullopt;
    // The interfaces' resolutions and offsets, from the blocks before the first packet (where writers put
    // them).
    struct Interface {
        std::uint8_t resolution = 6;  // microseconds unless told
        std::int64_t offset_s = 0;    // if_tsoffset: seconds added to every time of the interface
    };
    std::vector<Interface> interfaces;
    std::uint64_t at = 0;
    for (int n = 0; n < blocks_walked && file.read(at, 8, b); ++n) {
        const std::uint32_t type = s.u32(b, 0), length = s.u32(b, 4);
        if (length < 12 || length % 4 || length > file.size() - at) return std::nullopt;
        if (type == section_header_block && at != 0) break;  // another section: its interfaces are others
        if (type != section_header_block && type != interface_description_block) break;
        if (type == interface_description_block) {
            if (length > largest_block_read || !file.read(at, length, b) || length < 20) return std::nullopt;
            Interface i;
            each_option(s, b, 16, [&](std::uint16_t code, std::size_t value, std::uint16_t size) {
                if (code == if_tsresol && size == 1) i.resolution = b[value];
                if (code == if_tsoffset && size == 8)
                    i.offset_s = static_cast<std::int64_t>(
                        s.big_endian ? std::uint64_t{s.u32(b, value)} << 32 | s.u32(b, value + 4)
                                     : std::uint64_t{s.u32(b, value + 4)} << 32 | s.u32(b, value));
            });
            interfaces.push_back(i);
        }
        at += length;
    }
    if (interfaces.empty()) return std::nullopt;
    // An end is taken only where it can be one: not before the last packet, and within a day of it. Outside,
    // the file says something else than its end (a resolution or offset misread, a section concatenated
    // after the first with interfaces of its own) and the capture ends as before, at its last packet.
    const auto plausible = [&](std::optional<modbus::Timestamp> t) {
        return t && *t >= last_packet && *t - last_packet <= std::chrono::hours(24);
    };
    const auto at_offset = [](std::optional<modbus::Timestamp> t, std::int64_t offset_s) {
        if (!t || offset_s > 10'000'000'000 || offset_s < -10'000'000'000)
            return std::optional<modbus::Timestamp>{};
        return std::optional<modbus::Timestamp>(*t + std::chrono::seconds(offset_s));
    };
    // The statistics blocks at the end, walked back by their trailing lengths.
    std::optional<modbus::Timestamp> end;
    std::uint64_t to = file.size();
    for (int n = 0; n < blocks_walked && to > at && file.read(to - 4, 4, b); ++n) {
        const std::uint32_t length = s.u32(b, 0);
        if (length < 24 || length % 4 || length > to - at || length > largest_block_read) break;
        if (!file.read(to - length, length, b) || s.u32(b, 4) != length) break;
        if (s.u32(b, 0) != interface_statistics_block) break;
        const std::uint32_t interface = s.u32(b, 8);
        if (interface >= interfaces.size()) return std::nullopt;
        std::uint64_t ticks = std::uint64_t{s.u32(b, 12)} << 32 | s.u32(b, 16);
        each_option(s, b, 20, [&](std::uint16_t code, std::size_t value, std::uint16_t size) {
            if (code == isb_endtime && size == 8)
                ticks = std::uint64_t{s.u32(b, value)} << 32 | s.u32(b, value + 4);
            if ((code == isb_ifdrop || code == isb_osdrop) && size == 8 && dropped)
                *dropped += s.big_endian ? std::uint64_t{s.u32(b, value)} << 32 | s.u32(b, value + 4)
                                         : std::uint64_t{s.u32(b, value + 4)} << 32 | s.u32(b, value);
        });
        const Interface& i = interfaces[interface];
        auto t = at_offset(in_nanoseconds(ticks, i.resolution), i.offset_s);
        // dumpcap (Wireshark 4.0) writes its statistics' times in microseconds, whatever if_tsresol its
        // interfaces say: read so when the interface's own resolution gives no end the capture can have.
        if (!plausible(t) && i.resolution != 6) t = at_offset(in_nanoseconds(ticks, 6), i.offset_s);
        if (plausible(t) && (!end || *t > *end)) end = t;
        to -= length;
    }
    return end;
}

}  // namespace mbscope::analyzer
