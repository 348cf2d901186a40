#pragma once
// A pcapng writer for mbscope sniff --write FILE.pcapng: libpcap 1.10 reads pcapng but writes classic pcap
// only. One section: a Section Header Block naming mbscope (shb_userappl), an Interface Description Block
// for each interface, stamped in nanoseconds (if_tsresol 9), an Enhanced Packet Block for each packet, and
// at the end an Interface Statistics Block for each interface saying when the capture ended. Every block is
// little-endian (the section's byte-order magic says so to readers on any host), padded to 32 bits, its
// options ended by opt_endofopt.
//
// Errors are strings naming the file, empty on success. A failed write leaves the file unusable: every
// later call returns the same error rather than writing blocks after a torn one.

#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

class PcapngWriter {
  public:
    PcapngWriter() = default;
    ~PcapngWriter() = default;  // closes the file, its errors unseen: close() reports them
    PcapngWriter(PcapngWriter&&) noexcept = default;
    PcapngWriter& operator=(PcapngWriter&&) noexcept = default;

    // Creates (or truncates) `path` and writes the Section Header Block.
    std::string open(const std::string& path);
    // Describes the next interface: the first is interface 0, the next 1, and so on, as pcapng numbers
    // them by the order of their blocks. `snaplen` 0 means no limit.
    std::string add_interface(std::uint16_t linktype, std::uint32_t snaplen, std::string_view name);
    // One packet of a described interface: `time` since 1970 (not before), the bytes captured and the
    // packet's length on the wire (never less than what was captured).
    std::string write_packet(std::uint32_t interface_id, modbus::Timestamp time,
                             std::span<const std::uint8_t> data, std::uint32_t original_length);
    // Ends the capture: an Interface Statistics Block per interface whose isb_endtime is `end`, when the
    // capture stopped, which no packet says (a request unanswered until then timed out, or did not, by it).
    // Written once, last. `dropped`: packets the capture lost on interface 0 (libpcap's ps_drop, written as
    // isb_osdrop, as dumpcap does), so that a later decode can say so; 0 writes none.
    std::string end_statistics(modbus::Timestamp end, std::uint64_t dropped = 0);
    // Hands what is buffered to the file system, so the file is whole up to here if the process dies.
    std::string flush();
    // Flushes and closes; the writer can then open another file.
    std::string close();

    bool is_open() const noexcept { return file_ != nullptr; }
    const std::string& path() const noexcept { return path_; }
    std::uint32_t interfaces() const noexcept { return static_cast<std::uint32_t>(snaplens_.size()); }

  private:
    std::string unusable() const;  // why nothing can be written now, empty when it can
    std::string write(const std::vector<std::uint8_t>& block);
    std::string fail();  // records errno's reason as the sticky error

    struct Closer {
        void operator()(std::FILE* f) const noexcept { std::fclose(f); }
    };
    std::unique_ptr<std::FILE, Closer> file_;
    std::string path_;
    std::string error_;                    // the first write error, returned from then on
    std::vector<std::uint32_t> snaplens_;  // per described interface
};

}  // namespace mbscope::analyzer
