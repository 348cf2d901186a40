#include "cli/stop_signal.hpp"

#include <signal.h>

#include <csignal>

namespace mbscope::cli {
namespace {

std::atomic<bool> stop_requested{false};
std::atomic<bool> stop_requested_again{false};
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");

extern "C" void on_stop_signal(int) {
    if (stop_requested.exchange(true)) stop_requested_again.store(true);
}

}  // namespace

std::atomic<bool>& stop_on_signals(BrokenPipe broken_pipe) {
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    // A hangup (the terminal or SSH session gone) stops as Ctrl-C does: check restores what it wrote and
    // writes its reports, slave and sniff close and flush, instead of dying with the device left changed.
    // Unless it is ignored already (nohup): that is the user's wish to outlive the terminal.
    struct sigaction hup {};
    if (::sigaction(SIGHUP, nullptr, &hup) == 0 && hup.sa_handler != SIG_IGN)
        std::signal(SIGHUP, on_stop_signal);
    if (broken_pipe == BrokenPipe::Ignored) std::signal(SIGPIPE, SIG_IGN);
    if (broken_pipe == BrokenPipe::Stops) std::signal(SIGPIPE, on_stop_signal);
    return stop_requested;
}

const std::atomic<bool>& second_stop_signal() {
    return stop_requested_again;
}

}  // namespace mbscope::cli
