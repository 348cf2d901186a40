// mbscope replay: send a reproducer saved by `mbscope fuzz` to a target and judge it again.
#include <iostream>
#include <memory>

#include "cli/commands.hpp"
#include "cli/json_text.hpp"
#include "cli/profile_json.hpp"
#include "cli/stop_signal.hpp"
#include "conformance/report.hpp"
#include "fuzz/network/reproducer.hpp"
#include "fuzz/network/written_points.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/transport/endpoint.hpp"

namespace mbscope::cli {
namespace {

struct ReplayCliOptions {
    std::string target;
    std::string file;
    std::string profile;  // empty: the reproducer's
    int unit = -1;        // -1: the reproducer's
    int timeout_ms = 1000;
    int slow_ms = -1;  // -1: the reproducer's (timing.slow_reply), else none
    bool json = false;
    bool no_restore = false;
    std::vector<std::string> profile_dirs;
    std::vector<std::string> config;
};

// What a replay did: the steps sent (none when it was interrupted before the target was opened) and what it
// left where.
struct Replayed {
    std::vector<fuzz::network::ReplayedStep> steps;
    std::vector<conformance::Touched> restored;
    std::vector<fuzz::network::WriteRange> unread;
    fuzz::network::HeldReading unanswered;
};

// Sends the reproducer's steps to the open target and judges them; what they may write is read before and
// written back after (unless --no-restore). `stop` stops the steps, not the reads before them (which change
// nothing) nor the restore after them.
Replayed replay_steps(modbus::transport::Client& client, const modbus::transport::Endpoint& endpoint,
                      const modbus::Profile& profile, const fuzz::network::Reproducer& r,
                      const ReplayCliOptions& o, const std::atomic<bool>& stop) {
    const auto framing = modbus::transport::framing_of(endpoint.scheme);
    const std::uint8_t unit = o.unit >= 0 ? static_cast<std::uint8_t>(o.unit) : r.unit;
    conformance::ExchangeOracle oracle(framing, {{unit, &profile}},
                                       endpoint.scheme == modbus::transport::Scheme::Tcp ||
                                           endpoint.scheme == modbus::transport::Scheme::Udp);
    fuzz::network::ReplayOptions options;
    options.timeout = std::chrono::milliseconds(o.timeout_ms);
    // A slow reply is judged by the limit it broke when it was found, unless told another (0: not judged).
    options.slow =
        std::chrono::milliseconds(o.slow_ms >= 0 ? static_cast<std::uint32_t>(o.slow_ms) : r.slow_ms);
    options.slow_source = o.slow_ms >= 0 ? "--slow" : r.source;
    options.silence_wait = options.timeout;
    options.stop = &stop;
    // What the steps may write is read first and written back after them, as `mbscope fuzz` and
    // `mbscope check` do: replaying a finding leaves the device as it was.
    conformance::Session session(client, {unit, options.timeout, std::chrono::milliseconds(0)}, &profile);
    // The steps go out over the session's client: each is told to it, so that the restore puts back only what
    // they changed and leaves what the device changed itself (a write it refused wrote nothing).
    session.watch_writes();
    fuzz::network::RememberedWrites remembered;
    if (!o.no_restore) remembered = fuzz::network::remember_writes(session, profile, r.steps);
    Replayed done;
    done.steps = fuzz::network::replay(client, oracle, r.steps, options);
    for (std::size_t i = 0; i < done.steps.size(); ++i)
        fuzz::network::note_step_writes(session, r.steps[i], done.steps[i]);
    // Writes to points outside the map were not read first: a device that acknowledged one changed them.
    done.unread = remembered.unread;
    for (const auto& w : fuzz::network::acknowledged_unchecked(remembered.unchecked, framing, done.steps))
        done.unread.push_back(w);
    // Those a step wrote without drawing a reply (a broadcast): the device may have executed it where it
    // holds them; read now to see which it holds.
    done.unanswered = fuzz::network::read_held(
        session, fuzz::network::unanswered_unchecked(remembered.unchecked, framing, done.steps));
    if (!session.touched().empty()) done.restored = session.restore();
    return done;
}

// Prints what the replay did (text, or JSON with --json) and returns the exit code.
int report_replay(const ReplayCliOptions& o, const fuzz::network::Reproducer& r, const Replayed& done) {
    const auto& [steps, restored, unread, unanswered] = done;
    bool unrestored = !unread.empty() || !unanswered.held.empty() || !unanswered.unread.empty();
    for (const auto& t : restored)
        unrestored |= !t.restored;

    const bool stopped = steps.size() < r.steps.size();
    const bool again = fuzz::network::breaks(steps, r.rule);
    std::size_t violations = 0;
    nlohmann::json out = nlohmann::json::array();
    for (std::size_t i = 0; i < steps.size(); ++i) {
        const auto& s = steps[i];
        violations += s.violations.size();
        nlohmann::json broken = nlohmann::json::array();
        for (const auto& v : s.violations)
            broken.push_back(
                {{"rule", v.rule}, {"source", v.source}, {"expected", v.expected}, {"observed", v.observed}});
        out.push_back({{"step", i + 1},
                       {"sent", modbus::hex_bytes(s.exchange.sent)},
                       {"received", modbus::hex_bytes(s.exchange.received)},
                       {"elapsed_ms", std::chrono::duration<double, std::milli>(s.exchange.elapsed).count()},
                       {"violations", broken}});
        if (!o.json) {
            std::cout << "step " << i + 1 << "  " << r.steps[i].recipe << "\n  sent     "
                      << modbus::hex_bytes(s.exchange.sent) << "\n  received "
                      << (s.exchange.received.empty() ? "(nothing)" : modbus::hex_bytes(s.exchange.received))
                      << '\n';
            for (const auto& v : s.violations)
                std::cout << "  broken   " << conformance::to_string(v) << '\n';
        }
    }
    if (o.json) {
        std::cout << json_text(
                         nlohmann::json{{"file", o.file},
                                        {"rule", r.rule},
                                        {"reproduced", again},
                                        {"stopped", stopped},
                                        {"steps", out},
                                        {"restored", conformance::to_json(restored)},
                                        {"not_read", fuzz::network::to_json(unread)},
                                        {"unanswered_writes", fuzz::network::to_json(unanswered.held)},
                                        {"unanswered_unread", fuzz::network::to_json(unanswered.unread)},
                                        {"unanswered_refused", fuzz::network::to_json(unanswered.refused)}})
                  << '\n';
    } else {
        for (const auto& w : unread)
            std::cout << "not read before the replay, not restored: " << fuzz::network::to_string(w) << '\n';
        for (const auto& p : unanswered.held)
            std::cout << "written by a step that drew no reply, not read before, not restored: "
                      << modbus::to_string(p.table) << ' ' << p.address << " holds " << p.value << '\n';
        for (const auto& w : unanswered.unread)
            std::cout
                << "written by a step that drew no reply, no answer to the read after, may have changed, "
                   "not restored: "
                << fuzz::network::to_string(w) << '\n';
        for (const auto& w : unanswered.refused)
            std::cout
                << "written by a step that drew no reply, the device refused to read it as a whole, not "
                   "read point by point (taken for points it does not hold): "
                << fuzz::network::to_string(w) << '\n';
        std::size_t back = 0;
        for (const auto& t : restored) {
            if (t.restored)
                ++back;
            else
                std::cout << "not restored: " << modbus::to_string(t.table) << ' ' << t.address << ": "
                          << t.problem << '\n';
        }
        if (stopped)
            std::cout << "stopped after step " << steps.size() << " of " << r.steps.size()
                      << " (interrupted)\n";
        if (!restored.empty())
            std::cout << "restored " << back << " of " << restored.size()
                      << " points the steps may have written\n";
        std::cout << (again     ? "reproduced: "
                      : stopped ? "not reproduced in the steps sent before the interrupt: "
                                : "not reproduced: ")
                  << r.rule << " (" << r.source << ")";
        if (!again && violations) std::cout << "; other rules broken: " << violations;
        std::cout << '\n';
    }
    if (unrestored) std::cerr << "mbscope replay: some points the steps may have written were not restored\n";
    if (again || violations || unrestored) return exit_findings;
    // Steps left unsent cannot show the rule kept: "not reproduced" is said only of a whole replay.
    return stopped ? exit_failure : exit_ok;
}

int run_replay_command(const ReplayCliOptions& o) {
    // Reading its file an interrupt ends the command as it would any other (a file that never ends, a FIFO
    // that no one writes to). From the file on, it ends the replay the documented way: before the target is
    // opened, with nothing sent (exit 2, "stopped": true); later it stops the steps, not the restore.
    auto reproducer = fuzz::network::load_reproducer(o.file);
    if (!reproducer) {
        std::cerr << "mbscope replay: " << reproducer.error() << '\n';
        return exit_failure;
    }
    const std::atomic<bool>& stop = stop_on_signals(BrokenPipe::Ignored);
    const auto& r = *reproducer;
    auto endpoint = modbus::transport::parse_endpoint(o.target.empty() ? r.target : o.target);
    if (!endpoint) {
        std::cerr << "mbscope replay: " << modbus::printable(endpoint.error()) << '\n';
        return exit_failure;
    }
    const auto profile =
        load_profile_for(o.profile.empty() ? r.profile : o.profile, o.profile_dirs, o.config, "replay");
    if (!profile) return exit_failure;
    const auto framing = modbus::transport::framing_of(endpoint->scheme);
    // Frames of another framing are bytes the target does not read as requests: sent as recorded, every step
    // drew nothing and the run said "not reproduced" with exit 0, as if the device had been cleared.
    if (!r.framing.empty() && r.framing != modbus::to_string(framing)) {
        std::cerr << "mbscope replay: the reproducer was recorded with " << r.framing
                  << " framing and the target uses " << modbus::to_string(framing)
                  << ": its steps are frames the target would not read as requests; give a target of "
                  << r.framing << " framing\n";
        return exit_failure;
    }
    if (stop) return report_replay(o, r, {});  // before the target was opened: nothing sent
    auto client = modbus::transport::Client::open(*endpoint);
    if (!client && stop) return report_replay(o, r, {});  // the signal cut the opening short
    if (!client) {
        std::cerr << "mbscope replay: cannot reach the target: " << modbus::printable(client.error()) << '\n';
        return exit_failure;
    }
    run_begins();
    return report_replay(o, r, replay_steps(*client, *endpoint, *profile, r, o, stop));
}

}  // namespace

void register_replay(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<ReplayCliOptions>();
    auto* cmd = app.add_subcommand("replay", "Send a reproducer saved by `mbscope fuzz` and judge it again");
    cmd->footer(
        "Sends each step exactly as recorded (pieces, pauses, reconnections) and judges every reply with "
        "the\n"
        "rules of `mbscope fuzz` and `mbscope check`.\n"
        "What the steps may write is read before them and written back after them (--no-restore: left as\n"
        "the steps leave it); an interrupt (Ctrl-C) stops the steps, not the restore. Points outside the\n"
        "profile's map are not read; a write there the device acknowledges is listed as not restored.\n"
        "Exit codes: 0 no rule broken, 1 the recorded rule (or another) broken again or a point not\n"
        "restored, 2 the file or the target could not be used, or the steps were interrupted before the\n"
        "rule was broken again.\n"
        "Example: mbscope replay --target tcp://127.0.0.1:5020 out/reply.checksum-fc3.json");
    cmd->add_option("file", o->file, "Reproducer (JSON) written by mbscope fuzz --artifacts")->required();
    cmd->add_option("--target", o->target, "The slave (URI; default: the one recorded)");
    cmd->add_option("--profile", o->profile, "Device profile (default: the one recorded)");
    cmd->add_option("--unit", o->unit, "Unit id the rules expect (default: the one recorded)")
        ->check(CLI::Range(0, 255));
    cmd->add_option("--timeout", o->timeout_ms, "Milliseconds to wait for each reply (default 1000)")
        ->check(CLI::Range(1, 60000));
    cmd->add_option(
           "--slow", o->slow_ms,
           "A reply later than this many ms breaks timing.slow_reply (default: the limit recorded with a "
           "timing.slow_reply finding, else not judged; 0: not judged)")
        ->check(CLI::Range(0, 600000));
    cmd->add_flag("--json", o->json, "Print the exchanges as JSON");
    cmd->add_flag("--no-restore", o->no_restore,
                  "Leave what the steps write as they leave it (to look at the device afterwards)");
    cmd->add_option("--profile-dir", o->profile_dirs, "Extra directory of profile files (repeatable)");
    cmd->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
    cmd->callback([o, &exit_code] { exit_code = run_replay_command(*o); });
}

}  // namespace mbscope::cli
