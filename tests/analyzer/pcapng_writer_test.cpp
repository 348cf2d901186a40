// The pcapng writer (mbscope sniff --write FILE.pcapng) against two independent readers: libpcap, through
// the analyzer's CaptureSource, and tshark (skipped without it; capinfos names the format when present).
// Both must see the link types, bytes, lengths and timestamps written, to the nanosecond. Write errors are
// strings naming the file, never a crash.
#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include "analyzer/capture_source.hpp"
#include "analyzer/pcapng_end.hpp"
#include "analyzer/pcapng_writer.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_pcapng_writer_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;

namespace {

constexpr std::uint16_t link_user0 = 147;

struct Written {
    std::uint32_t interface;
    mb::Timestamp time;
    std::vector<std::uint8_t> data;
    std::uint32_t original_length;
};

// Two ports of a serial line as two USER0 interfaces (libpcap reads several interfaces of one link type),
// lengths that need padding or none, a sub-second part of 0, and a record cut short of its packet.
const std::vector<Written> packets = {
    {0, mb::Timestamp(1'700'000'000'123'456'789), bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45}), 8},
    {1, mb::Timestamp(1'700'000'000'130'000'001),
     bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA}), 11},
    {0, mb::Timestamp(1'700'000'001'000'000'000), bytes({0x11, 0x83, 0x02}), 3},
    {1, mb::Timestamp(1'700'000'001'999'999'999), bytes({0x11, 0x06, 0x00, 0x01}), 8},
};

// With `end`, the capture's end statistics too (and `dropped` on the first interface).
std::string write_file(const std::string& name, const std::vector<Written>& records,
                       std::uint16_t second_linktype = link_user0,
                       std::optional<mb::Timestamp> end = std::nullopt, std::uint64_t dropped = 0) {
    const std::string path = ::testing::TempDir() + name;
    an::PcapngWriter w;
    EXPECT_EQ(w.open(path), "");
    EXPECT_EQ(w.add_interface(link_user0, 65535, "/dev/ttyUSB0"), "");
    EXPECT_EQ(w.add_interface(second_linktype, 65535, "/dev/ttyUSB1"), "");
    EXPECT_EQ(w.interfaces(), 2u);
    for (const auto& r : records)
        EXPECT_EQ(w.write_packet(r.interface, r.time, r.data, r.original_length), "");
    if (end) {
        EXPECT_EQ(w.end_statistics(*end, dropped), "");
    }
    EXPECT_EQ(w.close(), "");
    return path;
}

}  // namespace

TEST(PcapngWriter, LibpcapReadsBackLinkTypesBytesAndNanoseconds) {
    const std::string path = write_file("writer_libpcap.pcapng", packets);
    std::string error;
    auto source = an::CaptureSource::open_file(path, error);
    ASSERT_TRUE(source) << error;
    EXPECT_EQ(source->linktype(), link_user0);
    for (const auto& want : packets) {
        const auto got = source->next();
        ASSERT_TRUE(got) << source->error();
        EXPECT_EQ(got->linktype, link_user0);
        EXPECT_FALSE(got->time_out_of_range);
        EXPECT_EQ(got->time, want.time);
        EXPECT_EQ(std::vector<std::uint8_t>(got->data.begin(), got->data.end()), want.data);
        EXPECT_EQ(got->original_length, want.original_length);
    }
    EXPECT_FALSE(source->next());
    EXPECT_EQ(source->error(), "");
    EXPECT_EQ(source->offset(), std::filesystem::file_size(path));
}

TEST(PcapngWriter, TsharkReadsTimesLengthsAndInterfaces) {
    if (!mbscope::test::have("tshark")) GTEST_SKIP() << "needs tshark";
    // Interfaces of two link types, which tshark takes and libpcap 1.10 does not: raw IP on the second.
    auto records = packets;
    records[1].data = mbscope::test::packet(true, 1000, bytes({0, 7, 0, 0, 0, 6, 0x11, 3, 0, 0x60, 0, 3}));
    records[1].original_length = static_cast<std::uint32_t>(records[1].data.size());
    const std::string path = write_file("writer_tshark.pcapng", records, mbscope::test::link_raw);
    const std::string err = path + ".err";
    const std::string out = mbscope::test::run(
        "tshark -r '" + path + "' -T fields -E separator=/t -e frame.time_epoch -e frame.len " +
        "-e frame.cap_len -e frame.interface_name -e frame.protocols 2>'" + err + "'; echo exit $?");
    EXPECT_EQ(out,
              "1700000000.123456789\t8\t8\t/dev/ttyUSB0\tuser_dlt:data\n"
              "1700000000.130000001\t52\t52\t/dev/ttyUSB1\traw:ip:tcp:mbtcp:modbus\n"
              "1700000001.000000000\t3\t3\t/dev/ttyUSB0\tuser_dlt:data\n"
              "1700000001.999999999\t8\t4\t/dev/ttyUSB1\traw\n"
              "exit 0\n")
        << mbscope::test::slurp(err);
    if (!mbscope::test::have("capinfos")) return;
    const std::string info = mbscope::test::run("capinfos -t '" + path + "'");
    EXPECT_NE(info.find("pcapng"), std::string::npos) << info;
}

// What the capture lost (sniff's kernel drops) is written as the first interface's isb_osdrop, as dumpcap
// writes it, and read back with the end; tshark reads the file as before. A decode of the file says so: the
// live run's input error was lost to it.
TEST(PcapngWriter, DroppedPacketsAreWrittenAndReadBack) {
    const std::string path = write_file("writer_drops.pcapng", packets, link_user0,
                                        mb::Timestamp(1'700'000'005'250'000'001), 0x1'0000'0007);
    std::uint64_t dropped = 0;
    EXPECT_EQ(an::pcapng_capture_end(path, packets.back().time, &dropped),
              mb::Timestamp(1'700'000'005'250'000'001));
    EXPECT_EQ(dropped, 0x1'0000'0007u);
    dropped = 0;
    (void)an::pcapng_capture_end(write_file("writer_no_drops.pcapng", packets), packets.back().time,
                                 &dropped);
    EXPECT_EQ(dropped, 0u);
    if (mbscope::test::have("tshark")) {
        const std::string out = mbscope::test::run("tshark -r '" + path + "' 2>&1 >/dev/null; echo exit $?");
        EXPECT_NE(out.find("exit 0"), std::string::npos) << out;
    }
}

// The capture's end, which no packet says, is an Interface Statistics Block per interface (isb_endtime):
// read back in the interfaces' resolution, passed over by libpcap and tshark. A file without one, not
// pcapng, or whose last block's length makes no sense has no end to tell.
TEST(PcapngWriter, TheCapturesEndIsWrittenAndReadBack) {
    const std::string path =
        write_file("writer_end.pcapng", packets, link_user0, mb::Timestamp(1'700'000'005'250'000'001));
    EXPECT_EQ(an::pcapng_capture_end(path, packets.back().time), mb::Timestamp(1'700'000'005'250'000'001));
    std::string error;
    auto source = an::CaptureSource::open_file(path, error);
    ASSERT_TRUE(source) << error;
    std::size_t read = 0;
    while (source->next())
        ++read;
    EXPECT_EQ(read, packets.size());
    EXPECT_EQ(source->error(), "");
    if (mbscope::test::have("tshark")) {
        const std::string out = mbscope::test::run("tshark -r '" + path + "' 2>&1 >/dev/null; echo exit $?");
        EXPECT_NE(out.find("exit 0"), std::string::npos) << out;
    }

    EXPECT_FALSE(an::pcapng_capture_end(write_file("writer_no_end.pcapng", packets), packets.back().time));
    EXPECT_FALSE(an::pcapng_capture_end(std::string(MBSCOPE_SOURCE_DIR) + "/captures/zeek-modbusSmall.pcap",
                                        mb::Timestamp(0)));
    EXPECT_FALSE(an::pcapng_capture_end(::testing::TempDir() + "no-such-file.pcapng", mb::Timestamp(0)));
    // The last block's trailing length pointing before the file's interfaces: nothing guessed.
    std::string bytes = mbscope::test::slurp(path);
    bytes[bytes.size() - 4] = '\xFF';
    bytes[bytes.size() - 3] = '\xFF';
    const std::string damaged = ::testing::TempDir() + "writer_end_damaged.pcapng";
    std::ofstream(damaged, std::ios::binary) << bytes;
    EXPECT_FALSE(an::pcapng_capture_end(damaged, packets.back().time));
}

// A microsecond interface (if_tsresol absent: 10^-6) in a big-endian section, as other writers make: the
// end is converted from the interface's ticks.
TEST(PcapngWriter, AnEndInMicrosecondsOfABigEndianSectionIsRead) {
    std::string f;
    const auto be32 = [&f](std::uint32_t v) {
        for (int i = 3; i >= 0; --i)
            f.push_back(static_cast<char>(v >> (8 * i)));
    };
    be32(0x0A0D0D0A), be32(28), be32(0x1A2B3C4D), be32(0x00010000), be32(0xFFFFFFFF), be32(0xFFFFFFFF),
        be32(28);
    be32(1), be32(20), be32(link_user0 << 16), be32(0), be32(20);  // no options: microseconds
    const std::uint64_t ticks = 1'700'000'003'000'000ull;          // microseconds
    be32(5), be32(40), be32(0), be32(0), be32(0);                  // statistics of interface 0
    be32(3 << 16 | 8), be32(static_cast<std::uint32_t>(ticks >> 32)), be32(static_cast<std::uint32_t>(ticks));
    be32(0), be32(40);
    const std::string path = ::testing::TempDir() + "writer_end_be.pcapng";
    std::ofstream(path, std::ios::binary) << f;
    EXPECT_EQ(an::pcapng_capture_end(path, mb::Timestamp(1'700'000'002'000'000'000)),
              mb::Timestamp(1'700'000'003'000'000'000));
}

// dumpcap (Wireshark 4.0) stamps its packets in nanoseconds (if_tsresol 9) and writes its statistics'
// times in microseconds: read in the interface's resolution the end falls in 1970, before every packet, and
// is read in microseconds instead, 3 s after the last packet of this capture of lo. An end that no reading
// puts at or after the last packet, or that lies more than a day after it, is none.
TEST(PcapngWriter, DumpcapsEndInMicrosecondsIsRead) {
    const std::string dumpcap = std::string(MBSCOPE_SOURCE_DIR) + "/captures/dumpcap-lo-and-any.pcapng";
    const mb::Timestamp last(1'796'479'478'169'385'721);  // capinfos: the last packet
    EXPECT_EQ(an::pcapng_capture_end(dumpcap, last), mb::Timestamp(1'796'479'481'465'790'000));
    EXPECT_FALSE(an::pcapng_capture_end(dumpcap, last + std::chrono::seconds(4)));
    EXPECT_FALSE(an::pcapng_capture_end(dumpcap, last - std::chrono::hours(25)));
}

// if_tsoffset (seconds added to an interface's times, as libpcap and tshark add them to its packets')
// applies to its end too.
TEST(PcapngWriter, AnInterfacesOffsetAppliesToItsEnd) {
    std::string f;
    const auto le32 = [&f](std::uint32_t v) {
        for (int i = 0; i < 4; ++i)
            f.push_back(static_cast<char>(v >> (8 * i)));
    };
    le32(0x0A0D0D0A), le32(28), le32(0x1A2B3C4D), le32(0x00000001), le32(0xFFFFFFFF), le32(0xFFFFFFFF),
        le32(28);
    const std::uint64_t offset = 1'700'000'000;
    le32(1), le32(36), le32(link_user0), le32(0);  // microseconds, if_tsoffset
    le32(14 | 8 << 16), le32(static_cast<std::uint32_t>(offset)),
        le32(static_cast<std::uint32_t>(offset >> 32));
    le32(0), le32(36);
    le32(5), le32(40), le32(0), le32(0), le32(0);  // statistics of interface 0: ended 3 s after the offset
    le32(3 | 8 << 16), le32(0), le32(3'000'000), le32(0), le32(40);
    const std::string path = ::testing::TempDir() + "writer_end_offset.pcapng";
    std::ofstream(path, std::ios::binary) << f;
    EXPECT_EQ(an::pcapng_capture_end(path, mb::Timestamp(1'700'000'001'000'000'000)),
              mb::Timestamp(1'700'000'003'000'000'000));
}

TEST(PcapngWriter, ErrorsNameTheFileAndNeverCrash) {
    an::PcapngWriter w;
    EXPECT_NE(w.write_packet(0, mb::Timestamp(0), bytes({1}), 1).find("not open"), std::string::npos);

    // A directory cannot be opened for writing.
    const std::string dir = ::testing::TempDir() + "writer_dir.pcapng";
    std::filesystem::create_directories(dir);
    const std::string opened = w.open(dir);
    EXPECT_NE(opened.find(dir + ": "), std::string::npos) << opened;
    EXPECT_FALSE(w.is_open());

    // Wrong arguments are refused, and the file stays good for the right ones.
    const std::string path = ::testing::TempDir() + "writer_args.pcapng";
    ASSERT_EQ(w.open(path), "");
    ASSERT_EQ(w.add_interface(link_user0, 4, "port"), "");
    EXPECT_NE(w.write_packet(1, mb::Timestamp(0), bytes({1}), 1).find(path + ": packet for interface 1"),
              std::string::npos);
    EXPECT_NE(w.write_packet(0, mb::Timestamp(-1), bytes({1}), 1).find("before 1970"), std::string::npos);
    EXPECT_NE(w.write_packet(0, mb::Timestamp(0), bytes({1, 2, 3, 4, 5}), 5).find("snapshot length"),
              std::string::npos);
    EXPECT_NE(w.add_interface(link_user0, 0, std::string(70000, 'x')).find("too long"), std::string::npos);
    EXPECT_EQ(w.write_packet(0, mb::Timestamp(1), bytes({1, 2, 3, 4}), 4), "");
    EXPECT_EQ(w.close(), "");
    std::string error;
    auto source = an::CaptureSource::open_file(path, error);
    ASSERT_TRUE(source) << error;
    EXPECT_TRUE(source->next());
    EXPECT_FALSE(source->next());
    EXPECT_EQ(source->error(), "");

    // A full disk: the first write that reaches it fails, and so does everything after.
    if (!std::filesystem::exists("/dev/full")) return;
    ASSERT_EQ(w.open("/dev/full"), "");  // the header is buffered
    std::string full = w.add_interface(link_user0, 0, "port");
    for (int i = 0; i < 1000 && full.empty(); ++i)
        full = w.write_packet(0, mb::Timestamp(i), std::vector<std::uint8_t>(1000, 0x55), 1000);
    if (full.empty()) full = w.flush();
    EXPECT_EQ(full, "/dev/full: " + std::string(std::strerror(ENOSPC)));
    EXPECT_EQ(w.write_packet(0, mb::Timestamp(0), bytes({1}), 1), full);
    EXPECT_EQ(w.close(), full);
    EXPECT_FALSE(w.is_open());
}

}  // namespace test_analyzer_pcapng_writer_test
