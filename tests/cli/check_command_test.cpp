// `mbscope check` end to end against the reference slave (the mbscope binary in another process): what it
// says when the rules asked for select nothing, or select only rules that send nothing.
#include <gtest/gtest.h>

#include <string>

#include "tests/cli/cli_run.hpp"
#include "tests/slave/slave_process.hpp"

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
    // Broadcast rules over Modbus/TCP are skipped with a reason and send nothing: a clean run, exit 0.
    r = run_mbscope(check + "--rules 'broadcast*'");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("1 skipped"), std::string::npos) << r.out;
}
