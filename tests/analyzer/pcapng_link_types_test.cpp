// pcapng files whose interfaces are of several link types, which libpcap 1.10 refuses to read as one ("an
// interface has a type 113 different from the type of the first interface"): dumpcap capturing on loopback
// and on "any" at once, mergecap's merge of an Ethernet and a raw-IP capture, files written here in both byte
// orders with every kind of packet block. They are read once per link type (analyzer/pcapng_interfaces.hpp)
// and the passes merged by their place in the file: checked against tshark, which reads such files, against
// the same packets decoded from separate files, and for damage that only one pass meets.
#include <gtest/gtest.h>

#include <pcap/dlt.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "analyzer/capture_source.hpp"
#include "analyzer/pcapng_interfaces.hpp"
#include "analyzer/pcapng_writer.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_pcapng_link_types_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;
using mbscope::test::link_raw;  // LINKTYPE_RAW, as files have it

namespace {

constexpr std::uint16_t link_ethernet = 1, link_sll = 113;  // Linux cooked capture v1

// An IPv4 datagram carrying a Modbus/TCP request with transaction id `tid`, and the same in an Ethernet
// frame.
std::vector<std::uint8_t> datagram(std::uint16_t tid) {
    return mbscope::test::packet(true, tid, bytes({0, tid, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1}));
}
std::vector<std::uint8_t> in_ethernet(const std::vector<std::uint8_t>& ip) {
    auto frame = bytes({0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 1, 0x08, 0x00});
    frame.insert(frame.end(), ip.begin(), ip.end());
    return frame;
}
std::vector<std::uint8_t> framed(std::uint16_t link, std::uint16_t tid) {
    return link == link_raw ? datagram(tid) : in_ethernet(datagram(tid));
}

std::string temp_path(const std::string& what) {
    return ::testing::TempDir() + "pcapng_link_types_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" + what;
}

struct Written {
    std::uint32_t interface;
    std::uint16_t tid;  // the packet's transaction id; its time is tid seconds
};

// A little-endian file written by the project's pcapng writer: interfaces of `links`, then `packets`.
std::vector<std::uint8_t> written(const std::vector<std::uint16_t>& links,
                                  const std::vector<Written>& packets) {
    const std::string path = temp_path("written.pcapng");
    an::PcapngWriter w;
    EXPECT_EQ(w.open(path), "");
    for (const auto link : links)
        EXPECT_EQ(w.add_interface(link, 65535, "if"), "");
    for (const auto& p : packets) {
        const auto data = framed(links.at(p.interface), p.tid);
        EXPECT_EQ(w.write_packet(p.interface, mb::Timestamp(std::int64_t{p.tid} * 1'000'000'000), data,
                                 static_cast<std::uint32_t>(data.size())),
                  "");
    }
    EXPECT_EQ(w.close(), "");
    const std::string file = mbscope::test::slurp(path);
    return {file.begin(), file.end()};
}

// The offsets of a little-endian file's blocks.
std::vector<std::size_t> blocks(const std::vector<std::uint8_t>& f) {
    std::vector<std::size_t> at;
    for (std::size_t i = 0; i + 8 <= f.size();) {
        at.push_back(i);
        const std::uint32_t length = f[i + 4] | f[i + 5] << 8 | f[i + 6] << 16 | f[i + 7] << 24;
        if (length < 12) break;
        i += length;
    }
    return at;
}

// A little-endian custom block (type 0x40000BAD, which libpcap skips) `length` bytes long.
std::vector<std::uint8_t> custom_block(std::size_t length) {
    auto block = bytes({0xAD, 0x0B, 0, 0x40});
    for (int shift : {0, 8, 16, 24})
        block.push_back(static_cast<std::uint8_t>(length >> shift));
    block.resize(length - 4, 0);
    for (int shift : {0, 8, 16, 24})
        block.push_back(static_cast<std::uint8_t>(length >> shift));
    return block;
}

struct Read {
    std::uint64_t number;
    int linktype;
    std::uint16_t tid;  // from the packet's time
    bool data_as_written;
};

// Every packet of `source` (each checked against what its interface's link type frames), and its error.
std::vector<Read> read_all(std::unique_ptr<an::CaptureSource> source, std::string& error) {
    std::vector<Read> out;
    if (!source) return out;
    std::uint64_t offset = 0;
    while (auto p = source->next()) {
        const auto tid = static_cast<std::uint16_t>(p->time.count() / 1'000'000'000);
        const std::uint16_t link =
            p->linktype == DLT_RAW ? link_raw : static_cast<std::uint16_t>(p->linktype);
        const auto expected = framed(link, tid);
        out.push_back({p->number, p->linktype, tid,
                       std::vector<std::uint8_t>(p->data.begin(), p->data.end()) == expected});
        EXPECT_GT(source->offset(), offset) << "packet " << p->number;  // the file's order
        offset = source->offset();
    }
    error = source->error();
    return out;
}

bool operator==(const Read& a, const Read& b) {
    return a.number == b.number && a.linktype == b.linktype && a.tid == b.tid &&
           a.data_as_written == b.data_as_written;
}
std::ostream& operator<<(std::ostream& os, const Read& r) {
    return os << "{packet " << r.number << ", link " << r.linktype << ", tid " << r.tid
              << (r.data_as_written ? "" : ", data changed") << "}";
}

// What libpcap reports for a file's link type.
int dlt(std::uint16_t link) {
    return link == link_raw ? DLT_RAW : link;
}

// Read from memory and from a file (read ahead by a thread of its own): the same packets and error.
std::vector<Read> read_both_ways(const std::vector<std::uint8_t>& file, std::string& error) {
    std::string memory_error;
    const auto from_memory = read_all(an::CaptureSource::open_memory(file, memory_error), memory_error);
    const std::string path = mbscope::test::write_temp(
        std::string("pcapng_link_types_") + ::testing::UnitTest::GetInstance()->current_test_info()->name() +
            ".pcapng",
        file);
    const auto from_file = read_all(an::CaptureSource::open_file(path, error, "capture"), error);
    EXPECT_EQ(from_memory, from_file);
    EXPECT_EQ(memory_error.empty(), error.empty()) << memory_error << " / " << error;
    const std::string prefix = "capture: ";
    if (error.starts_with(prefix)) {
        EXPECT_EQ("memory: " + error.substr(prefix.size()), memory_error);
    }
    return from_file;
}

}  // namespace

// Three interfaces, two link types, packets written out of time order as dumpcap writes each interface's
// buffer in turn: numbered in the file's order, each with its own interface's link type and bytes.
TEST(PcapngLinkTypes, PacketsComeInTheFilesOrderEachWithItsInterfacesLinkType) {
    const auto file =
        written({link_ethernet, link_raw, link_ethernet}, {{0, 5}, {1, 1}, {2, 4}, {1, 2}, {0, 3}, {1, 6}});
    std::string error;
    const auto read = read_both_ways(file, error);
    EXPECT_EQ(error, "");
    const int e = dlt(link_ethernet), r = dlt(link_raw);
    EXPECT_EQ(read, (std::vector<Read>{{1, e, 5, true},
                                       {2, r, 1, true},
                                       {3, e, 4, true},
                                       {4, r, 2, true},
                                       {5, e, 3, true},
                                       {6, r, 6, true}}));
}

// A pass's patch, byte for byte: the other link type's interface is written as the kept one, the packet
// blocks on it carry the local-use bit of their type, every interface's snapshot length is levelled, and
// nothing else changes; the same whether the file is passed whole or in chunks of 1 to 40 bytes of the
// same memory (a header's first bytes then lie in an earlier chunk).
TEST(PcapngLinkTypes, APassHidesTheOtherLinkTypesPacketBlocksAndNothingElse) {
    const auto file = written({link_ethernet, link_raw}, {{0, 1}, {1, 2}, {1, 3}, {0, 4}});
    const auto at = blocks(file);
    ASSERT_EQ(at.size(), 7u);  // section, two interfaces, four packets
    const std::vector<std::uint16_t> known{link_ethernet, static_cast<std::uint16_t>(dlt(link_raw))};
    for (const std::uint16_t kept : known) {
        SCOPED_TRACE(kept);
        auto expected = file;
        for (const std::size_t interface : {at[1], at[2]}) {
            expected[interface + 8] = static_cast<std::uint8_t>(kept);  // little-endian, under 256
            std::fill_n(expected.begin() + static_cast<long>(interface + 12), 4, 0);
        }
        for (const std::size_t packet :
             kept == link_ethernet ? std::vector{at[4], at[5]} : std::vector{at[3], at[6]})
            expected[packet + 3] |= 0x80;
        for (std::size_t chunk = 1; chunk <= 40; ++chunk) {
            auto pieces = file;
            an::PcapngInterfacePatch patch;
            patch.keep_only(kept, known);
            for (std::size_t from = 0; from < pieces.size(); from += chunk)
                patch.pass(std::span(pieces).subspan(from, std::min(chunk, pieces.size() - from)));
            ASSERT_EQ(pieces, expected) << "chunks of " << chunk;
            EXPECT_EQ(patch.link_types(), known);
        }
    }
}

// Big-endian, with a Simple Packet Block (on interface 0, no interface field) and an Obsolete Packet Block
// (its interface in 16 bits) among Enhanced ones.
TEST(PcapngLinkTypes, SimpleAndObsoletePacketBlocksBigEndian) {
    std::vector<std::uint8_t> f;
    const auto u16 = [&f](std::uint16_t v) { f.insert(f.end(), {std::uint8_t(v >> 8), std::uint8_t(v)}); };
    const auto u32 = [&](std::uint32_t v) {
        u16(static_cast<std::uint16_t>(v >> 16));
        u16(static_cast<std::uint16_t>(v));
    };
    const auto data = [&f](const std::vector<std::uint8_t>& d) {
        f.insert(f.end(), d.begin(), d.end());
        f.resize(f.size() + ((d.size() + 3) & ~std::size_t{3}) - d.size(), 0);
    };
    const auto padded = [](std::size_t n) { return static_cast<std::uint32_t>((n + 3) & ~std::size_t{3}); };
    u32(0x0A0D0D0A), u32(28), u32(0x1A2B3C4D), u16(1), u16(0), u32(0xFFFFFFFF), u32(0xFFFFFFFF), u32(28);
    for (const std::uint16_t link :
         {std::uint16_t{link_raw}, link_ethernet})  // interface 0 raw IP, 1 Ethernet
        u32(1), u32(20), u16(link), u16(0), u32(65535), u32(20);
    // Interface 1, tid 1 (an Obsolete Packet Block's time is in microseconds, as its interface's default).
    const auto opb = framed(link_ethernet, 1);
    const std::uint32_t opb_length = 32 + padded(opb.size());
    u32(2), u32(opb_length), u16(1), u16(0), u32(0), u32(1'000'000);
    u32(static_cast<std::uint32_t>(opb.size())), u32(static_cast<std::uint32_t>(opb.size())), data(opb);
    u32(opb_length);
    // Interface 0, no time: a Simple Packet Block has none.
    const auto spb = framed(link_raw, 0);
    const std::uint32_t spb_length = 16 + padded(spb.size());
    u32(3), u32(spb_length), u32(static_cast<std::uint32_t>(spb.size())), data(spb), u32(spb_length);
    // Interface 0 and 1, Enhanced, tids 2 and 3.
    for (const auto& [interface, tid] : {std::pair{0u, 2}, std::pair{1u, 3}}) {
        const auto epb = framed(interface == 0 ? link_raw : link_ethernet, static_cast<std::uint16_t>(tid));
        const std::uint32_t length = 32 + padded(epb.size());
        u32(6), u32(length), u32(interface), u32(0), u32(static_cast<std::uint32_t>(tid) * 1'000'000);
        u32(static_cast<std::uint32_t>(epb.size())), u32(static_cast<std::uint32_t>(epb.size())), data(epb);
        u32(length);
    }
    std::string error;
    const auto read = read_both_ways(f, error);
    EXPECT_EQ(error, "");
    const int e = dlt(link_ethernet), r = dlt(link_raw);
    EXPECT_EQ(read, (std::vector<Read>{{1, e, 1, true}, {2, r, 0, true}, {3, r, 2, true}, {4, e, 3, true}}));
}

// Wherever stdio's reads of the file end on a packet block's first twelve bytes (type, length, interface),
// the block is hidden from the pass that does not keep it: a custom block (libpcap skips it) moves the third
// packet's block across the end of the first read.
TEST(PcapngLinkTypes, APacketBlockIsHiddenWhereverAReadEnds) {
    const auto file = written({link_ethernet, link_raw}, {{0, 1}, {1, 2}, {1, 3}, {0, 4}});
    const auto at = blocks(file);
    ASSERT_EQ(at.size(), 7u);  // section, two interfaces, four packets
    const std::size_t third = at[5];
    const int e = dlt(link_ethernet), r = dlt(link_raw);
    const std::vector<Read> expected{{1, e, 1, true}, {2, r, 2, true}, {3, r, 3, true}, {4, e, 4, true}};
    for (std::size_t moved_to = 65536 - 48; moved_to <= 65536 + 8; moved_to += 4) {
        const auto custom = custom_block(moved_to - third);
        std::vector<std::uint8_t> f(file.begin(), file.begin() + static_cast<long>(third));
        f.insert(f.end(), custom.begin(), custom.end());
        f.insert(f.end(), file.begin() + static_cast<long>(third), file.end());
        ASSERT_EQ(blocks(f).at(6), moved_to);
        SCOPED_TRACE(moved_to);
        std::string error;
        EXPECT_EQ(read_both_ways(f, error), expected);
        EXPECT_EQ(error, "");
    }
}

// An interface described after packets, as a writer that describes each interface when its first packet
// comes does: read with the others (it is among the first bytes, which are looked at before reading).
TEST(PcapngLinkTypes, AnInterfaceDescribedAfterPacketsIsRead) {
    const auto first = written({link_ethernet, link_raw}, {{0, 1}, {1, 2}});
    const auto later = written({link_ethernet, link_raw, link_sll}, {{2, 3}, {0, 4}});
    auto f = first;
    f.insert(f.end(), later.begin() + static_cast<long>(blocks(later)[3]), later.end());
    std::string error;
    const auto read = read_both_ways(f, error);
    EXPECT_EQ(read, (std::vector<Read>{{1, dlt(link_ethernet), 1, true},
                                       {2, dlt(link_raw), 2, true},
                                       {3, link_sll, 3, true},
                                       {4, dlt(link_ethernet), 4, true}}));
    EXPECT_EQ(error, "");
}

// Interfaces of new link types beyond the first bytes (a custom block of 70,000 bytes before them): libpcap
// refuses the first, the file is read again in a pass per link type met, the packets handed out already
// skipped; then again at the next. Every packet once, in the file's order, numbered as in the file.
TEST(PcapngLinkTypes, AnInterfaceBeyondTheFirstBytesIsReadByReadingTheFileAgain) {
    const auto parts =
        written({link_ethernet, link_raw, link_sll}, {{0, 1}, {1, 2}, {0, 3}, {2, 4}, {0, 5}, {1, 6}});
    const auto at = blocks(parts);
    ASSERT_EQ(at.size(), 10u);  // section, three interfaces, six packets
    const auto piece = [&parts, &at](std::size_t from, std::size_t to) {
        return std::vector<std::uint8_t>(
            parts.begin() + static_cast<long>(at[from]),
            to < at.size() ? parts.begin() + static_cast<long>(at[to]) : parts.end());
    };
    std::vector<std::uint8_t> f;
    for (const auto& p : {piece(0, 2), piece(4, 5), custom_block(70'000), piece(2, 3), piece(5, 7),
                          piece(3, 4), piece(7, 10)})
        f.insert(f.end(), p.begin(), p.end());
    std::string error;
    const auto read = read_both_ways(f, error);
    const int e = dlt(link_ethernet), r = dlt(link_raw);
    EXPECT_EQ(read, (std::vector<Read>{{1, e, 1, true},
                                       {2, r, 2, true},
                                       {3, e, 3, true},
                                       {4, link_sll, 4, true},
                                       {5, e, 5, true},
                                       {6, r, 6, true}}));
    EXPECT_EQ(error, "");
}

// A file is read in at most eight passes (each a reading of the whole file, and a thread): one of nine link
// types is refused as libpcap refuses it, at its second interface, before its packet.
TEST(PcapngLinkTypes, NineLinkTypesAreRefused) {
    const std::vector<std::uint16_t> nine{link_ethernet, link_raw, link_sll, 276, 0, 108, 228, 229, 147};
    for (const std::size_t n : {8u, 9u}) {
        const std::vector<std::uint16_t> links(nine.begin(), nine.begin() + static_cast<long>(n));
        std::string error;
        const auto read = read_both_ways(written(links, {{0, 1}}), error);
        SCOPED_TRACE(n);
        if (n == 8) {
            EXPECT_EQ(read, (std::vector<Read>{{1, dlt(link_ethernet), 1, true}}));
            EXPECT_EQ(error, "");
        } else {
            EXPECT_TRUE(read.empty());
            EXPECT_TRUE(error.starts_with("capture: after 0 packets, an interface block at byte offset "))
                << error;
        }
    }
}

// A packet block only one pass reads is damaged (its captured length runs past the block): the other pass's
// packets before it come first, then the error names the packet by its number in the file and the block's
// offset, and nothing after it is read, as for a file read once.
TEST(PcapngLinkTypes, DamageOnePassMeetsEndsReadingWhereItLies) {
    auto f = written({link_ethernet, link_raw}, {{0, 1}, {1, 2}, {1, 3}, {0, 4}, {1, 5}});
    const auto at = blocks(f);
    const std::size_t damaged = at[6];  // the fourth packet, Ethernet
    f[damaged + 20] = 0xFF;             // its captured length
    f[damaged + 21] = 0xFF;
    std::string error;
    const auto read = read_both_ways(f, error);
    EXPECT_EQ(read, (std::vector<Read>{{1, dlt(link_ethernet), 1, true},
                                       {2, dlt(link_raw), 2, true},
                                       {3, dlt(link_raw), 3, true}}));
    EXPECT_TRUE(error.starts_with("capture: packet 4 at byte offset " + std::to_string(damaged) + ": "))
        << error;
}

// A file cut short inside a packet block: every packet before it, then an error naming the cut block.
TEST(PcapngLinkTypes, AFileCutShortEndsAtTheCutBlock) {
    auto f = written({link_ethernet, link_raw}, {{0, 1}, {1, 2}, {0, 3}, {1, 4}});
    const auto at = blocks(f);
    f.resize(at[6] + 30);  // inside the fourth packet's block
    std::string error;
    const auto read = read_both_ways(f, error);
    EXPECT_EQ(read, (std::vector<Read>{{1, dlt(link_ethernet), 1, true},
                                       {2, dlt(link_raw), 2, true},
                                       {3, dlt(link_ethernet), 3, true}}));
    EXPECT_TRUE(error.starts_with("capture: packet 4 at byte offset " + std::to_string(at[6]) + ": "))
        << error;
}

namespace {

// The command's exit status and standard output (with its standard error when `errors_too`).
std::pair<int, std::string> run(const std::string& command, bool errors_too = false) {
    FILE* p = popen((command + (errors_too ? " 2>&1" : "")).c_str(), "r");
    std::string out;
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p))
        out.append(buf, n);
    const int status = pclose(p);
    return {WEXITSTATUS(status), out};
}

const std::string dumpcap_capture = std::string(MBSCOPE_SOURCE_DIR) + "/captures/dumpcap-lo-and-any.pcapng";

}  // namespace

// dumpcap 4.0 capturing on loopback (Ethernet) and on "any" (Linux cooked) at once, a connection to a slave
// on each (captures/SOURCES.md): every Modbus/TCP frame tshark finds, with its packet number, transaction,
// unit, function and bytes, and no other.
TEST(PcapngLinkTypes, DumpcapOnLoopbackAndAnyDecodesAsTsharkReadsIt) {
    const auto [status, out] =
        run(std::string(MBSCOPE_BINARY) + " decode --tcp-port 1502 --jsonl '" + dumpcap_capture + "'");
    EXPECT_EQ(status, 0) << out;
    std::ostringstream ours;
    std::istringstream lines(out);
    nlohmann::json summary;
    for (std::string line; std::getline(lines, line);) {
        const auto j = nlohmann::json::parse(line);
        if (j.value("type", "") == "summary") summary = j;
        if (j.value("type", "") != "frame") continue;
        std::string raw = j.at("raw").get<std::string>();
        std::erase(raw, ' ');
        for (auto& c : raw)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        ours << j.at("packet").get<std::uint64_t>() << ' ' << j.at("transaction_id").get<int>() << ' '
             << j.at("unit_id").get<int>() << ' ' << j.at("function").get<int>() << ' ' << raw << '\n';
    }
    EXPECT_EQ(summary.value("packets", 0u), 28u) << out;
    EXPECT_EQ(summary.value("frames", 0u), 12u) << out;
    EXPECT_EQ(summary.value("transactions", 0u), 6u) << out;
    if (!mbscope::test::have("tshark")) GTEST_SKIP() << "tshark not installed";
    const auto [tshark_status, theirs] =
        run("tshark -r '" + dumpcap_capture +
            "' -d tcp.port==1502,mbtcp -Y mbtcp -T fields -E separator=' ' -e frame.number -e mbtcp.trans_id "
            "-e mbtcp.unit_id -e modbus.func_code -e tcp.payload 2>/dev/null");
    EXPECT_EQ(tshark_status, 0);
    EXPECT_EQ(ours.str(), theirs);
}

// The same file piped in is read once, as it comes: refused at the second interface, with the way round.
TEST(PcapngLinkTypes, APipedFileIsRefusedWithTheWayRound) {
    const auto [status, out] = run("cat '" + dumpcap_capture + "' | " + MBSCOPE_BINARY + " decode -", true);
    EXPECT_NE(status, 0) << out;
    EXPECT_NE(out.find("an interface has a type 113 different from the type of the first interface"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("a file (not a pipe) of up to 8 link types is read once for each: save it to a file"),
              std::string::npos)
        << out;
}

// mergecap's merge of an Ethernet capture of the requests and a raw-IP capture of the responses: one pcapng
// file, two link types; decoded as the two captures are together.
TEST(PcapngLinkTypes, MergecapsMergeOfEthernetAndRawIpCapturesDecodes) {
    if (!mbscope::test::have("mergecap")) GTEST_SKIP() << "mergecap not installed";
    const auto c = mbscope::test::five_reads();
    std::vector<mbscope::test::PcapRecord> requests, responses;
    for (std::size_t i = 0; i < c.records.size(); ++i) {
        auto r = c.records[i];
        if (i % 2 == 0) r.data = in_ethernet(r.data);  // the requests in Ethernet frames
        (i % 2 == 0 ? requests : responses).push_back(r);
    }
    const std::string request_file = mbscope::test::write_temp(
        "pcapng_link_types_requests.pcap", mbscope::test::pcap_file(link_ethernet, requests));
    const std::string response_file = mbscope::test::write_temp(
        "pcapng_link_types_responses.pcap", mbscope::test::pcap_file(link_raw, responses));
    const std::string merged = temp_path("merged.pcapng");
    ASSERT_EQ(
        std::system(("mergecap -F pcapng -w '" + merged + "' '" + request_file + "' '" + response_file + "'")
                        .c_str()),
        0);
    const std::string decode = std::string(MBSCOPE_BINARY) + " decode --jsonl ";
    const auto apart = run(decode + "'" + request_file + "' '" + response_file + "'");
    const auto together = run(decode + "'" + merged + "'");
    EXPECT_EQ(apart.first, 0) << apart.second;
    EXPECT_EQ(together.first, 0) << together.second;
    const auto without_source = [](const std::string& out) {
        std::vector<nlohmann::json> records;
        std::istringstream lines(out);
        for (std::string line; std::getline(lines, line);) {
            auto j = nlohmann::json::parse(line);
            j.erase("source");
            j.erase("packet");  // a packet's number in its own file, or in the merge
            records.push_back(j);
        }
        return records;
    };
    const auto ours = without_source(together.second);
    EXPECT_EQ(ours, without_source(apart.second));
    EXPECT_EQ(std::count_if(ours.begin(), ours.end(),
                            [](const nlohmann::json& j) { return j.value("type", "") == "transaction"; }),
              5);
}

}  // namespace test_analyzer_pcapng_link_types_test
