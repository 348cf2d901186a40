// mbscope sniff: live traffic in (a network interface, or one or two serial ports); frames, transactions,
// findings and a summary out, as mbscope decode prints them (the same output, profile and port options),
// and optionally a capture file.
#include <algorithm>
#include <iostream>
#include <limits>
#include <memory>

#include "analyzer/analyzer.hpp"
#include "analyzer/live_capture.hpp"
#include "cli/analysis_options.hpp"
#include "cli/commands.hpp"
#include "cli/number_checks.hpp"
#include "cli/stop_signal.hpp"

namespace mbscope::cli {
namespace {

struct SniffCliOptions {
    AnalysisCliOptions common;
    analyzer::SniffOptions sniff;
    std::string duration;  // checked by duration_text()
    std::uint64_t count = 0;
};

// A step before the capture failed: exit 2, and said to be the stop's doing when a signal cut it short (the
// open of a --csv FIFO no one reads, interrupted).
// A stop ends the capture, drains what is waiting (half a second at most) and prints the summary: far less
// than this, unless the output is blocked.
constexpr unsigned stop_forced_after_s = 5;

int not_started(const std::atomic<bool>& stop) {
    if (stop) std::cerr << "mbscope sniff: interrupted before the capture began\n";
    return exit_failure;
}

int run_sniff(SniffCliOptions o) {
    // Before the profiles load and the capture opens: a signal from here on stops the capture as one during
    // it does (the summary printed), not by killing it.
    const auto& stop = stop_on_signals(BrokenPipe::Stops);
    analyzer::AnalyzerOptions options;
    if (!apply_analysis_options(o.common, "sniff", options)) return not_started(stop);
    auto& s = o.sniff;
    s.tcp_ports = options.tcp_ports;
    // A serial gateway's port is captured as a Modbus/TCP port is; the analyzer reads its streams as RTU.
    for (auto p : options.rtu_over_tcp_ports)
        if (std::find(s.tcp_ports.begin(), s.tcp_ports.end(), p) == s.tcp_ports.end())
            s.tcp_ports.push_back(p);
    s.udp_ports = options.udp_ports;
    s.line = options.serial_line;
    if (!o.duration.empty()) s.duration = *parse_duration(o.duration);
    if (o.count > 0) s.count = o.count;
    Outputs outputs;
    if (!outputs.open(o.common, "sniff")) return not_started(stop);
    std::string error;
    bool permission_denied = false;
    auto capture = analyzer::LiveCapture::open(s, error, permission_denied);
    if (!capture) {
        std::cerr << "mbscope sniff: " << error
                  << (permission_denied ? " (capturing needs root or CAP_NET_RAW; serial ports need the "
                                          "device's group)"
                                        : "")
                  << '\n';
        return not_started(stop);
    }
    analyzer::Analyzer a(options, outputs.sink());
    run_begins();
    // From here a blocking write starts again after a signal (the preparation's calls fail with EINTR).
    stop_is_forced(stop_forced_after_s);
    const bool ok = capture->run(a, stop);
    a.finish();
    const bool input_errors = report_input_problems(a.summary(), "sniff");
    report_unused_maps(o.common, options, "sniff");
    if (!s.write.empty() && !s.serial.empty()) {
        // The framing the line was read in: the records do not say it, --user-dlt must.
        const auto read = a.serial_framings_read();
        const std::string framing = read.size() == 1 && read[0] == modbus::Framing::Ascii ? "ascii" : "rtu";
        std::cerr << "mbscope sniff: " << s.write << " holds the serial bytes as USER0 records; read it "
                  << "with mbscope decode --user-dlt " << framing
                  << (capture->direction_header() ? "-dir" : "") << '\n';
    }
    if (!ok || input_errors) return exit_failure;
    return a.summary().errors ? exit_findings : exit_ok;
}

}  // namespace

void register_sniff(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<SniffCliOptions>();
    auto* cmd = app.add_subcommand("sniff", "Capture live traffic and decode it as it comes");
    auto* iface = cmd->add_option("-i,--interface", o->sniff.interface,
                                  "Network interface to capture from (libpcap: lo, eth0, any)");
    auto* serial = cmd->add_option("--serial", o->sniff.serial,
                                   "Serial port to read (the whole line, or the master's transmit line "
                                   "with --serial2)");
    cmd->add_option("--serial2", o->sniff.serial2, "Serial port carrying the slaves' responses")
        ->needs(serial);
    iface->excludes(serial);
    add_analysis_options(*cmd, o->common);
    cmd->add_option("--write", o->sniff.write,
                    "Also write what was captured to FILE: pcapng (nanosecond timestamps) when the name "
                    "ends in .pcapng, in any case; classic pcap otherwise. Serial bytes are USER0 records: "
                    "read back with mbscope decode --user-dlt rtu (or ascii), --user-dlt rtu-dir (ascii-dir) "
                    "with --serial2 (a direction byte leads each record), as said at the end");
    cmd->add_option("--duration", o->duration, "Stop after this long: 60 (seconds), 60s, 500ms, 5m")
        ->check(duration_text());
    cmd->add_option("--buffer-size", o->sniff.buffer_mib,
                    "Network capture: the kernel's buffer for packets not yet read, in MiB (as tcpdump -B); "
                    "packets it drops when full are said as input errors")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    cmd->add_option("--count", o->count, "Stop after this many packets (serial: reads)")
        ->check(whole_number("N"))  // before the range: CLI11 wraps "-1" to 2^64-1, which it passes
        ->check(CLI::Range(std::uint64_t{1}, std::numeric_limits<std::uint64_t>::max()));
    cmd->footer(
        "Stops at --duration, --count, SIGINT, SIGTERM or SIGHUP, then prints the summary. A stop that has\n"
        "not ended within 5 s (its output blocked by a reader that does not read), or a second signal,\n"
        "ends the process by the signal; the --write file holds what was captured until then.\n"
        "Exit codes: 0 no error-severity finding, 1 faults found, 2 the capture could not be opened "
        "or failed, or its --write file could not be written.");
    cmd->callback([o, &exit_code] { exit_code = run_sniff(*o); });
}

}  // namespace mbscope::cli
