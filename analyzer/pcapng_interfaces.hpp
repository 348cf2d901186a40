#pragma once
// libpcap 1.10 reads a pcapng file only while every Interface Description Block agrees with the first one,
// and refuses two kinds of agreement it does not see:
// - interfaces that differ in snapshot length ("an interface has a snapshot length 262144 different from
//   the snapshot length of the first interface"), as in what mergecap and Wireshark's File > Merge make of
//   captures taken with different limits. The snapshot length is the most a capturing program kept of a
//   packet; a reader needs it for nothing, since each packet block says how many bytes it holds.
// - raw-IP interfaces: it compares a later interface's link type as written, LINKTYPE_RAW (101), with the
//   first one's as it mapped it, DLT_RAW (12 on this system), and finds them different ("an interface has
//   a type 101 different from the type of the first interface"): two tun or VPN interfaces, or a merge of
//   two raw-IP captures.
// When the second interface block comes before the first packet, nothing of the file is read. So, as the
// file's bytes pass from the disk to libpcap, every interface block's snapshot length is set to 0, pcapng's
// "no limit" (libpcap then takes its own limit for the link type), and a link type LINKTYPE_RAW is written
// as DLT_RAW, which libpcap reads as the same raw IP: the interfaces agree, no packet is cut that the file
// holds whole, and every packet reaches the analyzer with the link type it had.
//
// Interfaces of different link types (dumpcap capturing on Ethernet and on "any", Linux cooked, at once; a
// merge of an Ethernet and a raw-IP capture) cannot be levelled: libpcap gives one link type for the whole
// file. Such a file is read once per link type, each pass through a patch told which link type it keeps
// (keep_only): every interface of the file's other link types is written as the kept one, so libpcap
// accepts it, and every packet block on one of them is hidden from libpcap (the high bit of its block type
// set: a block type of local use, which libpcap skips unread). Each packet then reaches the analyzer from
// exactly one pass, with its interface's own link type, and at its own offset in the file (nothing moves).
// The link types of the file come from a patch that has passed the file's first blocks (link_types()). An
// interface of a link type not named to keep_only is left as it is, so libpcap refuses it instead of a pass
// hiding its packets; the reader then learns its link type from the patch and reads the file again.
//
// It follows the block structure (type and total length) through the bytes given it in any chunks, in file
// order, and changes nothing in a file that is not pcapng or whose blocks stop making sense (a damaged file
// is left for libpcap to report).

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace mbscope::analyzer {

class PcapngInterfacePatch {
  public:
    // Pass on packets of interfaces of link type `kept` alone, among the file's link types `known` (as
    // link_types() gives them; at least two). Before the first bytes are passed.
    void keep_only(std::uint16_t kept, std::vector<std::uint16_t> known);
    // The next bytes of the file, changed in place where they hold an interface's snapshot length or link
    // type, or (keep_only) the type of a packet block to hide.
    void pass(std::span<std::uint8_t> bytes);
    // How many more bytes of the file are wanted before the bytes passed can be handed on: the last ones
    // passed begin a field that can only be changed with bytes still to come (an interface's link type; with
    // keep_only, the first 12 bytes of a block, whose type is changed once its interface is known). Pass
    // them, in memory right after the others, first. (Bytes passed anywhere else leave the field as it is.)
    std::size_t bytes_wanted() const noexcept;
    // The bytes passed so far have been handed on: none of them is changed any more, wherever the next
    // bytes lie in memory.
    void handed_on() noexcept {
        block_first_ = link_type_first_ = nullptr;
        next_in_memory_ = nullptr;
    }
    // The most bytes_wanted() asks for.
    static constexpr std::size_t most_wanted = 12;
    // The link types of the interfaces passed so far, each once, in the order met, as libpcap is given them
    // (LINKTYPE_RAW as DLT_RAW); the first most_link_types of them.
    const std::vector<std::uint16_t>& link_types() const noexcept { return link_types_; }
    static constexpr std::size_t most_link_types = 16;
    bool keeping() const noexcept { return keeping_; }
    // Where the first interface block libpcap refuses starts: the first whose link type, as libpcap is given
    // it, differs from the first interface's.
    std::optional<std::uint64_t> refused_at() const noexcept { return refused_at_; }
    // Whether the bytes are still followed (a pcapng file read in order so far).
    bool following() const noexcept { return state_ != State::Off; }
    // The bytes are no longer read in order (a seek): change nothing from here on.
    void stop() noexcept { state_ = State::Off; }

  private:
    enum class State : std::uint8_t { Start, Blocks, Off };
    static constexpr std::uint8_t block_header = 8;             // type, total length
    static constexpr std::uint8_t section_header = 12;          // and the byte-order magic
    static constexpr std::uint8_t interface_header = 16;        // and link type, reserved, snapshot length
    static constexpr std::uint8_t packet_header = most_wanted;  // and the interface
    static constexpr std::uint8_t link_type_at = 8;
    static constexpr std::uint8_t interface_at = 8;
    static constexpr std::uint8_t snaplen_at = 12;

    void header_byte(std::uint8_t& byte);
    void begin_block() noexcept;
    void link_type(std::uint8_t& second);
    void packet_on(std::uint32_t interface) noexcept;
    std::uint32_t u32(std::size_t at) const noexcept;

    State state_ = State::Start;
    bool big_endian_ = false;     // the section's byte order, from its byte-order magic
    std::uint64_t position_ = 0;  // file offset of the next byte passed
    std::uint64_t block_ = 0;     // file offset of the block whose header is being read
    std::uint64_t end_ = 0;       // where that block ends, once its length is known
    std::array<std::uint8_t, interface_header> header_{};  // its first bytes as the file has them
    std::uint8_t seen_ = 0;                                // how many of them have passed
    std::uint8_t wanted_ = block_header;                   // how many are wanted
    std::uint8_t* block_first_ = nullptr;                  // where the block's first byte went
    std::uint8_t* link_type_first_ = nullptr;              // where an interface's link type's first went
    const std::uint8_t* next_in_memory_ = nullptr;         // right after the last byte passed
    bool section_header_ = false;  // the block whose header is being read starts a section
    std::vector<std::uint16_t> link_types_;
    std::vector<std::uint16_t> interfaces_;  // the section's interfaces' link types, by interface number
    bool keeping_ = false;                   // keep_only was called
    std::uint16_t kept_ = 0;
    std::vector<std::uint16_t> known_;
    std::optional<std::uint16_t> first_written_;  // the first interface's link type, as libpcap is given it
    std::optional<std::uint64_t> refused_at_;
};

}  // namespace mbscope::analyzer
