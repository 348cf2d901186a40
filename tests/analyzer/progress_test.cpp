// The progress line of mbscope decode: its text, its pacing, and its absence when standard error is not a
// terminal.
#include <gtest/gtest.h>

#include <sstream>

#include "analyzer/progress.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_progress_test {

namespace {

using mbscope::analyzer::format_progress;
using mbscope::analyzer::ProgressMeter;
using mbscope::analyzer::ProgressState;

TEST(Progress, FormatsCountsSizesAndPercentage) {
    ProgressState s;
    s.packets = 1234567;
    s.bytes_read = 96'100'000;
    s.total_bytes = 120'000'000;
    s.frames = 2345678;
    s.findings = 12;
    EXPECT_EQ(format_progress(s),
              "1,234,567 packets, 96.1 MB of 120.0 MB (80%), 2,345,678 frames, 12 findings");
}

TEST(Progress, SingularAndNoTotal) {
    ProgressState s;
    s.packets = 1;
    s.bytes_read = 50'000;
    s.frames = 1;
    s.findings = 1;
    EXPECT_EQ(format_progress(s), "1 packet, 0.1 MB, 1 frame, 1 finding");
}

TEST(Progress, PercentageNeverPassesOneHundred) {
    ProgressState s;
    s.bytes_read = 2'000'000;
    s.total_bytes = 1'000'000;
    EXPECT_EQ(format_progress(s), "0 packets, 2.0 MB of 1.0 MB (100%), 0 frames, 0 findings");
}

TEST(Progress, MeterRedrawsOneLineAndErasesIt) {
    std::ostringstream out;
    ProgressMeter meter(out, std::chrono::steady_clock::duration::zero());
    ProgressState s;
    s.packets = 10;
    meter.update(s);
    s.packets = 20;
    meter.update(s);
    meter.clear();
    EXPECT_EQ(out.str(),
              "\r10 packets, 0.0 MB, 0 frames, 0 findings\x1b[K"
              "\r20 packets, 0.0 MB, 0 frames, 0 findings\x1b[K"
              "\r\x1b[K");
}

TEST(Progress, MeterWaitsAnIntervalAndClearsNothingUndrawn) {
    std::ostringstream out;
    ProgressMeter meter(out, std::chrono::hours(1));
    meter.update(ProgressState{});
    meter.clear();
    EXPECT_EQ(out.str(), "");
}

// Standard error redirected to a file (not a terminal): mbscope decode writes nothing there on a clean
// capture, with and without --summary.
TEST(Progress, NothingOnStandardErrorWhenItIsNotATerminal) {
    const std::string capture = std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap";
    const std::string err = ::testing::TempDir() + "progress_stderr.txt";
    for (const char* mode : {"--summary", "--jsonl"}) {
        SCOPED_TRACE(mode);
        const std::string out = mbscope::test::run(std::string(MBSCOPE_BINARY) + " decode " + mode + " '" +
                                                   capture + "' 2>'" + err + "'");
        EXPECT_FALSE(out.empty());
        EXPECT_EQ(mbscope::test::slurp(err), "");
    }
}

}  // namespace

}  // namespace test_analyzer_progress_test
