#pragma once
// When a pcapng capture ended, which no packet says: a request still unanswered then had its whole timeout,
// or had not, by that time, not by the last packet's. dumpcap and `mbscope sniff --write` end their files
// with an Interface Statistics Block per interface whose isb_endtime says it (libpcap reads past them).

#include <cstdint>
#include <optional>
#include <string>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

// The latest isb_endtime (or, without one, the block's own timestamp) of the Interface Statistics Blocks
// that end the pcapng file at `path`, in each interface's if_tsresol and if_tsoffset, taken only where it
// can end a capture whose last packet was at `last_packet`: not before it, and within a day of it. nullopt
// when the file is not pcapng, cannot be read, does not end with such blocks, or they give no such end
// (nothing is guessed: the capture then ends at its last packet, as a file without them does).
// `dropped`, when given, adds what those blocks say the capture lost (isb_ifdrop and isb_osdrop, as dumpcap
// and `mbscope sniff --write` write them), whether or not an end is taken.
std::optional<modbus::Timestamp> pcapng_capture_end(const std::string& path, modbus::Timestamp last_packet,
                                                    std::uint64_t* dropped = nullptr);

}  // namespace mbscope::analyzer
