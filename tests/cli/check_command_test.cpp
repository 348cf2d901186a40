// `mbscope check` end to end against the reference slave (the mbscope binary in another process): what it
// says when the rules asked for select nothing, or select only rules that send nothing, and what it reports
// when the target cannot be reached.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/cli/cli_run.hpp"
#include "tests/slave/slave_process.hpp"

namespace test_cli_check_command_test {

using mbscope::test::run_mbscope;

TEST(CheckCommand, RulesThatSelectNothingOrSendNothingAreToldApartFromASilentTarget) {
    mbscope::slave::test::SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    const std::string check = "check --target " + slave.address() + " --profile mmk-2030 ";
    // A mistyped glob: nothing runs, and the message says so (it said "the target never answered").
    auto r = run_mbscope(check + "--rules 'nosuch.*' --rules quantity");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("--rules 'nosuch.*', 'quantity' match no rule for mmk-2030"), std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("never answered"), std::string::npos) << r.out;
    // Broadcast rules over Modbus/TCP are skipped with a reason and send nothing: no silent target either,
    // but nothing judged, which is no pass (exit 2, as for a glob that matches nothing; it was exit 0, and
    // so was --read-only with writing rules only against a target that never answered).
    r = run_mbscope(check + "--rules 'broadcast*'");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("1 skipped"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("nothing judged: the one rule selected was skipped (broadcast: "), std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("never answered"), std::string::npos) << r.out;
}

// A target that cannot be reached still gets the reports asked for (a CI job publishing the JUnit file found
// none): one rule, target.reachable, in error with the reason; exit 2 as before.
TEST(CheckCommand, AnUnreachableTargetIsReportedInEveryFileAskedFor) {
    const std::string dir = ::testing::TempDir() + "mbscope-unreachable-";
    for (const char* f : {"r.json", "j.xml", "h.html"})
        std::remove((dir + f).c_str());
    const auto r = run_mbscope("check --target rtu:/nonexistent/ttyUSB9 --report " + dir + "r.json --junit " +
                               dir + "j.xml --html " + dir + "h.html");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("cannot reach the target"), std::string::npos) << r.out;
    const auto read = [](const std::string& path) {
        std::ifstream in(path);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    const auto report = nlohmann::json::parse(read(dir + "r.json"));
    // Nothing was judged, so nothing failed: a CI job reading the verdict must not record a cabling or
    // network problem as a device defect.
    EXPECT_EQ(report["summary"]["verdict"], "error");
    EXPECT_NE(report["unanswered"].get<std::string>().find("cannot reach the target: "), std::string::npos);
    ASSERT_EQ(report["rules"].size(), 1u);
    EXPECT_EQ(report["rules"][0]["id"], "target.reachable");
    EXPECT_EQ(report["rules"][0]["outcome"], "error");
    const std::string junit = read(dir + "j.xml");
    EXPECT_NE(junit.find("errors=\"1\""), std::string::npos) << junit;
    EXPECT_NE(junit.find("<error message=\"cannot reach the target: "), std::string::npos) << junit;
    EXPECT_NE(junit.find("/nonexistent/ttyUSB9"), std::string::npos) << junit;
    EXPECT_NE(read(dir + "h.html").find("target.reachable"), std::string::npos);
    EXPECT_EQ(read(dir + "h.html").find("Verdict: fail"), std::string::npos);
    // And on standard output when --json asks for it there (it printed nothing).
    const auto json = run_mbscope("check --target tcp://127.0.0.1:1 --json");
    EXPECT_EQ(json.exit_code, 2) << json.out;
    const auto printed =
        nlohmann::json::parse(json.out.substr(std::min(json.out.find('{'), json.out.size())), nullptr, false);
    ASSERT_FALSE(printed.is_discarded()) << json.out;
    EXPECT_EQ(printed["rules"][0]["id"], "target.reachable");
}

// A report file that opens but cannot be written (a full disk; /dev/full) ended the run with exit 2 and no
// word about it: the reason is said, naming the file.
TEST(CheckCommand, AReportThatCannotBeWrittenIsSaidWithItsReason) {
    std::ofstream probe("/dev/full");
    if (!probe) GTEST_SKIP() << "this system has no /dev/full";
    mbscope::slave::test::SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    const auto r = run_mbscope("check --target " + slave.address() +
                               " --profile mmk-2030 --interval 0 --rules fc.supported.3 --report /dev/full");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope check: writing /dev/full failed: No space left on device"),
              std::string::npos)
        << r.out;
}

// A target (or a reproducer's, or a listening address) with terminal control sequences in it is quoted
// escaped in the error, as every other input is: it drove the reader's terminal.
TEST(CheckCommand, AnEndpointInAnErrorIsWrittenEscaped) {
    const std::string bad = "\"$(printf 'tcp://127.0.0.1:1\\033[2J')\"";
    for (const std::string& command : {"check --target " + bad + " --profile mmk-2030",
                                       "fuzz --target " + bad + " --profile mmk-2030 --requests 1",
                                       "slave --profile mmk-2030 --listen " + bad}) {
        const auto r = run_mbscope(command);
        EXPECT_EQ(r.exit_code, 2) << command << r.out;
        EXPECT_EQ(r.out.find('\x1b'), std::string::npos) << command << r.out;
        EXPECT_NE(r.out.find("1\\x1B[2J"), std::string::npos) << command << r.out;
    }
}

}  // namespace test_cli_check_command_test
