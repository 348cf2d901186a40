// mbscope decode: captures in; frames, transactions, findings and a summary out.
#include <unistd.h>

#include <fstream>
#include <iostream>
#include <memory>

#include "analyzer/analyzer.hpp"
#include "analyzer/sinks.hpp"
#include "cli/commands.hpp"

namespace mbscope::cli {
namespace {

struct DecodeOptions {
    std::vector<std::string> files;
    std::vector<std::uint16_t> tcp_ports;
    std::vector<std::uint16_t> udp_ports;
    bool json = false, jsonl = false, summary = false;
    double timeout_s = 3.0;
    std::string format = "auto";
};

int run_decode(const DecodeOptions& o) {
    analyzer::AnalyzerOptions options;
    for (auto p : o.tcp_ports)
        options.tcp_ports.push_back(p);
    for (auto p : o.udp_ports)
        options.udp_ports.push_back(p);
    options.timeout =
        std::chrono::duration_cast<modbus::Timestamp>(std::chrono::duration<double>(o.timeout_s));
    std::unique_ptr<analyzer::Sink> sink;
    if (o.json || o.jsonl)
        sink = std::make_unique<analyzer::JsonSink>(std::cout, o.jsonl);
    else
        sink = std::make_unique<analyzer::TextSink>(std::cout, o.summary);
    analyzer::Analyzer a(options, *sink);
    bool all_read = true, any_read = false;
    for (const auto& f : o.files) {
        const bool ok = a.read_capture(f);
        all_read &= ok;
        any_read |= ok || a.summary().packets > 0;
    }
    a.finish();
    for (const auto& e : a.summary().input_errors)
        std::cerr << "mbscope decode: " << e << '\n';
    if (!any_read) return exit_failure;
    if (!all_read) return exit_failure;
    return a.summary().errors ? exit_findings : exit_ok;
}

}  // namespace

void register_decode(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<DecodeOptions>();
    auto* cmd = app.add_subcommand("decode", "Decode captures: every frame, every transaction, every fault");
    cmd->add_option("files", o->files, "pcap or pcapng files")->required()->check(CLI::ExistingFile);
    cmd->add_option("--tcp-port", o->tcp_ports, "Modbus/TCP server port besides 502 (repeatable)");
    cmd->add_option("--udp-port", o->udp_ports, "Modbus/UDP server port besides 502 (repeatable)");
    cmd->add_option("--timeout", o->timeout_s,
                    "Seconds without a response before a request is reported unanswered")
        ->capture_default_str();
    auto* json = cmd->add_flag("--json", o->json, "One JSON document: every record, then the summary");
    auto* jsonl = cmd->add_flag("--jsonl", o->jsonl,
                                "One JSON object per line (frame, transaction, finding, unparsed, summary)");
    cmd->add_flag("--summary", o->summary, "Only the summary (the fastest path)");
    json->excludes(jsonl);
    cmd->footer(
        "Exit codes: 0 decoded with no error-severity finding, 1 faults found, 2 an input could not be "
        "read.\n"
        "Record types and fields: analyzer/README.md.");
    cmd->callback([o, &exit_code] { exit_code = run_decode(*o); });
}

}  // namespace mbscope::cli
