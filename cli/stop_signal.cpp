#include "cli/stop_signal.hpp"

#include <csignal>

namespace mbscope::cli {
namespace {

std::atomic<bool> stop_requested{false};
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");

extern "C" void on_stop_signal(int) {
    stop_requested.store(true);
}

}  // namespace

std::atomic<bool>& stop_on_signals(BrokenPipe broken_pipe) {
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    if (broken_pipe == BrokenPipe::Ignored) std::signal(SIGPIPE, SIG_IGN);
    return stop_requested;
}

}  // namespace mbscope::cli
