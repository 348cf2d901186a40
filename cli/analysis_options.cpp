#include "cli/analysis_options.hpp"

#include <algorithm>
#include <iostream>

#include "analyzer/csv_sink.hpp"
#include "cli/number_checks.hpp"
#include "cli/profile_json.hpp"
#include "modbus/storage/profile_store.hpp"

namespace mbscope::cli {

void add_analysis_options(CLI::App& cmd, AnalysisCliOptions& o) {
    // Port 0 is no port a packet is sent to: a typo for another number, not a request to decode nothing.
    cmd.add_option("--tcp-port", o.tcp_ports, "Modbus/TCP server port besides 502 (repeatable)")
        ->check(CLI::Range(1, 65535));
    cmd.add_option("--udp-port", o.udp_ports, "Modbus/UDP server port besides 502 (repeatable)")
        ->check(CLI::Range(1, 65535));
    cmd.add_option("--rtu-over-tcp", o.rtu_over_tcp_ports,
                   "TCP port of a serial gateway whose streams carry raw RTU frames, no MBAP (repeatable)")
        ->check(CLI::Range(1, 65535));
    cmd.add_option("--baud", o.baud, "Serial line: baud rate (for t1.5/t3.5)")
        ->check(CLI::Range(50u, 10'000'000u))
        ->capture_default_str();
    cmd.add_option("--parity", o.parity, "Serial line: N, E or O")
        ->check(CLI::IsMember({"N", "E", "O", "n", "e", "o", "none", "even", "odd"}))
        ->capture_default_str();
    cmd.add_option("--data-bits", o.data_bits, "Serial line: data bits")
        ->check(CLI::Range(5, 8))
        ->capture_default_str();
    cmd.add_option("--stop-bits", o.stop_bits, "Serial line: stop bits")
        ->check(CLI::Range(1, 2))
        ->capture_default_str();
    cmd.add_option("--framing", o.framing,
                   "Serial line: rtu or ascii; auto tells it per line from its first bytes. A device that "
                   "acknowledges other line settings (MK PROT, BAUD, PARID, with --profile or --map) "
                   "changes it from there")
        ->check(CLI::IsMember({"auto", "rtu", "ascii"}))
        ->capture_default_str();
    cmd.add_option("--timeout", o.timeout_s,
                   "Seconds without a response before a request is reported unanswered, on TCP and serial "
                   "lines alike (default 3 on TCP, 1 on a serial line)")
        ->check(finite_between(0.001, 86400, "seconds"));
    auto* json = cmd.add_flag("--json", o.json, "One JSON document: every record, then the summary");
    auto* jsonl = cmd.add_flag("--jsonl", o.jsonl,
                               "One JSON object per line (frame, transaction, finding, unparsed, summary)");
    json->excludes(jsonl);
    cmd.add_flag("--summary", o.summary,
                 "Only the summary (the fastest path; with --json or --jsonl, the summary record alone)");
    cmd.add_option("--csv", o.csv,
                   "One CSV row per transaction (RFC 4180) to FILE, or to standard output with -");
    cmd.add_option("--word-order", o.word_order,
                   "Devices without a profile: read FC3/FC4 replies two registers at a time as u32 and "
                   "float32 in this order (abcd = big-endian, cdab = registers swapped, badc, dcba). A "
                   "profile whose manual makes the order a device setting (Walchem's inverse format) reads "
                   "its 32-bit values so; one whose manual fixes it keeps its own, and says so")
        ->check(CLI::IsMember({"abcd", "badc", "cdab", "dcba"}));
    cmd.add_option("--profile", o.profile, "Device profile for every device (see mbscope profile list)");
    cmd.add_option(
        "--map", o.maps,
        "Profile per device: UNIT=ID, IP=ID or IP:UNIT=ID; IPv6 as IP=ID or [IP]:UNIT=ID (repeatable)");
    cmd.add_option("--profile-dir", o.profile_dirs, "Extra directory of profile files (repeatable)");
    cmd.add_option("--config", o.config, "Modular devices: CHANNEL=MAP (repeatable)");
}

namespace {

// --profile ID for every device, --map SELECTOR=ID per device (SELECTOR: UNIT, IP or IP:UNIT).
bool load_semantics(const AnalysisCliOptions& o, const std::string& command,
                    analyzer::AnalyzerOptions& options) {
    if (o.profile.empty() && o.maps.empty()) {
        if (o.config.empty()) return true;
        std::cerr << "mbscope " << command
                  << ": --config configures a device given with --profile or --map\n";
        return false;
    }
    const auto store = open_profile_store(o.profile_dirs, command.c_str());
    if (!store) return false;
    const auto parsed = parse_config_options(o.config, command.c_str());
    if (!parsed) return false;
    const modbus::ProfileConfig& config = *parsed;
    std::vector<std::string> ids;
    if (!o.profile.empty()) ids.push_back(o.profile);
    for (const auto& m : o.maps)
        if (const auto eq = m.find('='); eq != std::string::npos) ids.push_back(m.substr(eq + 1));
    if (!config_is_for_a_modular_device(*store, ids, config, command.c_str())) return false;
    auto semantics = std::make_shared<analyzer::Semantics>();
    auto add = [&](const analyzer::DeviceSelector& selector, const std::string& id) {
        auto p = store->load(id, config);
        if (!p) {
            for (const auto& e : p.error())
                std::cerr << "mbscope " << command << ": " << modbus::to_string(e) << '\n';
            return false;
        }
        // The device may be set to send its 32-bit values in another order (Walchem, 002:470-477): given,
        // it is read so. Dropped without a word, a controller set to the inverse format read 1.5 as 0.
        // A manual that fixes the order leaves nothing to choose: read in it, with a note. An order the
        // device cannot be set to, where its manual lists those it can (Walchem: cdab or abcd), is a wrong
        // argument, as in `profile decode`: noted, the values were read in the profile's order all the same.
        if (!o.word_order.empty())
            if (const auto order = modbus::parse_word_order(o.word_order))
                if (auto why = modbus::set_word_order(p.value(), *order)) {
                    if (!p->word_orders.empty()) {
                        std::cerr << "mbscope " << command << ": --word-order " << o.word_order << ": "
                                  << *why << '\n';
                        return false;
                    }
                    std::cerr << "mbscope " << command << ": note: --word-order " << o.word_order
                              << " is not applied to " << id << ": " << *why << '\n';
                }
        semantics->add(selector, std::make_shared<const modbus::Profile>(std::move(p.value())));
        return true;
    };
    if (!o.profile.empty() && !add({}, o.profile)) return false;
    for (const auto& m : o.maps) {
        const auto eq = m.find('=');
        auto selector = eq == std::string::npos ? std::nullopt : analyzer::parse_selector(m.substr(0, eq));
        if (!selector) {
            std::cerr << "mbscope " << command
                      << ": --map takes UNIT=ID, IP=ID or IP:UNIT=ID ([IPv6]:UNIT=ID), not '" << m << "'\n";
            return false;
        }
        if (!add(*selector, m.substr(eq + 1))) return false;
    }
    options.semantics = std::move(semantics);
    return true;
}

}  // namespace

bool apply_analysis_options(const AnalysisCliOptions& o, const std::string& command,
                            analyzer::AnalyzerOptions& options) {
    options.tcp_ports.insert(options.tcp_ports.end(), o.tcp_ports.begin(), o.tcp_ports.end());
    options.udp_ports.insert(options.udp_ports.end(), o.udp_ports.begin(), o.udp_ports.end());
    options.rtu_over_tcp_ports = o.rtu_over_tcp_ports;
    if (!o.word_order.empty()) options.word_order = modbus::parse_word_order(o.word_order);
    if (o.timeout_s > 0) {
        options.timeout =
            std::chrono::duration_cast<modbus::Timestamp>(std::chrono::duration<double>(o.timeout_s));
        options.serial_timeout = options.timeout;
    }
    if (o.framing != "auto")
        options.serial_framing = o.framing == "ascii" ? modbus::Framing::Ascii : modbus::Framing::Rtu;
    options.serial_line = {o.baud, static_cast<std::uint8_t>(o.data_bits), *modbus::parse_parity(o.parity),
                           static_cast<std::uint8_t>(o.stop_bits)};
    return load_semantics(o, command, options);
}

bool report_input_problems(const analyzer::Summary& s, const std::string& command) {
    for (const auto& e : s.input_errors)
        std::cerr << "mbscope " << command << ": " << e << '\n';
    if (s.input_errors_unlisted)
        std::cerr << "mbscope " << command << ": " << s.input_errors_unlisted
                  << " more input errors, not listed\n";
    for (const auto& n : s.input_notes)
        std::cerr << "mbscope " << command << ": note: " << n << '\n';
    if (s.input_notes_unlisted)
        std::cerr << "mbscope " << command << ": " << s.input_notes_unlisted
                  << " more input notes, not listed\n";
    return !s.input_errors.empty() || s.input_errors_unlisted;
}

void report_unused_maps(const AnalysisCliOptions& o, const analyzer::AnalyzerOptions& options,
                        const std::string& command) {
    if (!options.semantics || o.maps.empty()) return;
    const auto uses = options.semantics->selector_uses();
    // Selectors were added --profile first, then each --map in order (load_semantics).
    const std::size_t first_map = o.profile.empty() ? 0 : 1;
    for (std::size_t i = 0; i < o.maps.size() && first_map + i < uses.size(); ++i) {
        using Use = analyzer::Semantics::SelectorUse;
        const Use use = uses[first_map + i];
        if (use == Use::Used) continue;
        const std::string& m = o.maps[i];
        const std::string selector = m.substr(0, m.find('='));
        std::cerr << "mbscope " << command << ": note: --map " << m << " described no device: ";
        const auto parsed = analyzer::parse_selector(selector);
        if (use == Use::Shadowed) {
            // The same selector given before wins the tie; else a more specific one took its devices.
            const bool repeated =
                parsed && std::any_of(o.maps.begin(), o.maps.begin() + static_cast<std::ptrdiff_t>(i),
                                      [&](const std::string& earlier) {
                                          const auto e =
                                              analyzer::parse_selector(earlier.substr(0, earlier.find('=')));
                                          return e && e->host == parsed->host && e->unit == parsed->unit;
                                      });
            std::cerr << (repeated ? "an earlier --map for the same devices took them\n"
                                   : "every device it matched took a more specific --map\n");
            continue;
        }
        // Profiles are looked up by requests: replies alone (their requests not captured) name no profile.
        std::cerr << "no request in the input went to"
                  << (parsed && parsed->host ? " " + *parsed->host : std::string())
                  << (parsed && parsed->unit ? " unit " + std::to_string(*parsed->unit) : std::string());
        // "2001:db8::2:1" is an address, not host 2001:db8::2 and unit 1: the likeliest slip with IPv6.
        if (selector.find(':') != selector.rfind(':') && !selector.starts_with('['))
            std::cerr << " (an IPv6 address; a unit behind one is written [IP]:UNIT)";
        std::cerr << '\n';
    }
}

bool Outputs::open(const AnalysisCliOptions& o, const std::string& command) {
    // --csv - takes standard output for itself; --csv FILE goes beside the usual output.
    if (o.csv == "-" && (o.json || o.jsonl || o.summary)) {
        std::cerr << "mbscope " << command
                  << ": --csv - and --json, --jsonl or --summary all want standard output\n";
        return false;
    }
    if (!o.csv.empty() && o.csv != "-") {
        csv_file_.open(o.csv, std::ios::binary);
        if (!csv_file_) {
            std::cerr << "mbscope " << command << ": cannot write " << o.csv << '\n';
            return false;
        }
    }
    if (!o.csv.empty())
        sinks_.push_back(std::make_unique<analyzer::CsvSink>(o.csv == "-" ? std::cout : csv_file_));
    if (o.csv != "-") {
        if (o.json || o.jsonl)
            sinks_.push_back(std::make_unique<analyzer::JsonSink>(std::cout, o.jsonl, o.summary));
        else
            sinks_.push_back(std::make_unique<analyzer::TextSink>(std::cout, o.summary));
    }
    records_on_stdout_ = !o.summary && !o.json;  // a JSON document is written at the end
    std::vector<analyzer::Sink*> outputs;
    for (auto& s : sinks_)
        outputs.push_back(s.get());
    tee_ = std::make_unique<analyzer::TeeSink>(outputs);
    return true;
}

}  // namespace mbscope::cli
