#include "conformance/runner.hpp"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iterator>
#include <span>

namespace mbscope::conformance {

using modbus::Table;

std::size_t Report::count(Outcome o) const {
    std::size_t n = 0;
    for (const auto& r : results)
        n += r.outcome == o;
    return n;
}

std::size_t Report::failures_of(Authority a) const {
    std::size_t n = 0;
    for (const auto& r : results)
        n += r.outcome == Outcome::Fail && r.rule.authority == a;
    return n;
}

bool Report::all_restored() const {
    for (const auto& t : restored)
        if (!t.restored) return false;
    return true;
}

int verdict(const Report& report) {
    const bool failed =
        report.failures_of(Authority::Specification) + report.failures_of(Authority::Manual) > 0 ||
        report.count(Outcome::Error) > 0 || !report.all_restored();
    return failed ? 1 : 0;
}

std::string nothing_judged(const Report& report) {
    if (report.stopped) return {};
    if (report.results.empty()) {
        std::string globs;
        for (const auto& g : report.rule_globs)
            globs += (globs.empty() ? "'" : ", '") + g + "'";
        return "--rules " + (globs.empty() ? std::string("(all)") : globs) + " match no rule for " +
               report.profile_id;
    }
    // Every rule skipped (--read-only with writing rules only, broadcast rules over Modbus/TCP): as empty a
    // run, whatever the target is, even one that never answers (it was sent nothing).
    const auto skipped = report.count(Outcome::Skip);
    // Every rule skipped or ended in error (none could be judged: a device that damaged every reply to
    // them, say): as empty a run, not a failed one ("fail", exit 1, with 0 failed). Unless a point written
    // was not put back: that fails the run whatever else.
    const auto errors = report.count(Outcome::Error);
    if (errors > 0 && skipped + errors == report.results.size() && report.all_restored()) {
        const auto error = std::find_if(report.results.begin(), report.results.end(),
                                        [](const RuleResult& r) { return r.outcome == Outcome::Error; });
        return "no rule selected could be judged: " + std::to_string(errors) + " ended in error (" +
               error->rule.id + ": " + (error->reason.empty() ? error->observed : error->reason) +
               (errors > 1 ? ", ..." : "") + ")" +
               (skipped ? ", " + std::to_string(skipped) + " skipped" : "");
    }
    if (skipped < report.results.size()) return {};
    const RuleResult& first = report.results.front();
    return (skipped == 1 ? std::string("the one rule selected was skipped (")
                         : "all " + std::to_string(skipped) + " rules selected were skipped (") +
           first.rule.id + ": " + first.reason + (skipped > 1 ? ", ..." : "") + ")";
}

std::string_view verdict_text(const Report& report) {
    if (report.stopped) return "interrupted";
    if (!report.unanswered.empty() || !nothing_judged(report).empty()) return "error";
    return verdict(report) == 0 ? "pass" : "fail";
}

namespace {

std::string fnv1a_of_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return "unavailable";
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (std::istreambuf_iterator<char> it(in), end; it != end; ++it) {
        h ^= static_cast<unsigned char>(*it);
        h *= 0x100000001b3ull;
    }
    char buf[24];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
}

std::string utc_now() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

// The valid addresses of a table as runs, from the profile's points.
void facts_from_profile(const modbus::Profile& p, TableFacts& f) {
    std::vector<std::uint16_t> addresses;
    for (const auto& pt : p.table(f.table))
        for (int w = 0; w < pt.encoding.words; ++w)
            addresses.push_back(static_cast<std::uint16_t>(pt.address + w));
    std::sort(addresses.begin(), addresses.end());
    for (auto a : addresses) {
        if (!f.runs.empty() && a <= f.runs.back().second + 1)
            f.runs.back().second = std::max(f.runs.back().second, a);
        else
            f.runs.push_back({a, a});
    }
}

// The reply is the device's own and arrived whole (its checksum holds, its envelope is the request's), of
// function `fc` and not an exception, whether or not its body decodes.
bool answered_normally(const modbus::transport::Exchange& ex, std::uint8_t fc) {
    if (!ex.response || !ex.response->checksum_ok || !envelope_fault(ex).empty()) return false;
    const auto pdu = ex.response->pdu();
    return !pdu.empty() && pdu[0] == fc;
}

// The generic profile names no addresses: find how far the table reaches from 0 by bisection. Only a reply
// tells: a normal one that the address is readable, an exception that it is not. A request lost on the way
// (no reply, or one whose checksum is damaged or that is someone else's) is asked again; one that stays
// unanswered makes the table's extent unknown and says so, rather than deleting the table (its rules skipped
// as "no address in the map") or moving its end (a readable address failed as "past the end"). A reply that
// arrived whole and is the device's own, of the read's function and no exception, answered: the address is
// readable, and what is wrong inside the reply (a byte count unlike the quantity) is for the rules to fail.
// Taken as unknown, every read rule was skipped and a device damaging every read passed. A reply that came
// damaged is not silence either: the device answers and damages its replies (SL §2.5.1.2: a master discards
// a frame whose CRC fails; SL §2.2: a reply carries the slave's own address), which the rules must fail, not
// skip (TableFacts::damaged).
void facts_by_probing(Session& s, std::uint8_t fc, TableFacts& f, const std::atomic<bool>* stop) {
    enum class Read : std::uint8_t { Yes, No, Unknown };
    std::string damage;  // the last reply that came and answered nothing, in words
    const auto readable = [&](std::uint16_t a) {
        damage.clear();
        for (int attempt = 0; attempt < 3; ++attempt) {
            const auto ex = s.request(
                modbus::encode_pdu(modbus::make_read_request(static_cast<modbus::FunctionCode>(fc), a, 1)),
                "probe the address space");
            if (answered_normally(ex, fc)) return Read::Yes;
            if (const auto pdu = response_pdu(ex); pdu && pdu->is_exception()) return Read::No;
            // Bytes that came for this request (not a late reply to an earlier one set aside).
            if (!ex.own_received().empty()) damage = describe(ex);
            if (stop && stop->load()) break;
        }
        return Read::Unknown;
    };
    const auto unanswered = [&](std::uint32_t a) {
        return "address " + std::to_string(a) + " got no usable reply to three reads while the " +
               std::string(modbus::to_string(f.table)) + " were probed" +
               (damage.empty() ? std::string() : " (every reply that came was damaged: " + damage + ")");
    };
    if (const Read at_0 = readable(0); at_0 != Read::Yes) {
        if (at_0 == Read::Unknown) {
            f.unknown = unanswered(0) + ": whether the table has points is unknown";
            if (!damage.empty())
                f.damaged = "the device damaged every reply to the reads of address 0 that probed the " +
                            std::string(modbus::to_string(f.table)) + " (" + damage +
                            "): the map is unknown, not empty";
        }
        return;
    }
    const Read at_end = readable(0xFFFF);
    if (at_end == Read::Yes) {
        f.runs.push_back({0, 0xFFFF});
        return;
    }
    std::uint32_t lo = 0, hi = 0xFFFF;  // lo readable, hi not
    if (at_end == Read::Unknown) f.end_unknown = unanswered(0xFFFF);
    while (hi - lo > 1 && f.end_unknown.empty()) {
        if (stop && stop->load()) return;  // Ctrl-C: the run ends before its rules
        const auto mid = (lo + hi) / 2;
        switch (readable(static_cast<std::uint16_t>(mid))) {
            case Read::Yes:
                lo = mid;
                break;
            case Read::No:
                hi = mid;
                break;
            case Read::Unknown:
                f.end_unknown = unanswered(mid);
                break;
        }
    }
    if (!f.end_unknown.empty()) f.end_unknown += ": the table reaches at least " + std::to_string(lo);
    f.runs.push_back({0, static_cast<std::uint16_t>(lo)});
}

}  // namespace

namespace {

// What every report says of its run before a rule is tried.
Report report_heading(const modbus::Profile& profile, const CheckOptions& options) {
    Report report;
    report.mbscope_version = MBSCOPE_VERSION;
    report.profile_id = profile.id;
    report.profile_file = profile.file;
    report.profile_hash = fnv1a_of_file(profile.file);
    report.target = options.target;
    report.unit = options.session.unit;
    report.seed = options.run.seed;
    report.read_only = options.run.read_only;
    report.rule_globs = options.run.rule_globs;
    report.interval_ms = options.session.interval.count();
    report.timeout_ms = options.session.timeout.count();
    report.started = utc_now();
    return report;
}

}  // namespace

Report unreachable_report(const modbus::Profile& profile, const CheckOptions& options,
                          const std::string& why) {
    Report report = report_heading(profile, options);
    RuleResult r;
    r.rule = {
        "target.reachable",
        "target",
        "TCP §4.2; SL §2.5",
        "The target can be reached: its connection opens (TCP) or its serial device opens and takes the "
        "line settings.",
        Authority::Specification,
        false};
    r.outcome = Outcome::Error;
    r.expected = "the connection or device opens";
    r.observed = why;
    r.reason = "cannot reach the target: " + why;
    // Nothing judged: the verdict is "error", not "fail" (no device defect was found).
    report.unanswered = r.reason;
    report.results.push_back(std::move(r));
    return report;
}

Report interrupted_report(const modbus::Profile& profile, const CheckOptions& options) {
    Report report = report_heading(profile, options);
    report.stopped = true;
    return report;
}

Report run_check(modbus::transport::Client& client, const modbus::Profile& profile,
                 const CheckOptions& options, const std::atomic<bool>* stop) {
    const auto started = std::chrono::steady_clock::now();
    Report report = report_heading(profile, options);

    Session session(client, options.session, &profile);
    // Every rule writes through the session: the restore knows what the run changed, and leaves the rest
    // (a refused write, one of the value a point held, a device's own change) alone.
    session.watch_writes();
    Context c{session, profile, options.run, {}, {}, stop};
    for (Table t : {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters}) {
        if (stop && stop->load()) break;
        TableFacts& f = c.tables[static_cast<int>(t)];
        f.table = t;
        const auto read_fc = static_cast<std::uint8_t>(modbus::read_function(t));
        f.present = profile.functions.supports(read_fc);
        if (!f.present) continue;
        if (profile.open_address_space)
            facts_by_probing(session, read_fc, f, stop);
        else
            facts_from_profile(profile, f);
    }
    session.take_evidence();
    using Family = void (*)(Context&);
    // The families that write, then those that send frames a faulty device may not survive (half frames,
    // garbage, bad headers) and write nothing: what the first wrote goes back between them, while the device
    // still answers (one that hung on a half frame kept every value a rule had written).
    const Family writing[] = {check_function_codes, check_quantities, check_addresses, check_values,
                              check_write_encoding, check_data,       check_broadcast};
    const Family after_restore[] = {check_framing, check_tcp, check_robustness, check_response_times,
                                    check_unsolicited};
    const auto run_families = [&](std::span<const Family> families) {
        for (Family family : families) {
            if (stop && stop->load()) {
                report.stopped = true;
                break;
            }
            family(c);
        }
    };
    run_families(writing);
    const auto restore = [&] {
        if (const auto text = session.restore_announcement(); options.run.note && !text.empty())
            options.run.note(text);
        // One entry per point, its last outcome: a point that did not go back the first time and did the
        // second is restored.
        for (auto& t : session.restore_and_forget()) {
            const auto same =
                std::find_if(report.restored.begin(), report.restored.end(),
                             [&](const Touched& r) { return r.table == t.table && r.address == t.address; });
            if (same != report.restored.end())
                *same = std::move(t);
            else
                report.restored.push_back(std::move(t));
        }
    };
    if (!report.stopped) {
        restore();
        run_families(after_restore);
    }
    // A stop during the last family, or before the first (while the address space was probed).
    if (stop && stop->load()) report.stopped = true;
    // Rules whose requests every slave must ignore (half a request, a broadcast) pass on silence, which a
    // target that answers nothing (a wrong unit id) gives as well: with no request owed a reply in the run,
    // one read that any device of the profile answers tells the two apart (it was taken for a target
    // answering nothing, exit 2, for `--rules framing.truncated` against a correct device), and shows whether
    // the device still answers after them. Made whenever no request was owed a reply, as
    // conformance/README.md says, not only when nothing came back: a device that answered a bad checksum
    // and then no more was left unasked.
    if (!report.stopped && session.requests() > 0 && session.requests_owed_reply() == 0)
        if (const auto probe = c.probe_read()) {
            (void)session.request(probe->pdu,
                                  "is the target answering? a read any device of the profile answers");
            (void)session.take_evidence();
        }
    // A target that answered nothing may be slower than the timeout several times over rather than silent:
    // it was told "wrong unit id, transport or line settings?" (a device 4x slower than the timeout, whose
    // first reply came after the run had stopped). Three timeouts more are listened to, as long again as the
    // run's first requests waited, and what comes is late.
    const bool silent =
        session.requests_owed_reply() > 0 && session.response_times().empty() && session.late_replies() == 0;
    const auto listened = 3 * options.session.timeout;
    std::vector<Evidence> last_listening;
    if (!report.stopped && silent) {
        session.listen_for_late(listened);
        last_listening = session.take_evidence();
    }
    // Nothing lost: every point a rule wrote goes back to its original value, even after a stop (and any a
    // later family wrote, none today).
    restore();
    report.results = std::move(c.results);
    report.response_times = session.response_times();
    report.requests = session.requests();
    report.late_replies = session.late_replies();
    // A target whose every reply came after the timeout is judged no better: each rule saw no reply (the
    // command said "could not run" with exit 2 while its reports failed 122 rules). Nor is one that answered
    // more requests late than in time: its rules failed for the timeout the run was given, not for what the
    // device does (a few replies taken in time, some of them late ones to other requests, kept a run against
    // a device 150 ms slower than the timeout judged, 163 rules failed).
    const std::size_t in_time = report.response_times.size();
    const bool mostly_late = session.answered_late() > in_time;
    if (report.requests > 0 && (in_time == 0 || mostly_late) && !report.stopped) {
        // Bytes that came back all the same are no silence: a peer that speaks something else, or breaks
        // off its replies, is not a wrong unit id. Counted over the whole run: a target answering every
        // request with noise stops the run in its probing, before any rule kept evidence.
        const std::uint64_t heard = session.bytes_received();
        // The count is every request sent, the address space's probing (three reads of each table's address
        // 0) included; the rules stop after the first three owed a reply (Context::silent_after).
        if (in_time > 0)
            report.unanswered = "the target answered " + std::to_string(session.answered_late()) +
                                " of the " + std::to_string(report.requests) +
                                " requests sent only after the " + std::to_string(report.timeout_ms) +
                                " ms timeout, " + std::to_string(in_time) + " within it (" +
                                std::to_string(report.late_replies) + " late replies): raise --timeout";
        else if (report.late_replies)
            report.unanswered = "the target answered none of the " + std::to_string(report.requests) +
                                " requests sent within the " + std::to_string(report.timeout_ms) +
                                " ms timeout, only after it (" + std::to_string(report.late_replies) +
                                " late replies): raise --timeout";
        else
            report.unanswered =
                "the target answered none of the " + std::to_string(report.requests) + " requests sent " +
                (heard == 0
                     ? "(wrong unit id, transport or line settings?" +
                           (last_listening.empty() ? std::string()
                                                   : " Nothing came in " + std::to_string(listened.count()) +
                                                         " ms more either") +
                           ")"
                     : "with a reply: the " + std::to_string(heard) +
                           " bytes it sent form none for this framing and unit (another protocol, or "
                           "replies cut off?)");
        // What the rules saw is silence, not the device's behaviour: nothing was judged. Rules that pass on
        // silence pass vacuously, and failures for want of a reply are no failures of the device.
        for (auto& r : report.results) {
            if (r.outcome == Outcome::Skip) continue;
            r.outcome = Outcome::Error;
            r.reason = "not judged: " + report.unanswered;
        }
        RuleResult answered;
        answered.rule = {
            "target.answered",        "target",
            "AP §4.1; SL §2.1",       "The target answers the run's requests within the timeout.",
            Authority::Specification, false};
        answered.outcome = Outcome::Error;
        answered.evidence = std::move(last_listening);
        answered.expected = "replies to requests any device of the profile answers";
        answered.observed = in_time > 0           ? "more late replies than replies in time"
                            : report.late_replies ? "only late replies"
                                                  : "no reply";
        // "Below" only when a rule ran: a target silent from the probing on had none run at all.
        const bool ran = !report.results.empty();
        answered.reason = report.unanswered + (!c.rules_not_run ? std::string()
                                               : ran            ? "; the rules after those below were not run"
                                                     : "; no rule was run, the run stopping once " +
                                                           std::to_string(Context::silent_after) +
                                                           " requests owed a reply got none");
        report.results.insert(report.results.begin(), std::move(answered));
    }
    report.wall = std::chrono::steady_clock::now() - started;
    return report;
}

}  // namespace mbscope::conformance
