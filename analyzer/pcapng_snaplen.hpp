#pragma once
// libpcap 1.10 refuses a pcapng file whose interfaces differ in snapshot length ("an interface has a
// snapshot length 262144 different from the snapshot length of the first interface"), and reads none of it
// when the second interface block comes before the first packet, as in what mergecap and Wireshark's
// File > Merge make of captures taken with different snapshot lengths. The snapshot length is the most a
// capturing program kept of a packet; a reader needs it for nothing, since each packet block says how many
// bytes it holds. So, as the file's bytes pass from the disk to libpcap, every Interface Description Block's
// snapshot length is set to 0, pcapng's "no limit" (libpcap then takes its own limit for the link type):
// the interfaces agree, and no packet is cut that the file holds whole.
//
// It follows the block structure (type and total length) through the bytes given it in any chunks, in file
// order, and changes nothing in a file that is not pcapng or whose blocks stop making sense (a damaged file
// is left for libpcap to report).

#include <array>
#include <cstdint>
#include <span>

namespace mbscope::analyzer {

class PcapngSnaplenPatch {
  public:
    // The next bytes of the file, changed in place where they hold an interface's snapshot length.
    void pass(std::span<std::uint8_t> bytes) noexcept;
    // The bytes are no longer read in order (a seek): change nothing from here on.
    void stop() noexcept { state_ = State::Off; }

  private:
    enum class State : std::uint8_t { Start, Blocks, Off };
    void header_byte(std::uint8_t& byte) noexcept;
    std::uint32_t u32(std::size_t at) const noexcept;

    State state_ = State::Start;
    bool big_endian_ = false;     // the section's byte order, from its byte-order magic
    std::uint64_t position_ = 0;  // file offset of the next byte passed
    std::uint64_t block_ = 0;     // file offset of the block whose header is being read
    std::uint64_t end_ = 0;       // where that block ends, once its length is known
    std::array<std::uint8_t, 16>
        header_{};              // its first bytes: type, total length, and an IDB's snapshot length
    std::uint8_t seen_ = 0;     // how many of them have passed
    std::uint8_t wanted_ = 12;  // how many are wanted: 16 for an interface block, else 12
};

}  // namespace mbscope::analyzer
