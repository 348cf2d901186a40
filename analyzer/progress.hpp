#pragma once
// Progress of a long decode, for a person watching a terminal: packets and bytes read, how far into the
// input files (by byte offset), frames and findings so far. The meter redraws one line at most a few times
// a second and erases it at the end, so nothing of it stays in a scrollback or a redirected stream; the
// caller decides whether a terminal is there (isatty on standard error).

#include <chrono>
#include <cstdint>
#include <ostream>
#include <string>

namespace mbscope::analyzer {

struct ProgressState {
    std::uint64_t packets = 0;      // packets (or serial chunks) read so far
    std::uint64_t bytes_read = 0;   // byte offset reached over all input files
    std::uint64_t total_bytes = 0;  // size of all input files; 0 when unknown (no percentage then)
    std::uint64_t frames = 0;
    std::uint64_t findings = 0;
};

// One line, e.g. "1,234,567 packets, 96.1 MB of 120.0 MB (80%), 2,345,678 frames, 12 findings".
std::string format_progress(const ProgressState& state);

class ProgressMeter {
  public:
    // `interval`: the least time between two redraws.
    explicit ProgressMeter(std::ostream& out,
                           std::chrono::steady_clock::duration interval = std::chrono::milliseconds(250))
        : out_(out), interval_(interval) {}
    // Redraws the line if `interval` has passed since the last redraw (the first call waits one interval:
    // short runs print nothing).
    void update(const ProgressState& state);
    // Erases the line if one was drawn.
    void clear();

  private:
    std::ostream& out_;
    std::chrono::steady_clock::duration interval_;
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
    bool drawn_ = false;
};

}  // namespace mbscope::analyzer
