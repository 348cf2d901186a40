// Numeric options are refused outside what they can mean, before anything runs (exit 2, the option named):
// NaN passed CLI11's range checks, --timeout 1e300 overflowed its conversion to nanoseconds, --baud 0
// divided by zero for t1.5/t3.5, and --timeout 0 or -1 reported every request as unanswered.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_number_options_test {

using mbscope::test::run_mbscope;

TEST(NumberOptions, ValuesOutsideTheirMeaningAreRefusedBeforeAnythingRuns) {
    const std::string capture = " " + std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap";
    const struct {
        std::string args, message;
    } cases[] = {
        {"decode --timeout nan" + capture, "--timeout: seconds from 0.001 to 86400, not 'nan'"},
        {"decode --timeout 1e300" + capture, "--timeout: seconds from 0.001 to 86400, not '1e300'"},
        {"decode --timeout 0" + capture, "--timeout: seconds from 0.001 to 86400, not '0'"},
        {"decode --timeout -1" + capture, "--timeout: seconds from 0.001 to 86400, not '-1'"},
        {"decode --timeout 3s" + capture, "--timeout: seconds: not a number: '3s'"},
        {"decode --baud 0" + capture, "--baud: Value 0 not in range 50 to 10000000"},
        {"decode --tcp-port 0" + capture, "--tcp-port: Value 0 not in range 1 to 65535"},
        {"decode --udp-port 0" + capture, "--udp-port: Value 0 not in range 1 to 65535"},
        {"decode --rtu-over-tcp 0" + capture, "--rtu-over-tcp: Value 0 not in range 1 to 65535"},
        {"sniff -i lo --tcp-port 0", "--tcp-port: Value 0 not in range 1 to 65535"},
        {"slave --profile mmk-2030 --listen tcp://127.0.0.1:0 --idle-timeout inf", "--idle-timeout: seconds"},
        {"slave --profile mmk-2030 --listen tcp://127.0.0.1:0 --max-clients 0", "--max-clients: Value 0"},
        {"check --target tcp://127.0.0.1:1 --interval -5", "--interval: Value -5 not in range 0 to 600000"},
        {"fuzz --target tcp://127.0.0.1:1 --interval -5", "--interval: Value -5 not in range 0 to 600000"},
        {"fuzz --target tcp://127.0.0.1:1 --requests 0", "--requests: Value 0 not in range 1 to"},
        // A run bounded by nothing: sniff took --duration nan, -1, 0 and inf and --count 0 as "no bound".
        {"sniff -i lo --duration nan",
         "--duration: a time such as 60s, 500ms or 5m (a bare number is seconds), not 'nan'"},
        {"sniff -i lo --duration -1", "--duration: a time such as 60s"},
        {"sniff -i lo --duration 0", "--duration: a time such as 60s"},
        {"sniff -i lo --duration inf", "--duration: a time such as 60s"},
        {"sniff -i lo --count 0", "--count: Value 0 not in range 1 to"},
        // sniff takes a serial gateway's port as decode does (it refused the option its own hint named).
        {"sniff -i lo --rtu-over-tcp 0", "--rtu-over-tcp: Value 0 not in range 1 to 65535"},
        {"sniff -i lo --buffer-size 0", "--buffer-size: Value 0 not in range 1 to 4096"},
        {"fuzz --target tcp://127.0.0.1:1 --duration 0s", "--duration: a time such as 60s"},
        {"fuzz --target tcp://127.0.0.1:1 --duration 10x", "--duration: a time such as 60s"},
        // CLI11 wrapped a negative seed into 2^64-1 and the run went on with it.
        {"check --target tcp://127.0.0.1:1 --seed -1",
         "--seed: a whole number from 0 to 18446744073709551615, not '-1'"},
        {"fuzz --target tcp://127.0.0.1:1 --seed -1", "--seed: a whole number from 0 to"},
        {"slave --listen tcp://127.0.0.1:0 --seed -1", "--seed: a whole number from 0 to"},
        {"fuzz --target tcp://127.0.0.1:1 --seed 18446744073709551616", "--seed: a whole number from 0 to"},
        {"fuzz --target tcp://127.0.0.1:1 --seed 1e3", "--seed: a whole number from 0 to"},
        // Wrapped to 2^64-1 as well: a run with no limit on findings and on shortening.
        {"fuzz --target tcp://127.0.0.1:1 --max-findings -1", "--max-findings: a whole number from 0 to"},
        {"fuzz --target tcp://127.0.0.1:1 --minimise -1", "--minimise: a whole number from 0 to"},
        // And runs that ended only at a signal: --requests -1 sent requests without end.
        {"fuzz --target tcp://127.0.0.1:1 --requests -1", "--requests: a whole number from 0 to"},
        {"fuzz --target tcp://127.0.0.1:1 --requests 18446744073709551616", "--requests: a whole number"},
        {"sniff -i lo --count -1", "--count: a whole number from 0 to"},
        // Not a number, but refused as early: two reports into one file, the last replacing the first.
        {"check --target tcp://127.0.0.1:1 --report same-report.json --junit ./same-report.json",
         "--report and --junit name the same file, same-report.json: one report would replace the other"},
    };
    for (const auto& c : cases) {
        const auto r = run_mbscope(c.args);
        EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.out;
        EXPECT_NE(r.out.find(c.message), std::string::npos) << c.args << "\n" << r.out;
    }
    EXPECT_EQ(run_mbscope("decode --summary --timeout 0.5" + capture).exit_code, 0);
}

// --timeout was applied to TCP only: a serial line kept its 1 s default whatever was asked.
TEST(NumberOptions, TimeoutAppliesToSerialLinesToo) {
    const std::string path = testing::TempDir() + "/slow_slave.txt";
    {
        std::ofstream f(path);
        f << "1.000000 > 11 03 00 60 00 03 07 45\n"            // MK manual's FC3 request
          << "2.500000 < 11 03 06 02 2B 00 00 00 64 C8 BA\n";  // its answer, 1.5 s later
    }
    const auto by_default = run_mbscope("decode " + path);
    EXPECT_EQ(by_default.exit_code, 1) << by_default.out;
    EXPECT_NE(by_default.out.find("0 responses, 0 exceptions, 1 timeouts (1 answered late)"),
              std::string::npos)
        << by_default.out;
    // The late reply is paired with its request all the same, its latency and the timeout it missed said.
    EXPECT_NE(by_default.out.find("1500.000 ms  late, past the 1000 ms timeout"), std::string::npos)
        << by_default.out;
    const auto longer = run_mbscope("decode --timeout 5 " + path);
    EXPECT_EQ(longer.exit_code, 0) << longer.out;
    EXPECT_NE(longer.out.find("1 responses, 0 exceptions, 0 timeouts"), std::string::npos) << longer.out;
    EXPECT_NE(longer.out.find("1500.000 ms"), std::string::npos) << longer.out;
}

}  // namespace test_cli_number_options_test
