#pragma once
// Live capture for mbscope sniff: packets from a network interface through libpcap (pcap_create,
// immediate mode, a BPF filter on the Modbus ports), or bytes from one or two serial ports read raw with
// the host's clock, fed to the same Analyzer as files are, and optionally written to a capture file.
//
// The file is pcapng when its name ends in .pcapng (any case; PcapngWriter, nanosecond timestamps, one
// interface for the network interface or for each serial port), classic pcap otherwise (libpcap's pcap_dump,
// microseconds). Records carry the interface's link type for network captures, USER0 (147) for serial
// bytes, one record a read, stamped when the read returned. One serial port: the records are the line's
// bytes, read back with `mbscope decode --user-dlt rtu`. Two ports: each record starts with a one-byte
// direction pseudo-header (UserDltDirection: 0 the first port, master to slave; 1 the second, slave to
// master), read back with `--user-dlt rtu-dir` into the same directions.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/analyzer.hpp"
#include "modbus/serial_line.hpp"

namespace mbscope::analyzer {

struct SniffOptions {
    std::string interface;  // network capture: a libpcap device ("lo", "eth0")
    std::vector<std::uint16_t> tcp_ports{502}, udp_ports{502};
    std::string serial;   // serial capture: the line, or the master's transmit line when serial2 is set
    std::string serial2;  // the slaves' transmit line (two taps of a full-duplex or RS-232 link)
    modbus::SerialLine line{};
    std::string write;  // capture file to write (see writes_pcapng), empty for none
    std::optional<std::chrono::duration<double>> duration;  // stop after this long
    std::optional<std::uint64_t> count;                     // stop after this many packets or serial reads
    // The kernel's buffer for packets not yet read (libpcap's, tcpdump's -B), in MiB. libpcap's 2 MiB hold
    // 16 packets on lo at its 64 KiB frames: a short burst overflowed it.
    int buffer_mib = 32;
};

// The filter for the options' ports: "tcp port 502 or udp port 502 ...", and every IP fragment but a
// datagram's first (which alone carries the ports): a Modbus/UDP request in two fragments lost its second.
std::string capture_filter(const SniffOptions& options);

// True when `path` ends in .pcapng, in any case: the capture file is then written as pcapng, otherwise as
// classic pcap.
bool writes_pcapng(std::string_view path);

class LiveCapture {
  public:
    // Opens the interface or the serial ports (and the output file). nullptr with `error` set when they
    // cannot be opened; `permission_denied` tells a missing capture privilege from other failures.
    static std::unique_ptr<LiveCapture> open(const SniffOptions& options, std::string& error,
                                             bool& permission_denied);
    ~LiveCapture();
    LiveCapture(const LiveCapture&) = delete;
    LiveCapture& operator=(const LiveCapture&) = delete;

    // Captures into the analyzer until the duration or count is reached or `stop` is set; then reads what
    // is already waiting, flushes the capture file and returns. False on a capture error or a failed write
    // of the capture file (recorded as the analyzer's input error, naming the file). Packets the kernel
    // dropped (its buffer full: the reader fell behind) are the analyzer's input errors too, said at the
    // loop's pace as they are counted: the exchanges around them may show as unanswered, cut or unsolicited.
    bool run(Analyzer& analyzer, const std::atomic<bool>& stop);
    std::uint64_t captured() const noexcept { return captured_; }
    std::uint64_t dropped() const noexcept;  // packets the kernel dropped (network capture)
    const std::string& name() const noexcept { return name_; }
    // True when serial records carry the direction pseudo-header (two ports).
    bool direction_header() const noexcept;

  private:
    LiveCapture() = default;
    struct Impl;
    std::unique_ptr<Impl> impl_;
    SniffOptions options_;
    std::string name_;
    std::uint64_t captured_ = 0;
};

}  // namespace mbscope::analyzer
