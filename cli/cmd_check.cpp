// mbscope check: certify a slave against the Modbus specification and its device's manual.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <thread>

#include "cli/commands.hpp"
#include "cli/json_text.hpp"
#include "cli/number_checks.hpp"
#include "cli/output_paths.hpp"
#include "cli/profile_json.hpp"
#include "cli/stop_signal.hpp"
#include "conformance/report.hpp"
#include "conformance/runner.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/client.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::cli {
namespace {

struct CheckCliOptions {
    std::string target;
    std::string profile = "modbus";
    int unit = 1;
    std::vector<std::string> rules;
    bool read_only = false;
    bool broadcast_writes = false;
    std::string report, junit, html;
    int timeout_ms = 1000;
    int interval_ms = -1;  // -1: the profile's minimum polling interval
    int idle_ms = 1000;
    std::optional<int> other_unit;
    std::uint64_t seed = 1;
    bool verbose = false;
    bool json = false;
    std::vector<std::string> profile_dirs;
    std::vector<std::string> config;
};

// A report going to a FIFO waits for its reader, and a stop signal ends the wait: opened blocking, a FIFO no
// one read held the finished run in open() for ever, SIGINT and SIGTERM ignored (the call starts again
// after the handler). The reader, once there, is held open until the report's own open has it.
bool wait_for_reader(const std::string& path, modbus::transport::UniqueFd& held) {
    std::error_code ec;
    if (!std::filesystem::is_fifo(path, ec)) return true;
    const unsigned signals = stop_signal_count();
    for (;;) {
        held = modbus::transport::UniqueFd(::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC));
        if (held) return true;
        if (errno != ENXIO) return true;  // the open below says what is wrong
        if (stop_signal_count() != signals) {
            std::cerr << "mbscope check: " << path << ": no reader of the FIFO came before the stop; "
                      << "the report was not written\n";
            return false;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
}

bool write_file(const std::string& path, const std::function<void(std::ostream&)>& writer) {
    modbus::transport::UniqueFd reader_waiting;
    if (!wait_for_reader(path, reader_waiting)) return false;
    std::ofstream out(path, std::ios::binary);
    if (!out) {
        std::cerr << "mbscope check: cannot write " << path << '\n';
        return false;
    }
    writer(out);
    // A full disk (or /dev/full) fails the writes or the close, not the open: say so, or the run ends with
    // exit 2 and no word about the report it did not leave.
    out.close();
    if (!out) {
        std::cerr << "mbscope check: writing " << path << " failed: " << std::strerror(errno) << '\n';
        return false;
    }
    return true;
}

// The --report, --junit and --html files asked for; false when one could not be written.
bool write_reports(const CheckCliOptions& o, const conformance::Report& report) {
    bool written = true;
    if (!o.report.empty())
        written &= write_file(
            o.report, [&](std::ostream& out) { out << json_text(conformance::to_json(report)) << '\n'; });
    if (!o.junit.empty())
        written &= write_file(o.junit, [&](std::ostream& out) { conformance::write_junit(out, report); });
    if (!o.html.empty())
        written &= write_file(o.html, [&](std::ostream& out) { conformance::write_html(out, report); });
    return written;
}

// Prints the report of a run that was made (or interrupted) and writes its files; returns the exit code.
int print_and_write(const CheckCliOptions& o, const conformance::Report& report) {
    if (o.json)
        std::cout << json_text(conformance::to_json(report)) << '\n';
    else
        conformance::write_text(std::cout, report, o.verbose);
    const bool written = write_reports(o, report);
    if (const auto none = conformance::nothing_judged(report); !none.empty()) {
        std::cerr << "mbscope check: " << none << '\n';
        return exit_failure;
    }
    if (!report.unanswered.empty()) {
        std::cerr << "mbscope check: " << report.unanswered << '\n';
        return exit_failure;
    }
    if (!written || report.stopped) return exit_failure;
    return conformance::verdict(report) == 0 ? exit_ok : exit_findings;
}

int run_check_command(const CheckCliOptions& o) {
    // Before the profile loads and the target opens: a signal from here on ends the run with its reports.
    auto& stop = stop_on_signals(BrokenPipe::Ignored);
    auto endpoint = modbus::transport::parse_endpoint(o.target);
    if (!endpoint) {
        std::cerr << "mbscope check: " << modbus::printable(endpoint.error()) << '\n';
        return exit_failure;
    }
    for (const auto* file : {&o.report, &o.junit, &o.html})
        if (!file->empty())
            if (const auto why = cannot_write_file(*file)) {
                std::cerr << "mbscope check: cannot write " << *why << '\n';
                return exit_failure;
            }
    // Two reports into one file: the last written replaced the first (--report X --junit X kept the JUnit
    // file alone, exit 0).
    const std::pair<const char*, const std::string*> reports[] = {
        {"--report", &o.report}, {"--junit", &o.junit}, {"--html", &o.html}};
    for (std::size_t i = 0; i < std::size(reports); ++i)
        for (std::size_t j = i + 1; j < std::size(reports); ++j) {
            const std::string &a = *reports[i].second, &b = *reports[j].second;
            std::error_code ea, eb;
            if (!a.empty() && !b.empty() &&
                std::filesystem::weakly_canonical(std::filesystem::absolute(a), ea) ==
                    std::filesystem::weakly_canonical(std::filesystem::absolute(b), eb)) {
                std::cerr << "mbscope check: " << reports[i].first << " and " << reports[j].first
                          << " name the same file, " << a << ": one report would replace the other\n";
                return exit_failure;
            }
        }
    const auto profile = load_profile_for(o.profile, o.profile_dirs, o.config, "check");
    if (!profile) return exit_failure;
    conformance::CheckOptions options;
    options.target = o.target;
    options.session.unit = static_cast<std::uint8_t>(o.unit);
    options.session.timeout = std::chrono::milliseconds(o.timeout_ms);
    options.session.interval = std::chrono::milliseconds(
        o.interval_ms >= 0 ? o.interval_ms : profile->line.min_poll_interval_ms.value_or(0));
    options.run.read_only = o.read_only;
    options.run.broadcast_writes = o.broadcast_writes;
    options.run.rule_globs = o.rules;
    options.run.seed = o.seed;
    options.run.idle = std::chrono::milliseconds(o.idle_ms);
    if (o.other_unit) options.run.other_unit = static_cast<std::uint8_t>(*o.other_unit);
    std::size_t done = 0;
    if (isatty(STDERR_FILENO)) {
        options.run.progress = [&done](const conformance::RuleResult& r) {
            std::cerr << "\r\033[K" << ++done << " rules  " << r.rule.id << std::flush;
        };
        options.run.note = [](const std::string& text) {
            std::cerr << "\r\033[Kmbscope check: " << text << '\n';
        };
    }
    // Stopped before the target was opened, or while it opened (the signal cut the connection short): no
    // rule ran, and every report says the run was interrupted.
    if (stop) return print_and_write(o, conformance::interrupted_report(*profile, options));
    auto client = modbus::transport::Client::open(*endpoint);
    if (!client && stop) return print_and_write(o, conformance::interrupted_report(*profile, options));
    if (!client) {
        // The reports asked for are still written, one rule in error saying why: a CI job that publishes
        // them finds the reason instead of no file.
        std::cerr << "mbscope check: cannot reach the target: " << modbus::printable(client.error()) << '\n';
        const auto report = conformance::unreachable_report(*profile, options, client.error());
        if (o.json) std::cout << json_text(conformance::to_json(report)) << '\n';
        write_reports(o, report);
        return exit_failure;
    }
    run_begins();
    const auto report = conformance::run_check(*client, *profile, options, &stop);
    if (done) std::cerr << "\r\033[K";
    return print_and_write(o, report);
}

}  // namespace

void register_check(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<CheckCliOptions>();
    auto* cmd =
        app.add_subcommand("check", "Certify a slave against the Modbus specification and its manual");
    cmd->footer(
        "Targets: tcp://HOST:PORT  udp://HOST:PORT  rtu-tcp://HOST:PORT  ascii-tcp://HOST:PORT\n"
        "         'rtu:DEVICE?baud=9600&parity=E&stop=1'   'ascii:DEVICE?...'   (quoted: ? and & are the "
        "shell's)\n"
        "Every value the run writes is read first and written back once the rules that write are done\n"
        "(again at the end, also on Ctrl-C); the report lists each point and whether it was restored.\n"
        "Rules the manual only implies, and what this host cannot judge surely (pauses it times, frames\n"
        "told apart by content on a stream), fail as warnings.\n"
        "Exit codes: 0 every rule judged passed (others skipped), 1 a rule failed or a point was not\n"
        "restored, 2 the target could not be reached, never answered, the run judged no rule (--rules\n"
        "matched none, or every rule selected was skipped) or was interrupted. A target that answers\n"
        "none of the first three requests owed a reply (after the generic profile's probing, three\n"
        "reads of each table) is not judged: the run stops there, its reports' verdict \"error\".\n"
        "Pacing: requests are spaced by the manual's minimum polling interval (Walchem: 5000 ms, so a full "
        "run\n"
        "takes about 25 minutes on a real controller); --interval 0 against a bench slave.\n"
        "Example: mbscope check --target tcp://127.0.0.1:5020 --profile mmk-2030 --junit check.xml");
    cmd->add_option("--target", o->target, "The slave to certify (URI)")->required();
    cmd->add_option("--profile", o->profile,
                    "Device profile id or alias (default: modbus, the specification only)");
    cmd->add_option("--unit", o->unit, "Unit id of the slave (default 1)")->check(CLI::Range(1, 255));
    cmd->add_option("--rules", o->rules,
                    "Run only rules whose id matches GLOB (repeatable), e.g. 'quantity.*'");
    cmd->add_flag("--read-only", o->read_only, "Run only rules that write nothing");
    cmd->add_flag("--broadcast-writes", o->broadcast_writes,
                  "Send the broadcast rules' writes to unit 0 (broadcast.fc6/fc16): every device on the "
                  "line executes them and only the device under test is put back, so for a device alone on "
                  "its line (skipped without)");
    cmd->add_option("--report", o->report, "Write the JSON report to FILE");
    cmd->add_option("--junit", o->junit, "Write a JUnit XML report to FILE (one testcase per rule)");
    cmd->add_option("--html", o->html, "Write a self-contained HTML report to FILE");
    cmd->add_option("--timeout", o->timeout_ms, "Milliseconds to wait for each reply (default 1000)")
        ->check(CLI::Range(1, 60000));
    cmd->add_option("--interval", o->interval_ms,
                    "Milliseconds between requests (default: the profile's minimum polling interval)")
        ->check(CLI::Range(0, 600000));
    cmd->add_option("--other-unit", o->other_unit,
                    "Unit framing.other_unit asks on a serial line, expecting no reply: one no device on the "
                    "line answers (default: the device's unit + 1, for a device alone on its line; 0: the "
                    "rule is not run)")
        ->check(CLI::Range(0, 247));
    cmd->add_option("--idle", o->idle_ms,
                    "Milliseconds silence.idle listens with no request out (default 1000; the MK manual's "
                    "own test idles 10000, the Walchem manual's 15000)")
        ->check(CLI::Range(0, 600000));
    cmd->add_option("--seed", o->seed, "Seed of the randomised rules (default 1)")->check(seed_value());
    cmd->add_flag("--verbose,-v", o->verbose, "List passing rules too");
    cmd->add_flag("--json", o->json, "Print the JSON report instead of text");
    cmd->add_option("--profile-dir", o->profile_dirs, "Extra directory of profile files (repeatable)");
    cmd->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
    cmd->callback([o, &exit_code] { exit_code = run_check_command(*o); });
}

}  // namespace mbscope::cli
