#pragma once
// The slave as a whole process: the mbscope binary (MBSCOPE_BINARY) started with `slave` and the given
// arguments, its stdout read for the address it prints first, stopped with SIGTERM when the object goes.
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <string>
#include <vector>

extern char** environ;

namespace mbscope::slave::test {

// `mbscope slave ...` with its stdout read for the address it prints first. With `with_stderr`, standard
// error goes to the same pipe, kept open for read_until().
class SlaveProcess {
  public:
    explicit SlaveProcess(std::vector<std::string> args, bool with_stderr = false) {
        args.insert(args.begin(), {MBSCOPE_BINARY, "slave"});
        std::vector<char*> argv;
        for (auto& a : args)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        int out[2];
        if (::pipe(out) != 0) return;
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_adddup2(&actions, out[1], 1);
        if (with_stderr) posix_spawn_file_actions_adddup2(&actions, out[1], 2);
        posix_spawn_file_actions_addclose(&actions, out[0]);
        spawned_ = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) == 0;
        posix_spawn_file_actions_destroy(&actions);
        ::close(out[1]);
        // The first line: "tcp://127.0.0.1:PORT", or the pseudo-terminal's path. A sanitizer build on a
        // loaded machine takes seconds to load the profiles before it prints it.
        char ch;
        pollfd p{out[0], POLLIN, 0};
        while (spawned_ && ::poll(&p, 1, 30'000) > 0 && ::read(out[0], &ch, 1) == 1 && ch != '\n')
            address_ += ch;
        if (with_stderr)
            output_fd_ = out[0];
        else
            ::close(out[0]);
        const auto colon = address_.rfind(':');
        if (colon != std::string::npos && address_.find("://") != std::string::npos)
            port_ = static_cast<std::uint16_t>(std::stoi(address_.substr(colon + 1)));
    }
    ~SlaveProcess() {
        kill(SIGTERM);
        if (output_fd_ >= 0) ::close(output_fd_);
    }
    SlaveProcess(const SlaveProcess&) = delete;
    SlaveProcess& operator=(const SlaveProcess&) = delete;

    std::uint16_t port() const noexcept { return port_; }
    // What the slave printed first: the URI clients connect to, or the pseudo-terminal's path.
    const std::string& address() const noexcept { return address_; }
    // With with_stderr: what the slave writes after its first line, read until the whole line holding `text`
    // has come (standard error is unbuffered: a line may arrive in pieces) or 30 s have passed (a sanitizer
    // build starts slowly).
    std::string read_until(const std::string& text) {
        std::string got;
        char buf[512];
        pollfd p{output_fd_, POLLIN, 0};
        const auto line_complete = [&] {
            const auto at = got.find(text);
            return at != std::string::npos && got.find('\n', at) != std::string::npos;
        };
        while (output_fd_ >= 0 && !line_complete() && ::poll(&p, 1, 30'000) > 0) {
            const ssize_t n = ::read(output_fd_, buf, sizeof buf);
            if (n <= 0) break;
            got.append(buf, static_cast<std::size_t>(n));
        }
        return got;
    }
    // Waits for the process to end by itself: its exit code, or -1 when a signal ended it.
    int wait_exit() {
        if (!spawned_ || pid_ <= 0) return -1;
        int status = 0;
        ::waitpid(pid_, &status, 0);
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    // Sends `sig` and reaps the process.
    void kill(int sig) {
        if (!spawned_ || pid_ <= 0) return;
        ::kill(pid_, sig);
        int status = 0;
        ::waitpid(pid_, &status, 0);
        pid_ = -1;
    }

  private:
    pid_t pid_ = -1;
    bool spawned_ = false;
    std::uint16_t port_ = 0;
    std::string address_;
    int output_fd_ = -1;
};

}  // namespace mbscope::slave::test
