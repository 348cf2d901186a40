// jpnevulator itself (Debian package jpnevulator) as the logger: two socat pty pairs stand for the two taps
// of a serial line, jpnevulator --read --timing-print reads one end of each under the aliases "master" and
// "slave", the MK manual's FC3 request and reply (000:356-370) are written into the other ends, and the log
// it writes is decoded. Skipped when jpnevulator or socat is not installed.
#include <gtest/gtest.h>

#include <filesystem>

#include "analyzer/serial_input.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_jpnevulator_peer_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace mbscope::test;

TEST(JpnevulatorPeer, LogOfTwoTapsDecodesIntoATransaction) {
    if (!have("jpnevulator") || !have("socat")) GTEST_SKIP() << "needs jpnevulator and socat";
    const std::string dir = ::testing::TempDir() + "jpnevulator_peer";
    SocatTaps taps(dir);
    ASSERT_TRUE(taps.ready());
    const int master_end = taps.master_end, slave_end = taps.slave_end;
    const std::string log = dir + "/bus.log";
    Child logger({"jpnevulator", "--read", "--timing-print", "--ascii", "--tty",
                  taps.master_tap() + ":master", "--tty", taps.slave_tap() + ":slave", "--file", log},
                 "/dev/null", dir + "/jpnevulator.err");
    const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    const auto response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
    ASSERT_EQ(::write(master_end, request.data(), request.size()), 8);
    ASSERT_TRUE(wait_for([&] { return slurp(log).find("07 45") != std::string::npos; }))
        << slurp(dir + "/jpnevulator.err");
    ASSERT_EQ(::write(slave_end, response.data(), response.size()), 11);
    ASSERT_TRUE(wait_for([&] { return slurp(log).find("C8 BA") != std::string::npos; }));
    logger.stop();

    Collect sink;
    an::Analyzer a({}, sink);
    EXPECT_TRUE(an::read_input(a, log, an::InputFormat::Auto)) << slurp(log);
    a.finish();
    ASSERT_EQ(sink.transactions.size(), 1u) << slurp(log);
    const auto& t = sink.transactions[0];
    ASSERT_TRUE(t.response.has_value());
    EXPECT_EQ(t.request.direction, mb::Direction::Request);
    EXPECT_EQ(t.response->direction, mb::Direction::Response);
    EXPECT_TRUE(sink.findings.empty()) << slurp(log);
}

}  // namespace test_analyzer_jpnevulator_peer_test
