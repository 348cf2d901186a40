#pragma once
// Serial-line logs written by other tools, read into timed, direction-tagged chunks of line bytes. Each
// reader is pure: it turns a log into chunks and errors (file and line) through callbacks, and never stops
// at a bad line.
//
// jpnevulator --read --timing-print (jpnevulator 2.3.6, jpnevulator.c headerWrite/jpnevulatorRead):
//
//     2026-11-30 06:22:57.009496: master          <- "%04d-%02d-%02d %02d:%02d:%02d.%06ld:" local time,
//     11 03 00 6B 00 03 76 87    \t...k..v.          then " ALIAS" when several --tty are read
//     2026-11-30 06:22:57.028670: slave           <- "%02X" bytes, --width (16) a line, "\t" + the ASCII
//     11 03 06 02 2B 00 00 00 64 C8 BA \t....+...d..    column with --ascii, "%08lX\t" first with
//                                                        --byte-count; "le=%d, dtr=%d, ..." with --control
//   A timestamp line is written before every run of bytes whose reads are less than --timing-delta (100 ms)
//   apart, and whenever the tty changes; the time is taken when the run's first read returned. The run is
//   read as bytes back to back on the line, the first one ending at that time. ALIAS (or the device name
//   when --tty has no alias) gives the direction through SerialLogOptions, or by itself when it is one of
//   the text format's direction words (master, slave, M, S, TX, RX, REQ, RSP, >, <).
//
// socat -x -v ADDRESS1 ADDRESS2, its standard error (socat 1.7.4.4, xiotransfer.c xioprintblockheader):
//
//     > 2026/11/30 06:23:27.000754320  length=8 from=0 to=7     <- ">" ADDRESS1 → ADDRESS2, "<" back;
//      11 03 00 6b 00 03 76 87                          ...k..v.    from/to count each direction's bytes
//     --                                                          <- " %02x" bytes, 16 a line, ASCII column
//   A hex line holds at most 16 bytes and also ends after a 0x0A byte (-v breaks lines at the data's
//   newlines). The time is taken after the read that returned the block, so it is when the block's last byte
//   arrived. socat 1.7.4 prints the microseconds in a nine-digit field ("27.000754320" is 27 s + 754320 us,
//   as the blocks' spacing shows); a file whose nine-digit fractions all start with "000" is read that way,
//   one with any other nine-digit fraction as nanoseconds, six digits as microseconds. Diagnostic lines (-d:
//   "2026/11/30 ... socat[PID] N
//   ...") are skipped. `socat -v` without -x writes the bytes as text with non-printable ones replaced by
//   '.', which cannot be decoded: such a file is an input error that says to capture with -x.
//
// Both tools write local time without a zone; it is read as if it were UTC, so record times show the
// logging machine's wall clock.

#include <cstdint>
#include <functional>
#include <istream>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"
#include "modbus/serial_line.hpp"

namespace mbscope::modbus::storage {
class LineReader;
}

namespace mbscope::analyzer {

struct SerialLogOptions {
    // jpnevulator: the --tty alias (or device name) that carries the master's bytes, and the slave's.
    std::string master_alias;
    std::string slave_alias;
    // socat: whether ADDRESS1 (the left one, '>' blocks come from it) is the master's side.
    bool socat_master_left = true;
    // jpnevulator stamps the start of a run: its end is placed by the line's character time.
    modbus::SerialLine line{};
    // The serial inputs are consecutive parts of one line (a log written a file an hour, a capture in
    // pieces), read as one stream in the order named (Analyzer::serial_part_of); else each is a line.
    bool parts_of_one_line = false;
};

struct SerialChunk {
    std::vector<std::uint8_t> bytes;
    modbus::Timestamp received{0};  // when the chunk's last byte arrived; zero: the log has no timing
    modbus::Direction direction = modbus::Direction::Unknown;
};

using ChunkCallback = std::function<void(const SerialChunk&)>;
using LogErrorCallback = std::function<void(const std::string&)>;  // "NAME:LINE: what is wrong"

// Read a jpnevulator log; chunks in order. Returns false when a line could not be read (each reported
// through `error`); every other line is still read.
bool read_jpnevulator_log(std::istream& in, const std::string& name, const SerialLogOptions& options,
                          const ChunkCallback& chunk, const LogErrorCallback& error);
// Read a socat -x log (in must be seekable: a first pass decides how to read the timestamps' fractions).
// Returns false when a line could not be read or the log holds text (-v without -x).
bool read_socat_log(std::istream& in, const std::string& name, const SerialLogOptions& options,
                    const ChunkCallback& chunk, const LogErrorCallback& error);

// The text format's direction words, any case: ">", "M", "TX", "REQ", "MASTER" (master → slave) and "<",
// "S", "RX", "RSP", "SLAVE" (slave → master).
// The next line of a text log that fits the line bound (modbus/storage/text_file.hpp) into `text`; a longer
// one is named to `error` ("NAME:LINE: line of N bytes is longer ...") and read past, and `ok` set false.
bool next_log_line(modbus::storage::LineReader& lines, std::string& text, const std::string& name,
                   const LogErrorCallback& error, bool& ok);

std::optional<modbus::Direction> direction_word(std::string_view word);

// The head of a file (a few KiB) looks like such a log.
bool looks_like_jpnevulator_log(std::string_view head);
bool looks_like_socat_log(std::string_view head);

}  // namespace mbscope::analyzer
