// Damaged captures: truncated and corrupted copies of a real capture. Every packet before the damage is
// still analysed, the error names the packet and the byte offset, nothing crashes (run under ASan/UBSan in
// the asan preset).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <unistd.h>

#include "analyzer/analyzer.hpp"
#include "test_packets.hpp"

namespace test_analyzer_damaged_capture_test {

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

// What the analyzer makes of `capture` (null: not opened, `error` says why).
Outcome analysed(std::unique_ptr<an::CaptureSource> capture, const std::string& error) {
    Outcome o;
    if (!capture) {
        o.opened = false;
        o.error = error;
        return o;
    }
    mbscope::test::Collect sink;
    an::Analyzer a({}, sink);
    a.read_capture(*capture);
    a.finish();
    o.summary = a.summary();
    if (!o.summary.input_errors.empty()) o.error = o.summary.input_errors.front();
    return o;
}

Outcome analyse(std::span<const std::uint8_t> bytes) {
    std::string error;
    auto capture = an::CaptureSource::open_memory(bytes, error);
    return analysed(std::move(capture), error);
}

// The same read as a stream (a pipe), once, as it comes: `mbscope decode -` and tcpdump piped in.
Outcome analyse_stream(std::span<const std::uint8_t> bytes) {
    int ends[2];
    if (::pipe(ends) != 0) return {};
    EXPECT_LE(bytes.size(), 65536u);  // the pipe holds it all: written before it is read
    EXPECT_EQ(::write(ends[1], bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
    ::close(ends[1]);
    std::string error;
    auto capture = an::CaptureSource::open_stream(ends[0], {}, "stream", error);
    return analysed(std::move(capture), error);
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

// A command's exit status and what it printed, standard error included.
std::pair<int, std::string> run(const std::string& command) {
    FILE* p = popen((command + " 2>&1").c_str(), "r");
    std::string out;
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p))
        out.append(buf, n);
    const int status = pclose(p);
    return std::make_pair(WEXITSTATUS(status), out);
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
        if (cut == 24) {
            // The file header alone: nothing damaged, and nothing recorded either, which is no quiet network.
            EXPECT_NE(o.error.find("holds no packets"), std::string::npos) << o.error;
        } else if (at_record_end) {
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

namespace {

void put32(std::vector<std::uint8_t>& b, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
        b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// A pcapng block: type, total length, body padded to 32 bits, total length again.
void block(std::vector<std::uint8_t>& out, std::uint32_t type, std::vector<std::uint8_t> body) {
    body.resize((body.size() + 3) / 4 * 4);
    const auto total = static_cast<std::uint32_t>(12 + body.size());
    put32(out, type);
    put32(out, total);
    out.insert(out.end(), body.begin(), body.end());
    put32(out, total);
}

}  // namespace

// pcapng timestamps are 64-bit counts of microseconds: 2^64 of them is half a million years, beyond the
// nanosecond timestamps the analysis keeps (found by fuzzing: the conversion overflowed). The packet is
// still decoded, and an input note names it.
TEST(DamagedCapture, PcapngTimestampBeyond2262IsNamedAndThePacketStillDecoded) {
    std::vector<std::uint8_t> f;
    std::vector<std::uint8_t> shb;
    put32(shb, 0x1A2B3C4D);
    put32(shb, 1);  // version 1.0
    put32(shb, 0xFFFFFFFF);
    put32(shb, 0xFFFFFFFF);  // section length unknown
    block(f, 0x0A0D0D0A, shb);
    std::vector<std::uint8_t> idb;
    put32(idb, 101);  // LINKTYPE_RAW (IPv4), no reserved bits
    put32(idb, 65535);
    block(f, 1, idb);
    // IPv4 + TCP to port 502 carrying an FC3 request.
    const auto packet = mbscope::test::packet(
        true, 1, {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03});
    for (const std::uint64_t ts : {std::uint64_t{0xFFFFFFFFFFFFFFF0}, std::uint64_t{1'000'000}}) {
        std::vector<std::uint8_t> epb;
        put32(epb, 0);
        put32(epb, static_cast<std::uint32_t>(ts >> 32));
        put32(epb, static_cast<std::uint32_t>(ts));
        put32(epb, static_cast<std::uint32_t>(packet.size()));
        put32(epb, static_cast<std::uint32_t>(packet.size()));
        epb.insert(epb.end(), packet.begin(), packet.end());
        block(f, 6, epb);
    }
    const auto o = analyse(f);
    EXPECT_TRUE(o.opened);
    EXPECT_EQ(o.summary.packets, 2u);
    EXPECT_GE(o.summary.frames, 1u);
    EXPECT_TRUE(o.summary.input_errors.empty());  // read whole: a note, not an error
    ASSERT_EQ(o.summary.input_notes.size(), 1u);
    EXPECT_NE(o.summary.input_notes[0].find("packet 1: timestamp beyond April 2262"), std::string::npos)
        << o.summary.input_notes[0];
}

// libpcap refuses a pcapng stream whose second interface has another link type (Ethernet and raw IP): the
// error named "packet 1 at byte offset 48" as if a packet were damaged. It names the interface block, what
// libpcap allows, and how to split the file; the packets before it are still decoded. The block is named
// where it starts, also when other blocks (here a Name Resolution Block, as Wireshark writes them, and
// Interface Statistics) lie between the last packet and it. (A file or memory is read again, once per
// link type: tests/analyzer/pcapng_link_types_test.cpp.)
TEST(DamagedCapture, PcapngInterfacesOfDifferentLinkTypesAreNamedForWhatTheyAre) {
    for (bool blocks_between : {false, true}) {
        SCOPED_TRACE(blocks_between);
        std::vector<std::uint8_t> f;
        std::vector<std::uint8_t> shb;
        put32(shb, 0x1A2B3C4D);
        put32(shb, 1);
        put32(shb, 0xFFFFFFFF);
        put32(shb, 0xFFFFFFFF);
        block(f, 0x0A0D0D0A, shb);
        std::vector<std::uint8_t> idb;
        put32(idb, 101);  // LINKTYPE_RAW
        put32(idb, 65535);
        block(f, 1, idb);
        const auto packet = mbscope::test::packet(
            true, 1, {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03});
        std::vector<std::uint8_t> epb;
        put32(epb, 0);
        put32(epb, 0);
        put32(epb, 1'000'000);
        put32(epb, static_cast<std::uint32_t>(packet.size()));
        put32(epb, static_cast<std::uint32_t>(packet.size()));
        epb.insert(epb.end(), packet.begin(), packet.end());
        block(f, 6, epb);
        if (blocks_between) {
            std::vector<std::uint8_t> nrb = {1, 0, 8, 0, 10, 0, 0, 2, 'p', 'l', 'c', 0};  // 10.0.0.2 "plc"
            put32(nrb, 0);                                                                // end of records
            block(f, 4, nrb);
            std::vector<std::uint8_t> isb;
            put32(isb, 0);
            put32(isb, 0);
            put32(isb, 2'000'000);
            block(f, 5, isb);
        }
        const std::size_t second_interface = f.size();
        std::vector<std::uint8_t> ethernet;
        put32(ethernet, 1);  // LINKTYPE_ETHERNET
        put32(ethernet, 65535);
        block(f, 1, ethernet);
        const auto o = analyse_stream(f);
        EXPECT_TRUE(o.opened);
        EXPECT_EQ(o.summary.packets, 1u);
        EXPECT_EQ(o.summary.frames, 1u);
        EXPECT_NE(o.error.find("stream: after 1 packets, an interface block at byte offset " +
                               std::to_string(second_interface) + ": "),
                  std::string::npos)
            << o.error;
        EXPECT_NE(o.error.find("split it by interface"), std::string::npos) << o.error;
    }
}

// "-" is standard input: a capture piped in (over ssh, out of an archive) decodes as the file does.
TEST(DamagedCapture, StandardInputDecodesAsTheFileDoes) {
    const std::string decode = std::string(MBSCOPE_BINARY) + " decode --summary ";
    const auto file = run(decode + sample);
    const auto piped = run("cat " + sample + " | " + decode + "-");
    EXPECT_EQ(piped.first, file.first) << piped.second;
    const auto summary = [](const std::string& out) { return out.substr(0, out.find('\n', 2)); };
    EXPECT_NE(summary(file.second).find("summary: 99 packets"), std::string::npos) << file.second;
    EXPECT_EQ(summary(piped.second), summary(file.second));
    const auto empty = run(decode + "- < /dev/null");
    EXPECT_EQ(empty.first, 2) << empty.second;
    EXPECT_NE(empty.second.find("-: empty file, nothing to decode"), std::string::npos) << empty.second;
}

// The wrong file handed over must not pass for a quiet network or line (exit 0, "0 frames"): a file named
// as a capture that holds none, a capture of no packets, bytes among which not one frame is found. Each is
// exit 2, with the file named and why.
TEST(DamagedCapture, TheWrongFileIsNotACleanDecode) {
    const auto dir = std::filesystem::path(::testing::TempDir());
    const auto write = [&](const std::string& name, const std::string& bytes) {
        const auto path = (dir / name).string();
        std::ofstream(path, std::ios::binary) << bytes;
        return path;
    };
    const std::string decode = std::string(MBSCOPE_BINARY) + " decode --no-progress ";
    std::string text;
    for (int i = 0; i < 10; ++i)
        text += "This is not a capture file\n";

    const auto named = write("mbscope-not-a-capture.pcap", text);
    const auto as_capture = run(decode + named);
    EXPECT_EQ(as_capture.first, 2) << as_capture.second;
    EXPECT_NE(as_capture.second.find(named + ": named as a capture, but its first bytes (54 68 69 73)"),
              std::string::npos)
        << as_capture.second;
    // Told to, it is read as asked (and finds nothing).
    EXPECT_EQ(run(decode + "--format rtu " + named).first, 2);

    const auto header = read_file(sample);
    const auto no_packets =
        write("mbscope-no-packets.pcap", std::string(header.begin(), header.begin() + 24));  // file header
    const auto empty = run(decode + no_packets);
    EXPECT_EQ(empty.first, 2) << empty.second;
    EXPECT_NE(empty.second.find(no_packets + ": the capture holds no packets, nothing to decode"),
              std::string::npos)
        << empty.second;

    const auto garbage = run(decode + write("mbscope-no-frames.bin", text));
    EXPECT_EQ(garbage.first, 2) << garbage.second;
    EXPECT_NE(garbage.second.find("no Modbus frame in the 270 bytes read"), std::string::npos)
        << garbage.second;
}

}  // namespace test_analyzer_damaged_capture_test
