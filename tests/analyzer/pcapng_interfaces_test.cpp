// pcapng files whose interfaces libpcap 1.10 alone refuses to read together (different snapshot lengths,
// several raw-IP interfaces): the patch that levels them (analyzer/pcapng_interfaces.hpp) byte by byte,
// libpcap reading the result through CaptureSource from memory and from files, both byte orders, and
// mergecap's merges of captures taken with different snapshot lengths, and of raw-IP captures, decoding as
// the captures themselves do.
#include <gtest/gtest.h>

#include <pcap/dlt.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "analyzer/capture_source.hpp"
#include "analyzer/pcapng_interfaces.hpp"
#include "analyzer/pcapng_writer.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_pcapng_interfaces_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;

namespace {

constexpr std::uint16_t link_ethernet = 1;
constexpr std::uint16_t link_raw = mbscope::test::link_raw;  // LINKTYPE_RAW, as files have it
const auto ip_datagram = mbscope::test::packet(true, 0, bytes({0, 1, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1}), true);
std::vector<std::uint8_t> ethernet(const std::vector<std::uint8_t>& ip) {
    auto frame = bytes({0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 1, 0x08, 0x00});
    frame.insert(frame.end(), ip.begin(), ip.end());
    return frame;
}
const auto ethernet_frame = ethernet(ip_datagram);
const std::vector<std::uint8_t>& datagram(std::uint16_t link) {
    return link == link_raw ? ip_datagram : ethernet_frame;
}

// Written by the project's pcapng writer (little-endian): two interfaces of one link type, the first keeping
// 96 bytes of a packet, the second 65535, and a packet on each.
std::vector<std::uint8_t> two_interfaces(std::uint16_t link) {
    // Named after the test: CTest runs the tests of this file side by side.
    const std::string path = ::testing::TempDir() + "pcapng_interfaces_" +
                             ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
                             std::to_string(link) + ".pcapng";
    an::PcapngWriter w;
    EXPECT_EQ(w.open(path), "");
    EXPECT_EQ(w.add_interface(link, 96, "a"), "");
    EXPECT_EQ(w.add_interface(link, 65535, "b"), "");
    EXPECT_EQ(w.write_packet(0, mb::Timestamp(1'000'000'000), datagram(link), datagram(link).size()), "");
    EXPECT_EQ(w.write_packet(1, mb::Timestamp(2'000'000'000), datagram(link), datagram(link).size()), "");
    EXPECT_EQ(w.close(), "");
    const std::string written = mbscope::test::slurp(path);
    return {written.begin(), written.end()};
}

// The same blocks big-endian, built here: a section header, two interfaces (snapshot lengths 96 and
// 65535), an Enhanced Packet Block on each.
std::vector<std::uint8_t> two_interfaces_big_endian(std::uint16_t link) {
    std::vector<std::uint8_t> f;
    const auto u16 = [&f](std::uint16_t v) { f.insert(f.end(), {std::uint8_t(v >> 8), std::uint8_t(v)}); };
    const auto u32 = [&](std::uint32_t v) {
        u16(static_cast<std::uint16_t>(v >> 16));
        u16(static_cast<std::uint16_t>(v));
    };
    u32(0x0A0D0D0A), u32(28), u32(0x1A2B3C4D), u16(1), u16(0), u32(0xFFFFFFFF), u32(0xFFFFFFFF), u32(28);
    for (std::uint32_t snaplen : {96u, 65535u})
        u32(1), u32(20), u16(link), u16(0), u32(snaplen), u32(20);
    const auto& packet = datagram(link);
    for (std::uint32_t interface : {0u, 1u}) {
        const auto padded = (packet.size() + 3) & ~std::size_t{3};
        const auto total = static_cast<std::uint32_t>(32 + padded);
        u32(6), u32(total), u32(interface), u32(0), u32(1'000'000 * (interface + 1));  // microseconds
        u32(static_cast<std::uint32_t>(packet.size())), u32(static_cast<std::uint32_t>(packet.size()));
        f.insert(f.end(), packet.begin(), packet.end());
        f.resize(f.size() + padded - packet.size(), 0);
        u32(total);
    }
    return f;
}

// Every packet of a capture opened from memory or from a file, each expected to be `link`'s datagram;
// libpcap's link type for the capture in `linktype`.
std::size_t packets_read(std::unique_ptr<an::CaptureSource> source, std::uint16_t link, std::string& error,
                         int& linktype) {
    if (!source) return 0;
    linktype = source->linktype();
    std::size_t n = 0;
    while (auto p = source->next()) {
        EXPECT_EQ(std::vector<std::uint8_t>(p->data.begin(), p->data.end()), datagram(link));
        EXPECT_EQ(p->linktype, linktype);
        ++n;
    }
    error = source->error();
    return n;
}
std::size_t packets_read(const std::vector<std::uint8_t>& file, std::uint16_t link, std::string& error) {
    int linktype = 0;
    return packets_read(an::CaptureSource::open_memory(file, error), link, error, linktype);
}

// Offsets of the interface blocks in a little-endian file.
std::vector<std::size_t> interface_blocks(const std::vector<std::uint8_t>& little) {
    std::vector<std::size_t> at;
    for (std::size_t i = 0; i + 8 <= little.size();) {
        const std::uint32_t type = little[i] | little[i + 1] << 8 | little[i + 2] << 16 | little[i + 3] << 24;
        const std::uint32_t length =
            little[i + 4] | little[i + 5] << 8 | little[i + 6] << 16 | little[i + 7] << 24;
        if (type == 1) at.push_back(i);
        EXPECT_GE(length, 12u);
        if (length < 12) break;
        i += length;
    }
    return at;
}

// The interface blocks at `interfaces`: snapshot lengths 0, and a raw-IP link type DLT_RAW in the file's
// byte order; nothing else changed, whether the patch is given the file whole or in chunks of any size
// from 1 to 40.
void expect_levelled(std::vector<std::uint8_t> file, const std::vector<std::size_t>& interfaces,
                     bool big_endian) {
    const auto original = file;
    std::vector<std::uint8_t> expected = original;
    for (std::size_t at : interfaces) {
        std::fill_n(expected.begin() + static_cast<long>(at + 12), 4, 0);
        const std::size_t low = at + (big_endian ? 9 : 8);
        if (expected[low] == link_raw && expected[at + (big_endian ? 8 : 9)] == 0) expected[low] = DLT_RAW;
    }
    an::PcapngInterfacePatch whole;
    whole.pass(file);
    EXPECT_EQ(file, expected);
    for (std::size_t chunk = 1; chunk <= 40; ++chunk) {
        auto pieces = original;
        an::PcapngInterfacePatch patch;
        for (std::size_t at = 0; at < pieces.size(); at += chunk)
            patch.pass(std::span(pieces).subspan(at, std::min(chunk, pieces.size() - at)));
        ASSERT_EQ(pieces, expected) << "chunks of " << chunk;
    }
}

// `mbscope decode --jsonl` of the inputs: every record without its source and packet number, and the exit
// code.
std::vector<nlohmann::json> decode_records(const std::string& inputs) {
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
}

}  // namespace

TEST(PcapngInterfaces, LibpcapReadsInterfacesOfDifferentSnapshotLengths) {
    for (const auto& file : {two_interfaces(link_ethernet), two_interfaces_big_endian(link_ethernet)}) {
        std::string error;
        EXPECT_EQ(packets_read(file, link_ethernet, error), 2u);
        EXPECT_EQ(error, "");
    }
}

// Two tun interfaces: libpcap 1.10 alone stops at the second ("an interface has a type 101 different from
// the type of the first interface"), before the first packet.
TEST(PcapngInterfaces, LibpcapReadsSeveralRawIpInterfaces) {
    for (const auto& file : {two_interfaces(link_raw), two_interfaces_big_endian(link_raw)}) {
        std::string error;
        int linktype = 0;
        EXPECT_EQ(packets_read(an::CaptureSource::open_memory(file, error), link_raw, error, linktype), 2u);
        EXPECT_EQ(error, "");
        EXPECT_EQ(linktype, DLT_RAW);  // what libpcap makes of LINKTYPE_RAW, patched or not
    }
}

TEST(PcapngInterfaces, OnlySnapshotLengthsAndRawLinkTypesChange) {
    for (std::uint16_t link : {link_ethernet, link_raw}) {
        SCOPED_TRACE(link);
        // The writer's section header carries an option (shb_userappl "mbscope") and its interfaces a name
        // and a time resolution: the interface blocks are found by their type.
        const auto little = two_interfaces(link);
        const auto at = interface_blocks(little);
        ASSERT_EQ(at.size(), 2u);
        expect_levelled(little, at, false);
        expect_levelled(two_interfaces_big_endian(link), {28, 28 + 20}, true);
    }
}

// Little-endian, the link type's low byte comes first: it can be changed only when the high byte is known.
TEST(PcapngInterfaces, ALinkTypeWhoseBytesArePassedApartIsLeftAlone) {
    const auto file = two_interfaces(link_raw);
    const std::size_t second = interface_blocks(file).at(1);
    auto head = std::vector<std::uint8_t>(file.begin(), file.begin() + static_cast<long>(second + 9));
    auto tail = std::vector<std::uint8_t>(file.begin() + static_cast<long>(second + 9), file.end());
    an::PcapngInterfacePatch patch;
    patch.pass(head);
    EXPECT_EQ(patch.bytes_wanted(), 1u);
    patch.pass(tail);  // not next to the first byte in memory
    EXPECT_EQ(patch.bytes_wanted(), 0u);
    EXPECT_EQ(head[interface_blocks(file).at(0) + 8], DLT_RAW);  // the first interface: changed
    EXPECT_EQ(head[second + 8], link_raw);                       // the second: as it was
    EXPECT_EQ(tail[0], 0);
    EXPECT_EQ((std::vector<std::uint8_t>(tail.begin() + 3, tail.begin() + 7)), bytes({0, 0, 0, 0}));
}

// The stdio buffer's reads fall anywhere on an interface block: every position of a second raw-IP
// interface's header across the ends of the first three reads (the file's packets follow it), read from a
// file through CaptureSource as `mbscope decode` reads it.
TEST(PcapngInterfaces, AnInterfaceBlockIsLevelledWhereverAReadEnds) {
    const auto file = two_interfaces(link_raw);
    const auto at = interface_blocks(file);
    ASSERT_EQ(at.size(), 2u);
    const std::size_t before = at[1];  // the section header and the first interface
    // Custom blocks (type 0x40000BAD, a private enterprise number 0 and 0-12 bytes of data; libpcap skips
    // them), none over 28 bytes so that libpcap's reads stay within stdio's buffer, move the second
    // interface on.
    const auto custom = [](std::size_t length) {
        auto block = bytes({0xAD, 0x0B, 0, 0x40, static_cast<int>(length), 0, 0, 0, 0, 0, 0, 0});
        block.resize(length - 4, 0);
        block.insert(block.end(), {static_cast<std::uint8_t>(length), 0, 0, 0});
        return block;
    };
    // stdio asks for 64 KiB at a time, of which the reader keeps room for the bytes that complete a header
    // (PcapngInterfacePatch::most_wanted): when nothing is completed, its reads end at multiples of this.
    constexpr std::size_t read = 65536 - an::PcapngInterfacePatch::most_wanted;
    for (std::size_t boundary : {read, 2 * read, 3 * read}) {
        for (std::size_t second = boundary - 24; second <= boundary + 8; second += 4) {
            std::vector<std::uint8_t> moved(file.begin(), file.begin() + static_cast<long>(before));
            const std::size_t padding = second - before;
            for (std::size_t n = 1; n < padding / 16; ++n) {
                const auto block = custom(16);
                moved.insert(moved.end(), block.begin(), block.end());
            }
            const auto last = custom(16 + padding % 16);
            moved.insert(moved.end(), last.begin(), last.end());
            moved.insert(moved.end(), file.begin() + static_cast<long>(before), file.end());
            ASSERT_EQ(interface_blocks(moved).at(1), second);
            const auto path = mbscope::test::write_temp("pcapng_interfaces_moved.pcapng", moved);
            std::string error;
            int linktype = 0;
            SCOPED_TRACE(second);
            EXPECT_EQ(packets_read(an::CaptureSource::open_file(path, error), link_raw, error, linktype), 2u);
            EXPECT_EQ(error, "");
        }
    }
}

TEST(PcapngInterfaces, ClassicPcapAndBrokenBlocksAreLeftAlone) {
    // A classic pcap file: nothing to level, nothing changed.
    auto classic = mbscope::test::pcap_file(link_raw, {{mb::Timestamp(1), ip_datagram}});
    const auto classic_before = classic;
    an::PcapngInterfacePatch().pass(classic);
    EXPECT_EQ(classic, classic_before);
    // A section header type followed by no byte-order magic: not pcapng, left alone, though its bytes 8-9
    // read as LINKTYPE_RAW.
    auto not_pcapng = bytes({0x0A, 0x0D, 0x0D, 0x0A, 20, 0, 0, 0, 101, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF});
    const auto not_pcapng_before = not_pcapng;
    an::PcapngInterfacePatch().pass(not_pcapng);
    EXPECT_EQ(not_pcapng, not_pcapng_before);
    // A second interface block whose length is not a multiple of four: the patch stops before it, and
    // libpcap reports the damage where it is.
    auto broken = two_interfaces_big_endian(link_raw);
    broken[28 + 20 + 7] = 21;
    auto patched = broken;
    an::PcapngInterfacePatch().pass(patched);
    EXPECT_EQ(patched[28 + 12 + 3], 0);          // the first interface's snapshot length: levelled
    EXPECT_EQ(patched[28 + 9], DLT_RAW);         // and its link type
    EXPECT_EQ(patched[28 + 20 + 12 + 3], 0xFF);  // the broken block: untouched
    EXPECT_EQ(patched[28 + 20 + 9], link_raw);
    std::string error;
    packets_read(broken, link_raw, error);
    EXPECT_NE(error, "");
}

// mergecap (and Wireshark's File > Merge) keeps each input's interface, with its snapshot length: a merge
// of captures taken with 65535 and 262144 was refused whole ("an interface has a snapshot length 262144
// different from the snapshot length of the first interface", packet 1, nothing decoded).
TEST(PcapngInterfaces, MergecapsMergeOfCapturesWithDifferentSnapshotLengthsDecodes) {
    if (!mbscope::test::have("mergecap")) GTEST_SKIP() << "mergecap not installed";
    const std::string captures = std::string(MBSCOPE_SOURCE_DIR) + "/../shared/captures/zeek__zeek/";
    std::string files;
    for (const char* f : {"modbus-and-non-modbus-p502.pcap", "modbusSmall.pcap", "modbus-eit.pcap"})
        files += " '" + captures + f + "'";
    const std::string merged = ::testing::TempDir() + "pcapng_interfaces_merged.pcapng";
    ASSERT_EQ(std::system(("mergecap -F pcapng -w '" + merged + "'" + files).c_str()), 0);
    const auto ours = decode_records(files);
    ASSERT_GT(ours.size(), 10u);
    EXPECT_EQ(decode_records("'" + merged + "'"), ours);
}

// Raw-IP captures, one of each direction (as two tun interfaces give them), merged by mergecap into one
// pcapng file of two raw-IP interfaces: refused whole before ("an interface has a type 101 different from
// the type of the first interface").
TEST(PcapngInterfaces, MergecapsMergeOfRawIpCapturesDecodes) {
    if (!mbscope::test::have("mergecap")) GTEST_SKIP() << "mergecap not installed";
    const auto c = mbscope::test::five_reads();
    std::vector<mbscope::test::PcapRecord> requests, responses;
    for (std::size_t i = 0; i < c.records.size(); ++i)
        (i % 2 == 0 ? requests : responses).push_back(c.records[i]);
    std::string named;
    for (const auto& [name, records] : {std::pair{"requests", requests}, std::pair{"responses", responses}}) {
        named += " '" +
                 mbscope::test::write_temp("pcapng_interfaces_" + std::string(name) + ".pcap",
                                           mbscope::test::pcap_file(link_raw, records)) +
                 "'";
    }
    const std::string merged = ::testing::TempDir() + "pcapng_interfaces_raw.pcapng";
    ASSERT_EQ(std::system(("mergecap -F pcapng -w '" + merged + "'" + named).c_str()), 0);
    const auto ours = decode_records(named);
    ASSERT_EQ(std::count_if(ours.begin(), ours.end(),
                            [](const nlohmann::json& j) {
                                return j.is_object() && j.value("type", "") == "transaction";
                            }),
              5);
    EXPECT_EQ(ours.back(), "exit=0");
    EXPECT_EQ(decode_records("'" + merged + "'"), ours);
}

}  // namespace test_analyzer_pcapng_interfaces_test
