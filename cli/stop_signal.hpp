#pragma once
// SIGINT, SIGTERM and SIGHUP ask a long run (slave, check, fuzz, replay, sniff) to stop rather than kill it:
// the run sees the flag, finishes its step (restores what it wrote, writes its report, closes its capture
// file) and returns. SIGHUP is left ignored when it is already (nohup).

#include <atomic>

namespace mbscope::cli {

enum class BrokenPipe {
    Kills,    // output to a pipe: a reader that went away ends the run, as for any filter
    Stops,    // a reader that went away stops the run as SIGTERM does: what it keeps (a capture file) is kept
    Ignored,  // a peer closed its socket: a send fails with EPIPE and the run carries on or reports it
};

// Installs the handlers and returns the flag they set.
std::atomic<bool>& stop_on_signals(BrokenPipe broken_pipe);
// Set by a second stop signal, one that comes while the run is stopping: what is left of the stop
// that only informs (the fuzzer's read-back of points written without a reply) is cut short. Restoring what
// was written is not.
const std::atomic<bool>& second_stop_signal();

}  // namespace mbscope::cli
