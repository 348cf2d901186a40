// `mbscope slave` as a user starts it on a pseudo-terminal: stdout has the device path alone (what libmodbus
// and pyserial open, and what scripts read); standard error says how the mbscope commands reach it, with
// the scheme and line settings a bare path does not carry (`--target /dev/pts/3` is no endpoint).
#include <gtest/gtest.h>

#include <string>

#include "tests/slave/slave_process.hpp"

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
