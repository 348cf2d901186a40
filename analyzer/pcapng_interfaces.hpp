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
// It follows the block structure (type and total length) through the bytes given it in any chunks, in file
// order, and changes nothing in a file that is not pcapng or whose blocks stop making sense (a damaged file
// is left for libpcap to report).

#include <array>
#include <cstdint>
#include <span>

namespace mbscope::analyzer {

class PcapngInterfacePatch {
  public:
    // The next bytes of the file, changed in place where they hold an interface's snapshot length or link
    // type.
    void pass(std::span<std::uint8_t> bytes) noexcept;
    // The last byte passed is the first of an interface's link type, which can only be changed together
    // with the second: pass the next byte of the file, in memory right after it, before handing the bytes
    // on. (Bytes passed anywhere else leave that link type as it is.)
    bool wants_next_byte() const noexcept {
        return state_ == State::Blocks && seen_ == link_type_at + 1 && wanted_ == interface_header;
    }
    // Whether the bytes are still followed (a pcapng file read in order so far).
    bool following() const noexcept { return state_ != State::Off; }
    // The bytes are no longer read in order (a seek): change nothing from here on.
    void stop() noexcept { state_ = State::Off; }

  private:
    enum class State : std::uint8_t { Start, Blocks, Off };
    static constexpr std::uint8_t block_header = 8;       // type, total length
    static constexpr std::uint8_t section_header = 12;    // and the byte-order magic
    static constexpr std::uint8_t interface_header = 16;  // and link type, reserved, snapshot length
    static constexpr std::uint8_t link_type_at = 8;
    static constexpr std::uint8_t snaplen_at = 12;

    void header_byte(std::uint8_t& byte) noexcept;
    void begin_block() noexcept;
    void link_type(std::uint8_t& second) noexcept;
    std::uint32_t u32(std::size_t at) const noexcept;

    State state_ = State::Start;
    bool big_endian_ = false;     // the section's byte order, from its byte-order magic
    std::uint64_t position_ = 0;  // file offset of the next byte passed
    std::uint64_t block_ = 0;     // file offset of the block whose header is being read
    std::uint64_t end_ = 0;       // where that block ends, once its length is known
    std::array<std::uint8_t, interface_header> header_{};  // its first bytes as the file has them
    std::uint8_t seen_ = 0;                                // how many of them have passed
    std::uint8_t wanted_ = block_header;                   // how many are wanted
    std::uint8_t* link_type_first_ = nullptr;              // where the link type's first byte went
};

}  // namespace mbscope::analyzer
