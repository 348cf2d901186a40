// mbscope decode: captures in; frames, transactions, findings and a summary out.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>

#include "analyzer/analyzer.hpp"
#include "analyzer/pcapng_end.hpp"
#include "analyzer/progress.hpp"
#include "analyzer/serial_input.hpp"
#include "cli/analysis_options.hpp"
#include "cli/commands.hpp"

namespace mbscope::cli {
namespace {

struct DecodeOptions {
    AnalysisCliOptions common;
    std::vector<std::string> files;
    std::string user_dlt;
    bool no_progress = false;
    std::string format = "auto";
    std::string master_alias, slave_alias;
    std::string socat_master = "left";
    std::string rtac_role;
    bool one_line = false;
};

int run_decode(const DecodeOptions& o) {
    analyzer::AnalyzerOptions options;
    if (!o.user_dlt.empty()) {
        if (o.user_dlt.starts_with("serial"))
            options.user_dlt.emplace();  // no framing: the line's bytes tell it
        else
            options.user_dlt =
                o.user_dlt.starts_with("ascii") ? modbus::Framing::Ascii : modbus::Framing::Rtu;
        options.user_dlt_direction = o.user_dlt.ends_with("-dir");
    }
    if (!o.rtac_role.empty())
        options.rtac_tx = o.rtac_role == "master" ? modbus::Direction::Request : modbus::Direction::Response;
    if (!apply_analysis_options(o.common, "decode", options)) return exit_failure;
    // A raw dump named by its framing: two names for one thing must agree.
    const std::string& framing = o.common.framing;
    if ((o.format == "ascii" && framing == "rtu") ||
        ((o.format == "rtu" || o.format == "raw") && framing == "ascii")) {
        std::cerr << "mbscope decode: --format " << o.format << " reads a raw "
                  << (o.format == "ascii" ? "ASCII" : "RTU") << " dump; --framing " << framing
                  << " contradicts it\n";
        return exit_failure;
    }
    Outputs outputs;
    if (!outputs.open(o.common, "decode")) return exit_failure;
    analyzer::Sink& sink = outputs.sink();

    // A progress line on standard error, only for a person at a terminal: never into a file or a pipe, and
    // not while records stream to the same terminal on standard output (they would tear the line).
    const bool records_on_terminal = ::isatty(STDOUT_FILENO) && outputs.records_on_stdout();
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
    const auto format = analyzer::parse_input_format(o.format);
    analyzer::SerialLogOptions logs;
    logs.master_alias = o.master_alias;
    logs.slave_alias = o.slave_alias;
    logs.socat_master_left = o.socat_master == "left";
    logs.line = options.serial_line;
    logs.parts_of_one_line = o.one_line;
    std::function<void(const std::string&)> file_done;  // for the progress line
    if (meter)
        file_done = [&](const std::string& f) {
            std::error_code ec;
            const auto size = std::filesystem::file_size(f, ec);
            files_done += ec ? 0 : size;
            show(a.summary(), 0);
        };
    const bool all_read = analyzer::read_inputs(a, o.files, *format, logs, file_done);
    if (meter) meter->clear();
    // pcapng files that say when their capture ended (sniff --write, dumpcap): time ran to then, so what
    // timed out before it is a timeout, as the live run said, not "unanswered when the capture ended". With
    // several files, only when each says so, to the earliest end: every tap saw the line until then. Not
    // when part of the input was not read: a reply in what was lost would be taken for none.
    // Their statistics also say what the capture lost (isb_ifdrop, isb_osdrop): said, since the exchanges
    // around a loss may show as unanswered, cut or unsolicited. A note: an interface's count takes in
    // traffic of every kind, not only what was captured.
    std::optional<modbus::Timestamp> ended;
    bool every_file_ended = true;
    const bool whole = all_read && a.summary().input_errors.empty() && !a.summary().input_errors_unlisted;
    for (const auto& f : o.files) {
        std::error_code ec;
        std::uint64_t dropped = 0;
        const auto end = std::filesystem::is_regular_file(f, ec)
                             ? analyzer::pcapng_capture_end(f, a.latest_time(), &dropped)
                             : std::nullopt;
        if (dropped)
            a.input_note(f + ": its statistics say the capture dropped " + std::to_string(dropped) +
                         (dropped == 1 ? " packet" : " packets") +
                         ": the exchanges around a loss may show as unanswered, cut or unsolicited");
        every_file_ended = every_file_ended && end;
        if (end) ended = ended ? std::min(*ended, *end) : *end;
    }
    if (whole && every_file_ended && ended) a.idle(*ended);
    a.finish();
    const bool input_errors = report_input_problems(a.summary(), "decode");
    report_unused_maps(o.common, options, "decode");
    // Read apart, the parts of one line's log do not pair across a cut: the exchange at each cut is a timeout
    // and an unsolicited reply. Whether the inputs are parts or lines only the user knows: say how to join.
    if (!o.one_line) {
        const auto lines = std::count_if(o.files.begin(), o.files.end(), [&](const std::string& f) {
            return a.summary().serial_lines.contains(analyzer::serial_line_name(f));
        });
        if (lines > 1)
            std::cerr
                << "mbscope decode: " << lines << " serial inputs were read as " << lines
                << " lines; if they are parts of one line (a log in several files), --one-line reads them "
                   "as one stream\n";
    }
    // A link type not decoded, a serial record cut short: read to the end, yet not all decoded.
    if (!all_read || input_errors) return exit_failure;
    // Bytes read and not one frame among them: nothing was decoded (the wrong file, format or framing),
    // which is not a clean result.
    if (a.summary().frames == 0 && (a.summary().unparsed_bytes > 0 || a.summary().packets_cut > 0)) {
        std::cerr
            << "mbscope decode: no Modbus frame in the " << a.summary().unparsed_bytes
            << " bytes read, every one unparsed: "
            << (a.summary().packets_cut
                    ? "the capture's snapshot length cut them (capture with a larger one: tcpdump -s 0)"
                : !a.summary().rtu_over_tcp_connections.empty()
                    ? "RTU frames over TCP, not Modbus/TCP (a serial gateway): decode with --rtu-over-tcp " +
                          std::to_string(a.summary().rtu_over_tcp_connections.begin()->first)
                    : "not Modbus, or read in the wrong format or framing (--format, --framing)")
            << '\n';
        return exit_failure;
    }
    // Not one frame decoded while packets on ports not decoded held Modbus (the summary's hint names the
    // port and the option): the capture's Modbus was left undecoded, which exit 0 told a pipeline was clean.
    if (a.summary().frames == 0 &&
        (!a.summary().modbus_like_ports.empty() || !a.summary().rtu_like_ports.empty())) {
        std::cerr
            << "mbscope decode: no Modbus frame decoded, while packets on ports not decoded hold Modbus: "
               "decode them as the summary's hint says\n";
        return exit_failure;
    }
    return a.summary().errors ? exit_findings : exit_ok;
}

}  // namespace

void register_decode(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<DecodeOptions>();
    auto* cmd = app.add_subcommand("decode", "Decode captures: every frame, every transaction, every fault");
    add_analysis_options(*cmd, o->common);
    cmd->add_option(
           "files", o->files,
           "Captures: pcap, pcapng, raw serial dumps, the text format (analyzer/README.md); - for "
           "standard input (a pcap or pcapng capture alone is decoded as it comes, as from "
           "tcpdump -U -w -; other pipes are read to their end first). Several pcap/pcapng files are "
           "one capture merged by time, as mergecap merges them; serial inputs are read in the "
           "order given, each a line of its own (--one-line: parts of one line)")
        ->required()
        ->check(CLI::Validator(
            [](std::string& file) { return file == "-" ? std::string() : CLI::ExistingFile(file); },
            "FILE or -"));
    cmd->add_option("--format", o->format,
                    "auto, pcap, rtu (raw dump), ascii (raw dump), text (TIME [DIR] HEX...), hex (HEX... "
                    "without times), jpnevulator (--read --timing-print log), socat (socat -x -v standard "
                    "error)")
        ->check(CLI::IsMember(
            {"auto", "pcap", "pcapng", "rtu", "raw", "ascii", "text", "hex", "jpnevulator", "socat"}))
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
    cmd->add_flag(
        "--one-line", o->one_line,
        "The serial inputs are consecutive parts of one line (a log written a file an hour, a capture "
        "in pieces): one stream in the order given, its devices named after the first; a reply in "
        "the next part is its request's, a frame cut in two is whole");
    cmd->add_option(
           "--user-dlt", o->user_dlt,
           "What pcap link types USER0..USER15 (147-162) carry: rtu or ascii serial bytes, or serial "
           "bytes whose framing the line's bytes tell, one chunk per record with its capture time; "
           "rtu-dir, ascii-dir and serial-dir: each record starts with a direction byte (0 master to "
           "slave, 1 slave to master), as mbscope sniff writes two serial taps")
        ->check(CLI::IsMember({"rtu", "ascii", "serial", "rtu-dir", "ascii-dir", "serial-dir"}));
    cmd->add_option("--rtac-role", o->rtac_role,
                    "SEL RTAC serial captures (link type 250): the RTAC's role on the port, master (its TX "
                    "bytes are requests) or slave; unset, the request → response state machine decides")
        ->check(CLI::IsMember({"master", "slave"}));
    cmd->add_flag("--no-progress", o->no_progress,
                  "No progress line on standard error (shown only when it is a terminal and records do "
                  "not stream to the same terminal)");
    cmd->footer(
        "Link types: Ethernet, Linux cooked, raw IP, BSD loopback; USER0..15 with --user-dlt; Wireshark "
        "exported PDUs (252, text2pcap -P mbrtu|mbtcp); SEL RTAC serial (250). A pcapng file whose "
        "interfaces have several is read once per link type.\n"
        "Exit codes: 0 decoded with no error-severity finding (an exception response is a warning, a "
        "gateway's exceptions 10 and 11 are errors), 1 faults found, 2 an input could not be read or part "
        "of it was not decoded (an input error: a link type not decoded, USER0-15 without --user-dlt; no "
        "frame decoded while Modbus went by on a port not decoded), "
        "everything decodable still reported.\n"
        "Record types and fields: analyzer/README.md.");
    cmd->callback([o, &exit_code] { exit_code = run_decode(*o); });
}

}  // namespace mbscope::cli
