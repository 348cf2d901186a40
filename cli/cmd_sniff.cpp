// mbscope sniff: live traffic in (a network interface, or one or two serial ports); frames, transactions,
// findings and a summary out, as mbscope decode prints them, and optionally a capture file.
#include <csignal>
#include <iostream>
#include <memory>

#include "analyzer/analyzer.hpp"
#include "analyzer/live_capture.hpp"
#include "analyzer/sinks.hpp"
#include "cli/commands.hpp"

namespace mbscope::cli {
namespace {

std::atomic<bool> stop_requested{false};

extern "C" void on_stop_signal(int) {
    stop_requested = true;
}

struct SniffCliOptions {
    analyzer::SniffOptions sniff;
    std::vector<std::uint16_t> tcp_ports, udp_ports;
    double duration_s = 0;
    std::uint64_t count = 0;
    std::uint32_t baud = 9600;
    std::string parity = "N";
    int data_bits = 8, stop_bits = 1;
    bool jsonl = false, summary = false;
};

int run_sniff(SniffCliOptions o) {
    auto& s = o.sniff;
    s.tcp_ports.insert(s.tcp_ports.end(), o.tcp_ports.begin(), o.tcp_ports.end());
    s.udp_ports.insert(s.udp_ports.end(), o.udp_ports.begin(), o.udp_ports.end());
    if (o.duration_s > 0) s.duration = std::chrono::duration<double>(o.duration_s);
    if (o.count > 0) s.count = o.count;
    s.line = {o.baud, static_cast<std::uint8_t>(o.data_bits), *modbus::parse_parity(o.parity),
              static_cast<std::uint8_t>(o.stop_bits)};
    std::string error;
    bool permission_denied = false;
    auto capture = analyzer::LiveCapture::open(s, error, permission_denied);
    if (!capture) {
        std::cerr << "mbscope sniff: " << error
                  << (permission_denied ? " (capturing needs root or CAP_NET_RAW; serial ports need the "
                                          "device's group)"
                                        : "")
                  << '\n';
        return exit_failure;
    }
    analyzer::AnalyzerOptions options;
    options.tcp_ports = s.tcp_ports;
    options.udp_ports = s.udp_ports;
    options.serial_line = s.line;
    std::unique_ptr<analyzer::Sink> sink;
    if (o.jsonl)
        sink = std::make_unique<analyzer::JsonSink>(std::cout, true);
    else
        sink = std::make_unique<analyzer::TextSink>(std::cout, o.summary);
    analyzer::Analyzer a(options, *sink);
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    const bool ok = capture->run(a, stop_requested);
    a.finish();
    for (const auto& e : a.summary().input_errors)
        std::cerr << "mbscope sniff: " << e << '\n';
    if (!ok) return exit_failure;
    return a.summary().errors ? exit_findings : exit_ok;
}

}  // namespace

void register_sniff(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<SniffCliOptions>();
    auto* cmd = app.add_subcommand("sniff", "Capture live traffic and decode it as it comes");
    auto* iface = cmd->add_option("--interface", o->sniff.interface,
                                  "Network interface to capture from (libpcap: lo, eth0, any)");
    auto* serial = cmd->add_option("--serial", o->sniff.serial,
                                   "Serial port to read (the whole line, or the master's transmit line "
                                   "with --serial2)");
    cmd->add_option("--serial2", o->sniff.serial2, "Serial port carrying the slaves' responses")
        ->needs(serial);
    iface->excludes(serial);
    cmd->add_option("--tcp-port", o->tcp_ports, "Modbus/TCP server port besides 502 (repeatable)");
    cmd->add_option("--udp-port", o->udp_ports, "Modbus/UDP server port besides 502 (repeatable)");
    cmd->add_option("--baud", o->baud, "Serial line: baud rate")->capture_default_str();
    cmd->add_option("--parity", o->parity, "Serial line: N, E or O")
        ->check(CLI::IsMember({"N", "E", "O", "n", "e", "o", "none", "even", "odd"}))
        ->capture_default_str();
    cmd->add_option("--data-bits", o->data_bits, "Serial line: data bits")->check(CLI::Range(5, 8));
    cmd->add_option("--stop-bits", o->stop_bits, "Serial line: stop bits")->check(CLI::Range(1, 2));
    cmd->add_option("--write", o->sniff.write,
                    "Also write what was captured to FILE (classic pcap, as libpcap writes; serial bytes as "
                    "USER0 records, read back with mbscope decode --user-dlt rtu)");
    cmd->add_option("--duration", o->duration_s, "Stop after this many seconds");
    cmd->add_option("--count", o->count, "Stop after this many packets (serial: reads)");
    cmd->add_flag("--jsonl", o->jsonl, "One JSON object per line, as mbscope decode --jsonl");
    cmd->add_flag("--summary", o->summary, "Only the summary");
    cmd->footer(
        "Stops at --duration, --count, SIGINT or SIGTERM, then prints the summary.\n"
        "Exit codes: 0 no error-severity finding, 1 faults found, 2 the capture could not be opened "
        "or failed.");
    cmd->callback([o, &exit_code] { exit_code = run_sniff(*o); });
}

}  // namespace mbscope::cli
