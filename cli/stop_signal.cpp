#include "cli/stop_signal.hpp"

#include <signal.h>
#include <unistd.h>

#include <csignal>

namespace mbscope::cli {
namespace {

std::atomic<bool> stop_requested{false};
std::atomic<bool> stop_requested_again{false};
std::atomic<unsigned> stop_signals{0};
static_assert(std::atomic<unsigned>::is_always_lock_free, "set from a signal handler");
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");
BrokenPipe installed_broken_pipe = BrokenPipe::Kills;

// stop_is_forced(): seconds a stop may take before the process ends by its signal; 0 for never.
volatile sig_atomic_t forced_after_s = 0;
volatile sig_atomic_t first_stop_signal = 0;

extern "C" void die_by_stop_signal(int) {
    // The signal's default action, as if no handler had been installed: the process ends by it (exit status
    // 128 + its number in a shell). Raised here it is delivered as this handler returns.
    ::signal(first_stop_signal, SIG_DFL);
    ::raise(first_stop_signal);
}

extern "C" void on_stop_signal(int sig) {
    // A broken pipe is no user's stop: a write to it fails at once, it blocks nothing.
    const bool forced = forced_after_s && sig != SIGPIPE;
    stop_signals.fetch_add(1);
    if (stop_requested.exchange(true)) {
        stop_requested_again.store(true);
        if (forced) {
            first_stop_signal = sig;
            die_by_stop_signal(sig);
        }
        return;
    }
    first_stop_signal = sig;
    if (forced) ::alarm(static_cast<unsigned>(forced_after_s));
}

// Whether SIGHUP stops the run (it is not when it was ignored already).
bool hangup_stops = false;

void install(BrokenPipe broken_pipe, bool restart) {
    struct sigaction stop {};
    stop.sa_handler = on_stop_signal;
    sigemptyset(&stop.sa_mask);
    stop.sa_flags = restart ? SA_RESTART : 0;
    ::sigaction(SIGINT, &stop, nullptr);
    ::sigaction(SIGTERM, &stop, nullptr);
    // A hangup (the terminal or SSH session gone) stops as Ctrl-C does: check restores what it wrote and
    // writes its reports, slave and sniff close and flush, instead of dying with the device left changed.
    // Unless it is ignored already (nohup): that is the user's wish to outlive the terminal.
    struct sigaction hup {};
    if (::sigaction(SIGHUP, nullptr, &hup) == 0 && hup.sa_handler != SIG_IGN) {
        ::sigaction(SIGHUP, &stop, nullptr);
        hangup_stops = true;
    }
    if (broken_pipe == BrokenPipe::Ignored) std::signal(SIGPIPE, SIG_IGN);
    if (broken_pipe == BrokenPipe::Stops) ::sigaction(SIGPIPE, &stop, nullptr);
}

}  // namespace

std::atomic<bool>& stop_on_signals(BrokenPipe broken_pipe) {
    installed_broken_pipe = broken_pipe;
    install(broken_pipe, false);
    sigset_t stops;
    sigemptyset(&stops);
    sigaddset(&stops, SIGINT);
    sigaddset(&stops, SIGTERM);
    if (hangup_stops) sigaddset(&stops, SIGHUP);
    ::sigprocmask(SIG_UNBLOCK, &stops, nullptr);
    return stop_requested;
}

void run_begins() {
    install(installed_broken_pipe, true);
}

const std::atomic<bool>& second_stop_signal() {
    return stop_requested_again;
}

unsigned stop_signal_count() {
    return stop_signals.load();
}

void stop_is_forced(unsigned seconds) {
    struct sigaction alarm {};
    alarm.sa_handler = die_by_stop_signal;
    sigemptyset(&alarm.sa_mask);
    ::sigaction(SIGALRM, &alarm, nullptr);
    forced_after_s = static_cast<sig_atomic_t>(seconds);
}

}  // namespace mbscope::cli
