#pragma once
// Shared by the tests that drive other programs (socat, jpnevulator, pymodbus, mbscope itself):
// run a command for its output, read a file, start a process with its output in files and stop it by its
// id, poll for a condition.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace mbscope::test {

inline std::string run(const std::string& command) {
    std::string out;
    if (FILE* p = ::popen(command.c_str(), "r")) {
        std::array<char, 4096> buf{};
        while (std::size_t n = std::fread(buf.data(), 1, buf.size(), p))
            out.append(buf.data(), n);
        ::pclose(p);
    }
    return out;
}

inline std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

inline bool have(const std::string& program) {
    return std::system(("command -v " + program + " >/dev/null 2>&1").c_str()) == 0;
}

// A process whose standard output and error go to files; stopped with SIGTERM when it goes out of scope.
class Child {
  public:
    Child(std::vector<std::string> args, const std::string& out, const std::string& err) {
        std::vector<char*> argv;
        for (auto& a : args)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        spawned_ = ::posix_spawnp(&pid_, argv[0], &actions, nullptr, argv.data(), environ) == 0;
        posix_spawn_file_actions_destroy(&actions);
    }
    ~Child() { stop(); }
    Child(const Child&) = delete;
    Child& operator=(const Child&) = delete;
    bool spawned() const { return spawned_; }
    void stop() {
        if (!spawned_) return;
        ::kill(pid_, SIGTERM);
        int status = 0;
        ::waitpid(pid_, &status, 0);
        spawned_ = false;
    }
    // Waits for the child to end by itself: its exit code, or -1 when it was killed by a signal.
    int wait_exit() {
        if (!spawned_) return -1;
        int status = 0;
        ::waitpid(pid_, &status, 0);
        spawned_ = false;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }

  private:
    pid_t pid_ = 0;
    bool spawned_ = false;
};

// Polls until `ready` holds, for at most thirty seconds: under ASan+UBSan, with the suite running two tests
// at a time, a slave took more than five to print its pseudo-terminal. Only a failure waits that long.
template <typename F>
bool wait_for(F ready) {
    for (int i = 0; i < 3000; ++i) {
        if (ready()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
}

// Two socat pty pairs standing for the two taps of a serial line, in a fresh directory: DIR/m1 <-> DIR/m2
// (the master's transmit line) and DIR/s1 <-> DIR/s2 (the slaves'). The test writes into the m1 and s1
// ends, held open to the end (a pty end closed makes socat stop relaying); the program under test reads m2
// and s2. ready() is false when socat did not start or the ends could not be opened.
class SocatTaps {
  public:
    explicit SocatTaps(const std::string& dir)
        : dir_((std::filesystem::remove_all(dir), std::filesystem::create_directories(dir), dir)),
          master_pair_({"socat", "pty,raw,echo=0,link=" + dir + "/m1", "pty,raw,echo=0,link=" + dir + "/m2"},
                       "/dev/null", dir + "/socat1.err"),
          slave_pair_({"socat", "pty,raw,echo=0,link=" + dir + "/s1", "pty,raw,echo=0,link=" + dir + "/s2"},
                      "/dev/null", dir + "/socat2.err") {
        if (!wait_for([&] {
                return std::filesystem::exists(dir + "/m1") && std::filesystem::exists(dir + "/m2") &&
                       std::filesystem::exists(dir + "/s1") && std::filesystem::exists(dir + "/s2");
            }))
            return;
        master_end = ::open((dir + "/m1").c_str(), O_RDWR | O_NOCTTY);
        slave_end = ::open((dir + "/s1").c_str(), O_RDWR | O_NOCTTY);
    }
    ~SocatTaps() {
        if (master_end >= 0) ::close(master_end);
        if (slave_end >= 0) ::close(slave_end);
    }
    SocatTaps(const SocatTaps&) = delete;
    SocatTaps& operator=(const SocatTaps&) = delete;
    bool ready() const { return master_end >= 0 && slave_end >= 0; }
    std::string master_tap() const { return dir_ + "/m2"; }
    std::string slave_tap() const { return dir_ + "/s2"; }

    int master_end = -1, slave_end = -1;

  private:
    std::string dir_;
    Child master_pair_, slave_pair_;
};

}  // namespace mbscope::test
