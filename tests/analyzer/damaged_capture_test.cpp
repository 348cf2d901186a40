// Damaged captures: truncated and corrupted copies of a real capture. Every packet before the damage is
// still analysed, the error names the packet and the byte offset, nothing crashes (run under ASan/UBSan in
// the asan preset).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>

#include "analyzer/analyzer.hpp"
#include "test_packets.hpp"

namespace an = mbscope::analyzer;

namespace {

std::vector<std::uint8_t> read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

const std::string sample = std::string(MBSCOPE_SOURCE_DIR) + "/captures/suricata-modbus.pcap";

struct Outcome {
    an::Summary summary;
    bool opened = true;
    std::string error;
};

Outcome analyse(std::span<const std::uint8_t> bytes) {
    Outcome o;
    mbscope::test::Collect sink;
    an::Analyzer a({}, sink);
    std::string error;
    auto capture = an::CaptureSource::open_memory(bytes, error);
    if (!capture) {
        o.opened = false;
        o.error = error;
        return o;
    }
    a.read_capture(*capture);
    a.finish();
    o.summary = a.summary();
    if (!o.summary.input_errors.empty()) o.error = o.summary.input_errors.front();
    return o;
}

// Offsets where a classic little-endian pcap file's records end (24-byte file header, 16-byte record
// headers with the captured length at offset 8): a cut there damages nothing.
std::vector<std::size_t> record_ends(const std::vector<std::uint8_t>& f) {
    std::vector<std::size_t> ends{24};
    std::size_t pos = 24;
    while (pos + 16 <= f.size()) {
        const std::size_t len =
            f[pos + 8] | (f[pos + 9] << 8) | (f[pos + 10] << 16) | (std::size_t{f[pos + 11]} << 24);
        pos += 16 + len;
        if (pos > f.size()) break;
        ends.push_back(pos);
    }
    return ends;
}

}  // namespace

TEST(DamagedCapture, TruncatedAtEveryKindOfPlaceKeepsWhatCameBefore) {
    const auto whole = read_file(sample);
    ASSERT_GT(whole.size(), 1000u);
    const auto full = analyse(whole);
    ASSERT_TRUE(full.error.empty()) << full.error;
    const auto ends = record_ends(whole);
    ASSERT_EQ(ends.back(), whole.size());
    std::uint64_t previous_packets = 0;
    for (std::size_t cut : {std::size_t{10}, std::size_t{24}, std::size_t{30}, std::size_t{100},
                            std::size_t{130}, whole.size() / 3, whole.size() / 2, whole.size() - 7}) {
        SCOPED_TRACE("cut at " + std::to_string(cut));
        const auto o = analyse(std::span(whole).first(cut));
        if (cut < 24) {  // not even a file header: refused, with a reason
            EXPECT_FALSE(o.opened);
            EXPECT_FALSE(o.error.empty());
            continue;
        }
        EXPECT_LE(o.summary.packets, full.summary.packets);
        EXPECT_GE(o.summary.packets, previous_packets);  // a longer prefix never yields fewer packets
        previous_packets = o.summary.packets;
        const bool at_record_end = std::find(ends.begin(), ends.end(), cut) != ends.end();
        if (at_record_end) {
            EXPECT_TRUE(o.error.empty()) << o.error;  // nothing is damaged: no error may be claimed
        } else {
            EXPECT_NE(o.error.find("packet " + std::to_string(o.summary.packets + 1)), std::string::npos)
                << o.error;
            EXPECT_NE(o.error.find("byte offset"), std::string::npos) << o.error;
        }
    }
}

TEST(DamagedCapture, CorruptedBytesNeverCrash) {
    const auto whole = read_file(sample);
    std::mt19937 rng(2026);
    for (int round = 0; round < 60; ++round) {
        auto bytes = whole;
        const int flips = 1 + static_cast<int>(rng() % 40);
        for (int i = 0; i < flips; ++i)
            bytes[24 + rng() % (bytes.size() - 24)] = static_cast<std::uint8_t>(rng());
        const auto o = analyse(bytes);
        // Whatever the damage, the analysis ends and accounts for what it read.
        EXPECT_LE(o.summary.frames, 10u * (o.summary.packets + 1));
    }
}

TEST(DamagedCapture, NotACaptureAtAll) {
    const std::string text = "this is not a pcap file, it is a text file that happens to be long enough";
    const auto o = analyse({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
    EXPECT_FALSE(o.opened);
    EXPECT_FALSE(o.error.empty());
}

TEST(DamagedCapture, CommandExitsTwoAndStillReportsWhatItRead) {
    const auto whole = read_file(sample);
    const std::string path = ::testing::TempDir() + "mbscope-cut130.pcap";
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(whole.data()), 130);
    FILE* p = popen((std::string(MBSCOPE_BINARY) + " decode " + path + " 2>&1").c_str(), "r");
    std::string out;
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p))
        out.append(buf, n);
    const int status = pclose(p);
    EXPECT_EQ(WEXITSTATUS(status), 2) << out;
    EXPECT_NE(out.find("packet 2 at byte offset 100"), std::string::npos) << out;
    EXPECT_NE(out.find("summary: 1 packets"), std::string::npos) << out;
}
