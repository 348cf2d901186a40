// pcapng files whose interfaces differ in snapshot length, which libpcap 1.10 alone refuses: the patch that
// levels them (analyzer/pcapng_snaplen.hpp) byte by byte, libpcap reading the result through
// CaptureSource, both byte orders, and mergecap's merge of captures taken with different snapshot lengths
// decoding as the captures themselves do.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "analyzer/capture_source.hpp"
#include "analyzer/pcapng_snaplen.hpp"
#include "analyzer/pcapng_writer.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;

namespace {

// Ethernet, not raw IP: libpcap 1.10 compares a second interface's LINKTYPE_RAW (101) with the first one's
// DLT_RAW (12) and refuses raw-IP files of several interfaces whatever their snapshot lengths.
constexpr std::uint16_t link_ethernet = 1;
std::vector<std::uint8_t> ethernet(const std::vector<std::uint8_t>& ip) {
    auto frame = bytes({0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 1, 0x08, 0x00});
    frame.insert(frame.end(), ip.begin(), ip.end());
    return frame;
}
const auto datagram =
    ethernet(mbscope::test::packet(true, 0, bytes({0, 1, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1}), true));

// Written by the project's pcapng writer (little-endian): two Ethernet interfaces, the first keeping 96
// bytes of a packet, the second 65535, and a packet on each.
std::vector<std::uint8_t> two_snaplens() {
    const std::string path = ::testing::TempDir() + "pcapng_snaplen_two.pcapng";
    an::PcapngWriter w;
    EXPECT_EQ(w.open(path), "");
    EXPECT_EQ(w.add_interface(link_ethernet, 96, "a"), "");
    EXPECT_EQ(w.add_interface(link_ethernet, 65535, "b"), "");
    EXPECT_EQ(w.write_packet(0, mb::Timestamp(1'000'000'000), datagram, datagram.size()), "");
    EXPECT_EQ(w.write_packet(1, mb::Timestamp(2'000'000'000), datagram, datagram.size()), "");
    EXPECT_EQ(w.close(), "");
    const std::string written = mbscope::test::slurp(path);
    return {written.begin(), written.end()};
}

// The same blocks big-endian, built here: a section header, two interfaces (snapshot lengths 96 and
// 65535), an Enhanced Packet Block on each.
std::vector<std::uint8_t> two_snaplens_big_endian() {
    std::vector<std::uint8_t> f;
    const auto u16 = [&f](std::uint16_t v) { f.insert(f.end(), {std::uint8_t(v >> 8), std::uint8_t(v)}); };
    const auto u32 = [&](std::uint32_t v) {
        u16(static_cast<std::uint16_t>(v >> 16));
        u16(static_cast<std::uint16_t>(v));
    };
    u32(0x0A0D0D0A), u32(28), u32(0x1A2B3C4D), u16(1), u16(0), u32(0xFFFFFFFF), u32(0xFFFFFFFF), u32(28);
    for (std::uint32_t snaplen : {96u, 65535u})
        u32(1), u32(20), u16(link_ethernet), u16(0), u32(snaplen), u32(20);
    for (std::uint32_t interface : {0u, 1u}) {
        const auto padded = (datagram.size() + 3) & ~std::size_t{3};
        const auto total = static_cast<std::uint32_t>(32 + padded);
        u32(6), u32(total), u32(interface), u32(0), u32(1'000'000 * (interface + 1));  // microseconds
        u32(static_cast<std::uint32_t>(datagram.size())), u32(static_cast<std::uint32_t>(datagram.size()));
        f.insert(f.end(), datagram.begin(), datagram.end());
        f.resize(f.size() + padded - datagram.size(), 0);
        u32(total);
    }
    return f;
}

std::size_t packets_read(const std::vector<std::uint8_t>& file, std::string& error) {
    auto source = an::CaptureSource::open_memory(file, error);
    if (!source) return 0;
    std::size_t n = 0;
    while (auto p = source->next()) {
        EXPECT_EQ(std::vector<std::uint8_t>(p->data.begin(), p->data.end()), datagram);
        ++n;
    }
    error = source->error();
    return n;
}

// Offsets of the interface blocks' snapshot lengths in the files above (after a 28- or 36-byte section
// header, each interface block 20 bytes in the hand-made file).
void expect_levelled(std::vector<std::uint8_t> file, const std::vector<std::size_t>& snaplen_at) {
    const auto original = file;
    an::PcapngSnaplenPatch whole;
    whole.pass(file);
    std::vector<std::uint8_t> expected = original;
    for (std::size_t at : snaplen_at)
        std::fill(expected.begin() + static_cast<long>(at), expected.begin() + static_cast<long>(at) + 4, 0);
    EXPECT_EQ(file, expected);
    // In chunks of every size from 1 to 40: the same bytes, however the reads fall.
    for (std::size_t chunk = 1; chunk <= 40; ++chunk) {
        auto pieces = original;
        an::PcapngSnaplenPatch patch;
        for (std::size_t at = 0; at < pieces.size(); at += chunk)
            patch.pass(std::span(pieces).subspan(at, std::min(chunk, pieces.size() - at)));
        ASSERT_EQ(pieces, expected) << "chunks of " << chunk;
    }
}

}  // namespace

TEST(PcapngSnaplen, LibpcapReadsInterfacesOfDifferentSnapshotLengths) {
    for (const auto& file : {two_snaplens(), two_snaplens_big_endian()}) {
        std::string error;
        EXPECT_EQ(packets_read(file, error), 2u);
        EXPECT_EQ(error, "");
    }
}

TEST(PcapngSnaplen, OnlyTheSnapshotLengthsChange) {
    const auto little = two_snaplens();
    // The writer's section header carries an option (shb_userappl "mbscope": 4 + 8 bytes, and the end
    // of options) and its interfaces a name and a time resolution: find the interface blocks by their type.
    std::vector<std::size_t> at;
    for (std::size_t i = 0; i + 8 <= little.size();) {
        const std::uint32_t type = little[i] | little[i + 1] << 8 | little[i + 2] << 16 | little[i + 3] << 24;
        const std::uint32_t length =
            little[i + 4] | little[i + 5] << 8 | little[i + 6] << 16 | little[i + 7] << 24;
        if (type == 1) at.push_back(i + 12);
        ASSERT_GE(length, 12u);
        i += length;
    }
    ASSERT_EQ(at.size(), 2u);
    expect_levelled(little, at);
    expect_levelled(two_snaplens_big_endian(), {28 + 12, 28 + 20 + 12});
}

TEST(PcapngSnaplen, ClassicPcapAndBrokenBlocksAreLeftAlone) {
    // A classic pcap file: nothing to level, nothing changed.
    auto classic = mbscope::test::pcap_file(mbscope::test::link_raw, {{mb::Timestamp(1), datagram}});
    const auto classic_before = classic;
    an::PcapngSnaplenPatch().pass(classic);
    EXPECT_EQ(classic, classic_before);
    // A second interface block whose length is not a multiple of four: the patch stops before it, and
    // libpcap reports the damage where it is.
    auto broken = two_snaplens_big_endian();
    broken[28 + 20 + 7] = 21;
    auto patched = broken;
    an::PcapngSnaplenPatch().pass(patched);
    EXPECT_EQ(patched[28 + 12 + 3], 0);          // the first interface's snapshot length: levelled
    EXPECT_EQ(patched[28 + 20 + 12 + 3], 0xFF);  // the broken block: untouched
    std::string error;
    packets_read(broken, error);
    EXPECT_NE(error, "");
}

// mergecap (and Wireshark's File > Merge) keeps each input's interface, with its snapshot length: a merge
// of captures taken with 65535 and 262144 was refused whole ("an interface has a snapshot length 262144
// different from the snapshot length of the first interface", packet 1, nothing decoded).
TEST(PcapngSnaplen, MergecapsMergeOfCapturesWithDifferentSnapshotLengthsDecodes) {
    if (!mbscope::test::have("mergecap")) GTEST_SKIP() << "mergecap not installed";
    const std::string captures = std::string(MBSCOPE_SOURCE_DIR) + "/../shared/captures/zeek__zeek/";
    std::string files;
    for (const char* f : {"modbus-and-non-modbus-p502.pcap", "modbusSmall.pcap", "modbus-eit.pcap"})
        files += " '" + captures + f + "'";
    const std::string merged = ::testing::TempDir() + "pcapng_snaplen_merged.pcapng";
    ASSERT_EQ(std::system(("mergecap -F pcapng -w '" + merged + "'" + files).c_str()), 0);
    const auto decode = [](const std::string& inputs) {
        std::vector<nlohmann::json> out;
        std::istringstream in(
            mbscope::test::run(std::string(MBSCOPE_BINARY) + " decode --jsonl " + inputs + "; echo exit=$?"));
        for (std::string line; std::getline(in, line);) {
            if (line.rfind("exit=", 0) == 0) {
                out.push_back(line);
                continue;
            }
            auto j = nlohmann::json::parse(line);
            j.erase("source");
            j.erase("packet");
            out.push_back(std::move(j));
        }
        return out;
    };
    const auto theirs = decode("'" + merged + "'");
    const auto ours = decode(files);
    ASSERT_GT(ours.size(), 10u);
    EXPECT_EQ(theirs, ours);
}
