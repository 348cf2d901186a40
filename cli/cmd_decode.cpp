// mbscope decode: captures in; frames, transactions, findings and a summary out.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>

#include "analyzer/analyzer.hpp"
#include "analyzer/csv_sink.hpp"
#include "analyzer/progress.hpp"
#include "analyzer/serial_input.hpp"
#include "analyzer/sinks.hpp"
#include "cli/commands.hpp"
#include "cli/profile_json.hpp"
#include "modbus/storage/profile_store.hpp"

namespace mbscope::cli {
namespace {

struct DecodeOptions {
    std::vector<std::string> files;
    std::vector<std::uint16_t> tcp_ports;
    std::vector<std::uint16_t> udp_ports;
    std::vector<std::uint16_t> rtu_over_tcp_ports;
    std::string user_dlt;
    std::string csv;
    std::string word_order;
    bool json = false, jsonl = false, summary = false, no_progress = false;
    double timeout_s = 3.0;
    std::string format = "auto";
    std::string profile;
    std::vector<std::string> maps;
    std::vector<std::string> profile_dirs;
    std::vector<std::string> config;
    std::uint32_t baud = 9600;
    std::string parity = "N";
    int data_bits = 8, stop_bits = 1;
    std::string master_alias, slave_alias;
    std::string socat_master = "left";
    std::string rtac_role;
};

// --profile ID for every device, --map SELECTOR=ID per device (SELECTOR: UNIT, IP or IP:UNIT).
bool load_semantics(const DecodeOptions& o, analyzer::AnalyzerOptions& options) {
    if (o.profile.empty() && o.maps.empty()) return true;
    modbus::storage::ProfileStore store(profile_directories(o.profile_dirs));
    modbus::ProfileConfig config;
    for (const auto& kv : o.config) {
        const auto eq = kv.find('=');
        if (eq == std::string::npos) {
            std::cerr << "mbscope decode: --config takes CHANNEL=MAP, not '" << kv << "'\n";
            return false;
        }
        config[kv.substr(0, eq)] = kv.substr(eq + 1);
    }
    auto semantics = std::make_shared<analyzer::Semantics>();
    auto add = [&](const analyzer::DeviceSelector& selector, const std::string& id) {
        auto p = store.load(id, config);
        if (!p) {
            for (const auto& e : p.error())
                std::cerr << "mbscope decode: " << modbus::to_string(e) << '\n';
            return false;
        }
        semantics->add(selector, std::make_shared<const modbus::Profile>(std::move(p.value())));
        return true;
    };
    if (!o.profile.empty() && !add({}, o.profile)) return false;
    for (const auto& m : o.maps) {
        const auto eq = m.find('=');
        auto selector = eq == std::string::npos ? std::nullopt : analyzer::parse_selector(m.substr(0, eq));
        if (!selector) {
            std::cerr << "mbscope decode: --map takes UNIT=ID, IP=ID or IP:UNIT=ID, not '" << m << "'\n";
            return false;
        }
        if (!add(*selector, m.substr(eq + 1))) return false;
    }
    options.semantics = std::move(semantics);
    return true;
}

int run_decode(const DecodeOptions& o) {
    analyzer::AnalyzerOptions options;
    for (auto p : o.tcp_ports)
        options.tcp_ports.push_back(p);
    for (auto p : o.udp_ports)
        options.udp_ports.push_back(p);
    options.rtu_over_tcp_ports = o.rtu_over_tcp_ports;
    if (!o.user_dlt.empty())
        options.user_dlt = o.user_dlt == "ascii" ? modbus::Framing::Ascii : modbus::Framing::Rtu;
    if (!o.rtac_role.empty())
        options.rtac_tx = o.rtac_role == "master" ? modbus::Direction::Request : modbus::Direction::Response;
    if (!o.word_order.empty()) options.word_order = modbus::parse_word_order(o.word_order);
    options.timeout =
        std::chrono::duration_cast<modbus::Timestamp>(std::chrono::duration<double>(o.timeout_s));
    if (!load_semantics(o, options)) return exit_failure;
    options.serial_line = {o.baud, static_cast<std::uint8_t>(o.data_bits), *modbus::parse_parity(o.parity),
                           static_cast<std::uint8_t>(o.stop_bits)};
    // --csv - takes standard output for itself; --csv FILE goes beside the usual output.
    if (o.csv == "-" && (o.json || o.jsonl || o.summary)) {
        std::cerr << "mbscope decode: --csv - and --json, --jsonl or --summary all want standard output\n";
        return exit_failure;
    }
    std::ofstream csv_file;
    if (!o.csv.empty() && o.csv != "-") {
        csv_file.open(o.csv, std::ios::binary);
        if (!csv_file) {
            std::cerr << "mbscope decode: cannot write " << o.csv << '\n';
            return exit_failure;
        }
    }
    std::vector<std::unique_ptr<analyzer::Sink>> sinks;
    if (!o.csv.empty())
        sinks.push_back(std::make_unique<analyzer::CsvSink>(o.csv == "-" ? std::cout : csv_file));
    if (o.csv != "-") {
        if (o.json || o.jsonl)
            sinks.push_back(std::make_unique<analyzer::JsonSink>(std::cout, o.jsonl));
        else
            sinks.push_back(std::make_unique<analyzer::TextSink>(std::cout, o.summary));
    }
    std::vector<analyzer::Sink*> outputs;
    for (auto& s : sinks)
        outputs.push_back(s.get());
    analyzer::TeeSink sink(outputs);

    // A progress line on standard error, only for a person at a terminal: never into a file or a pipe, and
    // not while records stream to the same terminal on standard output (they would tear the line).
    const bool records_on_terminal = ::isatty(STDOUT_FILENO) && !o.summary && o.csv != "-";
    std::optional<analyzer::ProgressMeter> meter;
    analyzer::ProgressState progress;
    if (!o.no_progress && ::isatty(STDERR_FILENO) && !records_on_terminal) {
        meter.emplace(std::cerr);
        for (const auto& f : o.files) {
            std::error_code ec;
            const auto size = std::filesystem::file_size(f, ec);
            if (!ec) progress.total_bytes += size;
        }
    }
    std::uint64_t files_done = 0;  // bytes of the files already read
    const auto show = [&](const analyzer::Summary& s, std::uint64_t offset) {
        progress.packets = s.packets;
        progress.bytes_read = files_done + offset;
        progress.frames = s.frames;
        progress.findings = 0;
        for (const auto& [code, n] : s.findings)
            progress.findings += n;
        meter->update(progress);
    };
    if (meter) options.progress = show;
    analyzer::Analyzer a(options, sink);
    bool all_read = true, any_read = false;
    const auto format = analyzer::parse_input_format(o.format);
    analyzer::SerialLogOptions logs;
    logs.master_alias = o.master_alias;
    logs.slave_alias = o.slave_alias;
    logs.socat_master_left = o.socat_master == "left";
    logs.line = options.serial_line;
    for (const auto& f : o.files) {
        const bool ok = analyzer::read_input(a, f, *format, logs);
        all_read &= ok;
        any_read |= ok || a.summary().packets > 0;
        if (meter) {
            std::error_code ec;
            const auto size = std::filesystem::file_size(f, ec);
            show(a.summary(), ec ? 0 : size);
            files_done += ec ? 0 : size;
        }
    }
    if (meter) meter->clear();
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
    cmd->add_option("files", o->files,
                    "Captures: pcap, pcapng, raw serial dumps, the text format (analyzer/README.md)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--format", o->format,
                    "auto, pcap, rtu (raw dump), ascii (raw dump), text (TIME [DIR] HEX...), jpnevulator "
                    "(--read --timing-print log), socat (socat -x -v standard error)")
        ->check(
            CLI::IsMember({"auto", "pcap", "pcapng", "rtu", "raw", "ascii", "text", "jpnevulator", "socat"}))
        ->capture_default_str();
    cmd->add_option("--master-alias", o->master_alias,
                    "jpnevulator logs: the --tty alias (or device) that carries the master's requests; the "
                    "other tty is the slave's");
    cmd->add_option("--slave-alias", o->slave_alias,
                    "jpnevulator logs: the --tty alias (or device) that carries the slaves' responses");
    cmd->add_option("--socat-master", o->socat_master,
                    "socat logs: which socat address is the master's side; '>' blocks flow from the left "
                    "(first) address to the right one")
        ->check(CLI::IsMember({"left", "right"}))
        ->capture_default_str();
    cmd->add_option("--baud", o->baud, "Serial line: baud rate (for t1.5/t3.5)")->capture_default_str();
    cmd->add_option("--parity", o->parity, "Serial line: N, E or O")
        ->check(CLI::IsMember({"N", "E", "O", "n", "e", "o", "none", "even", "odd"}))
        ->capture_default_str();
    cmd->add_option("--data-bits", o->data_bits, "Serial line: data bits")
        ->check(CLI::Range(5, 8))
        ->capture_default_str();
    cmd->add_option("--stop-bits", o->stop_bits, "Serial line: stop bits")
        ->check(CLI::Range(1, 2))
        ->capture_default_str();
    cmd->add_option("--tcp-port", o->tcp_ports, "Modbus/TCP server port besides 502 (repeatable)");
    cmd->add_option("--udp-port", o->udp_ports, "Modbus/UDP server port besides 502 (repeatable)");
    cmd->add_option("--rtu-over-tcp", o->rtu_over_tcp_ports,
                    "TCP port of a serial gateway whose streams carry raw RTU frames, no MBAP (repeatable)");
    cmd->add_option(
           "--user-dlt", o->user_dlt,
           "What pcap link types USER0..USER15 (147-162) carry: rtu or ascii serial bytes, one chunk "
           "per record with its capture time")
        ->check(CLI::IsMember({"rtu", "ascii"}));
    cmd->add_option("--rtac-role", o->rtac_role,
                    "SEL RTAC serial captures (link type 250): the RTAC's role on the port, master (its TX "
                    "bytes are requests) or slave; unset, the request → response state machine decides")
        ->check(CLI::IsMember({"master", "slave"}));
    cmd->add_option("--timeout", o->timeout_s,
                    "Seconds without a response before a request is reported unanswered")
        ->capture_default_str();
    auto* json = cmd->add_flag("--json", o->json, "One JSON document: every record, then the summary");
    auto* jsonl = cmd->add_flag("--jsonl", o->jsonl,
                                "One JSON object per line (frame, transaction, finding, unparsed, summary)");
    cmd->add_flag("--summary", o->summary, "Only the summary (the fastest path)");
    cmd->add_flag("--no-progress", o->no_progress,
                  "No progress line on standard error (shown only when it is a terminal and records do "
                  "not stream to the same terminal)");
    cmd->add_option("--csv", o->csv,
                    "One CSV row per transaction (RFC 4180) to FILE, or to standard output with -");
    cmd->add_option("--word-order", o->word_order,
                    "Devices without a profile: read FC3/FC4 replies two registers at a time as u32 and "
                    "float32 in this order (abcd = big-endian, cdab = registers swapped, badc, dcba)")
        ->check(CLI::IsMember({"abcd", "badc", "cdab", "dcba"}));
    cmd->add_option("--profile", o->profile, "Device profile for every device (see mbscope profile list)");
    cmd->add_option("--map", o->maps, "Profile per device: UNIT=ID, IP=ID or IP:UNIT=ID (repeatable)");
    cmd->add_option("--profile-dir", o->profile_dirs, "Extra directory of profile files (repeatable)");
    cmd->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
    json->excludes(jsonl);
    cmd->footer(
        "Link types: Ethernet, Linux cooked, raw IP, BSD loopback; USER0..15 with --user-dlt; Wireshark "
        "exported PDUs (252, text2pcap -P mbrtu|mbtcp); SEL RTAC serial (250).\n"
        "Exit codes: 0 decoded with no error-severity finding, 1 faults found, 2 an input could not be "
        "read.\n"
        "Record types and fields: analyzer/README.md.");
    cmd->callback([o, &exit_code] { exit_code = run_decode(*o); });
}

}  // namespace mbscope::cli
