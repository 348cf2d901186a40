// The conformance runner over a true serial line: the slave on a pseudo-terminal it creates, the runner on
// the terminal's other side, with the line's t1.5 and t3.5 in force (gaps inside requests, silences between
// them). At 38400 baud t1.5 is 750 µs: the slave must be scheduled within that to see a gap, so these tests
// run alone (RUN_SERIAL in tests/CMakeLists.txt), never beside tests that keep both cores busy.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "tests/conformance/runner_support.hpp"

namespace mbscope::conformance {
namespace {

using namespace mbscope::conformance::test;

class OverPseudoTerminal : public ::testing::TestWithParam<std::string> {};

TEST_P(OverPseudoTerminal, CertifiesWithNoFailureAndRestoresEverything) {
    const std::string framing = GetParam();
    slave::FaultSet faults;
    auto listen = tp::parse_endpoint(framing + ":pty?baud=38400");
    ASSERT_TRUE(listen.has_value());
    slave::Device device(slave::test::profile("mmk-2030"), tp::line_state(*listen, 1), &faults);
    slave::ServerOptions so;
    so.create_pty = true;
    slave::Server server(*listen, {&device}, faults, so);
    auto opened = server.open();
    ASSERT_TRUE(opened.has_value()) << (opened ? "" : opened.error());
    std::atomic<bool> stop{false};
    std::thread thread([&] { (void)server.run(stop); });
    auto target = tp::parse_endpoint(framing + ":" + server.address() + "?baud=38400");
    ASSERT_TRUE(target.has_value());
    auto client = tp::Client::open(*target);
    ASSERT_TRUE(client.has_value()) << (client ? "" : client.error());
    CheckRun run;
    run.report =
        run_check(*client, slave::test::profile("mmk-2030"), options_for(std::chrono::milliseconds(500)));
    stop = true;
    thread.join();
    run.changes_after = device.image().changes();
    expect_clean(run, 150);
    // The serial framing rules ran, with the line's timing.
    std::size_t framing_rules = 0;
    for (const auto& x : run.report.results)
        if (x.rule.id.starts_with("framing.") && x.outcome == Outcome::Pass) ++framing_rules;
    EXPECT_GE(framing_rules, 3u);
}

INSTANTIATE_TEST_SUITE_P(Serial, OverPseudoTerminal, ::testing::Values("rtu", "ascii"));

}  // namespace
}  // namespace mbscope::conformance
