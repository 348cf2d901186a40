#pragma once
// SIGINT, SIGTERM and SIGHUP ask a long run (slave, check, fuzz, replay, sniff) to stop rather than kill it:
// the run sees the flag, finishes its step (restores what it wrote, writes its report, closes its capture
// file) and returns. SIGHUP is left ignored when it is already (nohup).
//
// A command installs the handlers before it prepares its run (loads the profile, opens its files and the
// target), so that a signal that early ends it as a later one does: with the exit code and the summary or
// report its documentation promises, saying it was interrupted. Installed once the profile had loaded, a
// SIGTERM in the first 0.3 s of `mbscope fuzz` killed it: exit 143 and no JSON.

#include <atomic>

namespace mbscope::cli {

enum class BrokenPipe {
    Kills,    // output to a pipe: a reader that went away ends the run, as for any filter
    Stops,    // a reader that went away stops the run as SIGTERM does: what it keeps (a capture file) is kept
    Ignored,  // a peer closed its socket: a send fails with EPIPE and the run carries on or reports it
};

// Installs the handlers and returns the flag they set. SIGINT, SIGTERM and SIGHUP (unless ignored) are
// unblocked too: a command started with them blocked (a mask inherited from its parent) would hold them
// pending for ever, and only SIGKILL could end it.
//
// Until run_begins(), a blocking call a stop signal interrupts fails with EINTR instead of starting again: a
// step of the preparation that would wait for ever (opening a FIFO no one opens at the other end) ends, and
// the command, finding the flag set, says it was interrupted.
std::atomic<bool>& stop_on_signals(BrokenPipe broken_pipe);
// The preparation is over: from here on a call a stop signal interrupts starts again (SA_RESTART), as the
// run's loops and its output expect; the run learns of the signal from the flag.
void run_begins();
// Set by a second stop signal, one that comes while the run is stopping: what is left of the stop
// that only informs (the fuzzer's read-back of points written without a reply) is cut short. Restoring what
// was written is not.
const std::atomic<bool>& second_stop_signal();
// For a run with nothing to restore (sniff): a stop that has not ended the process `seconds` after the
// first stop signal, or a second stop signal, ends it by that signal's default action. A run whose output
// a reader does not read is blocked in a write the signal cannot interrupt (SA_RESTART): `sniff | (sleep
// 20; cat)` ignored SIGTERM and SIGINT until its reader read.
void stop_is_forced(unsigned seconds);
// How many stop signals have come: a wait that a signal must end (one begun after the run was stopped
// included) ends when this moves.
unsigned stop_signal_count();

}  // namespace mbscope::cli
