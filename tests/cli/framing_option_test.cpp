// `mbscope decode --framing`: a serial capture's framing when its bytes should not decide it, and the two
// names of a raw dump's framing (`--format rtu|ascii` and `--framing`) that must agree.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_framing_option_test {

using mbscope::test::run_mbscope;

namespace {
// The MK manual's ASCII example (MK-ASC-02, 000:304-309) as a text log: a time, then the characters' bytes.
std::string ascii_log() {
    const std::string path = ::testing::TempDir() + "framing-option.txt";
    std::ofstream(path) << "1.000 3A 31 31 30 33 30 30 36 30 30 30 30 33 38 39 0D 0A\n";
    return path;
}
}  // namespace

TEST(FramingOption, AutoTellsAsciiAndAStatedFramingIsObeyed) {
    const auto found = run_mbscope("decode --jsonl " + ascii_log());
    EXPECT_EQ(found.exit_code, 0) << found.out;
    EXPECT_NE(found.out.find("\"framing\":\"ascii\""), std::string::npos) << found.out;

    const auto stated = run_mbscope("decode --jsonl --framing rtu " + ascii_log());
    EXPECT_EQ(stated.exit_code, 1) << stated.out;  // read as RTU: a CRC mismatch, an error finding
    EXPECT_NE(stated.out.find("rtu.crc_mismatch"), std::string::npos) << stated.out;
}

TEST(FramingOption, ARawDumpsTwoNamesMustAgree) {
    const auto r = run_mbscope("decode --format ascii --framing rtu " + ascii_log());
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find("--format ascii reads a raw ASCII dump; --framing rtu contradicts it"),
              std::string::npos)
        << r.out;
    const auto help = run_mbscope("decode --help");
    EXPECT_NE(help.out.find("--framing"), std::string::npos);
}

// Two parts of one line's log (a logger that starts a new file on the hour): read apart, the exchange across
// the cut is a timeout and an unsolicited reply, and decode says that --one-line reads them as one stream;
// with it the decode is clean.
TEST(FramingOption, PartsOfOneLineAreOneStreamWithOneLine) {
    const std::string fc3 = "11 03 00 60 00 03 07 45", reply = "11 03 06 02 2B 00 00 00 64 C8 BA";
    const std::string first = ::testing::TempDir() + "one-line-1.txt";
    const std::string second = ::testing::TempDir() + "one-line-2.txt";
    std::ofstream(first) << "1.000 " << fc3 << "\n1.020 " << reply << "\n2.000 " << fc3 << "\n";
    std::ofstream(second) << "2.020 " << reply << "\n3.000 " << fc3 << "\n3.020 " << reply << "\n";
    const auto apart = run_mbscope("decode " + first + " " + second);
    EXPECT_EQ(apart.exit_code, 1) << apart.out;
    EXPECT_NE(apart.out.find("mbscope decode: 2 serial inputs were read as 2 lines; if they are parts of one "
                             "line (a log in several files), --one-line reads them as one stream"),
              std::string::npos)
        << apart.out;
    const auto joined = run_mbscope("decode --one-line " + first + " " + second);
    EXPECT_EQ(joined.exit_code, 0) << joined.out;
    EXPECT_NE(joined.out.find("3 requests, 3 responses, 0 exceptions, 0 timeouts"), std::string::npos)
        << joined.out;
    EXPECT_EQ(joined.out.find("--one-line"), std::string::npos) << joined.out;
}

}  // namespace test_cli_framing_option_test
