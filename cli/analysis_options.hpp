#pragma once
// The options mbscope decode and mbscope sniff share, registered by one function so that both commands
// take them alike: server ports, the serial line's framing and character format, the response timeout, device
// profiles (--profile, --map, --profile-dir, --config), --word-order, and the outputs (--json, --jsonl,
// --summary, --csv).

#include <CLI/CLI.hpp>
#include <cstdint>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "analyzer/analyzer.hpp"
#include "analyzer/sinks.hpp"

namespace mbscope::cli {

struct AnalysisCliOptions {
    std::vector<std::uint16_t> tcp_ports, udp_ports;  // besides 502
    std::vector<std::uint16_t> rtu_over_tcp_ports;    // serial gateways' raw RTU streams
    std::uint32_t baud = 9600;
    std::string parity = "N";
    int data_bits = 8, stop_bits = 1;
    std::string framing = "auto";  // serial lines: auto, rtu, ascii
    double timeout_s = 0;  // --timeout; 0: not given, each carrier keeps its default (TCP 3 s, serial 1 s)
    std::string profile;
    std::vector<std::string> maps, profile_dirs, config;
    std::string word_order;
    std::string csv;
    bool json = false, jsonl = false, summary = false;
};

// Registers the shared options on `cmd`.
void add_analysis_options(CLI::App& cmd, AnalysisCliOptions& o);

// Fills the analyzer's options from the shared ones (profiles loaded from the profile directories).
// False, with the reason on standard error prefixed by "mbscope COMMAND: ", when a profile, map or
// configuration cannot be used.
bool apply_analysis_options(const AnalysisCliOptions& o, const std::string& command,
                            analyzer::AnalyzerOptions& options);

// Writes the summary's input errors and notes to standard error, prefixed by "mbscope COMMAND: ". True
// when there was an input error: part of the input could not be read or decoded, and the run fails (exit 2)
// with everything else decoded still reported; notes alone do not fail it.
bool report_input_problems(const analyzer::Summary& s, const std::string& command);

// Notes on standard error for each --map that described no device: its selector matched nothing the input
// showed (a mistyped address, a unit never on the line), or every device it matched took a more specific one.
// After the run; the exit code is not changed.
void report_unused_maps(const AnalysisCliOptions& o, const analyzer::AnalyzerOptions& options,
                        const std::string& command);

// The sinks the output options ask for, teed into one.
class Outputs {
  public:
    // False, with the reason on standard error, when the CSV file cannot be written or two outputs want
    // standard output.
    bool open(const AnalysisCliOptions& o, const std::string& command);
    analyzer::Sink& sink() { return *tee_; }
    // True when records (not only the summary) go to standard output.
    bool records_on_stdout() const noexcept { return records_on_stdout_; }

  private:
    std::ofstream csv_file_;
    std::vector<std::unique_ptr<analyzer::Sink>> sinks_;
    std::unique_ptr<analyzer::TeeSink> tee_;
    bool records_on_stdout_ = false;
};

}  // namespace mbscope::cli
