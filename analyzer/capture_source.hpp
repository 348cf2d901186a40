#pragma once
// Captured packets from pcap and pcapng files (or memory), read through libpcap. A damaged file yields every
// packet before the damage and then an error naming the file, the packet number and the byte offset.
// A file is read ahead by a thread of its own (libpcap's reading of the file and the kernel's copy of it
// were a fifth of a summary run, and the analysis behind them is single-threaded): packets are copied into
// batches, handed over a few at a time, and come out of next() in the file's order exactly as libpcap gave
// them. Memory is read in the caller's thread (the fuzzer and the tests).
//
// A pcapng file (or memory) whose interfaces are of several link types is read once per link type
// (analyzer/pcapng_interfaces.hpp says how and why) and the passes merged by where their packets lie in the
// file: packets come out in the file's order, numbered as in the file, each with its interface's link type.
// The link types are those described in the first 64 KiB; an interface of another one further on is refused
// by libpcap, and the file is read again with it, the packets handed out already skipped. A stream is read
// once; its refusal names the way round.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "modbus/frame.hpp"

struct pcap;  // libpcap's pcap_t

namespace mbscope::analyzer {

class PcapngInterfacePatch;

struct Packet {
    std::uint64_t number = 0;  // 1-based, as tshark counts
    modbus::Timestamp time{0};
    bool time_out_of_range = false;  // the record's time is not representable; `time` is the last one seen
    int linktype = 0;
    std::span<const std::uint8_t> data;  // valid until the next call to next()
    std::uint32_t original_length = 0;
};

class CaptureSource {
  public:
    // Errors (unreadable file, not a capture) are returned in `error`; nullptr then. `name` (the path when
    // empty) is what packets' source and errors are named after: a spooled pipe is read from elsewhere.
    static std::unique_ptr<CaptureSource> open_file(const std::string& path, std::string& error,
                                                    const std::string& name = {});
    static std::unique_ptr<CaptureSource> open_memory(std::span<const std::uint8_t> bytes,
                                                      std::string& error);
    // A capture coming through a pipe, FIFO or socket (`fd`, taken over) whose first bytes, `head`, were
    // read already to tell its format: read as it comes, a packet at a time rather than ahead in batches,
    // with `stalled` called whenever the next bytes are not there yet, before the read waits for them (for
    // the output to be flushed: `tcpdump -U -w - | mbscope decode -` shows each exchange as it happens).
    static std::unique_ptr<CaptureSource> open_stream(int fd, std::vector<std::uint8_t> head,
                                                      const std::string& name, std::string& error,
                                                      std::function<void()> stalled = {});
    ~CaptureSource();
    CaptureSource(const CaptureSource&) = delete;
    CaptureSource& operator=(const CaptureSource&) = delete;

    // The next packet; nullopt at the end or on damage (then error() says what and where).
    std::optional<Packet> next();
    const std::string& error() const noexcept { return error_; }
    int linktype() const noexcept { return linktype_; }
    // Byte offset in the file reached so far (the end of the last packet next() returned).
    std::uint64_t offset() const noexcept { return offset_; }
    const std::string& name() const noexcept { return name_; }

  private:
    // Why reading ended before the end, and where. `what` follows the packet count in the message.
    struct ReadFailure {
        bool interface_refused = false;  // an interface block libpcap will not take, not damage
        std::string what;
        std::uint64_t offset = 0;  // where the refused block or record starts (passes: the block)
        std::vector<std::uint16_t> link_types;  // refused: the file's, as far as its bytes were passed
        std::string message(const std::string& name, std::uint64_t packets) const;
    };
    // A pass of the file keeping packets of link type `kept` among the file's link types `known` (empty:
    // the file read once, all its packets).
    using Reopen = std::function<std::unique_ptr<CaptureSource>(
        std::uint16_t kept, const std::vector<std::uint16_t>& known, std::string& error)>;
    // One pass of a file read once per link type: its next packet, where it ends, and whether it is over.
    struct Pass {
        std::unique_ptr<CaptureSource> source;
        std::optional<Packet> packet;
        std::uint64_t end = 0;
        bool over = false;
    };

    CaptureSource() = default;
    static std::unique_ptr<CaptureSource> made(::pcap* pcap, const std::string& name, bool read_ahead,
                                               const PcapngInterfacePatch* interfaces,
                                               bool one_pass_of_several);
    static std::unique_ptr<CaptureSource> opened(const Reopen& open, const std::vector<std::uint16_t>& known,
                                                 std::string& error);
    void read_in_passes(std::vector<std::unique_ptr<CaptureSource>> passes, std::vector<std::uint16_t> known);
    bool read_again(const ReadFailure& failure);
    std::optional<Packet> next_of_passes();
    struct Impl;
    class ReadAhead;
    std::unique_ptr<Impl> impl_;
    std::unique_ptr<ReadAhead> ahead_;  // files only
    std::vector<Pass> passes_;          // several link types: the passes, impl_ empty
    Reopen reopen_;                     // a file or memory: how to read it again (a stream cannot be)
    std::vector<std::uint16_t> known_;  // the link types read (passes: one each)
    std::uint64_t skip_through_ = 0;    // read again: packets ending here or before were handed out
    std::uint64_t count_ = 0;           // packets handed out
    std::optional<ReadFailure> failure_;
    std::string error_;
    std::string name_;
    int linktype_ = 0;
    std::uint64_t offset_ = 0;
};

}  // namespace mbscope::analyzer
