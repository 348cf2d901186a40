#pragma once
// Serial captures without a pcap wrapper:
//  - raw dumps: the bytes of the line as a logger wrote them, no timing (RTU or ASCII);
//  - the text format any logger can produce, one chunk per line:
//        TIME [DIR] HEX...
//    TIME in seconds (decimal fraction allowed) when the chunk's last byte arrived; DIR optional: ">", "M",
//    "TX", "REQ" for master → slave, "<", "S", "RX", "RSP" for slave → master; HEX the bytes ("11 03 00 60",
//    "110300600003"). Lines starting with '#' and blank lines are skipped.
//  - logs of other tools: jpnevulator --read --timing-print and socat -x -v (analyzer/serial_logs.hpp).
// A malformed line is reported with file and line number; the lines around it are still decoded.

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/analyzer.hpp"
#include "analyzer/serial_logs.hpp"

namespace mbscope::analyzer {

enum class InputFormat { Auto, Pcap, RtuRaw, AsciiRaw, Text, Jpnevulator, Socat, Hex };
// auto, pcap, rtu, ascii, text, jpnevulator, socat, hex
std::optional<InputFormat> parse_input_format(std::string_view name);
// pcap/pcapng magic → Pcap; ':' → AsciiRaw; a jpnevulator timestamp line first → Jpnevulator; a socat -x
// block header (after socat -d lines, if any) → Socat; lines of hex bytes alone that the text format cannot
// be (a first byte with a hex letter, or a line that is a whole RTU frame) → Hex; a first line
// "NUMBER [DIR] HEX" → Text; otherwise RtuRaw. `head`: the file's first few KiB.
InputFormat detect_input_format(std::span<const std::uint8_t> head);

// Read a file in the given format into the analyzer; false when it could not be read completely (the
// analyzer's summary names what went wrong). "-" is standard input; it, a pipe or a FIFO (a shell's
// <(command)) is copied to a temporary file first and read from there under its own name, so that its
// format can be told from its head. `logs`: how the other tools' logs map to directions
// (analyzer/serial_logs.hpp).
bool read_input(Analyzer& analyzer, const std::string& path, InputFormat format,
                const SerialLogOptions& logs = {});
// Several inputs into one analyzer. The pcap and pcapng files among them are one capture, merged by time
// (analyzer/capture_merge.hpp) and read where the first of them is named; the others (serial dumps and
// logs) are read one after another in the order named, each a line of its own, or with
// `logs.parts_of_one_line` the parts of one line named after the first. `done`, when given, is called with
// each input's name once it is read (for a progress line). False when an input could not be read completely.
bool read_inputs(Analyzer& analyzer, const std::vector<std::string>& names, InputFormat format,
                 const SerialLogOptions& logs = {},
                 const std::function<void(const std::string& name)>& done = {});

}  // namespace mbscope::analyzer
