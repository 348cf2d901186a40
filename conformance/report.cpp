#include "conformance/report.hpp"

#include <algorithm>
#include <cstdio>
#include <map>

#include "modbus/frame_text.hpp"
#include "modbus/function_code.hpp"

namespace mbscope::conformance {

namespace {

std::string hex(const std::vector<std::uint8_t>& bytes) {
    std::string out;
    char buf[4];
    for (auto b : bytes) {
        std::snprintf(buf, sizeof buf, "%02X ", b);
        out += buf;
    }
    if (!out.empty()) out.pop_back();
    return out;
}

// What went out: a late reply's evidence sent nothing.
std::string sent_hex(const std::vector<std::uint8_t>& bytes) {
    return bytes.empty() ? "(nothing sent)" : hex(bytes);
}

std::string ms(std::chrono::nanoseconds d) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(d.count()) / 1e6);
    return buf;
}

// A JUnit `time`: seconds as the schema's xs:decimal, in fixed notation to the microsecond. Streamed as a
// double it read "4.9333e-05", which the JUnit XSD and the CI tools that check against it refuse.
std::string seconds_text(std::chrono::nanoseconds d) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6f", static_cast<double>(d.count()) / 1e9);
    return buf;
}

// Failures of implied rules are warnings: the manual does not say it in so many words.
std::string shown_outcome(const RuleResult& r) {
    if (r.outcome == Outcome::Fail && r.rule.authority == Authority::Implied) return "warn";
    return std::string(to_string(r.outcome));
}

// Text an XML 1.0 parser takes (§2.2): bytes that are not UTF-8 (a target or profile text may hold any) and
// U+FFFE/U+FFFF become U+FFFD; control characters other than tab and newline, a space.
std::string xml_escape(const std::string& s) {
    constexpr std::string_view replacement = "\xEF\xBF\xBD";
    std::string out;
    for (std::size_t i = 0; i < s.size();) {
        const auto c = modbus::utf8_at(s, i);
        if (c.length != 1) {
            if (c.length == 0 || c.code == 0xFFFE || c.code == 0xFFFF)
                out += replacement;
            else
                out.append(s, i, c.length);
            i += c.length == 0 ? 1 : c.length;
            continue;
        }
        const char ch = s[i++];
        switch (ch) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            case '\'':
                out += "&apos;";
                break;
            default:
                // XML 1.0 forbids most control characters even escaped.
                if (static_cast<unsigned char>(ch) < 0x20 && ch != '\n' && ch != '\t')
                    out += ' ';
                else
                    out += ch;
        }
    }
    return out;
}

struct Tally {
    std::size_t pass = 0, fail = 0, warn = 0, skip = 0, error = 0;
    void add(const RuleResult& r) {
        const std::string o = shown_outcome(r);
        if (o == "pass")
            ++pass;
        else if (o == "fail")
            ++fail;
        else if (o == "warn")
            ++warn;
        else if (o == "skip")
            ++skip;
        else
            ++error;
    }
};

std::map<std::string, Tally> by_family(const Report& report) {
    std::map<std::string, Tally> families;
    for (const auto& r : report.results)
        families[r.rule.family].add(r);
    return families;
}

}  // namespace

void write_text(std::ostream& out, const Report& report, bool verbose) {
    out << "mbscope check " << report.mbscope_version << ": " << report.target << " unit " << int(report.unit)
        << " as " << report.profile_id << " (profile " << report.profile_hash << ")\n";
    for (const auto& r : report.results) {
        const std::string o = shown_outcome(r);
        if (!verbose && (o == "pass")) continue;
        char line[16];
        std::snprintf(line, sizeof line, "%-5s ", o.c_str());
        out << line << r.rule.id << "  " << r.rule.text;
        if (r.outcome == Outcome::Skip || r.outcome == Outcome::Error) out << "  [" << r.reason << "]";
        out << '\n';
        if (r.outcome == Outcome::Fail || r.outcome == Outcome::Error) {
            out << "      source: " << r.rule.source << " (" << to_string(r.rule.authority) << ")\n";
            if (!r.expected.empty())
                out << "      expected: " << r.expected << "\n      observed: " << r.observed << '\n';
            for (const auto& e : r.evidence)
                out << "      > " << sent_hex(e.sent) << "   (" << e.note << ")\n      < "
                    << (e.received.empty() ? std::string("(nothing") + (e.timed_out ? ", timed out)" : ")")
                                           : hex(e.received))
                    << "   " << ms(e.elapsed) << " ms\n";
        }
    }
    out << "\nby family:\n";
    for (const auto& [family, t] : by_family(report)) {
        char line[160];
        std::snprintf(line, sizeof line, "  %-22s %4zu pass %4zu fail %4zu warn %4zu skip %4zu error\n",
                      family.c_str(), t.pass, t.fail, t.warn, t.skip, t.error);
        out << line;
    }
    std::size_t not_restored = 0;
    for (const auto& t : report.restored)
        not_restored += !t.restored;
    out << report.results.size() << " rules: " << report.count(Outcome::Pass) << " passed, "
        << report.failures_of(Authority::Specification) << " failed the specification, "
        << report.failures_of(Authority::Manual) << " failed the manual, "
        << report.failures_of(Authority::Implied) << " warnings (not counted in the exit code), "
        << report.count(Outcome::Skip) << " skipped, " << report.count(Outcome::Error) << " errors; "
        << report.requests << " requests in " << ms(report.wall) << " ms\n";
    if (report.late_replies)
        out << report.late_replies << " replies came after the " << report.timeout_ms
            << " ms timeout (\"late\" in the evidence): the rules saw no reply; a longer --timeout may suit "
               "the device\n";
    // "84 points written and restored, 84 NOT restored" contradicted itself.
    if (not_restored)
        out << report.restored.size() << " points written, " << report.restored.size() - not_restored
            << " restored";
    else
        out << report.restored.size() << " points written and restored";
    if (not_restored) {
        out << ", " << not_restored << " NOT restored:";
        for (const auto& t : report.restored)
            if (!t.restored)
                out << "\n  " << modbus::to_string(t.table) << " " << t.address << ": original " << t.original
                    << ", " << t.problem;
    }
    // Read-only points a rule's range reached count as restored when the device refused to take their
    // original back (a process value moves on its own); what they read now is said, not hidden.
    for (const auto& t : report.restored)
        if (t.restored && !t.problem.empty())
            out << "\n  note: " << modbus::to_string(t.table) << " " << t.address << ": " << t.problem;
    if (!report.unanswered.empty()) out << "\nnothing judged: " << report.unanswered;
    if (const auto none = nothing_judged(report); !none.empty()) out << "\nnothing judged: " << none;
    out << (report.stopped ? "\nstopped before the end (interrupted)\n" : "\n");
}

nlohmann::json to_json(const std::vector<Touched>& ledger) {
    nlohmann::json out = nlohmann::json::array();
    const auto value = [](const std::optional<std::uint16_t>& v) {
        return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
    };
    for (const auto& t : ledger)
        out.push_back({{"table", std::string(modbus::to_string(t.table))},
                       {"address", t.address},
                       {"original", t.original},
                       {"restored", t.restored},
                       {"problem", t.problem},
                       {"written", value(t.written)},
                       {"write_acknowledged", t.acknowledged},
                       {"device_changed", t.device_changed},
                       {"left", value(t.left)},
                       {"left_from", t.left_from},
                       {"restore_refused", t.restore_refused}});
    return out;
}

nlohmann::json to_json(const Report& report) {
    using nlohmann::json;
    json rules = json::array();
    for (const auto& r : report.results) {
        json evidence = json::array();
        for (const auto& e : r.evidence)
            evidence.push_back({{"note", e.note},
                                {"sent", hex(e.sent)},
                                {"received", hex(e.received)},
                                {"elapsed_ms", static_cast<double>(e.elapsed.count()) / 1e6},
                                {"timed_out", e.timed_out}});
        rules.push_back({{"id", r.rule.id},
                         {"family", r.rule.family},
                         {"source", r.rule.source},
                         {"text", r.rule.text},
                         {"authority", std::string(to_string(r.rule.authority))},
                         {"writes", r.rule.writes},
                         {"outcome", std::string(to_string(r.outcome))},
                         {"verdict", shown_outcome(r)},
                         {"expected", r.expected},
                         {"observed", r.observed},
                         {"reason", r.reason},
                         {"duration_ms", static_cast<double>(r.duration.count()) / 1e6},
                         {"evidence", evidence}});
    }
    const json restored = to_json(report.restored);
    json times = json::array();
    for (auto t : report.response_times)
        times.push_back(static_cast<double>(t.count()) / 1e6);
    return {{"format", "mbscope-check/1"},
            {"mbscope_version", report.mbscope_version},
            {"profile",
             {{"id", report.profile_id}, {"file", report.profile_file}, {"fnv1a64", report.profile_hash}}},
            {"configuration",
             {{"target", report.target},
              {"unit", report.unit},
              {"seed", report.seed},
              {"read_only", report.read_only},
              {"rules", report.rule_globs},
              {"interval_ms", report.interval_ms},
              {"timeout_ms", report.timeout_ms}}},
            {"started", report.started},
            {"wall_ms", static_cast<double>(report.wall.count()) / 1e6},
            {"requests", report.requests},
            {"late_replies", report.late_replies},
            {"stopped", report.stopped},
            {"unanswered", report.unanswered},
            {"summary",
             {{"rules", report.results.size()},
              {"pass", report.count(Outcome::Pass)},
              {"fail_specification", report.failures_of(Authority::Specification)},
              {"fail_manual", report.failures_of(Authority::Manual)},
              {"warn_implied", report.failures_of(Authority::Implied)},
              {"skip", report.count(Outcome::Skip)},
              {"error", report.count(Outcome::Error)},
              {"all_restored", report.all_restored()},
              {"verdict", verdict_text(report)}}},
            {"rules", rules},
            {"restored", restored},
            {"response_times_ms", times}};
}

void write_junit(std::ostream& out, const Report& report) {
    const std::string run_error =
        report.stopped ? "the run was interrupted before every rule ran" : nothing_judged(report);
    std::map<std::string, std::vector<const RuleResult*>> suites;
    for (const auto& r : report.results)
        suites[r.rule.family].push_back(&r);
    // Points written and not put back fail the run (verdict): a testcase of their own says so, or a CI job
    // reading the JUnit report alone publishes a green run for a device the run left changed.
    std::size_t not_restored = 0;
    for (const auto& t : report.restored)
        not_restored += !t.restored;
    const bool restore_case = !report.restored.empty();
    out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    out << "<testsuites name=\"" << xml_escape("mbscope check " + report.profile_id + " " + report.target)
        << "\" tests=\"" << report.results.size() + (run_error.empty() ? 0 : 1) + (restore_case ? 1 : 0)
        << "\" failures=\""
        << report.failures_of(Authority::Specification) + report.failures_of(Authority::Manual) +
               (not_restored ? 1 : 0)
        << "\" errors=\"" << report.count(Outcome::Error) + (run_error.empty() ? 0 : 1) << "\" skipped=\""
        << report.count(Outcome::Skip) << "\" time=\"" << seconds_text(report.wall) << "\">\n";
    // An interrupted run, or one that judged no rule, certifies nothing: one testcase in error says so, so
    // that a CI job fails on it.
    if (!run_error.empty())
        out << "  <testsuite name=\"run\" tests=\"1\" failures=\"0\" errors=\"1\" skipped=\"0\" time=\"0\">\n"
            << "    <testcase classname=\"" << xml_escape("mbscope." + report.profile_id + ".run")
            << "\" name=\""
            << (report.stopped           ? "run.interrupted"
                : report.results.empty() ? "run.no_rules"
                                         : "run.nothing_judged")
            << "\" time=\"0\">\n"
            << "      <error message=\"" << xml_escape(run_error) << "\"/>\n    </testcase>\n"
            << "  </testsuite>\n";
    for (const auto& [family, rules] : suites) {
        Tally t;
        std::chrono::nanoseconds time{0};
        for (const auto* r : rules) {
            t.add(*r);
            time += r->duration;
        }
        out << "  <testsuite name=\"" << xml_escape(family) << "\" tests=\"" << rules.size()
            << "\" failures=\"" << t.fail << "\" errors=\"" << t.error << "\" skipped=\"" << t.skip
            << "\" time=\"" << seconds_text(time) << "\">\n";
        for (const auto* r : rules) {
            out << "    <testcase classname=\"" << xml_escape("mbscope." + report.profile_id + "." + family)
                << "\" name=\"" << xml_escape(r->rule.id) << "\" time=\"" << seconds_text(r->duration)
                << "\">\n";
            std::string body = r->rule.text + "\nsource: " + r->rule.source + " (" +
                               std::string(to_string(r->rule.authority)) + ")\nexpected: " + r->expected +
                               "\nobserved: " + r->observed + "\n";
            for (const auto& e : r->evidence)
                body += "> " + sent_hex(e.sent) + "  (" + e.note + ")\n< " +
                        (e.received.empty() ? "(nothing)" : hex(e.received)) + "\n";
            const std::string shown = shown_outcome(*r);
            if (shown == "fail")
                out << "      <failure message=\"" << xml_escape(r->expected + " / " + r->observed)
                    << "\" type=\"" << xml_escape(r->rule.source) << "\">" << xml_escape(body)
                    << "</failure>\n";
            else if (shown == "error")
                out << "      <error message=\"" << xml_escape(r->reason) << "\">" << xml_escape(body)
                    << "</error>\n";
            else if (shown == "skip")
                out << "      <skipped message=\"" << xml_escape(r->reason) << "\"/>\n";
            else if (shown == "warn")
                out << "      <system-out>"
                    << xml_escape("warning (not counted in the exit code: " + std::string(r->rule.source) +
                                  ")\n" + body)
                    << "</system-out>\n";
            out << "    </testcase>\n";
        }
        out << "  </testsuite>\n";
    }
    if (restore_case) {
        std::string body;
        for (const auto& t : report.restored)
            body += std::string(modbus::to_string(t.table)) + " " + std::to_string(t.address) +
                    ": original " + std::to_string(t.original) +
                    (t.restored ? (t.problem.empty() ? ", restored" : ", restored; " + t.problem)
                                : ", NOT restored: " + t.problem) +
                    "\n";
        out << "  <testsuite name=\"restore\" tests=\"1\" failures=\"" << (not_restored ? 1 : 0)
            << "\" errors=\"0\" skipped=\"0\" time=\"0\">\n"
            << "    <testcase classname=\"" << xml_escape("mbscope." + report.profile_id + ".restore")
            << "\" name=\"restore.all_points\" time=\"0\">\n";
        if (not_restored)
            out << "      <failure message=\""
                << xml_escape(std::to_string(not_restored) + " of " + std::to_string(report.restored.size()) +
                              " points written NOT restored")
                << "\" type=\"restore\">" << xml_escape(body) << "</failure>\n";
        else
            out << "      <system-out>" << xml_escape(body) << "</system-out>\n";
        out << "    </testcase>\n  </testsuite>\n";
    }
    out << "</testsuites>\n";
}

void write_html(std::ostream& out, const Report& report) {
    const auto esc = [](const std::string& s) {
        std::string o;
        for (char ch : s) {
            if (ch == '&')
                o += "&amp;";
            else if (ch == '<')
                o += "&lt;";
            else if (ch == '>')
                o += "&gt;";
            else if (ch == '"')
                o += "&quot;";
            else
                o += ch;
        }
        return o;
    };
    out << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>mbscope check: "
        << esc(report.profile_id)
        << "</title>\n<style>body{font:14px "
           "system-ui,sans-serif;margin:2em;color:#222}table{border-collapse:collapse;width:100%}"
           "td,th{border-bottom:1px solid #ddd;padding:4px 6px;text-align:left;vertical-align:top}"
           ".pass{color:#17663a}.fail{color:#b00020;font-weight:bold}.warn{color:#a15c00}.skip,.error{color:#"
           "666}"
           "code,pre{font:12px ui-monospace,monospace}details pre{background:#f6f6f6;padding:6px}"
           ".bar{display:inline-block;background:#4a7ab5;height:12px}</style></head><body>\n";
    out << "<h1>Modbus conformance: " << esc(report.profile_id) << " at " << esc(report.target) << "</h1>\n";
    out << "<p>mbscope " << esc(report.mbscope_version) << ", profile " << esc(report.profile_file)
        << " (FNV-1a " << esc(report.profile_hash) << "), unit " << int(report.unit) << ", seed "
        << report.seed << (report.read_only ? ", read-only" : "") << ", started " << esc(report.started)
        << ", " << report.requests << " requests in " << ms(report.wall) << " ms.</p>\n";
    out << "<p><b>Verdict: " << verdict_text(report) << "</b> — " << report.count(Outcome::Pass)
        << " passed, " << report.failures_of(Authority::Specification) << " failed the specification, "
        << report.failures_of(Authority::Manual) << " failed the manual, "
        << report.failures_of(Authority::Implied) << " warnings, " << report.count(Outcome::Skip)
        << " skipped, " << report.count(Outcome::Error) << " errors; " << report.restored.size()
        << " points written, " << (report.all_restored() ? "all restored" : "NOT all restored")
        << ".</p>\n<h2>Summary by "
           "family</h2><table><tr><th>family</th><th>pass</th><th>fail</th><th>warn</th><th>skip</th>"
           "<th>error</th></tr>\n";
    for (const auto& [family, t] : by_family(report))
        out << "<tr><td>" << esc(family) << "</td><td>" << t.pass << "</td><td>" << t.fail << "</td><td>"
            << t.warn << "</td><td>" << t.skip << "</td><td>" << t.error << "</td></tr>\n";
    out << "</table>\n<h2>Response times</h2>\n";
    if (!report.response_times.empty()) {
        auto times = report.response_times;
        std::sort(times.begin(), times.end());
        const double lo = static_cast<double>(times.front().count()),
                     hi = static_cast<double>(times.back().count());
        constexpr int bins = 12;
        std::array<std::size_t, bins> counts{};
        for (auto t : times)
            ++counts[std::min<std::size_t>(
                bins - 1,
                hi > lo ? static_cast<std::size_t>((static_cast<double>(t.count()) - lo) / (hi - lo) * bins)
                        : 0)];
        const std::size_t peak = *std::max_element(counts.begin(), counts.end());
        out << "<table>\n";
        for (int i = 0; i < bins; ++i)
            out << "<tr><td>" << ms(std::chrono::nanoseconds(static_cast<long>(lo + (hi - lo) * i / bins)))
                << " ms</td><td><span class=\"bar\" style=\"width:" << (peak ? 400 * counts[i] / peak : 0)
                << "px\"></span> " << counts[i] << "</td></tr>\n";
        out << "</table><p>min " << ms(times.front()) << " ms, median " << ms(times[times.size() / 2])
            << " ms, max " << ms(times.back()) << " ms over " << times.size() << " replies.</p>\n";
    }
    out << "<h2>Rules</h2><table><tr><th>outcome</th><th>rule</th><th>what it "
           "checks</th><th>source</th><th>evidence</th></tr>\n";
    for (const auto& r : report.results) {
        const std::string o = shown_outcome(r);
        out << "<tr><td class=\"" << o << "\">" << o << "</td><td><code>" << esc(r.rule.id)
            << "</code></td><td>" << esc(r.rule.text);
        if (!r.reason.empty()) out << "<br><i>" << esc(r.reason) << "</i>";
        out << "</td><td>" << esc(r.rule.source) << " (" << to_string(r.rule.authority) << ")</td><td>";
        if (!r.evidence.empty()) {
            out << "<details><summary>"
                << esc(r.observed.empty() ? std::to_string(r.evidence.size()) + " exchanges" : r.observed)
                << "</summary><pre>expected: " << esc(r.expected) << "\n";
            for (const auto& e : r.evidence)
                out << "&gt; " << sent_hex(e.sent) << "  (" << esc(e.note) << ")\n&lt; "
                    << (e.received.empty() ? "(nothing)" : hex(e.received)) << "  " << ms(e.elapsed)
                    << " ms\n";
            out << "</pre></details>";
        }
        out << "</td></tr>\n";
    }
    out << "</table>\n<h2>Points written and "
           "restored</h2><table><tr><th>table</th><th>address</th><th>original</th>"
           "<th>restored</th></tr>\n";
    for (const auto& t : report.restored)
        out << "<tr><td>" << modbus::to_string(t.table) << "</td><td>" << t.address << "</td><td>"
            << t.original << "</td><td class=\"" << (t.restored ? "pass" : "fail") << "\">"
            << (t.restored ? (t.problem.empty() ? std::string("yes") : esc("yes; " + t.problem))
                           : esc("no: " + t.problem))
            << "</td></tr>\n";
    out << "</table></body></html>\n";
}

}  // namespace mbscope::conformance
