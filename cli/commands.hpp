#pragma once
// Each subcommand registers itself on the application and returns the exit code through `exit_code`.
// Exit codes are stable: 0 success / nothing wrong found, 1 faults found, 2 the run could not complete.

#include <CLI/CLI.hpp>

namespace mbscope::cli {

inline constexpr int exit_ok = 0;
inline constexpr int exit_findings = 1;
inline constexpr int exit_failure = 2;

void register_decode(CLI::App& app, int& exit_code);
void register_frame(CLI::App& app, int& exit_code);
void register_profile(CLI::App& app, int& exit_code);
void register_slave(CLI::App& app, int& exit_code);
void register_check(CLI::App& app, int& exit_code);
void register_sniff(CLI::App& app, int& exit_code);
void register_fuzz(CLI::App& app, int& exit_code);
void register_replay(CLI::App& app, int& exit_code);

}  // namespace mbscope::cli
