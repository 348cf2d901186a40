#pragma once
// The mbscope binary run as a user runs it: arguments as a shell line, standard output and error together,
// the exit code.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace mbscope::test {

struct CliRun {
    int exit_code = -1;
    std::string out;
};

// `env` (NAME=VALUE ...) is put before the command.
inline CliRun run_mbscope(const std::string& args, const std::string& env = "") {
    const std::string command = env + " " + std::string(MBSCOPE_BINARY) + " " + args + " 2>&1";
    FILE* p = ::popen(command.c_str(), "r");
    if (!p) return {};
    std::string out;
    std::array<char, 4096> buf{};
    while (std::size_t n = std::fread(buf.data(), 1, buf.size(), p))
        out.append(buf.data(), n);
    return {WEXITSTATUS(::pclose(p)), out};
}

}  // namespace mbscope::test
