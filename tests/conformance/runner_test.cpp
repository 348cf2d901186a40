// The conformance runner against the reference slave, in process: a slave::Server on 127.0.0.1 port 0 in a
// thread, the runner's Client on the other end.
//
//  - CleanSlave: every bundled profile over Modbus/TCP, and one profile of each manual over every other
//    transport (rtu-tcp, ascii-tcp, udp; RTU and ASCII over a pseudo-terminal in serial_line_test.cpp),
//    certify with no failure,
//    restore every point they wrote, and leave the slave's register image as they found it.
//  - PlantedFault: each of the slave's faults makes the run fail (or warn, where only an implied rule
//    of the manual catches it) through the rules that are meant to catch it.
//  - Reports: the JSON report carries every rule with its evidence and the summary adds up; the JUnit XML
//    report holds one testcase per rule with matching counts.
#include <gtest/gtest.h>

#include <fnmatch.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "conformance/context.hpp"
#include "conformance/session.hpp"
#include "modbus/adu.hpp"
#include "modbus/transport/socket.hpp"
#include "tests/conformance/runner_support.hpp"
#include "tests/support/garbage_peer.hpp"

namespace mbscope::conformance::test_conformance_runner_test {
namespace {

using namespace mbscope::conformance::test;

// ---- a clean slave passes

class EveryProfileOverTcp : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryProfileOverTcp, CertifiesWithNoFailureAndRestoresEverything) {
    RunningServer server({}, 1, GetParam());
    const auto run = certify(server, "tcp", GetParam());
    expect_clean(run, 150);
    // No momentary command was written (Walchem's "write 1 to reset" points): writing one acts, and no
    // restore undoes that. Every point written is in the restore list.
    const auto& profile = slave::test::profile(GetParam());
    for (const auto& t : run.report.restored) {
        const auto* point = profile.find(t.table, t.address);
        EXPECT_FALSE(point && point->momentary) << modbus::to_string(t.table) << ' ' << t.address;
    }
    // Every rule names where it comes from and says what it checks.
    for (const auto& x : run.report.results) {
        EXPECT_FALSE(x.rule.id.empty());
        EXPECT_FALSE(x.rule.source.empty()) << x.rule.id;
        EXPECT_FALSE(x.rule.text.empty()) << x.rule.id;
        if (x.outcome == Outcome::Skip) {
            EXPECT_FALSE(x.reason.empty()) << x.rule.id;
        }
        // Judged over the whole run's exchanges, not by exchanges of their own.
        if (x.outcome == Outcome::Pass && x.rule.id != "robustness.response_time" &&
            x.rule.id != "reply.once") {
            EXPECT_FALSE(x.evidence.empty()) << x.rule.id;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Bundled, EveryProfileOverTcp, ::testing::ValuesIn(slave::test::profile_ids()),
                         [](const auto& info) {
                             std::string n = info.param;
                             for (auto& ch : n)
                                 if (ch == '-') ch = '_';
                             return n;
                         });

struct TransportCase {
    std::string scheme;
    std::string profile;
};

std::ostream& operator<<(std::ostream& out, const TransportCase& c) {
    return out << c.profile << " over " << c.scheme;
}

class EveryTransport : public ::testing::TestWithParam<TransportCase> {};

TEST_P(EveryTransport, CertifiesWithNoFailureAndRestoresEverything) {
    RunningServer server({}, 1, GetParam().profile);
    expect_clean(certify(server, GetParam().scheme, GetParam().profile), 150);
}

std::vector<TransportCase> transport_cases() {
    std::vector<TransportCase> out;
    for (const char* scheme : {"rtu-tcp", "ascii-tcp", "udp"})
        for (const char* id : {"mmk-2030", "dcy-2050", "cth2265i", "walchem-w600", "modbus"})
            out.push_back({scheme, id});
    return out;
}

INSTANTIATE_TEST_SUITE_P(OneProfilePerManual, EveryTransport, ::testing::ValuesIn(transport_cases()),
                         [](const auto& info) {
                             std::string n = info.param.scheme + "_" + info.param.profile;
                             for (auto& ch : n)
                                 if (ch == '-') ch = '_';
                             return n;
                         });

// MK-CFG-01: the registers mirroring the line read what the runner uses. A device whose PROT says ASCII
// while it speaks RTU fails; speed and parity, which a gateway's serial side decides, are skipped over TCP.
TEST(LineMirrors, APortReadingAnotherFramingThanItSpeaksFails) {
    RunningServer server({}, 1, "mmk-2030");
    server.keep_image = true;  // made without a line: ENDER reads the unit, PROT its first code, ASCII
    auto options = options_for();
    options.run.rule_globs = {"data.mirror.*"};
    const auto run = certify(server, "rtu-tcp", "mmk-2030", options);
    std::map<std::string, Outcome> outcomes;
    for (const auto& x : run.report.results)
        outcomes[x.rule.id] = x.outcome;
    EXPECT_EQ(outcomes, (std::map<std::string, Outcome>{{"data.mirror.hr7", Outcome::Pass},
                                                        {"data.mirror.hr8", Outcome::Fail},
                                                        {"data.mirror.hr9", Outcome::Skip},
                                                        {"data.mirror.hr10", Outcome::Skip}}));
    for (const auto& x : run.report.results)
        if (x.rule.id == "data.mirror.hr8") {
            EXPECT_EQ(x.expected, "1 (RTU)");
            EXPECT_EQ(x.observed, "0 (ASCII)");
        }
}

// RTU over a stream has no silence to end a frame: a device finds a request's end by its function code, so
// one of a code whose length nothing tells (9, unassigned) has no end it can find, and silence there is no
// failure of the specification (pymodbus over rtu-tcp failed 113 such rules; peer_test.cpp). A device that
// answers found the end: a wrong exception fails as anywhere, with the manual's authority.
TEST(FunctionCodes, OverAStreamOnlySilenceToACodeWithoutALengthIsExcused) {
    for (const std::string scheme : {"rtu-tcp", "tcp"}) {
        SCOPED_TRACE(scheme);
        RunningServer server({"wrong-exception=4"}, 1, "mmk-2030");
        auto options = options_for();
        options.run.rule_globs = {"fc.unsupported.9"};
        const auto run = certify(server, scheme, "mmk-2030", options);
        ASSERT_EQ(run.report.results.size(), 1u);
        const auto& x = run.report.results[0];
        EXPECT_EQ(x.outcome, Outcome::Fail) << x.observed;
        EXPECT_EQ(x.rule.authority, Authority::Manual);
    }
}

// Over Modbus/TCP unit 255 asks the device on the connection, not one by its address (TCP §4.4.1): the
// register mirroring the address (ENDER, 0 to 99) cannot read 255, and the rule failed a correct device.
TEST(LineMirrors, TheAddressIsNotJudgedAgainstUnit255OverTcp) {
    RunningServer server({}, 1, "mmk-2030");
    auto options = options_for();
    options.session.unit = 255;
    options.run.rule_globs = {"data.mirror.hr7"};
    const auto run = certify(server, "tcp", "mmk-2030", options);
    ASSERT_EQ(run.report.results.size(), 1u);
    EXPECT_EQ(run.report.results[0].outcome, Outcome::Skip) << failures(run.report);
    EXPECT_NE(run.report.results[0].reason.find("TCP §4.4.1"), std::string::npos);
}

// A reply counts only in its request's envelope. echo.fc8.0 compared the PDU alone, and tcp.pipelined the
// transaction ids alone: a reply from another unit, to another transaction or of another function passed.
struct EnvelopeCase {
    std::string fault;
    std::string scheme;
    std::string rule;
};

std::ostream& operator<<(std::ostream& out, const EnvelopeCase& c) {
    return out << c.rule << " against " << c.fault << " over " << c.scheme;
}

class EnvelopeFault : public ::testing::TestWithParam<EnvelopeCase> {};

TEST_P(EnvelopeFault, FailsTheRuleThatSawTheReply) {
    const EnvelopeCase& c = GetParam();
    RunningServer server({c.fault}, 1, "mmk-2030");
    auto options = options_for();
    options.run.rule_globs = {c.rule};
    const auto run = certify(server, c.scheme, "mmk-2030", options);
    ASSERT_EQ(run.report.results.size(), 1u);
    EXPECT_EQ(run.report.results[0].outcome, Outcome::Fail) << run.report.results[0].observed;
    EXPECT_EQ(verdict(run.report), 1);
}

INSTANTIATE_TEST_SUITE_P(Rules, EnvelopeFault,
                         ::testing::Values(EnvelopeCase{"wrong-unit", "tcp", "echo.fc8.0"},
                                           EnvelopeCase{"wrong-unit", "rtu-tcp", "echo.fc8.0"},
                                           EnvelopeCase{"wrong-tid", "tcp", "echo.fc8.0"},
                                           EnvelopeCase{"wrong-unit", "tcp", "tcp.pipelined"},
                                           EnvelopeCase{"wrong-tid", "tcp", "tcp.pipelined"},
                                           EnvelopeCase{"wrong-function", "tcp", "tcp.pipelined"},
                                           EnvelopeCase{"bad-protocol-id", "tcp", "tcp.pipelined"}),
                         [](const auto& info) {
                             std::string n =
                                 info.param.rule + "_" + info.param.fault + "_" + info.param.scheme;
                             for (auto& ch : n)
                                 if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                             return n;
                         });

// A manual's response time limit is about the device's answers to its requests: replies with another
// transaction id (the envelope rules' business) were timed with them, and a run with no reply to its
// request passed the limit "over 28 replies".
TEST(ResponseTime, CountsOnlyRepliesToTheirRequest) {
    struct Case {
        const char* fault;
        Outcome outcome;
        const char* said;
    };
    for (const Case c :
         {Case{"wrong-tid", Outcome::Skip, "no reply to its request was received in this run, only "},
          Case{"wrong-tid=0.5", Outcome::Pass,
               " replies that did not answer their requests (a bad "
               "checksum, another unit or transaction id)"},
          Case{"", Outcome::Pass, " replies"}}) {
        RunningServer server(c.fault[0] ? std::vector<std::string>{c.fault} : std::vector<std::string>{}, 1,
                             "mmk-2030");
        auto options = options_for();
        options.run.rule_globs = {"fc.supported.*", "robustness.response_time"};
        const auto run = certify(server, "tcp", "mmk-2030", options);
        ASSERT_FALSE(run.report.results.empty()) << c.fault;
        const RuleResult& r = run.report.results.back();
        ASSERT_EQ(r.rule.id, "robustness.response_time");
        EXPECT_EQ(r.outcome, c.outcome) << c.fault << ": " << r.reason << r.observed;
        EXPECT_NE((r.reason + r.observed).find(c.said), std::string::npos)
            << c.fault << ": " << r.reason << r.observed;
        EXPECT_EQ((r.reason + r.observed).find("not counted") != std::string::npos,
                  std::string(c.fault) == "wrong-tid=0.5")
            << r.observed;
    }
}

// A peer that answers every request with bytes that form no frame is no silent target: the report says
// it sent bytes that are no reply, not "wrong unit id, transport or line settings?", which sent the user
// off to check those. With the generic profile the run stops in its probing of the address space, before
// any rule kept evidence: the bytes are counted there too.
TEST(Runner, ATargetWhoseBytesFormNoReplyIsToldApartFromASilentOne) {
    for (const char* id : {"mmk-2030", "modbus"}) {
        SCOPED_TRACE(id);
        mbscope::test::GarbagePeer peer;
        auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(peer.port())));
        ASSERT_TRUE(client.has_value());
        const Report r = run_check(*client, slave::test::profile(id), options_for());
        EXPECT_NE(r.unanswered.find("answered none of the"), std::string::npos) << r.unanswered;
        EXPECT_NE(r.unanswered.find("bytes it sent form none for this framing and unit"), std::string::npos)
            << r.unanswered;
        EXPECT_EQ(r.unanswered.find("wrong unit id"), std::string::npos) << r.unanswered;
        EXPECT_EQ(verdict_text(r), "error");
    }
}

// The generic profile maps no coil: FC5 and FC15 were skipped as having "no readable and writable coil"
// while echo.fc5 wrote the first coil the device reads. They rewrite that coil with its own value now.
TEST(GenericProfile, SupportedCoilWritesAreTriedOnTheFirstCoilTheDeviceReads) {
    RunningServer server({}, 1, "modbus");
    auto options = options_for();
    options.run.rule_globs = {"fc.supported.5", "fc.supported.15"};
    const auto run = certify(server, "tcp", "modbus", options);
    ASSERT_EQ(run.report.results.size(), 2u);
    for (const auto& x : run.report.results)
        EXPECT_EQ(x.outcome, Outcome::Pass) << x.rule.id << ": " << x.reason << x.observed;
    expect_clean(run, 2);
}

// A target that answers nothing (here a unit nobody serves) made a report of a hundred failures, each rule
// waiting out its timeouts, with an exit code saying the run could not judge. The run now stops once its
// first requests all went unanswered; what ran is in error, not failed, and the reports say why.
TEST(Runner, ATargetThatAnswersNothingIsAnErrorNotAHundredFailures) {
    RunningServer server({}, 1, "mmk-2030");
    auto options = options_for(std::chrono::milliseconds(100));
    options.session.unit = 5;
    const auto run = certify(server, "tcp", "mmk-2030", options);
    const Report& r = run.report;
    EXPECT_NE(r.unanswered.find("answered none of the"), std::string::npos) << r.unanswered;
    EXPECT_EQ(r.requests, Context::silent_after);
    EXPECT_EQ(r.count(Outcome::Fail), 0u) << failures(r);
    EXPECT_EQ(r.count(Outcome::Pass), 0u);
    ASSERT_FALSE(r.results.empty());
    EXPECT_EQ(r.results[0].rule.id, "target.answered");
    EXPECT_NE(r.results[0].reason.find("were not run"), std::string::npos) << r.results[0].reason;
    EXPECT_EQ(verdict_text(r), "error");
    EXPECT_EQ(verdict(r), 1);
    const auto json = to_json(r);
    EXPECT_EQ(json["summary"]["verdict"], "error");
    EXPECT_EQ(json["summary"]["fail_specification"], 0);
    EXPECT_EQ(json["unanswered"], r.unanswered);
    std::ostringstream junit;
    write_junit(junit, r);
    EXPECT_NE(junit.str().find("failures=\"0\""), std::string::npos) << junit.str();
}

// The broadcast rules write a value other than the one the register holds when they run. They took it from
// the value read before the run, which echo.fc6 had already written to the same register: a device that
// ignored the broadcast read back the value "written", and passed .executed (or failed .refused).
TEST(Broadcast, WritesAreJudgedAgainstTheValueTheRegisterHoldsThen) {
    // A firmware that executes only FC5 and FC15 broadcasts.
    slave::test::profile_variant("mmk-2030-broadcast-5-15", "mmk-2030", [](modbus::Profile& p) {
        p.functions.broadcast = {5, 15};
    });
    auto options = options_for();
    options.run.rule_globs = {"echo.fc6", "broadcast.fc*"};
    options.run.broadcast_writes = true;  // the device is alone on its line
    for (const char* manual : {"mmk-2030", "mmk-2030-broadcast-5-15"}) {
        RunningServer server({}, 1, "mmk-2030-broadcast-5-15");
        const auto run = certify(server, "rtu-tcp", manual, options);
        std::map<std::string, Outcome> outcomes;
        for (const auto& x : run.report.results)
            outcomes[x.rule.id] = x.outcome;
        // Certified against the bundled manual (broadcast FC6 and FC16 executed), the firmware fails.
        const bool bundled = std::string(manual) == "mmk-2030";
        EXPECT_EQ(outcomes, (std::map<std::string, Outcome>{
                                {"echo.fc6", Outcome::Pass},
                                {bundled ? "broadcast.fc6.executed" : "broadcast.fc6.refused",
                                 bundled ? Outcome::Fail : Outcome::Pass},
                                {bundled ? "broadcast.fc16.executed" : "broadcast.fc16.refused",
                                 bundled ? Outcome::Fail : Outcome::Pass}}))
            << manual << failures(run.report);
        EXPECT_TRUE(run.report.all_restored()) << failures(run.report);
    }
}

// A write to unit 0 is executed by every device on the line, and the run puts back only the device under
// test: on a line shared with a second MMK-2030 the broadcast rules changed it, and the ledger said every
// point written was restored. They are sent only when the user says the device is alone on its line.
TEST(Broadcast, WritesAreSentOnlyForADeviceSaidToBeAloneOnItsLine) {
    RunningServer server({}, 1, "mmk-2030");
    auto options = options_for();
    options.run.rule_globs = {"broadcast.fc*"};
    const auto run = certify(server, "rtu-tcp", "mmk-2030", options);
    ASSERT_EQ(run.report.results.size(), 2u);
    for (const auto& x : run.report.results) {
        EXPECT_EQ(x.outcome, Outcome::Skip) << x.rule.id;
        EXPECT_NE(x.reason.find("--broadcast-writes"), std::string::npos) << x.reason;
    }
    EXPECT_EQ(server.device().image().modifications(), 0u);  // nothing written, to anyone
}

// A run whose every rule ended in error judged nothing: it said "fail", exit 1, with 0 failed. The MMK-2030
// whose addresses are off by one refuses the read value.hr26.enumeration needs, which leaves it in error.
TEST(Reports, ARunWhoseEveryRuleEndedInErrorJudgedNothing) {
    RunningServer server({"off-by-one-address"}, 1, "mmk-2030");
    auto options = options_for();
    options.run.rule_globs = {"value.hr26.enumeration"};
    const auto run = certify(server, "tcp", "mmk-2030", options);
    ASSERT_EQ(run.report.results.size(), 1u);
    ASSERT_EQ(run.report.results[0].outcome, Outcome::Error) << failures(run.report);
    EXPECT_EQ(verdict_text(run.report), "error");
    EXPECT_NE(nothing_judged(run.report)
                  .find("no rule selected could be judged: 1 ended in error "
                        "(value.hr26.enumeration: "),
              std::string::npos)
        << nothing_judged(run.report);
}

// The generic profile knows no device: an MMK-2030 refuses FC2 (it has no discrete inputs) with 01, which
// passed fc.supported.2, and then failed quantity.fc2.zero and address.fc2.overflow; and its register 0, the
// first it reads, is a process value it does not let be written (02), which failed fc.supported.6 and 16 and
// echo.fc6. A device judged by the specification alone fails none of these.
TEST(GenericProfile, ADeviceIsNotFailedForAFunctionItLacksOrARegisterItKeepsReadOnly) {
    RunningServer server({}, 1, "mmk-2030");
    const auto run = certify(server, "tcp", "modbus");
    EXPECT_EQ(run.report.count(Outcome::Fail), 0u) << failures(run.report);
    EXPECT_TRUE(run.report.all_restored()) << failures(run.report);
    std::map<std::string, const RuleResult*> by_id;
    for (const auto& x : run.report.results)
        by_id[x.rule.id] = &x;
    for (const char* id : {"quantity.fc2.zero", "address.fc2.overflow"}) {
        ASSERT_TRUE(by_id.count(id)) << id;
        EXPECT_EQ(by_id[id]->outcome, Outcome::Skip) << id;
        EXPECT_NE(by_id[id]->reason.find("does not implement function 2"), std::string::npos)
            << by_id[id]->reason;
    }
    ASSERT_TRUE(by_id.count("fc.supported.6"));
    EXPECT_EQ(by_id["fc.supported.6"]->outcome, Outcome::Pass);
}

// --idle 0 listens to nothing: silence.idle passed saying "nothing in 0 ms".
TEST(Runner, SilenceIdleOfZeroMillisecondsIsNotJudged) {
    RunningServer server({}, 1, "modbus");
    auto options = options_for();
    options.run.rule_globs = {"silence.idle"};
    options.run.idle = std::chrono::milliseconds(0);
    const auto run = certify(server, "tcp", "modbus", options);
    ASSERT_EQ(run.report.results.size(), 1u);
    EXPECT_EQ(run.report.results[0].outcome, Outcome::Skip);
    EXPECT_EQ(run.report.results[0].reason, "--idle 0: nothing was listened for");
}

// A stop during the last family (here its only rule) was not recorded: the report said "pass", the exit
// code was 0. Every report now says the run was interrupted; the JUnit file has an error for it.
TEST(Runner, AStopDuringTheLastFamilyIsAnInterruptedRun) {
    RunningServer server({}, 1, "mmk-2030");
    const std::uint16_t port = server.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    std::atomic<bool> stop{false};
    auto options = options_for();
    options.run.rule_globs = {"silence.idle"};
    options.run.progress = [&stop](const RuleResult&) { stop = true; };
    const auto report = run_check(*client, slave::test::profile("mmk-2030"), options, &stop);
    EXPECT_TRUE(report.stopped);
    EXPECT_EQ(verdict_text(report), "interrupted");
    EXPECT_EQ(to_json(report)["summary"]["verdict"], "interrupted");
    std::ostringstream junit;
    write_junit(junit, report);
    EXPECT_NE(junit.str().find("name=\"run.interrupted\""), std::string::npos) << junit.str();
    EXPECT_NE(junit.str().find("errors=\"1\""), std::string::npos) << junit.str();
}

// At a polling interval the restore is announced (Walchem's 5 s: a minute for every 12 points written).
TEST(Runner, TheRestoreAtAPollingIntervalIsAnnounced) {
    RunningServer server({}, 1, "mmk-2030");
    const std::uint16_t port = server.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    auto options = options_for();
    options.run.rule_globs = {"echo.fc6"};
    options.session.interval = std::chrono::milliseconds(1);
    std::vector<std::string> notes;
    options.run.note = [&notes](const std::string& n) { notes.push_back(n); };
    const auto report = run_check(*client, slave::test::profile("mmk-2030"), options, nullptr);
    ASSERT_FALSE(report.restored.empty());
    EXPECT_TRUE(report.all_restored());
    ASSERT_EQ(notes.size(), 1u);
    ASSERT_EQ(report.restored.size(), 1u);  // the register echo.fc6 wrote (the fuzzer's test has several)
    EXPECT_EQ(notes[0], "restoring the 1 point written, a request every 1 ms (the polling interval)");
}

// ---- every planted fault is caught

struct FaultCase {
    std::string fault;    // as on the command line
    std::string profile;  // a profile where the fault shows
    std::string scheme;
    std::string catches;        // glob of a rule id that must fail
    bool warning_only = false;  // only rules the manual implies catch it (exit code 0, warnings reported)
    // Rules to run (--rules), where a fault makes every rule wait for its timeout; empty: all.
    std::vector<std::string> rules = {};
};

std::ostream& operator<<(std::ostream& out, const FaultCase& c) {
    return out << c.fault << " on " << c.scheme << " as " << c.profile;
}

class PlantedFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(PlantedFault, IsCaughtByTheRulesMeantToCatchIt) {
    const FaultCase& c = GetParam();
    RunningServer server({c.fault}, 7, c.profile);
    auto options = options_for();
    options.run.rule_globs = c.rules;
    const auto run = certify(server, c.scheme, c.profile, options);
    const Report& r = run.report;
    // A device whose every reply comes after the timeout is not judged rule by rule: the run is in error
    // and says to raise --timeout (Runner.ATargetAnsweringOnlyLateIsNotJudged).
    if (c.fault.starts_with("slow-reply")) {
        EXPECT_EQ(verdict_text(r), "error") << failures(r);
        EXPECT_NE(r.unanswered.find("raise --timeout"), std::string::npos) << r.unanswered;
        return;
    }
    std::vector<std::string> failed;
    for (const auto& x : r.results)
        if (x.outcome == Outcome::Fail) failed.push_back(x.rule.id);
    ASSERT_FALSE(failed.empty()) << "the fault went unnoticed";
    bool caught = false;
    for (const auto& id : failed)
        caught |= fnmatch(c.catches.c_str(), id.c_str(), 0) == 0;
    std::string list;
    for (const auto& id : failed)
        list += " " + id;
    EXPECT_TRUE(caught) << "no failing rule matches " << c.catches << "; failed:" << list;
    if (c.warning_only) {
        EXPECT_EQ(r.failures_of(Authority::Specification) + r.failures_of(Authority::Manual), 0u) << list;
        EXPECT_GT(r.failures_of(Authority::Implied), 0u);
    } else {
        EXPECT_EQ(verdict(r), 1) << list;
    }
}

std::vector<FaultCase> fault_cases() {
    return {
        {"bad-crc", "mmk-2030", "rtu-tcp", "fc.supported.3", false, {"fc.supported.*", "echo.*"}},
        {"bad-lrc", "mmk-2030", "ascii-tcp", "fc.supported.3", false, {"fc.supported.*", "echo.*"}},
        {"wrong-byte-count", "mmk-2030", "tcp", "quantity.fc3.max"},
        {"short-response", "mmk-2030", "tcp", "fc.supported.3"},
        {"extra-bytes", "mmk-2030", "rtu-tcp", "fc.supported.*", false, {"fc.supported.*", "echo.*"}},
        {"wrong-unit", "mmk-2030", "tcp", "fc.supported.3"},
        {"wrong-function", "mmk-2030", "tcp", "fc.supported.3"},
        {"wrong-tid", "mmk-2030", "tcp", "tcp.tid_echo.*"},
        {"bad-protocol-id", "walchem-w600", "tcp", "fc.supported.3"},
        {"any-protocol-id", "walchem-w600", "tcp", "tcp.protocol_id_nonzero"},
        {"reply-to-broadcast", "mmk-2030", "rtu-tcp", "broadcast.read.silent"},
        {"ignore-max-quantity", "mmk-2030", "tcp", "quantity.fc3.max_plus_one", true},
        {"wrong-exception=4", "mmk-2030", "tcp", "fc.unsupported.*"},
        {"exception-for-valid=0.5", "mmk-2030", "tcp", "fc.supported.*"},
        {"no-reply=0.3", "mmk-2030", "tcp", "*", false, {"fc.supported.*", "quantity.*"}},
        {"slow-reply=600", "cth2265i", "tcp", "fc.supported.3", false, {"fc.supported.*"}},
        // Over RTU on a stream a pause inside a reply shows only where two frames share one write (the reply
        // to the first is taken as ended at the pause): robustness.pipeline_after_exception, a warning there.
        // On a line framing.reply_continuous reports it (serial_line_test.cpp, on a pseudo-terminal).
        {"gap-inside-frame=5",
         "mmk-2030",
         "rtu-tcp",
         "robustness.pipeline_after_exception",
         true,
         {"fc.*", "robustness.*"}},
        {"word-swap", "walchem-w600", "tcp", "data.word_order.*"},
        {"off-by-one-address", "mmk-2030", "tcp", "address.fc3.last"},
        {"stuck-value=21", "mmk-2030", "tcp", "value.hr21.limits"},
        {"drop-write", "mmk-2030", "tcp", "echo.fc6"},
        {"accept-out-of-range", "mmk-2030", "tcp", "value.hr*.outside"},
        {"no-echo", "mmk-2030", "tcp", "echo.fc6"},
        {"crash-after=20", "cth2265i", "tcp", "quantity.*", false, {"fc.supported.*", "quantity.*"}},
        {"duplicate-reply", "mmk-2030", "tcp", "reply.once", false, {"fc.supported.*", "reply.once"}},
        {"wrong-quantity", "mmk-2030", "tcp", "quantity.fc3.one", false, {"fc.supported.*", "quantity.*"}},
    };
}

// Over UDP each copy of a reply sent twice is a datagram of its own: reply.once catches it, and the second
// copy, waiting when the next request goes out, is not taken for that request's reply (which blamed the
// device's transaction id echo when the next request carried id 0, 4660 or 65535).
TEST(PlantedFaults, ADuplicateReplyOverUdpFailsReplyOnceAndNothingElse) {
    RunningServer server({"duplicate-reply"}, 7, "mmk-2030");
    auto options = options_for();
    options.run.rule_globs = {"fc.supported.*", "reply.once", "tcp.tid_echo.*"};
    const auto run = certify(server, "udp", "mmk-2030", options);
    std::vector<std::string> failed;
    for (const auto& x : run.report.results) {
        if (x.outcome == Outcome::Fail || x.outcome == Outcome::Error) failed.push_back(x.rule.id);
    }
    EXPECT_EQ(failed, std::vector<std::string>{"reply.once"}) << failures(run.report);
}

TEST(PlantedFaults, EveryFaultOfTheSlaveHasACase) {
    std::set<std::string> named;
    for (const auto& c : fault_cases())
        named.insert(c.fault.substr(0, c.fault.find('=')));
    for (std::size_t i = 0; i < slave::fault_count; ++i) {
        const std::string name(slave::to_string(static_cast<slave::Fault>(i)));
        EXPECT_TRUE(named.count(name)) << name << " has no conformance case";
    }
}

// word-swap read 32-bit values swapped and wrote them as given: the run could not put back what it wrote (a
// Walchem float left at 361.25 instead of 1.0, the CTH2265I's K-factor words at 65535). Swapped both ways,
// every point goes back and the device holds what it held. Walchem still fails the word-order rule: the
// value written in the manual's order is one the device, reading the words the other way, refuses.
TEST(PlantedFaults, AWordSwappedDeviceIsRestoredAsFound) {
    for (const char* id : {"walchem-w600", "cth2265i"}) {
        SCOPED_TRACE(id);
        RunningServer server({"word-swap"}, 7, id);
        const auto run = certify(server, "tcp", id);
        EXPECT_FALSE(run.report.restored.empty());
        EXPECT_TRUE(run.report.all_restored()) << failures(run.report);
        std::string changed;
        for (const auto& [table, m] : run.changes_after)
            for (const auto& [address, value] : m)
                changed += " " + std::to_string(address) + "=" + std::to_string(value);
        EXPECT_EQ(changed, "") << "the run left values changed on the device";
        if (std::string(id) == "walchem-w600") {
            EXPECT_EQ(verdict(run.report), 1) << failures(run.report);
            for (const auto& x : run.report.results)
                if (x.rule.id == "data.word_order.hr148") {
                    EXPECT_EQ(x.outcome, Outcome::Fail) << x.observed;
                }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Slave, PlantedFault, ::testing::ValuesIn(fault_cases()), [](const auto& info) {
    std::string n = info.param.fault.substr(0, info.param.fault.find('='));
    for (auto& ch : n)
        if (ch == '-') ch = '_';
    return n;
});

// A normal reply that does not answer its request is not a normal reply: one register more than the one
// asked passed every rule that expected a normal reply (only the function code and the PDU's own
// consistency were looked at). (FC15 and FC16 acknowledging another quantity: hostile_slave_test.cpp; here
// the writes cannot be made, their points' reads failing the same way.)
TEST(PlantedFaults, ARepliesQuantityIsJudgedAgainstTheRequest) {
    RunningServer server({"wrong-quantity"}, 7, "mmk-2030");
    auto options = options_for();
    options.run.rule_globs = {"fc.supported.1", "fc.supported.3", "quantity.fc3.one"};
    const auto run = certify(server, "tcp", "mmk-2030", options);
    std::map<std::string, const RuleResult*> by_id;
    for (const auto& x : run.report.results)
        by_id[x.rule.id] = &x;
    for (const char* id : {"quantity.fc3.one", "fc.supported.1", "fc.supported.3"}) {
        ASSERT_TRUE(by_id.count(id)) << id;
        EXPECT_EQ(by_id[id]->outcome, Outcome::Fail) << id << ": " << by_id[id]->observed;
    }
    EXPECT_NE(by_id["quantity.fc3.one"]->observed.find(
                  "the request asks for 1 register, the reply carries 4 data bytes (AP §6.3)"),
              std::string::npos)
        << by_id["quantity.fc3.one"]->observed;
    // With the generic profile, whose tables are found by probing: a read answered with one item too many
    // still shows the table is there (it was taken for no answer, the table unknown and every rule on it
    // skipped: the fault passed, exit code 0).
    RunningServer generic({"wrong-quantity"}, 7, "modbus");
    auto generic_options = options_for();
    generic_options.run.rule_globs = {"quantity.fc3.one", "fc.supported.3"};
    const auto probed = certify(generic, "tcp", "modbus", generic_options);
    ASSERT_EQ(probed.report.results.size(), 2u);
    for (const auto& x : probed.report.results)
        EXPECT_EQ(x.outcome, Outcome::Fail) << x.rule.id << ": " << x.observed << x.reason;
    EXPECT_EQ(verdict(probed.report), 1);
    // Without the fault the same rules pass.
    RunningServer clean({}, 7, "mmk-2030");
    const auto good = certify(clean, "tcp", "mmk-2030", options);
    ASSERT_EQ(good.report.results.size(), 3u);
    for (const auto& x : good.report.results)
        EXPECT_EQ(x.outcome, Outcome::Pass) << x.rule.id << ": " << x.observed;
}

// The generic profile probes its tables: a read answered with a damaged reply of the read's function (a
// byte count unlike its data, a reply cut short) was taken for no answer, every table unknown and every read
// rule skipped: a device damaging every read passed certification with exit code 0. The reply shows the
// table is there, and the rules on it fail.
TEST(PlantedFaults, AGenericDevicesDamagedReadsFailTheReadRules) {
    for (const char* fault : {"wrong-byte-count", "short-response"}) {
        RunningServer server({fault}, 7, "modbus");
        auto options = options_for();
        options.run.rule_globs = {"fc.supported.3", "quantity.fc3.one", "address.fc3.first"};
        const auto run = certify(server, "tcp", "modbus", options);
        ASSERT_EQ(run.report.results.size(), 3u) << fault;
        for (const auto& x : run.report.results)
            EXPECT_EQ(x.outcome, Outcome::Fail)
                << fault << ' ' << x.rule.id << ": " << x.observed << x.reason;
        EXPECT_EQ(verdict(run.report), 1) << fault;
    }
}

// ---- late replies over RTU and ASCII, which carry no transaction id

// A device slower than the runner's timeout over RTU: every reply comes 400 ms after its request, the runner
// waits 200 ms. Each late reply arrives while a later request waits and must not be taken for that
// request's: no rule may observe another function's reply (before, FC4 "was answered" by FC3's reply, FC8
// by FC4's). The report counts the late replies.
TEST(LateReplies, ASlowSerialDeviceIsNeverJudgedByAnotherRequestsReply) {
    for (const std::string scheme : {"rtu-tcp", "ascii-tcp"}) {
        RunningServer server({"slow-reply=400"}, 1, "cth2265i");
        auto options = options_for(std::chrono::milliseconds(200));
        options.run.rule_globs = {"fc.supported.*"};
        const auto run = certify(server, scheme, "cth2265i", options);
        const Report& r = run.report;
        // Every reply late: nothing is judged (the run is in error, as for a silent target), and no rule
        // took another request's reply for its own.
        std::size_t not_judged = 0;
        for (const auto& x : r.results) {
            EXPECT_NE(x.outcome, Outcome::Fail) << scheme << ' ' << x.rule.id << ": " << x.observed;
            if (x.outcome != Outcome::Error || x.rule.id == "target.answered") continue;
            ++not_judged;
            EXPECT_TRUE(x.observed.starts_with("no reply"))
                << scheme << ' ' << x.rule.id << ": " << x.observed;
        }
        EXPECT_GE(not_judged, 3u) << scheme;  // FC3, FC4, FC8 at least: none answered in time
        EXPECT_EQ(verdict_text(r), "error") << scheme;
        EXPECT_GE(r.late_replies, 2u) << scheme;
        std::ostringstream text;
        write_text(text, r, false);
        EXPECT_NE(text.str().find("came after the 200 ms timeout"), std::string::npos) << text.str();
        EXPECT_EQ(to_json(r)["late_replies"], r.late_replies);
    }
}

// Two reads of the same shape (FC3, one register, other addresses), the first given up before its reply
// came: content cannot tell the replies apart, so the second waits the first one's reply out (logged as
// late) before it goes, and gets its own value.
TEST(LateReplies, ARequestOfTheSameShapeWaitsOutTheOwedReply) {
    RunningServer server({"slow-reply=400"}, 1, "modbus");
    const std::uint16_t port = server.start("rtu-tcp");
    server.device().image().set_reg(modbus::Table::HoldingRegisters, 10, 0x1111);
    server.device().image().set_reg(modbus::Table::HoldingRegisters, 20, 0x2222);
    auto client = tp::Client::open(*tp::parse_endpoint("rtu-tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    SessionOptions options;
    options.timeout = std::chrono::milliseconds(500);
    Session session(*client, options, &slave::test::profile("modbus"));
    const auto read = [](std::uint16_t address) {
        return modbus::encode_pdu(
            modbus::make_read_request(modbus::FunctionCode::ReadHoldingRegisters, address, 1));
    };
    const auto first = session.request(read(10), "first", std::nullopt, std::chrono::milliseconds(100));
    EXPECT_TRUE(first.timed_out);
    const auto second = session.request(read(20), "second", std::nullopt, std::chrono::milliseconds(2000));
    ASSERT_TRUE(second.response.has_value());
    EXPECT_TRUE(second.stale_replies.empty());
    const auto pdu = second.response->pdu();
    ASSERT_EQ(pdu.size(), 4u);
    EXPECT_EQ((pdu[2] << 8) | pdu[3], 0x2222);
    EXPECT_EQ(session.late_replies(), 1u);
    const auto evidence = session.take_evidence();
    ASSERT_EQ(evidence.size(), 3u);
    EXPECT_TRUE(evidence[1].note.starts_with("late")) << evidence[1].note;
    EXPECT_TRUE(evidence[1].sent.empty());
    EXPECT_EQ(evidence[1].received, modbus::encode_rtu(1, std::vector<std::uint8_t>{0x03, 0x02, 0x11, 0x11}));
}

// A device slower than the timeout, over Modbus/TCP: each reply comes while a later request waits. The TCP
// envelope rules send transaction ids of their own (0, 0x1234, 0xFFFF, 7 ... 23), far from the client's
// count: a late reply to one of the client's requests was taken for tcp.tid_echo.0's ("reply to transaction
// 284 instead of 0"), failing it, and its time counted as a reply in time, so that the run was judged and
// failed 163 rules (exit 1) where the cause was --timeout. Each late reply is set aside by the transaction id
// of the request it answers; no rule takes one for its own, none fails, and the run is not judged.
TEST(LateReplies, ASlowTcpDeviceFailsNoEnvelopeRuleAndIsNotJudged) {
    // Twice the timeout: each reply comes while the next request but one waits (three requests in a row
    // heard nothing, not even late, and the target would be taken for a silent one).
    RunningServer server({"slow-reply=200"}, 1, "mmk-2030");
    auto options = options_for(std::chrono::milliseconds(100));
    options.run.rule_globs = {"tcp.*", "robustness.*", "reply.once", "silence.idle"};
    const auto run = certify(server, "tcp", "mmk-2030", options);
    const Report& r = run.report;
    EXPECT_EQ(verdict_text(r), "error") << failures(r);
    EXPECT_NE(r.unanswered.find("raise --timeout"), std::string::npos) << r.unanswered;
    ASSERT_FALSE(r.results.empty());
    EXPECT_EQ(r.results[0].rule.id, "target.answered");
    std::size_t envelope_rules = 0;
    for (const auto& x : r.results) {
        EXPECT_NE(x.outcome, Outcome::Fail) << x.rule.id << ": " << x.observed;
        // A late reply is never the rule's answer: no envelope rule saw another transaction's reply.
        EXPECT_EQ(x.observed.find("reply to transaction"), std::string::npos)
            << x.rule.id << ": " << x.observed;
        envelope_rules += x.rule.id.starts_with("tcp.tid_echo.");
    }
    EXPECT_EQ(envelope_rules, 3u);
    EXPECT_GT(r.late_replies, 0u);
}

// The same over RTU on a stream, where nothing but what a reply answers tells it from another's: the rules
// sending several requests in one write (framing.back_to_back, robustness.pipeline_after_exception) wait the
// owed replies out first. The run is not judged, and no rule fails.
TEST(LateReplies, ASlowRtuDeviceFailsNoRuleAndIsNotJudged) {
    RunningServer server({"slow-reply=150"}, 1, "mmk-2030");
    auto options = options_for(std::chrono::milliseconds(100));
    options.run.rule_globs = {"fc.supported.*", "framing.*", "robustness.*", "reply.once", "silence.idle"};
    const auto run = certify(server, "rtu-tcp", "mmk-2030", options);
    const Report& r = run.report;
    EXPECT_EQ(verdict_text(r), "error") << failures(r);
    EXPECT_NE(r.unanswered.find("raise --timeout"), std::string::npos) << r.unanswered;
    ASSERT_FALSE(r.results.empty());
    EXPECT_EQ(r.results[0].rule.id, "target.answered");
    for (const auto& x : r.results)
        EXPECT_NE(x.outcome, Outcome::Fail) << x.rule.id << ": " << x.observed;
    EXPECT_GT(r.late_replies, 0u);
}

// The session over Modbus/TCP: a request of the rules' own transaction id 0 given up, the reply to it comes
// while a request of id 0x1234 waits, 0x1234 behind it (outside the window of ids just behind the request's,
// which a client counting up leaves): it is that owed request's late reply, set aside and counted, not the
// answer to 0x1234, which comes after it.
// Four times the timeout: the run's first three requests owed a reply all went unanswered before the first
// reply came, and the run stopped there. It was told "wrong unit id, transport or line settings?", which
// sent the user to check the wiring of a device that only needed a longer --timeout. The run listens three
// timeouts more: the replies are late, over Modbus/TCP and RTU alike; a unit nobody serves still hears
// nothing, and says it listened.
TEST(LateReplies, ADeviceSlowerThanTheRunWaitedIsToldToNeedALongerTimeout) {
    auto options = options_for(std::chrono::milliseconds(100));
    for (const char* transport : {"tcp", "rtu-tcp"}) {
        RunningServer server({"slow-reply=400"}, 1, "mmk-2030");
        const auto run = certify(server, transport, "mmk-2030", options);
        const Report& r = run.report;
        EXPECT_EQ(verdict_text(r), "error") << transport << failures(r);
        EXPECT_NE(r.unanswered.find("only after it"), std::string::npos) << transport << r.unanswered;
        EXPECT_NE(r.unanswered.find("raise --timeout"), std::string::npos) << transport << r.unanswered;
        EXPECT_EQ(r.unanswered.find("wrong unit id"), std::string::npos) << transport << r.unanswered;
        EXPECT_GT(r.late_replies, 0u) << transport;
        ASSERT_FALSE(r.results.empty()) << transport;
        EXPECT_EQ(r.results[0].rule.id, "target.answered");
        bool late_evidence = false;
        for (const auto& e : r.results[0].evidence)
            late_evidence =
                late_evidence || (!e.received.empty() && e.note.find("late") != std::string::npos);
        EXPECT_TRUE(late_evidence) << transport;
    }
    options.session.unit = 9;  // served by nobody
    RunningServer server({"slow-reply=400"}, 1, "mmk-2030");
    const auto run = certify(server, "tcp", "mmk-2030", options);
    EXPECT_NE(run.report.unanswered.find("wrong unit id, transport or line settings? Nothing came in 300 ms "
                                         "more either"),
              std::string::npos)
        << run.report.unanswered;
    EXPECT_EQ(run.report.late_replies, 0u);
}

TEST(LateReplies, AReplyToAnOwedTransactionIdIsSetAsideHoweverFarItsId) {
    RunningServer server({"slow-reply=400"}, 1, "mmk-2030");
    const std::uint16_t port = server.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    Session session(*client, SessionOptions{}, &slave::test::profile("mmk-2030"));
    const auto read =
        modbus::encode_pdu(modbus::make_read_request(modbus::FunctionCode::ReadHoldingRegisters, 0, 1));
    const auto first =
        session.raw(modbus::encode_tcp(0, 1, read), "transaction id 0", 1, std::chrono::milliseconds(100));
    EXPECT_TRUE(first.timed_out);
    const auto second = session.raw(modbus::encode_tcp(0x1234, 1, read), "transaction id 0x1234", 1,
                                    std::chrono::milliseconds(2000));
    ASSERT_EQ(second.stale_replies.size(), 1u);
    EXPECT_EQ(second.stale_replies[0].transaction_id(), 0);
    ASSERT_TRUE(second.response.has_value());
    EXPECT_EQ(second.response->transaction_id(), 0x1234);
    EXPECT_EQ(session.late_replies(), 1u);
    EXPECT_EQ(session.answered_late(), 1u);
}

// ---- the reports

// ---- restoring

// Consecutive points go back in blocks: 1,968 coils and 123 registers in one FC15 and one FC16, each read
// back once, where one by one they took 4,182 requests (minutes on a serial line).
TEST(Restore, ConsecutivePointsGoBackInBlocks) {
    RunningServer server({}, 1, "modbus");
    const std::uint16_t port = server.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    Session session(*client, options_for().session, &slave::test::profile("modbus"));
    ASSERT_TRUE(session.remember(modbus::Table::Coils, 0, 1968, 1968));
    ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 100, 123, 123));
    std::unique_ptr<bool[]> ones(new bool[1968]);
    std::fill(ones.get(), ones.get() + 1968, true);
    const std::vector<std::uint16_t> words(123, 0xBEEF);
    ASSERT_TRUE(
        is_normal(session.request(
                      modbus::encode_pdu(modbus::make_write_multiple_coils(0, {ones.get(), 1968})), "write"),
                  15));
    ASSERT_TRUE(is_normal(
        session.request(modbus::encode_pdu(modbus::make_write_multiple_registers(100, words)), "write"), 16));
    ASSERT_FALSE(server.device().image().changes().empty());

    const auto before = session.requests();
    const auto ledger = session.restore();
    EXPECT_EQ(session.requests() - before, 4u);
    ASSERT_EQ(ledger.size(), 1968u + 123u);
    for (const auto& t : ledger)
        EXPECT_TRUE(t.restored) << modbus::to_string(t.table) << ' ' << t.address << ": " << t.problem;
    server.stop();
    EXPECT_TRUE(server.device().image().changes().empty());
}

// Rules whose requests every slave must ignore pass on silence, which a target answering nothing gives too.
// `--rules framing.bad_checksum` against a correct device was "the target answered none of the run's 1
// requests", every rule in error, exit 2. The rule now follows its silence with a valid request of its own
// (the device must still answer); a run with no request owed a reply at all (`broadcast.read.silent`) ends
// with one read any device of the profile answers, which tells a correct device from a silent one, as
// conformance/README.md promises. Two requests either way: the silent one, then the read.
TEST(Runner, ARunOfRequestsThatAskForSilenceIsJudged) {
    for (const char* rule : {"framing.bad_checksum", "broadcast.read.silent"})
        for (const std::uint8_t unit : {std::uint8_t{1}, std::uint8_t{5}}) {
            SCOPED_TRACE(std::string(rule) + " unit " + std::to_string(unit));
            RunningServer server({}, 1, "mmk-2030");
            auto options = options_for(std::chrono::milliseconds(100));
            options.session.unit = unit;
            options.run.rule_globs = {rule};
            const auto run = certify(server, "rtu-tcp", "mmk-2030", options);
            const Report& r = run.report;
            EXPECT_EQ(r.requests, 2u);
            if (unit == 1) {
                EXPECT_EQ(r.unanswered, "");
                ASSERT_EQ(r.results.size(), 1u);
                EXPECT_EQ(r.results[0].outcome, Outcome::Pass) << r.results[0].reason;
                EXPECT_EQ(verdict(r), 0);
            } else {  // a unit nobody serves: the read goes unanswered too
                EXPECT_NE(r.unanswered.find("answered none of the"), std::string::npos) << r.unanswered;
                ASSERT_EQ(r.results.size(), 2u);
                EXPECT_EQ(r.results[0].rule.id, "target.answered");
            }
        }
}

// framing.other_unit asks unit + 1 by default, right for a device alone on its line; on a line with other
// devices that unit may be a neighbour's, so --other-unit names one none of them has, and 0 (or the
// device's own unit) does not run the rule.
TEST(Runner, TheOtherUnitAskedIsTheUsersToName) {
    const std::vector<std::pair<std::optional<std::uint8_t>, int>> cases = {
        {std::nullopt, 2}, {std::uint8_t{9}, 9}, {std::uint8_t{0}, -1}, {std::uint8_t{1}, -1}};
    for (const auto& [named, asked] : cases) {
        SCOPED_TRACE(named ? int{*named} : -2);
        RunningServer server({}, 1, "mmk-2030");
        auto options = options_for(std::chrono::milliseconds(100));
        options.run.rule_globs = {"framing.other_unit"};
        options.run.other_unit = named;
        const auto run = certify(server, "rtu-tcp", "mmk-2030", options);
        ASSERT_EQ(run.report.results.size(), 1u);
        const RuleResult& r = run.report.results.front();
        if (asked < 0) {
            EXPECT_EQ(r.outcome, Outcome::Skip);
            EXPECT_TRUE(r.evidence.empty());
            continue;
        }
        EXPECT_EQ(r.outcome, Outcome::Pass) << r.observed;
        ASSERT_FALSE(r.evidence.empty());
        ASSERT_FALSE(r.evidence.front().sent.empty());
        EXPECT_EQ(r.evidence.front().sent.front(), asked);  // RTU: the unit is the frame's first byte
        EXPECT_TRUE(r.evidence.front().received.empty());
    }
}

// A target silent from the generic profile's probing on (three reads of each table's address 0, twelve
// requests) had its run stopped before any rule: the text said "the rules after those below were not run"
// with nothing below, and "none of the run's 12 requests" where the README speaks of the first three.
TEST(Runner, ATargetSilentFromTheProbingOnIsToldNoRuleRan) {
    RunningServer server({}, 1, "modbus");
    auto options = options_for(std::chrono::milliseconds(50));
    options.session.unit = 5;
    const auto run = certify(server, "tcp", "modbus", options);
    const Report& r = run.report;
    ASSERT_EQ(r.results.size(), 1u) << failures(r);
    EXPECT_EQ(r.results[0].rule.id, "target.answered");
    EXPECT_EQ(r.results[0].reason.find("below"), std::string::npos) << r.results[0].reason;
    EXPECT_NE(r.results[0].reason.find("no rule was run"), std::string::npos) << r.results[0].reason;
    EXPECT_NE(r.unanswered.find("none of the 12 requests sent"), std::string::npos) << r.unanswered;
    EXPECT_EQ(verdict_text(r), "error");
}

// The reference slave damaging every reply (bad-crc, wrong-unit): the generic profile's probing got no
// usable read, and every rule needing the map was skipped, fc.supported.3 as "unknown" and quantity.fc3.*
// as "no valid address in the map" (the map is unknown, not empty): a selection of those passed. A reply that
// came damaged fails fc.supported.3; the rules needing the map are not judged, in error, and say why.
TEST(GenericProfile, ADeviceDamagingEveryReplyIsNotPassedBySkippedRules) {
    for (const std::string fault : {"bad-crc", "wrong-unit"}) {
        SCOPED_TRACE(fault);
        RunningServer server({fault}, 1, "modbus");
        auto options = options_for(std::chrono::milliseconds(100));
        options.run.rule_globs = {"fc.supported.3",           "address.fc3.first", "address.fc3.last",
                                  "address.fc3.past_end",     "quantity.fc3.one",  "quantity.fc3.max",
                                  "quantity.fc3.max_plus_one"};
        const auto run = certify(server, "rtu-tcp", "modbus", options);
        const Report& r = run.report;
        ASSERT_EQ(r.results.size(), 7u) << failures(r);
        for (const auto& x : r.results) {
            EXPECT_NE(x.outcome, Outcome::Skip) << x.rule.id << ": " << x.reason;
            EXPECT_NE(x.outcome, Outcome::Pass) << x.rule.id << ": " << x.observed;
            EXPECT_EQ((x.reason + x.observed).find("no valid address in the map"), std::string::npos);
        }
        EXPECT_EQ(r.results[0].rule.id, "fc.supported.3");
        EXPECT_EQ(r.results[0].outcome, Outcome::Fail);
        EXPECT_NE(r.results[0].observed.find(fault == "bad-crc" ? "bad checksum" : "reply from unit 2"),
                  std::string::npos)
            << r.results[0].observed;
        EXPECT_FALSE(r.results[0].evidence.empty());
        EXPECT_NE(r.results[1].reason.find("damaged every reply"), std::string::npos) << r.results[1].reason;
        EXPECT_EQ(verdict(r), 1) << failures(r);
        EXPECT_EQ(verdict_text(r), "fail");
    }
}

// The values kept for restoring and the read-backs that call a point restored come only from replies the
// rules accept as the read's answer: one carrying another transaction id, another unit or another
// function's code (of the same shape: FC4 for FC3) answers some other request and is no value of these
// points.
TEST(Restore, OnlyRepliesTheRulesAcceptAsTheReadsAnswerAreValues) {
    for (const std::string fault : {"wrong-tid", "wrong-unit", "wrong-function", "bad-protocol-id"}) {
        RunningServer server({fault}, 1, "modbus");
        const std::uint16_t port = server.start("tcp");
        auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
        ASSERT_TRUE(client.has_value());
        Session session(*client, options_for().session, &slave::test::profile("modbus"));
        EXPECT_FALSE(session.read_registers(modbus::Table::HoldingRegisters, 0, 2, "read")) << fault;
        EXPECT_FALSE(session.read_bits(modbus::Table::Coils, 0, 2, "read")) << fault;
        EXPECT_FALSE(session.remember(modbus::Table::HoldingRegisters, 0, 2)) << fault;
        EXPECT_TRUE(session.touched().empty()) << fault;
    }
    RunningServer clean({}, 1, "modbus");
    const std::uint16_t port = clean.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    Session session(*client, options_for().session, &slave::test::profile("modbus"));
    EXPECT_TRUE(session.read_registers(modbus::Table::HoldingRegisters, 0, 2, "read"));
    EXPECT_TRUE(session.read_bits(modbus::Table::Coils, 0, 2, "read"));
}

// A block the device does not keep falls back to the points one by one, and the ledger says why each one
// is not back.
TEST(Restore, WhatABlockDidNotBringBackIsTriedOneByOne) {
    RunningServer server({"drop-write"}, 1, "modbus");
    const std::uint16_t port = server.start("tcp");
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value());
    Session session(*client, options_for().session, &slave::test::profile("modbus"));
    ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 10, 3, 3));
    // The device's values change behind the runner's back (as a process value would, or another master).
    for (std::uint16_t a = 10; a < 13; ++a)
        server.device().image().set_reg(modbus::Table::HoldingRegisters, a, 7);
    const auto before = session.requests();
    const auto ledger = session.restore();
    // One block write and its read, then each point's write and read.
    EXPECT_EQ(session.requests() - before, 2u + 3u * 2u);
    ASSERT_EQ(ledger.size(), 3u);
    for (const auto& t : ledger) {
        EXPECT_FALSE(t.restored);
        EXPECT_EQ(t.problem, "reads 7 after restoring 0; left holding 7 (read back)");
    }
}

// A Modbus/TCP device on loopback that answers each request's PDU as `answer` says (nullopt: silence), one
// connection, until the client closes it.
class ScriptedDevice {
  public:
    using Answer = std::function<std::optional<std::vector<std::uint8_t>>(const std::vector<std::uint8_t>&)>;
    explicit ScriptedDevice(Answer answer) : answer_(std::move(answer)) {
        auto listener = tp::listen_tcp("127.0.0.1", 0);
        EXPECT_TRUE(listener.has_value());
        if (listener) listener_ = std::move(listener).value();
        thread_ = std::thread([this] { serve(); });
    }
    ~ScriptedDevice() { finish(); }
    // Waits for the device's end: the client closed its connection (or never came within 5 s).
    void finish() {
        if (thread_.joinable()) thread_.join();
    }
    ScriptedDevice(const ScriptedDevice&) = delete;
    ScriptedDevice& operator=(const ScriptedDevice&) = delete;

    std::uint16_t port() const { return tp::bound_port(listener_.get()); }

  private:
    void serve() {
        pollfd incoming{listener_.get(), POLLIN, 0};
        if (::poll(&incoming, 1, 5000) != 1) return;
        const tp::UniqueFd fd(::accept(listener_.get(), nullptr, nullptr));
        std::uint8_t header[7];
        while (fd && ::recv(fd.get(), header, 7, MSG_WAITALL) == 7) {
            const std::size_t length = (header[4] << 8) | header[5];
            std::vector<std::uint8_t> pdu(length > 1 ? length - 1 : 0);
            if (!pdu.empty() && ::recv(fd.get(), pdu.data(), pdu.size(), MSG_WAITALL) != ssize_t(pdu.size()))
                return;
            const auto reply = answer_(pdu);
            if (!reply) continue;
            std::vector<std::uint8_t> adu(header, header + 7);
            adu[4] = static_cast<std::uint8_t>((reply->size() + 1) >> 8);
            adu[5] = static_cast<std::uint8_t>(reply->size() + 1);
            adu.insert(adu.end(), reply->begin(), reply->end());
            (void)::send(fd.get(), adu.data(), adu.size(), MSG_NOSIGNAL);
        }
    }

    Answer answer_;
    tp::UniqueFd listener_;
    std::thread thread_;
};

// One 32-bit holding value at 148-149 (a Walchem set-point's place): either half written alone with FC6 is
// refused (Walchem's manual wants 32-bit values written whole, 002:452-459, 499) and, once, the second half
// of a block reads back wrong: the device that leaves the one-by-one restore a lone half to bring back.
class PairOnlyDevice {
  public:
    std::uint16_t port() const { return device_.port(); }
    void finish() { device_.finish(); }
    std::uint16_t reg(std::uint16_t a) const { return regs_[a - 148]; }
    int lone_writes() const { return lone_writes_; }

  private:
    std::vector<std::uint8_t> answer(const std::vector<std::uint8_t>& pdu) {
        if (pdu.size() < 5) return {static_cast<std::uint8_t>((pdu.empty() ? 0 : pdu[0]) | 0x80), 0x03};
        const std::uint8_t fc = pdu[0];
        const unsigned start = (pdu[1] << 8) | pdu[2];
        const unsigned n = (pdu[3] << 8) | pdu[4];
        if (fc == 3 && start >= 148 && start + n <= 150 && n >= 1) {
            std::vector<std::uint8_t> r{3, static_cast<std::uint8_t>(2 * n)};
            for (unsigned a = start; a < start + n; ++a) {
                std::uint16_t v = regs_[a - 148];
                if (n == 2 && a == 149 && ++block_reads_ == 2) v ^= 1;  // the restore's read-back, once
                r.push_back(static_cast<std::uint8_t>(v >> 8));
                r.push_back(static_cast<std::uint8_t>(v));
            }
            return r;
        }
        if (fc == 16 && start == 148 && n == 2 && pdu.size() >= 10) {
            regs_[0] = static_cast<std::uint16_t>((pdu[6] << 8) | pdu[7]);
            regs_[1] = static_cast<std::uint16_t>((pdu[8] << 8) | pdu[9]);
            return {pdu.begin(), pdu.begin() + 5};
        }
        if (fc == 6 && (start == 148 || start == 149)) ++lone_writes_;
        return {static_cast<std::uint8_t>(fc | 0x80), fc == 6 ? std::uint8_t{0x04} : std::uint8_t{0x02}};
    }

    std::uint16_t regs_[2] = {0x0000, 0x3F80};  // 1.0f, low word first
    int block_reads_ = 0;
    int lone_writes_ = 0;
    ScriptedDevice device_{[this](const std::vector<std::uint8_t>& pdu) { return answer(pdu); }};  // last
};

// A block's read-back that gets no answer is read once more before the block is given up to the one-by-one
// path (two requests a point).
TEST(Restore, AReadBackWithoutAnswerIsReadAgain) {
    std::uint16_t regs[3] = {1, 2, 3};
    int block_reads = 0;
    int single_writes = 0;
    ScriptedDevice device(
        [&](const std::vector<std::uint8_t>& pdu) -> std::optional<std::vector<std::uint8_t>> {
            const std::uint8_t fc = pdu.empty() ? 0 : pdu[0];
            const unsigned start = pdu.size() >= 5 ? (pdu[1] << 8) | pdu[2] : 0;
            const unsigned n = pdu.size() >= 5 ? (pdu[3] << 8) | pdu[4] : 0;
            if (fc == 3 && n >= 1 && start >= 10 && start + n <= 13) {
                if (n == 3 && ++block_reads == 2) return std::nullopt;  // the restore's read-back, once
                std::vector<std::uint8_t> r{3, static_cast<std::uint8_t>(2 * n)};
                for (unsigned a = start; a < start + n; ++a) {
                    r.push_back(static_cast<std::uint8_t>(regs[a - 10] >> 8));
                    r.push_back(static_cast<std::uint8_t>(regs[a - 10]));
                }
                return r;
            }
            if (fc == 16 && start == 10 && n == 3 && pdu.size() >= 12) {
                for (unsigned k = 0; k < 3; ++k)
                    regs[k] = static_cast<std::uint16_t>((pdu[6 + 2 * k] << 8) | pdu[7 + 2 * k]);
                return std::vector<std::uint8_t>(pdu.begin(), pdu.begin() + 5);
            }
            if (fc == 6) ++single_writes;
            return std::vector<std::uint8_t>{static_cast<std::uint8_t>(fc | 0x80), 0x02};
        });
    {
        auto client =
            tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(device.port())));
        ASSERT_TRUE(client.has_value());
        Session session(*client, options_for().session, &slave::test::profile("modbus"));
        ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 10, 3, 3));
        const std::uint16_t other[3] = {7, 8, 9};
        ASSERT_TRUE(is_normal(
            session.request(modbus::encode_pdu(modbus::make_write_multiple_registers(10, other)), "write"),
            16));
        const auto before = session.requests();
        const auto ledger = session.restore();
        // The block's write, its read-back unanswered, the read again.
        EXPECT_EQ(session.requests() - before, 3u);
        ASSERT_EQ(ledger.size(), 3u);
        for (const auto& t : ledger)
            EXPECT_TRUE(t.restored) << t.address << ": " << t.problem;
    }  // the connection closes, the device ends
    device.finish();
    EXPECT_EQ(single_writes, 0);
    EXPECT_EQ(regs[0], 1);
    EXPECT_EQ(regs[2], 3);
}

// The generic profile's address space is found by probing, and a reply lost on the way decided it: the read
// of holding register 0 unanswered once deleted the table (its rules skipped as "the map has no address"),
// a bisection read unanswered once moved the table's end, and a readable address failed as "past the end".
// Only a reply tells: an unanswered read is asked again. A device of 100 points per table that loses the
// first read of register 0 and the first of register 63 (a point the bisection reads) is certified whole.
TEST(GenericProfile, AReadLostWhileProbingIsAskedAgainNotTakenForTheMapsEnd) {
    int asked_0 = 0, asked_63 = 0;
    ScriptedDevice device(
        [&](const std::vector<std::uint8_t>& pdu) -> std::optional<std::vector<std::uint8_t>> {
            const std::uint8_t fc = pdu.empty() ? 0 : pdu[0];
            if (pdu.size() < 5 || fc < 1 || fc > 4)
                return std::vector<std::uint8_t>{static_cast<std::uint8_t>(fc | 0x80), 0x01};
            const unsigned start = (pdu[1] << 8) | pdu[2];
            const unsigned n = (pdu[3] << 8) | pdu[4];
            if (fc == 3 && n == 1 && start == 0 && ++asked_0 == 1) return std::nullopt;
            if (fc == 3 && n == 1 && start == 63 && ++asked_63 == 1) return std::nullopt;
            if (n == 0 || n > (fc <= 2 ? 2000u : 125u))
                return std::vector<std::uint8_t>{static_cast<std::uint8_t>(fc | 0x80), 0x03};
            if (start + n > 100) return std::vector<std::uint8_t>{static_cast<std::uint8_t>(fc | 0x80), 0x02};
            std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>(fc <= 2 ? (n + 7) / 8 : 2 * n)};
            r.resize(2 + r[1], 0);
            return r;
        });
    Report report;
    {
        auto client =
            tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(device.port())));
        ASSERT_TRUE(client.has_value());
        auto options = options_for();
        options.run.rule_globs = {"address.fc3.*"};
        report = run_check(*client, slave::test::profile("modbus"), options);
    }
    device.finish();
    EXPECT_GE(asked_0, 2);
    EXPECT_GE(asked_63, 2);
    std::map<std::string, RuleResult> by_id;
    for (const auto& r : report.results)
        by_id[r.rule.id] = r;
    for (const char* id : {"address.fc3.first", "address.fc3.last", "address.fc3.past_end"}) {
        ASSERT_TRUE(by_id.count(id)) << id;
        EXPECT_EQ(by_id[id].outcome, Outcome::Pass) << id << ": " << by_id[id].observed << by_id[id].reason;
    }
    // The map is the device's own answers, judged by the specification: no manual here.
    EXPECT_EQ(by_id["address.fc3.last"].rule.authority, Authority::Specification);
    EXPECT_EQ(report.failures_of(Authority::Manual), 0u);
}

// The runner restores between the families that write and those that send malformed frames, and again at
// the end. A point the first restore could not bring back (the device silent then) was forgotten with the
// others, and the end's restore, the device answering again, left it written. It is tried again.
TEST(Restore, APointTheFirstRestoreCouldNotBringBackIsTriedAgain) {
    std::atomic<std::uint16_t> reg{1};
    std::atomic<bool> answering{true};
    ScriptedDevice device(
        [&](const std::vector<std::uint8_t>& pdu) -> std::optional<std::vector<std::uint8_t>> {
            if (!answering) return std::nullopt;
            const std::uint8_t fc = pdu.empty() ? 0 : pdu[0];
            const unsigned start = pdu.size() >= 5 ? (pdu[1] << 8) | pdu[2] : 0;
            const unsigned word = pdu.size() >= 5 ? (pdu[3] << 8) | pdu[4] : 0;
            if (fc == 3 && start == 10 && word == 1)
                return std::vector<std::uint8_t>{3, 2, static_cast<std::uint8_t>(reg >> 8),
                                                 static_cast<std::uint8_t>(reg)};
            if (fc == 6 && start == 10) {
                reg = static_cast<std::uint16_t>(word);
                return pdu;
            }
            if (fc == 16 && start == 10 && word == 1 && pdu.size() >= 8) {
                reg = static_cast<std::uint16_t>((pdu[6] << 8) | pdu[7]);
                return std::vector<std::uint8_t>(pdu.begin(), pdu.begin() + 5);
            }
            return std::vector<std::uint8_t>{static_cast<std::uint8_t>(fc | 0x80), 0x02};
        });
    {
        auto client =
            tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(device.port())));
        ASSERT_TRUE(client.has_value());
        Session session(*client, options_for().session, &slave::test::profile("modbus"));
        ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 10, 1));
        ASSERT_TRUE(is_normal(
            session.request(modbus::encode_pdu(modbus::make_write_single_register(10, 7)), "write"), 6));
        answering = false;
        const auto first = session.restore_and_forget();
        ASSERT_EQ(first.size(), 1u);
        EXPECT_FALSE(first[0].restored);
        EXPECT_EQ(reg, 7);
        answering = true;
        const auto second = session.restore_and_forget();
        ASSERT_EQ(second.size(), 1u);
        EXPECT_TRUE(second[0].restored) << second[0].problem;
        EXPECT_EQ(second[0].problem, "");
        EXPECT_TRUE(session.restore_and_forget().empty());
    }
    device.finish();
    EXPECT_EQ(reg, 1);
}

// What a block did not bring back of a 32-bit value goes back with its other half in one FC16, in the
// one-by-one path and in the passes that retry refused points: never a lone half.
TEST(Restore, A32BitValueGoesBackWhole) {
    PairOnlyDevice device;
    {
        auto client =
            tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(device.port())));
        ASSERT_TRUE(client.has_value());
        Session session(*client, options_for().session, &slave::test::profile("walchem-w600"));
        ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 148, 2, 2));
        const std::uint16_t other[2] = {0x0000, 0x40E0};  // 7.0f
        ASSERT_TRUE(is_normal(
            session.request(modbus::encode_pdu(modbus::make_write_multiple_registers(148, other)), "write"),
            16));
        const auto ledger = session.restore();
        ASSERT_EQ(ledger.size(), 2u);
        for (const auto& t : ledger)
            EXPECT_TRUE(t.restored) << t.address << ": " << t.problem;
    }  // the connection closes, the device ends
    device.finish();
    EXPECT_EQ(device.lone_writes(), 0);
    EXPECT_EQ(device.reg(148), 0x0000);
    EXPECT_EQ(device.reg(149), 0x3F80);
}

TEST(Reports, JsonCarriesEveryRuleWithEvidenceAndTheSummaryAddsUp) {
    RunningServer server({"accept-out-of-range"}, 1, "mmk-2030");
    const auto run = certify(server, "tcp", "mmk-2030");
    const auto j = to_json(run.report);
    ASSERT_TRUE(j.contains("rules"));
    EXPECT_EQ(j["rules"].size(), run.report.results.size());
    EXPECT_EQ(j["profile"]["id"], "mmk-2030");
    std::size_t pass = 0, fail = 0;
    for (const auto& rule : j["rules"]) {
        for (const char* key : {"id", "family", "source", "text", "authority", "outcome", "evidence"})
            EXPECT_TRUE(rule.contains(key)) << key;
        pass += rule["outcome"] == "pass";
        fail += rule["outcome"] == "fail";
        if (rule["outcome"] == "fail") {
            ASSERT_FALSE(rule["evidence"].empty()) << rule["id"];
            EXPECT_FALSE(rule["evidence"][0]["sent"].get<std::string>().empty());
        }
    }
    EXPECT_EQ(pass, run.report.count(Outcome::Pass));
    EXPECT_EQ(fail, run.report.count(Outcome::Fail));
    EXPECT_GT(fail, 0u);
    EXPECT_EQ(j["restored"].size(), run.report.restored.size());
}

// A target and a profile's text may hold any bytes: the JUnit report stays XML an XML parser takes (bytes
// that are not UTF-8, and U+FFFE, were copied in, and Python's expat refused the file).
// --rules that match nothing: the command exits 2, but its reports said "pass" and JUnit was an empty
// green run, which a CI job with a typo in its glob published as a certificate. Every report now says the
// run judged nothing.
TEST(Reports, ARunWhoseRulesMatchNothingIsAnErrorInEveryReport) {
    Report report;
    report.profile_id = "mmk-2030";
    report.rule_globs = {"nosuch.*"};
    EXPECT_EQ(nothing_judged(report), "--rules 'nosuch.*' match no rule for mmk-2030");
    EXPECT_EQ(verdict_text(report), "error");
    EXPECT_EQ(to_json(report)["summary"]["verdict"], "error");
    std::ostringstream junit, text;
    write_junit(junit, report);
    EXPECT_NE(junit.str().find("tests=\"1\" failures=\"0\" errors=\"1\""), std::string::npos) << junit.str();
    EXPECT_NE(junit.str().find("name=\"run.no_rules\""), std::string::npos) << junit.str();
    EXPECT_NE(junit.str().find("<error message=\"--rules &apos;nosuch.*&apos; match no rule for mmk-2030\""),
              std::string::npos)
        << junit.str();
    write_text(text, report, false);
    EXPECT_NE(text.str().find("nothing judged: --rules 'nosuch.*' match no rule for mmk-2030"),
              std::string::npos)
        << text.str();
    report.stopped = true;  // interrupted before the first rule: said as such
    EXPECT_EQ(nothing_judged(report), "");
    EXPECT_EQ(verdict_text(report), "interrupted");

    // Every rule selected skipped (--read-only with writing rules only), against a target that was sent
    // nothing and may answer nothing: "pass", exit 0 and a green JUnit of 111 skipped tests before.
    Report skipped;
    skipped.profile_id = "mmk-2030";
    for (const char* id : {"value.hr23.limits", "value.hr24.limits"}) {
        RuleResult r;
        r.rule.id = id;
        r.outcome = Outcome::Skip;
        r.reason = "writes to the device (--read-only)";
        skipped.results.push_back(r);
    }
    EXPECT_EQ(
        nothing_judged(skipped),
        "all 2 rules selected were skipped (value.hr23.limits: writes to the device (--read-only), ...)");
    EXPECT_EQ(verdict_text(skipped), "error");
    std::ostringstream skipped_junit;
    write_junit(skipped_junit, skipped);
    EXPECT_NE(skipped_junit.str().find("tests=\"3\" failures=\"0\" errors=\"1\" skipped=\"2\""),
              std::string::npos)
        << skipped_junit.str();
    EXPECT_NE(skipped_junit.str().find("name=\"run.nothing_judged\""), std::string::npos);
    skipped.results.front().outcome = Outcome::Pass;  // one rule judged: a run like any other
    EXPECT_EQ(nothing_judged(skipped), "");
    EXPECT_EQ(verdict_text(skipped), "pass");
}

// The restore ledger in words: "84 points written and restored, 84 NOT restored" contradicted itself.
TEST(Reports, TheTextLedgerCountsWhatWasRestoredAndWhatWasNot) {
    Report report;
    report.results.push_back({});
    report.restored.push_back({modbus::Table::HoldingRegisters, 10, 5, true, ""});
    report.restored.push_back({modbus::Table::HoldingRegisters, 11, 6, false, "no reply"});
    std::ostringstream text;
    write_text(text, report, false);
    EXPECT_NE(
        text.str().find("2 points written, 1 restored, 1 NOT restored:\n  holding_registers 11: original 6, "
                        "no reply"),
        std::string::npos)
        << text.str();
    report.restored[1].restored = true;
    std::ostringstream all;
    write_text(all, report, false);
    EXPECT_NE(all.str().find("2 points written and restored"), std::string::npos) << all.str();
}

TEST(Reports, JunitIsWellFormedWhateverTheTextsHold) {
    Report report;
    report.target = "tcp://<b>x\xff&\"\x01:502";
    report.profile_id = "hostile\xEF\xBF\xBE\xEF\xBF\xBF\xED\xA0\x80 \xC3\xA9";
    std::ostringstream out;
    write_junit(out, report);
    const auto path = std::filesystem::temp_directory_path() /
                      ("mbscope-junit-hostile-" + std::to_string(::getpid()) + ".xml");
    {
        std::ofstream f(path, std::ios::binary);
        f << out.str();
    }
    const std::string check =
        "python3 -c \"import sys, xml.etree.ElementTree as E\n"
        "root = E.parse(sys.argv[1]).getroot()\n"
        "name = root.get('name')\n"
        "assert '\\u00e9' in name and '<b>x\\ufffd&' in name, ascii(name)\n"
        "\" " +
        path.string();
    EXPECT_EQ(std::system(check.c_str()), 0) << out.str();
    std::filesystem::remove(path);
}

// JUnit's `time` is an xs:decimal: a double streamed as is read "4.9333e-05" for a rule judged in 49 µs, and
// the JUnit XSD (and the CI tools that validate against it) refused the file. Every time, of the run, of each
// suite and of each testcase, is in seconds in fixed notation, to the microsecond.
TEST(Reports, JunitTimesAreDecimalsNotScientificNotation) {
    Report report;
    report.profile_id = "mmk-2030";
    report.wall = std::chrono::nanoseconds(49'333);
    for (const auto& [id, ns] :
         {std::pair{"fc.supported.3", 49'333}, std::pair{"fc.supported.4", 1'250'000'000}}) {
        RuleResult r;
        r.rule.id = id;
        r.rule.family = "function codes";
        r.outcome = Outcome::Pass;
        r.duration = std::chrono::nanoseconds(ns);
        report.results.push_back(r);
    }
    std::ostringstream out;
    write_junit(out, report);
    const std::string xml = out.str();
    EXPECT_NE(xml.find("<testsuites name=\"mbscope check mmk-2030 \" tests=\"2\" failures=\"0\" errors=\"0\" "
                       "skipped=\"0\" time=\"0.000049\">"),
              std::string::npos)
        << xml;
    EXPECT_NE(xml.find("<testsuite name=\"function codes\" tests=\"2\" failures=\"0\" errors=\"0\" "
                       "skipped=\"0\" time=\"1.250049\">"),
              std::string::npos)
        << xml;
    EXPECT_NE(xml.find("name=\"fc.supported.3\" time=\"0.000049\""), std::string::npos) << xml;
    EXPECT_NE(xml.find("name=\"fc.supported.4\" time=\"1.250000\""), std::string::npos) << xml;
    // Every time attribute is an xs:decimal: digits, a point, digits; no exponent.
    std::size_t times = 0;
    for (auto at = xml.find(" time=\""); at != std::string::npos; at = xml.find(" time=\"", at + 1)) {
        const auto from = at + 7;
        const std::string value = xml.substr(from, xml.find('"', from) - from);
        ++times;
        EXPECT_FALSE(value.empty());
        EXPECT_EQ(value.find_first_not_of("0123456789."), std::string::npos) << value;
        EXPECT_LE(std::count(value.begin(), value.end(), '.'), 1) << value;
    }
    EXPECT_EQ(times, 4u) << xml;  // the run, the suite, its two testcases
}

TEST(Reports, JunitHasOneTestcasePerRuleAndMatchingCounts) {
    RunningServer server({"no-echo"}, 1, "cth2265i");
    const auto run = certify(server, "tcp", "cth2265i");
    std::ostringstream out;
    write_junit(out, run.report);
    const std::string xml = out.str();
    ASSERT_TRUE(xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>")) << xml.substr(0, 80);
    const auto count = [&](const std::string& needle) {
        std::size_t n = 0;
        for (auto at = xml.find(needle); at != std::string::npos; at = xml.find(needle, at + 1))
            ++n;
        return n;
    };
    // One testcase a rule, and one for the points written and restored.
    ASSERT_FALSE(run.report.restored.empty());
    EXPECT_EQ(count("<testcase "), run.report.results.size() + 1);
    EXPECT_EQ(count("name=\"restore.all_points\""), 1u);
    // Rules the manual only implies are warnings: in the output, not counted as failures.
    const std::size_t failing =
        run.report.failures_of(Authority::Specification) + run.report.failures_of(Authority::Manual);
    EXPECT_GT(failing, 0u);
    EXPECT_EQ(count("<failure "), failing);
    EXPECT_EQ(count("<skipped"), run.report.count(Outcome::Skip));
    // The suite's totals agree with its testcases.
    // (No std::regex: GCC 12 warns inside it under the sanitizers.)
    const auto root = xml.substr(0, xml.find('>', xml.find("<testsuites")));
    const auto attribute = [&](const std::string& name) -> std::size_t {
        const auto at = root.find(" " + name + "=\"");
        return at == std::string::npos ? std::string::npos : std::stoul(root.substr(at + name.size() + 3));
    };
    EXPECT_EQ(attribute("tests"), run.report.results.size() + 1) << root;
    EXPECT_EQ(attribute("failures"), failing) << root;
    // Well-formed for an XML parser nobody here wrote (Python's expat), which also checks the counts of
    // every testsuite against its testcases.
    const auto path =
        std::filesystem::temp_directory_path() / ("mbscope-junit-" + std::to_string(::getpid()) + ".xml");
    {
        std::ofstream f(path);
        f << xml;
    }
    const std::string check =
        "python3 -c \"import sys, xml.etree.ElementTree as E\n"
        "root = E.parse(sys.argv[1]).getroot()\n"
        "assert root.tag == 'testsuites'\n"
        "for s in root.iter('testsuite'):\n"
        "    cases = s.findall('testcase')\n"
        "    assert int(s.get('tests')) == len(cases), s.get('name')\n"
        "    assert int(s.get('skipped')) == sum(1 for c in cases if c.find('skipped') is not None)\n"
        "    assert int(s.get('errors')) == sum(1 for c in cases if c.find('error') is not None)\n"
        "\" " +
        path.string();
    EXPECT_EQ(std::system(check.c_str()), 0) << "python3 rejects " << path;
    std::filesystem::remove(path);
}

TEST(Reports, HtmlIsOneSelfContainedPageWithEveryRuleAndTheResponseTimes) {
    RunningServer server({"no-echo"}, 1, "cth2265i");
    const auto run = certify(server, "tcp", "cth2265i");
    std::ostringstream out;
    write_html(out, run.report);
    const std::string html = out.str();
    EXPECT_TRUE(html.starts_with("<!DOCTYPE html>"));
    EXPECT_NE(html.find("</html>"), std::string::npos);
    EXPECT_NE(html.find("Response times"), std::string::npos);
    // Self-contained: nothing fetched from elsewhere.
    EXPECT_EQ(html.find("src=\"http"), std::string::npos);
    EXPECT_EQ(html.find("href=\"http"), std::string::npos);
    for (const auto& x : run.report.results)
        EXPECT_NE(html.find(x.rule.id), std::string::npos) << x.rule.id;
    // The failing echo shows its bytes.
    EXPECT_NE(html.find("echo.fc6"), std::string::npos);
}

// A read-only point a rule's range reached is counted restored when the device refused to take its original
// back, but what it reads now is said in every report, not shown as a plain "yes".
TEST(Reports, AReadOnlyPointThatMovedIsShownWithWhatItReads) {
    Report report;
    report.restored.push_back({modbus::Table::HoldingRegisters, 5, 7, true, ""});
    report.restored.push_back({modbus::Table::HoldingRegisters, 0, 120, true,
                               "read-only in the map, not written back; reads 133, was 120"});
    report.restored.push_back({modbus::Table::Coils, 3, 1, false, "reads 0 after restoring 1"});
    std::ostringstream text;
    write_text(text, report, false);
    EXPECT_NE(text.str().find("1 NOT restored:\n  coils 3: original 1, reads 0 after restoring 1"),
              std::string::npos)
        << text.str();
    EXPECT_NE(text.str().find(
                  "note: holding_registers 0: read-only in the map, not written back; reads 133, was 120"),
              std::string::npos)
        << text.str();
    std::ostringstream html;
    write_html(html, report);
    EXPECT_NE(html.str().find(">yes; read-only in the map, not written back; reads 133, was 120<"),
              std::string::npos)
        << html.str();
    EXPECT_NE(html.str().find(">yes<"), std::string::npos);
    const auto json = to_json(report.restored);
    EXPECT_EQ(json[1]["problem"], "read-only in the map, not written back; reads 133, was 120");
    // A point not restored fails the run (verdict 1): the JUnit report, which a CI job may read alone, has a
    // failing testcase for it, not only the rules' (here none, all passed).
    std::ostringstream junit;
    write_junit(junit, report);
    EXPECT_NE(junit.str().find("<testsuites name=\"mbscope check  \" tests=\"2\" failures=\"1\""),
              std::string::npos)
        << junit.str();
    EXPECT_NE(junit.str().find("name=\"restore.all_points\""), std::string::npos) << junit.str();
    EXPECT_NE(junit.str().find("<failure message=\"1 of 3 points written NOT restored\" type=\"restore\">"),
              std::string::npos)
        << junit.str();
    EXPECT_NE(junit.str().find("coils 3: original 1, NOT restored: reads 0 after restoring 1"),
              std::string::npos)
        << junit.str();
    EXPECT_EQ(verdict(report), 1);
}

// A DCY controller in automatic mode (coil 0 set) makes its loop output, register 2, read-only (000:961):
// the rules that rewrite a register with its own value, and the write of the maximum quantity, picked it and
// failed a correct device with its exception 02, in the same report that passed access.hr2.read_only_when
// for that very refusal.
TEST(Runner, APointReadOnlyInTheDevicesStateIsNotTheOneRewritten) {
    RunningServer server({}, 1, "dcy-2050");
    server.device().image().set_bit(modbus::Table::Coils, 0, true);  // automatic mode
    auto options = options_for();
    options.run.rule_globs = {"fc.supported.*", "quantity.fc16.max", "access.hr2.*"};
    const auto run = certify(server, "tcp", "dcy-2050", options);
    EXPECT_EQ(run.report.count(Outcome::Fail), 0u) << failures(run.report);
    EXPECT_GT(run.report.count(Outcome::Pass), 5u);
    EXPECT_TRUE(run.report.all_restored()) << failures(run.report);
}

// FC24 points at a register the device holds: one counting more than 31 is refused with 03, as AP §6.18
// demands. fc.supported.24 failed the reference slave for the value its register 0 held.
TEST(Runner, AFifoCountAbove31RefusedWith03StillShowsTheFunctionSupported) {
    for (const std::uint16_t held : {std::uint16_t{0}, std::uint16_t{40}}) {
        RunningServer server({}, 1, "modbus");
        server.device().image().set_reg(modbus::Table::HoldingRegisters, 0, held);
        auto options = options_for();
        options.run.rule_globs = {"fc.supported.24"};
        const auto run = certify(server, "tcp", "modbus", options);
        ASSERT_EQ(run.report.results.size(), 1u);
        EXPECT_EQ(run.report.results[0].outcome, Outcome::Pass) << held << failures(run.report);
    }
}

}  // namespace
}  // namespace mbscope::conformance::test_conformance_runner_test
