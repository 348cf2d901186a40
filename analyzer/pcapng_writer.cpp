#include "analyzer/pcapng_writer.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>

#include "analyzer/pcapng_format.hpp"

namespace mbscope::analyzer {

namespace {

using namespace pcapng;
constexpr std::uint8_t nanoseconds = 9;  // if_tsresol: a power of ten, 10^-9 s
// An Enhanced Packet Block's fixed part and trailing length, around the padded packet bytes.
constexpr std::size_t epb_overhead = 32;
constexpr std::size_t max_packet = std::numeric_limits<std::uint32_t>::max() - epb_overhead - 3;

std::size_t padded_size(std::size_t n) {
    return (n + 3) & ~std::size_t{3};
}

std::span<const std::uint8_t> text(std::string_view s) {
    return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// One block: type, total length, body, total length again, in little-endian whatever the host.
class Block {
  public:
    explicit Block(std::uint32_t type) {
        u32(type);
        u32(0);  // total length, known at the end
    }
    void u16(std::uint16_t v) { le(v, 2); }
    void u32(std::uint32_t v) { le(v, 4); }
    void u64(std::uint64_t v) { le(v, 8); }
    // The bytes, then zeros to the next 32-bit boundary.
    void padded(std::span<const std::uint8_t> bytes) {
        bytes_.insert(bytes_.end(), bytes.begin(), bytes.end());
        bytes_.resize(padded_size(bytes_.size()), 0);
    }
    // The caller keeps `value` within 65535 bytes, the option length field's range.
    void option(std::uint16_t code, std::span<const std::uint8_t> value) {
        u16(code);
        u16(static_cast<std::uint16_t>(value.size()));
        padded(value);
    }
    void end_of_options() { u32(0); }  // opt_endofopt: code 0, length 0
    const std::vector<std::uint8_t>& finish() {
        const auto total = static_cast<std::uint32_t>(bytes_.size() + 4);
        u32(total);
        for (int i = 0; i < 4; ++i)
            bytes_[4 + i] = static_cast<std::uint8_t>(total >> (8 * i));
        return bytes_;
    }

  private:
    void le(std::uint64_t v, int n) {
        for (int i = 0; i < n; ++i)
            bytes_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
    }
    std::vector<std::uint8_t> bytes_;
};

}  // namespace

std::string PcapngWriter::open(const std::string& path) {
    if (file_) {
        if (auto e = close(); !e.empty()) return e;
    }
    path_ = path;
    error_.clear();
    snaplens_.clear();
    errno = 0;
    file_.reset(std::fopen(path.c_str(), "wb"));
    if (!file_) return path + ": " + (errno ? std::strerror(errno) : "cannot open");
    Block b(section_header_block);
    b.u32(byte_order_magic);
    b.u16(1);  // version 1.0
    b.u16(0);
    b.u64(~std::uint64_t{0});  // section length not given: the writer does not seek back
    b.option(shb_userappl, text("mbscope"));
    b.end_of_options();
    return write(b.finish());
}

std::string PcapngWriter::add_interface(std::uint16_t linktype, std::uint32_t snaplen,
                                        std::string_view name) {
    if (auto e = unusable(); !e.empty()) return e;
    if (name.size() > std::numeric_limits<std::uint16_t>::max())
        return path_ + ": interface name of " + std::to_string(name.size()) + " bytes is too long for pcapng";
    Block b(interface_description_block);
    b.u16(linktype);
    b.u16(0);  // reserved
    b.u32(snaplen);
    if (!name.empty()) b.option(if_name, text(name));
    b.option(if_tsresol, std::span<const std::uint8_t>(&nanoseconds, 1));
    b.end_of_options();
    if (auto e = write(b.finish()); !e.empty()) return e;
    snaplens_.push_back(snaplen);
    return {};
}

std::string PcapngWriter::write_packet(std::uint32_t interface_id, modbus::Timestamp time,
                                       std::span<const std::uint8_t> data, std::uint32_t original_length) {
    if (auto e = unusable(); !e.empty()) return e;
    if (interface_id >= snaplens_.size())
        return path_ + ": packet for interface " + std::to_string(interface_id) + ", which was not described";
    if (time.count() < 0) return path_ + ": packet time before 1970, which pcapng cannot hold";
    const std::uint32_t snaplen = snaplens_[interface_id];
    if (data.size() > max_packet || (snaplen != 0 && data.size() > snaplen))
        return path_ + ": packet of " + std::to_string(data.size()) + " bytes is longer than interface " +
               std::to_string(interface_id) + "'s snapshot length";
    const auto captured = static_cast<std::uint32_t>(data.size());
    const auto ns = static_cast<std::uint64_t>(time.count());
    Block b(enhanced_packet_block);
    b.u32(interface_id);
    b.u32(static_cast<std::uint32_t>(ns >> 32));
    b.u32(static_cast<std::uint32_t>(ns));
    b.u32(captured);
    b.u32(std::max(original_length, captured));  // a packet is never shorter than what was kept of it
    b.padded(data);
    return write(b.finish());
}

std::string PcapngWriter::end_statistics(modbus::Timestamp end, std::uint64_t dropped) {
    if (auto e = unusable(); !e.empty()) return e;
    const auto ns = static_cast<std::uint64_t>(std::max<std::int64_t>(end.count(), 0));
    std::uint8_t value[8];
    for (int i = 0; i < 4; ++i) {  // high 32 bits, then low, each in the section's byte order
        value[i] = static_cast<std::uint8_t>(ns >> (32 + 8 * i));
        value[4 + i] = static_cast<std::uint8_t>(ns >> (8 * i));
    }
    for (std::uint32_t i = 0; i < interfaces(); ++i) {
        Block b(interface_statistics_block);
        b.u32(i);
        b.u32(static_cast<std::uint32_t>(ns >> 32));
        b.u32(static_cast<std::uint32_t>(ns));
        b.option(isb_endtime, value);
        if (i == 0 && dropped > 0) {
            std::uint8_t count[8];  // a plain 64-bit number in the section's (the host's) byte order
            std::memcpy(count, &dropped, sizeof count);
            b.option(isb_osdrop, count);
        }
        b.end_of_options();
        if (auto e = write(b.finish()); !e.empty()) return e;
    }
    return {};
}

std::string PcapngWriter::flush() {
    if (!file_ || !error_.empty()) return error_;
    errno = 0;
    if (std::fflush(file_.get()) != 0) return fail();
    return {};
}

std::string PcapngWriter::close() {
    if (!file_) return {};
    std::string e = flush();
    errno = 0;
    if (std::fclose(file_.release()) != 0 && e.empty()) e = fail();
    error_.clear();
    snaplens_.clear();
    return e;
}

std::string PcapngWriter::unusable() const {
    if (!file_) return (path_.empty() ? std::string("pcapng") : path_) + ": not open for writing";
    return error_;
}

std::string PcapngWriter::write(const std::vector<std::uint8_t>& block) {
    if (auto e = unusable(); !e.empty()) return e;
    errno = 0;
    if (std::fwrite(block.data(), 1, block.size(), file_.get()) != block.size()) return fail();
    return {};
}

std::string PcapngWriter::fail() {
    error_ = path_ + ": " + (errno ? std::strerror(errno) : "write error");
    return error_;
}

}  // namespace mbscope::analyzer
