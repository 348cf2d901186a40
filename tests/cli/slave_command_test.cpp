// `mbscope slave` as a user starts it on a pseudo-terminal: stdout has the device path alone (what libmodbus
// and pyserial open, and what scripts read); standard error says how the mbscope commands reach it, with
// the scheme and line settings a bare path does not carry (`--target /dev/pts/3` is no endpoint).
#include <gtest/gtest.h>

#include <string>

#include "tests/cli/cli_run.hpp"
#include "tests/slave/slave_process.hpp"

namespace test_cli_slave_command_test {

TEST(SlaveCommand, APseudoTerminalIsNamedAsATargetTheOtherCommandsTake) {
    mbscope::slave::test::SlaveProcess slave(
        {"--profile", "mmk-2030", "--listen", "ascii:pty?baud=19200&parity=N", "--pty"}, true);
    const std::string& path = slave.address();
    ASSERT_EQ(path.rfind("/dev/pts/", 0), 0u) << path;
    const std::string said = slave.read_until("reach it as");
    EXPECT_NE(said.find("mbscope slave: mbscope commands reach it as --target 'ascii:" + path +
                        "?baud=19200&parity=N&stop=1&data=7'"),
              std::string::npos)
        << said;
}

// A fault planted where the transport has nothing for it to change (bad-crc over Modbus/TCP) would let a
// checker that catches nothing pass as if it had caught it: the slave refuses to start, naming why.
TEST(SlaveCommand, AFaultWithoutEffectOnTheEndpointIsRefused) {
    using mbscope::test::run_mbscope;
    const auto refused = run_mbscope("slave --listen tcp://127.0.0.1:0 --fault bad-crc");
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.out.find("--fault bad-crc has no effect on tcp://127.0.0.1:0: it changes the CRC, "
                               "which only RTU frames carry"),
              std::string::npos)
        << refused.out;
    EXPECT_EQ(refused.out.find("planted"), std::string::npos) << refused.out;
    EXPECT_EQ(run_mbscope("slave --listen udp://127.0.0.1:0 --fault gap-inside-frame=4").exit_code, 2);
    EXPECT_EQ(run_mbscope("slave --listen rtu-tcp://127.0.0.1:0 --fault wrong-tid").exit_code, 2);
}

}  // namespace test_cli_slave_command_test
