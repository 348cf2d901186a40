// `mbscope slave` as a user starts it on a pseudo-terminal: stdout has the device path alone (what libmodbus
// and pyserial open, and what scripts read); standard error says how the mbscope commands reach it, with
// the scheme and line settings a bare path does not carry (`--target /dev/pts/3` is no endpoint).
#include <gtest/gtest.h>

#include <string>

#include "tests/cli/cli_run.hpp"

using mbscope::test::run_mbscope;

TEST(SlaveCommand, APseudoTerminalIsNamedAsATargetTheOtherCommandsTake) {
    const auto r = run_mbscope("slave --profile mmk-2030 --listen 'ascii:pty?baud=19200&parity=N' --pty",
                               "timeout --preserve-status -s INT 1");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    ASSERT_EQ(r.out.rfind("/dev/pts/", 0), 0u) << r.out;
    const std::string path = r.out.substr(0, r.out.find('\n'));
    EXPECT_NE(r.out.find("mbscope slave: mbscope commands reach it as --target 'ascii:" + path +
                         "?baud=19200&parity=N&stop=1&data=7'"),
              std::string::npos)
        << r.out;
}
