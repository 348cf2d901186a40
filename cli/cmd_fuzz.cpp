// mbscope fuzz: fuzz any slave over the network or a serial line, with the rules as the oracle.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <set>

#include "cli/commands.hpp"
#include "cli/json_text.hpp"
#include "cli/number_checks.hpp"
#include "cli/output_paths.hpp"
#include "cli/profile_json.hpp"
#include "cli/stop_signal.hpp"
#include "fuzz/network/campaign.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/transport/endpoint.hpp"

namespace mbscope::cli {
namespace {

struct FuzzCliOptions {
    std::string target;
    std::string profile = "modbus";
    int unit = 1;
    std::string duration;
    std::uint64_t requests = 0;
    std::uint64_t seed = 1;
    std::string artifacts;
    bool read_only = false;
    int timeout_ms = 1000;
    int silence_ms = -1;  // -1: learnt from the target's replies
    int slow_ms = 0;
    int interval_ms = -1;  // -1: the profile's minimum polling interval
    std::size_t minimise = 64;
    std::size_t max_findings = 0;
    bool progress = true;
    std::vector<std::string> profile_dirs;
    std::vector<std::string> config;
};

void show_progress(const fuzz::network::CampaignSummary& s) {
    // Tenths below 10 a second: at a manual's polling interval (Walchem: one request in 5 s) the rate read
    // "0/s".
    const double rate = s.requests_per_second();
    std::fprintf(stderr,
                 "\r\033[K%llu requests  %.*f/s  %zu findings  %zu response classes  %zu rule outcomes",
                 static_cast<unsigned long long>(s.requests), rate < 10 ? 1 : 0, rate, s.findings.size(),
                 s.response_classes, s.outcomes.size());
    std::fflush(stderr);
}

int run_fuzz_command(const FuzzCliOptions& o) {
    // Before the profile loads (it takes a while): a signal from here on ends the run with its summary.
    const auto& stop = stop_on_signals(BrokenPipe::Ignored);
    auto endpoint = modbus::transport::parse_endpoint(o.target);
    if (!endpoint) {
        std::cerr << "mbscope fuzz: " << modbus::printable(endpoint.error()) << '\n';
        return exit_failure;
    }
    if (!o.artifacts.empty())
        if (const auto why = cannot_use_directory(o.artifacts)) {
            std::cerr << "mbscope fuzz: --artifacts " << *why << '\n';
            return exit_failure;
        }
    const auto profile = load_profile_for(o.profile, o.profile_dirs, o.config, "fuzz");
    if (!profile) return exit_failure;
    fuzz::network::CampaignOptions options;
    options.endpoint = *endpoint;
    options.target = o.target;
    options.unit = static_cast<std::uint8_t>(o.unit);
    options.read_only = o.read_only;
    options.seed = o.seed;
    if (o.requests) options.requests = o.requests;
    if (!o.duration.empty()) options.duration = parse_duration(o.duration);  // checked by duration_text()
    if (!options.requests && !options.duration) options.duration = std::chrono::seconds(60);
    options.timeout = std::chrono::milliseconds(o.timeout_ms);
    if (o.silence_ms >= 0) options.silence_wait = std::chrono::milliseconds(o.silence_ms);
    options.slow = std::chrono::milliseconds(o.slow_ms);
    options.interval = std::chrono::milliseconds(
        o.interval_ms >= 0 ? o.interval_ms : profile->line.min_poll_interval_ms.value_or(0));
    options.artifacts = o.artifacts;
    options.minimise_budget = o.minimise;
    options.max_findings = o.max_findings;
    const bool meter = o.progress && isatty(STDERR_FILENO);
    if (meter) options.progress = show_progress;
    options.stop = &stop;
    options.stop_again = &second_stop_signal();
    if (meter)
        options.note = [](const std::string& text) { std::cerr << "\r\033[Kmbscope fuzz: " << text << '\n'; };

    run_begins();
    const auto summary = fuzz::network::run_campaign(*profile, options);
    if (meter) std::cerr << "\r\033[K";
    auto j = fuzz::network::to_json(summary);
    j["target"] = o.target;
    j["profile"] = profile->id;
    j["unit"] = o.unit;
    j["seed"] = o.seed;
    for (const auto& f : summary.findings)
        std::cerr
            << "mbscope fuzz: finding " << f.rule << " (" << f.source << ") on function " << int(f.function)
            << ", " << f.count << "x: expected " << f.expected << "; observed " << f.observed
            << (f.file.empty() ? ""
                               : "\n  reproducer: " + f.file + "  (mbscope replay --target " + o.target +
                                     " " + f.file + ")")
            << (f.file_error.empty() ? "" : "\n  reproducer not saved: " + f.file_error)
            << (f.reproducer.replays_on_new_connection == false
                    ? "\n  the reproducer broke the rule again on the fuzzer's connection but not on a new "
                      "one, as mbscope replay sends it: it depends on the connection's history or timing"
                    : "")
            << '\n';
    std::cout << json_text(j) << '\n';
    if (summary.replies_after_timeout > 0)
        std::cerr << "mbscope fuzz: " << summary.replies_after_timeout << " replies came after --timeout ("
                  << options.timeout.count() << " ms); each was judged as its request's, "
                  << "and a longer --timeout may suit the target\n";
    if (summary.writes_past_deadline > 0)
        std::cerr << "mbscope fuzz: " << summary.writes_past_deadline
                  << " write probes not sent: with a request every " << options.interval.count()
                  << " ms, reading their points first would have run past --duration\n";
    if (!summary.reachable) {
        if (summary.stopped)
            std::cerr << "mbscope fuzz: interrupted before the fuzzing began; nothing was judged\n";
        else
            std::cerr << "mbscope fuzz: cannot reach the target: " << modbus::printable(summary.error)
                      << '\n';
        return exit_failure;
    }
    bool unrestored = !summary.not_read.empty();
    for (const auto& t : summary.restored)
        unrestored |= !t.restored;
    for (const auto& w : summary.not_read)
        std::cerr << "mbscope fuzz: written without being read first, not restored: "
                  << fuzz::network::to_string(w) << '\n';
    std::set<std::pair<modbus::Table, std::uint16_t>> unanswered;
    for (const auto& u : summary.unanswered_writes)
        unanswered.insert({u.table, u.address});
    for (const auto& w : fuzz::network::ranges_of(unanswered))
        std::cerr << "mbscope fuzz: written by a write that drew no reply, without being read first, not "
                     "restored: "
                  << fuzz::network::to_string(w) << '\n';
    const char* why_unread = summary.target_lost             ? "(the target stopped answering)"
                             : summary.read_back_interrupted ? "(no answer to the read, or not reached: the "
                                                               "read-back was interrupted)"
                                                             : "(no answer to the read)";
    for (const auto& w : summary.unanswered_unread)
        std::cerr << "mbscope fuzz: written by a write that drew no reply, could not be read " << why_unread
                  << ", may have changed, not restored: " << fuzz::network::to_string(w) << '\n';
    if (!summary.unanswered_refused.empty()) {
        std::size_t points = 0;
        for (const auto& w : summary.unanswered_refused)
            points += w.count;
        const std::size_t ranges = summary.unanswered_refused.size();
        std::cerr << "mbscope fuzz: " << points << (points == 1 ? " point" : " points") << " in " << ranges
                  << (ranges == 1 ? " range" : " ranges")
                  << " written by writes that drew no reply were refused as a whole and not read "
                     "point by point; taken for points the device does not hold (\"unanswered_refused\")\n";
    }
    unrestored |= !unanswered.empty() || !summary.unanswered_unread.empty();
    if (unrestored)
        std::cerr << "mbscope fuzz: some written points could not be restored (see \"restored\", "
                     "\"not_read\", \"unanswered_writes\" and \"unanswered_unread\")\n";
    // Said whatever was found: a log of findings alone does not tell a run cut short. Nothing found in part
    // of the budget is not the clean result exit 0 promises (a CI job's timeout sends SIGTERM): an
    // interrupted run without findings could not complete.
    const bool found = !summary.findings.empty() || unrestored;
    if (summary.stopped)
        std::cerr << "mbscope fuzz: interrupted after " << summary.requests << " requests"
                  << (found ? "; what is above comes from the part of the run that was made\n"
                            : ", nothing found so far; the run did not complete\n");
    if (found) return exit_findings;
    // A run that sent no request judged nothing (every planned write skipped because its points could
    // not be read first): not the clean result exit 0 promises.
    if (summary.requests == 0 && !summary.stopped) {
        std::cerr << "mbscope fuzz: no request was sent in the budget (" << summary.skipped_writes
                  << " planned writes skipped: their points could not be read first); nothing was judged\n";
        return exit_failure;
    }
    return summary.stopped ? exit_failure : exit_ok;
}

}  // namespace

void register_fuzz(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<FuzzCliOptions>();
    auto* cmd = app.add_subcommand(
        "fuzz", "Fuzz a slave over any transport, judged by the Modbus rules and its manual");
    cmd->footer(
        "Targets: tcp://HOST:PORT  udp://HOST:PORT  rtu-tcp://HOST:PORT  ascii-tcp://HOST:PORT\n"
        "         'rtu:DEVICE?baud=9600&parity=E&stop=1'   'ascii:DEVICE?...'   (quoted: ? and & are the "
        "shell's)\n"
        "Requests are made from the grammar and the profile's map (boundaries, quantities, byte counts, "
        "MBAP\n"
        "fields, checksums, split frames; FC 23, 20, 21, 43 and 8 drawn more often) and mutated where they\n"
        "showed a new response class. Every reply is judged with the rules of `mbscope check`; a target "
        "that\n"
        "stops answering a health-check read, replies late, or answers slower than --slow is a finding too.\n"
        "Each finding is saved once per rule and function in --artifacts as a JSON reproducer, shortened to\n"
        "the fewest requests that break the rule again; `mbscope replay --target URI FILE` runs it.\n"
        "Every point written is read first and written back at the end; --read-only writes nothing.\n"
        "Output: progress on a terminal (stderr), findings on stderr, a JSON summary on stdout.\n"
        "Exit codes: 0 nothing found, 1 at least one finding (or a point not restored), 2 the target could\n"
        "not be reached or never answered the health check (over Modbus/TCP, with a frame), no request\n"
        "was sent, or the run was interrupted (SIGINT, SIGTERM, SIGHUP) before it found anything.\n"
        "Example: mbscope fuzz --target tcp://127.0.0.1:5020 --profile mmk-2030 --duration 60s --artifacts "
        "out");
    cmd->add_option("--target", o->target, "The slave to fuzz (URI)")->required();
    cmd->add_option("--profile", o->profile,
                    "Device profile id or alias (default: modbus, the specification only)");
    cmd->add_option("--unit", o->unit, "Unit id of the slave (default 1)")->check(CLI::Range(1, 255));
    cmd->add_option("--duration", o->duration,
                    "Run this long: 60s, 500ms, 5m (default 60s without --requests)")
        ->check(duration_text());
    cmd->add_option("--requests", o->requests, "Stop after N requests")
        ->check(whole_number("N"))  // before the range: CLI11 wraps "-1" to 2^64-1, which it passes
        ->check(CLI::Range(std::uint64_t{1}, std::numeric_limits<std::uint64_t>::max()));
    cmd->add_option("--seed", o->seed,
                    "Seed: the same seed against a target that answers alike sends the same requests "
                    "(requests_digest in the summary)")
        ->check(seed_value());
    cmd->add_option("--artifacts", o->artifacts, "Directory for reproducers (created)");
    cmd->add_flag("--read-only", o->read_only,
                  "Send only requests that cannot write (public read functions)");
    cmd->add_option("--timeout", o->timeout_ms, "Milliseconds to wait for a reply that is due (default 1000)")
        ->check(CLI::Range(1, 60000));
    cmd->add_option("--silence-wait", o->silence_ms,
                    "Milliseconds to wait where the rules demand silence. Default over Modbus/TCP: none, "
                    "the next request goes out at once and a reply that comes anyway is matched to its "
                    "request by transaction id for up to --timeout; elsewhere learnt from the target's "
                    "replies (twice TCP's retransmission timeout estimate, at least 0.2 ms, at most "
                    "--timeout), and a reply arriving later is judged as that request's when it comes "
                    "before the next one")
        ->check(CLI::Range(0, 60000));
    cmd->add_option("--slow", o->slow_ms,
                    "A reply later than this many ms is a finding (default: the profile's response timeout, "
                    "else 250; plus the longest frame's transmission on a serial line)")
        ->check(CLI::Range(0, 600000));
    cmd->add_option("--interval", o->interval_ms,
                    "Milliseconds between requests (default: the profile's minimum polling interval)")
        ->check(CLI::Range(0, 600000));
    cmd->add_option("--minimise", o->minimise,
                    "Replays spent shortening each reproducer (default 64, 0: none)")
        ->check(whole_number("N"));
    cmd->add_option("--max-findings", o->max_findings,
                    "Stop once N findings are saved (default: run the whole budget)")
        ->check(whole_number("N"));
    cmd->add_flag("!--no-progress", o->progress, "No progress line, even on a terminal");
    cmd->add_option("--profile-dir", o->profile_dirs, "Extra directory of profile files (repeatable)");
    cmd->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
    cmd->callback([o, &exit_code] { exit_code = run_fuzz_command(*o); });
}

}  // namespace mbscope::cli
