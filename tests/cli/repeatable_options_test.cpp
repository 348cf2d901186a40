// A repeatable option takes one value each time it is given, wherever it stands: the natural
// `mbscope decode --tcp-port 5020 plant.pcap` read the capture's name as a second port (exit 2), and
// `--map 1=mmk-2030 plant.pcap` swallowed the file ("files is required").
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_repeatable_options_test {

using mbscope::test::run_mbscope;

TEST(RepeatableOptions, TakeOneValueEachAndLeaveTheFilesAlone) {
    const std::string capture = std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap";
    // An empty directory of profiles: any directory would do, but one full of files (as /tmp may be) is
    // read whole before the option is reached.
    std::string empty_dir = (std::filesystem::temp_directory_path() / "mbscope-repeatable-XXXXXX").string();
    ASSERT_NE(::mkdtemp(empty_dir.data()), nullptr);
    const std::string spellings[] = {
        "decode --tcp-port 5020 ",
        "decode --map 1=mmk-2030 ",
        "decode --profile-dir " + empty_dir + " --config 1=none --map 1=mmk-2030 ",
        "decode --tcp-port 5020 --tcp-port 5021 --udp-port 5020 --rtu-over-tcp 4001 ",
    };
    for (const std::string& s : spellings) {
        const auto r = run_mbscope(s + capture + " --summary");
        if (s.find("--config") != std::string::npos) {
            // Reaches the --config check (mmk-2030 has no channels): the file was not taken as a value.
            EXPECT_NE(r.out.find("--config"), std::string::npos) << s << "\n" << r.out;
            EXPECT_EQ(r.out.find("files is required"), std::string::npos) << s << "\n" << r.out;
            continue;
        }
        EXPECT_EQ(r.exit_code, 0) << s << "\n" << r.out;
        EXPECT_NE(r.out.find("166 packets, 32 frames, 16 transactions"), std::string::npos) << s << "\n"
                                                                                            << r.out;
    }
    // Two values after one option: the second is a file, and a missing one is named.
    const auto two = run_mbscope("decode --tcp-port 5020 5021 " + capture + " --summary");
    EXPECT_EQ(two.exit_code, 2) << two.out;
    EXPECT_NE(two.out.find("5021"), std::string::npos) << two.out;
    std::filesystem::remove(empty_dir);
}

// Each --map that described no device is a note after the run, the exit code unchanged: a mistyped address
// (and an IPv6 address read as one where a unit was meant) mapped nothing without a word. zeek-modbusSmall
// shows one device, 118.189.96.132:502 unit 1.
TEST(RepeatableOptions, AMapThatDescribedNoDeviceIsNoted) {
    const std::string capture = std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap";
    const auto r =
        run_mbscope("decode " + capture +
                    " --summary --map 118.189.96.132:1=modbus --map 1=modbus --map 10.0.0.99=modbus"
                    " --map 2001:db8::2:1=modbus --map 7=modbus");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(r.out.find("--map 118.189.96.132:1=modbus described"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("note: --map 1=modbus described no device: every device it matched took a more "
                         "specific --map"),
              std::string::npos)
        << r.out;
    EXPECT_NE(
        r.out.find("--map 10.0.0.99=modbus described no device: no request in the input went to 10.0.0.99\n"),
        std::string::npos)
        << r.out;
    EXPECT_NE(
        r.out.find("no request in the input went to [2001:db8::2:1] (an IPv6 address; a unit behind one is "
                   "written [IP]:UNIT)"),
        std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("--map 7=modbus described no device: no request in the input went to unit 7\n"),
              std::string::npos)
        << r.out;
    const auto used = run_mbscope("decode " + capture + " --summary --map 1=modbus");
    EXPECT_EQ(used.out.find("described no device"), std::string::npos) << used.out;
    // The same selector twice: the first given wins, and the second is not said to be less specific.
    const auto twice = run_mbscope("decode " + capture + " --summary --map 1=modbus --map 1=cth2265i");
    EXPECT_NE(
        twice.out.find("--map 1=cth2265i described no device: an earlier --map for the same devices took "
                       "them"),
        std::string::npos)
        << twice.out;
}

}  // namespace test_cli_repeatable_options_test
