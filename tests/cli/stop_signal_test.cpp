// A stop signal that comes before a long run has begun (cli/stop_signal.hpp): fuzz, check, replay, slave and
// sniff end the documented way, with their exit code and their summary or report saying they were
// interrupted, not killed by it. `mbscope fuzz --profile walchem-w900 --duration 20s` sent SIGTERM in its
// first 0.3 s exited 143 with no JSON: the handlers were installed once the profile had loaded (check's once
// the target was open).
//
// The signal is made as early as can be with no timing: SIGTERM is blocked and raised before the exec, which
// keeps both, so it is pending when the command starts and lands the moment the command installs its
// handlers and unblocks it. Before, it stayed pending and the run went on as if never signalled.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "tests/slave/slave_process.hpp"
#include "tests/support/process_support.hpp"

namespace test_cli_stop_signal_test {

namespace {

namespace fs = std::filesystem;
using mbscope::test::slurp;
using mbscope::test::wait_for;

struct Ended {
    int exit_code = -1;  // -1: killed by a signal, or did not end
    int signal = 0;      // the signal that killed it
    std::string out, err;
};

// `mbscope ARGS` in a child process, its standard output and error in files, `pending` (SIGTERM unless
// told) pending from the start (blocked until the command unblocks it: stop_on_signals).
class Mbscope {
  public:
    Mbscope(const std::string& name, std::vector<std::string> args, int pending = SIGTERM)
        : out_(fs::path(::testing::TempDir()) / (name + ".out")),
          err_(fs::path(::testing::TempDir()) / (name + ".err")) {
        args.insert(args.begin(), MBSCOPE_BINARY);
        std::vector<char*> argv;
        for (auto& a : args)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        const std::string out = out_.string(), err = err_.string();
        // Blocked across the fork: a SIGTERM the test sends at once waits for the command's handlers rather
        // than ending the child before its exec.
        sigset_t term, before;
        sigemptyset(&term);
        sigaddset(&term, pending);
        ::sigprocmask(SIG_BLOCK, &term, &before);
        pid_ = ::fork();
        if (pid_ != 0) {
            ::sigprocmask(SIG_SETMASK, &before, nullptr);
            return;
        }
        // The child: only calls that are safe between fork and exec.
        const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (o < 0 || e < 0 || ::dup2(o, 1) < 0 || ::dup2(e, 2) < 0) ::_exit(127);
        struct sigaction by_default {};
        by_default.sa_handler = SIG_DFL;
        ::sigaction(pending, &by_default, nullptr);
        ::raise(pending);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    ~Mbscope() {
        if (!running()) return;
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status_, 0);
    }
    Mbscope(const Mbscope&) = delete;
    Mbscope& operator=(const Mbscope&) = delete;

    bool started() const { return pid_ > 0; }
    bool running() { return pid_ > 0 && !reap(); }
    void signal(int number) {
        if (running()) ::kill(pid_, number);
    }
    // Waits for the command to end by itself (a run that would not end is killed, and said to be).
    Ended wait() {
        if (!wait_for([&] { return !running(); }) && running()) {
            ::kill(pid_, SIGKILL);
            ::waitpid(pid_, &status_, 0);
            ended_ = true;
            return {-1, SIGKILL, slurp(out_.string()), "did not end: " + slurp(err_.string())};
        }
        Ended e;
        e.exit_code = WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
        e.signal = WIFSIGNALED(status_) ? WTERMSIG(status_) : 0;
        e.out = slurp(out_.string());
        e.err = slurp(err_.string());
        return e;
    }

  private:
    // True once the child has ended (its status kept).
    bool reap() {
        if (pid_ <= 0) return true;
        if (ended_) return true;
        ended_ = ::waitpid(pid_, &status_, WNOHANG) == pid_;
        return ended_;
    }

    fs::path out_, err_;
    pid_t pid_ = -1;
    int status_ = 0;
    bool ended_ = false;
};

std::string read_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

// A pseudo-terminal's slave side for sniff to read: the path, the master kept open while the object lives.
class Pty {
  public:
    Pty() : master_(::posix_openpt(O_RDWR | O_NOCTTY)) {
        if (master_ >= 0 && ::grantpt(master_) == 0 && ::unlockpt(master_) == 0) path_ = ::ptsname(master_);
    }
    ~Pty() {
        if (master_ >= 0) ::close(master_);
    }
    Pty(const Pty&) = delete;
    Pty& operator=(const Pty&) = delete;
    const std::string& path() const { return path_; }
    int master() const { return master_; }  // the line's far end

  private:
    int master_;
    std::string path_;
};

}  // namespace

// The reported case: the summary on stdout says the run was interrupted with nothing sent, exit 2 ("the run
// was interrupted before it found anything").
TEST(StopSignal, AFuzzRunSignalledBeforeItBeganPrintsItsSummaryAndExitsTwo) {
    mbscope::slave::test::SlaveProcess slave({"--profile", "walchem-w900", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    Mbscope fuzz("stop-signal-fuzz", {"fuzz", "--target", slave.address(), "--profile", "walchem-w900",
                                      "--duration", "20s", "--no-progress"});
    ASSERT_TRUE(fuzz.started());
    const auto ended = fuzz.wait();
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 2) << ended.err;
    const auto summary = nlohmann::json::parse(ended.out, nullptr, false);
    ASSERT_FALSE(summary.is_discarded()) << ended.out << ended.err;
    EXPECT_EQ(summary["stopped"], true) << ended.out;
    EXPECT_EQ(summary["requests"], 0) << ended.out;
    EXPECT_EQ(summary["profile"], "walchem-w900") << ended.out;
    EXPECT_NE(ended.err.find("mbscope fuzz: interrupted before the fuzzing began; nothing was judged"),
              std::string::npos)
        << ended.err;
    EXPECT_EQ(ended.err.find("cannot reach"), std::string::npos) << ended.err;
}

// check interrupted before it opened the target: every report asked for says "interrupted" (JUnit's
// run.interrupted in error), no rule run, exit 2.
TEST(StopSignal, ACheckSignalledBeforeItBeganWritesEveryReportAsInterrupted) {
    mbscope::slave::test::SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    const fs::path junit = fs::path(::testing::TempDir()) / "stop-signal-check.xml";
    const fs::path report = fs::path(::testing::TempDir()) / "stop-signal-check.json";
    fs::remove(junit);
    fs::remove(report);
    Mbscope check("stop-signal-check",
                  {"check", "--target", slave.address(), "--profile", "mmk-2030", "--interval", "0", "--json",
                   "--junit", junit.string(), "--report", report.string()});
    ASSERT_TRUE(check.started());
    const auto ended = check.wait();
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 2) << ended.err;
    const auto printed = nlohmann::json::parse(ended.out, nullptr, false);
    ASSERT_FALSE(printed.is_discarded()) << ended.out << ended.err;
    EXPECT_EQ(printed["summary"]["verdict"], "interrupted") << ended.out;
    EXPECT_EQ(printed["stopped"], true);
    EXPECT_EQ(printed["requests"], 0);
    EXPECT_TRUE(printed["rules"].empty()) << ended.out;
    const auto written = nlohmann::json::parse(read_file(report), nullptr, false);
    ASSERT_FALSE(written.is_discarded());
    EXPECT_EQ(written["summary"]["verdict"], "interrupted");
    EXPECT_NE(read_file(junit).find("name=\"run.interrupted\""), std::string::npos) << read_file(junit);
}

// replay interrupted once its file was read, before the target was opened: nothing sent, "stopped", exit 2.
TEST(StopSignal, AReplaySignalledBeforeItOpenedTheTargetSendsNothingAndExitsTwo) {
    mbscope::slave::test::SlaveProcess slave({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    const fs::path file = fs::path(::testing::TempDir()) / "stop-signal-replay.json";
    // One step: FC6 writes holding register 20 (Modbus/TCP, transaction 1, unit 1).
    std::ofstream(file) << R"({"mbscope_reproducer": 1, "rule": "reply.echo", "source": "AP §6",
        "profile": "modbus", "unit": 1, "framing": "tcp", "target": ")"
                        << slave.address() << R"(",
        "steps": [{"parts": ["00 01 00 00 00 06 01 06 00 14 77 77"], "recipe": "write register 20"}]})";
    Mbscope replay("stop-signal-replay", {"replay", file.string(), "--json"});
    ASSERT_TRUE(replay.started());
    const auto ended = replay.wait();
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 2) << ended.out << ended.err;
    const auto printed = nlohmann::json::parse(ended.out, nullptr, false);
    ASSERT_FALSE(printed.is_discarded()) << ended.out << ended.err;
    EXPECT_EQ(printed["stopped"], true) << ended.out;
    EXPECT_EQ(printed["reproduced"], false);
    EXPECT_TRUE(printed["steps"].empty()) << ended.out;
    EXPECT_TRUE(printed["restored"].empty()) << ended.out;
}

// A slave stops as it does when it is serving: exit 0, its counts said.
void expect_slave_stopped_with_counts(Mbscope& slave) {
    ASSERT_TRUE(slave.started());
    const auto ended = slave.wait();
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 0) << ended.err;
    EXPECT_NE(ended.err.find("mbscope slave: 0 requests, 0 responses, 0 bad frames, 0 connections"),
              std::string::npos)
        << ended.err;
}

TEST(StopSignal, ASlaveSignalledBeforeItServedStopsWithItsCounts) {
    Mbscope slave("stop-signal-slave", {"slave", "--listen", "tcp://127.0.0.1:0"});
    expect_slave_stopped_with_counts(slave);
}

// A hangup stops a run as SIGTERM does (cli/stop_signal.hpp), blocked or not when the command started: a
// slave started with SIGHUP blocked (a parent's mask) held a hangup pending for ever, where it unblocked
// SIGINT and SIGTERM.
TEST(StopSignal, AHangupPendingFromTheStartStopsASlaveAsSigtermDoes) {
    Mbscope slave("stop-signal-slave-hup", {"slave", "--listen", "tcp://127.0.0.1:0"}, SIGHUP);
    expect_slave_stopped_with_counts(slave);
}

// A capture stops and prints its summary, as at a later SIGTERM.
TEST(StopSignal, ASniffSignalledBeforeItCapturedPrintsItsSummary) {
    Pty line;
    ASSERT_FALSE(line.path().empty());
    Mbscope sniff("stop-signal-sniff", {"sniff", "--serial", line.path(), "--summary"});
    ASSERT_TRUE(sniff.started());
    const auto ended = sniff.wait();
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 0) << ended.out << ended.err;
    EXPECT_NE(ended.out.find("summary: 0 packets"), std::string::npos) << ended.out << ended.err;
}

// While a command prepares, a signal cuts short a call that would wait for ever: sniff opening its --csv
// FIFO, which no one reads, ends saying it was interrupted (exit 2), instead of waiting on (the call started
// again after the handler). SIGTERM is sent until the command ends, one of them coming while it waits in the
// open; pending from the start, as above, so that none comes before the handlers are there.
TEST(StopSignal, ASignalCutsShortAStepOfThePreparationThatWouldWaitForEver) {
    Pty line;
    ASSERT_FALSE(line.path().empty());
    const fs::path fifo = fs::path(::testing::TempDir()) / "stop-signal-sniff.csv";
    fs::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    Mbscope sniff("stop-signal-sniff-fifo", {"sniff", "--serial", line.path(), "--csv", fifo.string()});
    ASSERT_TRUE(sniff.started());
    const bool ended_by_signals = wait_for([&] {
        sniff.signal(SIGTERM);
        return !sniff.running();
    });
    // Should it wait on, a reader lets it through the open.
    if (!ended_by_signals) ::close(::open(fifo.c_str(), O_RDONLY | O_NONBLOCK));
    const auto ended = sniff.wait();
    EXPECT_TRUE(ended_by_signals) << ended.err;
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 2) << ended.err;
    EXPECT_NE(ended.err.find("mbscope sniff: interrupted before the capture began"), std::string::npos)
        << ended.err;
    fs::remove(fifo);
}

// Sniff's output blocked by a reader that never reads (here its --csv FIFO; `sniff | (sleep 20; cat)` alike):
// the write it waits in starts again after the handler, and SIGTERM was ignored until the reader read. A stop
// that has not ended the run in 5 s ends it by the signal.
TEST(StopSignal, ASniffWhoseOutputIsBlockedEndsByTheSignal) {
    Pty line;
    ASSERT_FALSE(line.path().empty());
    const fs::path fifo = fs::path(::testing::TempDir()) / "stop-signal-blocked.csv";
    fs::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);  // open, and never read
    ASSERT_GE(reader, 0);
    // Nothing pending from the start: SIGWINCH, ignored by default.
    Mbscope sniff("stop-signal-blocked",
                  {"sniff", "--serial", line.path(), "--framing", "rtu", "--csv", fifo}, SIGWINCH);
    ASSERT_TRUE(sniff.started());
    // The MK manual's FC3 exchange (000:356-370), again and again, until the FIFO is full.
    const std::vector<std::uint8_t> exchange{0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45, 0x11, 0x03,
                                             0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA};
    ::fcntl(line.master(), F_SETFL, ::fcntl(line.master(), F_GETFL) | O_NONBLOCK);
    // Full: what it holds no longer grows while the line still brings exchanges (a pipe's pages fill with
    // whatever each flush wrote, so how much it holds when full varies).
    int queued = 0, unchanged = 0;
    const bool full = wait_for([&] {
        for (int i = 0; i < 20; ++i)
            if (::write(line.master(), exchange.data(), exchange.size()) < 0) break;
        int now = 0;
        if (::ioctl(reader, FIONREAD, &now) != 0) return false;
        unchanged = now > 0 && now == queued ? unchanged + 1 : 0;
        queued = now;
        return unchanged >= 50;
    });
    ASSERT_TRUE(full) << "the CSV FIFO never filled: " << queued << " bytes; "
                      << read_file(fs::path(::testing::TempDir()) / "stop-signal-blocked.err");
    sniff.signal(SIGTERM);
    const auto ended = sniff.wait();
    EXPECT_EQ(ended.signal, SIGTERM) << ended.exit_code << ": " << ended.err;
    ::close(reader);
}

// check's report going to a FIFO no one reads: the finished run waited in the open for ever, SIGINT and
// SIGTERM ignored (the call starts again after the handler). It waits for a reader until a stop signal, then
// says the report was not written (exit 2).
TEST(StopSignal, ACheckWaitingForItsReportsReaderStopsAtASignal) {
    const fs::path fifo = fs::path(::testing::TempDir()) / "stop-signal-check.json";
    fs::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    // SIGTERM pending from the start, as above: the run is interrupted before it begins and its report goes
    // to the FIFO, where the signals sent next find it waiting.
    Mbscope check("stop-signal-check-fifo",
                  {"check", "--target", "tcp://127.0.0.1:1", "--report", fifo.string()});
    ASSERT_TRUE(check.started());
    const bool ended_by_signals = wait_for([&] {
        check.signal(SIGTERM);
        return !check.running();
    });
    // Should it wait on, a reader lets it through.
    if (!ended_by_signals) ::close(::open(fifo.c_str(), O_RDONLY | O_NONBLOCK));
    const auto ended = check.wait();
    EXPECT_TRUE(ended_by_signals) << ended.err;
    EXPECT_EQ(ended.signal, 0) << ended.err;
    EXPECT_EQ(ended.exit_code, 2) << ended.err;
    EXPECT_NE(ended.err.find("no reader of the FIFO came before the stop"), std::string::npos) << ended.err;
    fs::remove(fifo);
}

}  // namespace test_cli_stop_signal_test
