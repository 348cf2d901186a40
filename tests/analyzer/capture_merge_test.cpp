// Several capture files as one capture, merged by time: the merge's order against hand-made files, the
// analyzer pairing across files, and `mbscope decode A B` against mergecap (Wireshark's, a merger nobody
// here wrote) on the public captures: the same records in the same order as the file mergecap makes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "analyzer/capture_merge.hpp"
#include "analyzer/serial_input.hpp"
#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_capture_merge_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::write_temp;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Collect;
using mbscope::test::Conversation;
using mbscope::test::PcapRecord;

namespace {

const std::string captures = std::string(MBSCOPE_SOURCE_DIR) + "/../shared/captures/";

// A raw-IP pcap of UDP datagrams at the given times (in seconds); each datagram's payload is its time, so
// the order packets come out in can be read back from them.
std::string datagrams(const std::string& name, const std::vector<int>& seconds) {
    std::vector<PcapRecord> records;
    for (int s : seconds)
        records.push_back(
            {std::chrono::seconds(s), mbscope::test::packet(true, 0, {static_cast<std::uint8_t>(s)}, true)});
    return write_temp("capture_merge_" + name, mbscope::test::pcap_file(mbscope::test::link_raw, records));
}

struct Merged {
    std::string file;
    std::uint64_t number;
    int second;
    bool operator==(const Merged&) const = default;
};
std::ostream& operator<<(std::ostream& o, const Merged& m) {
    return o << std::filesystem::path(m.file).filename().string() << "#" << m.number << "@" << m.second;
}

std::vector<Merged> merge_all(an::CaptureMerge& merge, std::size_t* most_open = nullptr) {
    std::vector<Merged> out;
    while (auto p = merge.next()) {
        out.push_back({merge.name(), p->number, p->data.back()});
        if (most_open) *most_open = std::max(*most_open, merge.files_open());
    }
    return out;
}

TEST(CaptureMerge, PacketsComeInTimeOrderEachFileInItsOwn) {
    // a's clock goes back (4 then 2): its own order is kept. a and c both have a packet at 4: a, named
    // first, goes first.
    const auto a = datagrams("a.pcap", {1, 4, 2, 7});
    const auto b = datagrams("b.pcap", {3, 5});
    const auto c = datagrams("c.pcap", {4});
    an::CaptureMerge merge({{a, "a"}, {b, "b"}, {c, "c"}});
    const std::vector<Merged> expected{{"a", 1, 1}, {"b", 1, 3}, {"a", 2, 4}, {"a", 3, 2},
                                       {"c", 1, 4}, {"b", 2, 5}, {"a", 4, 7}};
    EXPECT_EQ(merge_all(merge), expected);
    EXPECT_TRUE(merge.errors().empty());
    EXPECT_EQ(merge.files_open(), 0u);
}

TEST(CaptureMerge, FilesNamedOutOfOrderComeOutInTimeOrder) {
    const auto late = datagrams("late.pcap", {20, 21});
    const auto early = datagrams("early.pcap", {10, 11});
    an::CaptureMerge merge({{late, "late"}, {early, "early"}});
    const std::vector<Merged> expected{{"early", 1, 10}, {"early", 2, 11}, {"late", 1, 20}, {"late", 2, 21}};
    EXPECT_EQ(merge_all(merge), expected);
}

TEST(CaptureMerge, AFileThatCannotBeReadIsNamedAndTheOthersAreMergedWhole) {
    const auto good = datagrams("good.pcap", {1, 3, 5});
    // Damaged: its third record's header promises more bytes than the file holds.
    auto damaged_bytes =
        mbscope::test::pcap_file(mbscope::test::link_raw, {{2s, mbscope::test::packet(true, 0, {2}, true)},
                                                           {4s, mbscope::test::packet(true, 0, {4}, true)},
                                                           {6s, mbscope::test::packet(true, 0, {6}, true)}});
    damaged_bytes.resize(damaged_bytes.size() - 10);
    const auto damaged = write_temp("capture_merge_damaged.pcap", damaged_bytes);
    const std::string missing = ::testing::TempDir() + "capture_merge_no_such_file.pcap";
    an::CaptureMerge merge({{good, "good"}, {missing, "missing"}, {damaged, "damaged"}});
    const std::vector<Merged> expected{
        {"good", 1, 1}, {"damaged", 1, 2}, {"good", 2, 3}, {"damaged", 2, 4}, {"good", 3, 5}};
    EXPECT_EQ(merge_all(merge), expected);
    ASSERT_EQ(merge.errors().size(), 2u);
    EXPECT_NE(merge.errors()[0].find("missing"), std::string::npos) << merge.errors()[0];
    EXPECT_NE(merge.errors()[1].find("damaged: packet 3"), std::string::npos) << merge.errors()[1];
}

// A capture of no packets among others is refused as it is alone (exit 2): before, merged, it passed without
// a word.
TEST(CaptureMerge, ACaptureOfNoPacketsIsNamed) {
    const auto good = datagrams("good_beside_empty.pcap", {1, 2});
    const auto empty =
        write_temp("capture_merge_empty.pcap", mbscope::test::pcap_file(mbscope::test::link_raw, {}));
    an::CaptureMerge merge({{good, "good"}, {empty, "empty"}});
    const std::vector<Merged> expected{{"good", 1, 1}, {"good", 2, 2}};
    EXPECT_EQ(merge_all(merge), expected);
    ASSERT_EQ(merge.errors().size(), 1u);
    EXPECT_EQ(merge.errors()[0], "empty: the capture holds no packets, nothing to decode");
}

TEST(CaptureMerge, ARingBufferHoldsOnlyTheFilesItIsReading) {
    // 300 parts named last first: every packet in time order, and never more than two files open (the one
    // being read and the next, opened when its first packet is due).
    std::vector<an::CaptureFile> files;
    for (int i = 299; i >= 0; --i)
        files.push_back({datagrams("ring_" + std::to_string(i) + ".pcap", {2 * i, 2 * i + 1}), ""});
    an::CaptureMerge merge(std::move(files));
    std::size_t most_open = 0;
    const auto merged = merge_all(merge, &most_open);
    ASSERT_EQ(merged.size(), 600u);
    for (std::size_t i = 0; i < merged.size(); ++i)
        EXPECT_EQ(merged[i].second, static_cast<int>(i % 256)) << merged[i];  // payload: the time's low byte
    EXPECT_LE(most_open, 2u);
    EXPECT_GE(merge.offset(), 300u * 24);  // every file's header at least
}

// A request in one file and its response in the other, as a tap's two directions recorded on two
// interfaces: one transaction, whichever file is named first.
TEST(CaptureMerge, ARequestAndItsResponseInTwoFilesPair) {
    Conversation c;
    const auto request = bytes({0, 1, 0, 0, 0, 6, 1, 3, 0, 0, 0, 2});
    const auto response = bytes({0, 1, 0, 0, 0, 7, 1, 3, 4, 0, 10, 0, 20});
    for (int i = 0; i < 5; ++i) {
        auto req = request, rsp = response;
        req[1] = rsp[1] = static_cast<std::uint8_t>(i);
        c.send(true, req, mb::Timestamp(std::chrono::seconds(100 + 10 * i)));
        c.send(false, rsp, mb::Timestamp(std::chrono::seconds(100 + 10 * i) + 20ms));
    }
    std::vector<PcapRecord> to_server, to_client;
    for (std::size_t i = 0; i < c.records.size(); ++i)
        (i % 2 == 0 ? to_server : to_client).push_back(c.records[i]);
    const auto requests = write_temp("capture_merge_requests.pcap",
                                     mbscope::test::pcap_file(mbscope::test::link_raw, to_server));
    const auto responses = write_temp("capture_merge_responses.pcap",
                                      mbscope::test::pcap_file(mbscope::test::link_raw, to_client));
    for (const auto& order : {std::vector{responses, requests}, std::vector{requests, responses}}) {
        Collect sink;
        an::Analyzer a({}, sink);
        EXPECT_TRUE(an::read_inputs(a, order, an::InputFormat::Auto));
        a.finish();
        EXPECT_EQ(a.summary().transactions, 5u);
        EXPECT_TRUE(a.summary().findings.empty());
        // Each frame named after its own file and its packet there: request i and response i are packet
        // i + 1 of theirs.
        ASSERT_EQ(sink.frames.size(), 10u);
        for (std::size_t i = 0; i < sink.frames.size(); ++i) {
            const auto& f = sink.frames[i];
            const bool request = f.direction == mb::Direction::Request;
            EXPECT_EQ(request, i % 2 == 0);
            EXPECT_EQ(f.source.str(), request ? requests : responses);
            EXPECT_EQ(f.packet, i / 2 + 1);
        }
    }
}

// `mbscope decode` as JSON lines, without what names the file and the packet in it (a merged file numbers
// its packets anew).
std::vector<nlohmann::json> records(const std::string& files) {
    std::vector<nlohmann::json> out;
    std::istringstream in(
        mbscope::test::run(std::string(MBSCOPE_BINARY) + " decode --jsonl " + files + " 2>/dev/null"));
    for (std::string line; std::getline(in, line);) {
        auto j = nlohmann::json::parse(line);
        j.erase("source");
        j.erase("packet");
        out.push_back(std::move(j));
    }
    return out;
}

void expect_same_as_mergecap(const std::vector<std::string>& names) {
    std::string files;
    for (const auto& n : names)
        files += " '" + captures + n + "'";
    // Classic pcap: libpcap 1.10 refuses a pcapng whose interfaces differ in snapshot length, as mergecap's
    // do when the inputs' did.
    const std::string merged = ::testing::TempDir() + "capture_merge_mergecap.pcap";
    ASSERT_EQ(std::system(("mergecap -F pcap -w '" + merged + "'" + files).c_str()), 0);
    const auto ours = records(files);
    const auto theirs = records("'" + merged + "'");
    ASSERT_FALSE(ours.empty());
    ASSERT_EQ(ours.size(), theirs.size());
    for (std::size_t i = 0; i < ours.size(); ++i)
        ASSERT_EQ(ours[i], theirs[i]) << "record " << i << " of " << files;
}

TEST(CaptureMerge, DecodingSeveralFilesIsDecodingWhatMergecapMakesOfThem) {
    if (!mbscope::test::have("mergecap")) GTEST_SKIP() << "mergecap (Wireshark) not installed";
    // Named out of time order (2015 before 2013): every request of the second used to expire at once,
    // 2,775 responses reported unsolicited.
    expect_same_as_mergecap({"zeek__zeek/modbus-eit.pcap", "zeek__zeek/modbusBig.pcap"});
    // The two parts of one capture, the second named first.
    expect_same_as_mergecap({"ITI__ICS-Security-Tools/modbus_test_data_part2.pcap",
                             "ITI__ICS-Security-Tools/modbus_test_data_part1.pcap"});
    // Seven captures, one of them with its clock going back and forth.
    expect_same_as_mergecap({"zeek__zeek/4SICS-GeekLounge-151022-min.pcap", "zeek__zeek/fuzz-1011.pcap",
                             "zeek__zeek/fuzz-72.pcap", "zeek__zeek/modbus-and-non-modbus-p502.pcap",
                             "zeek__zeek/modbus-eit.pcap", "zeek__zeek/modbusBig.pcap",
                             "zeek__zeek/modbusSmall.pcap"});
}

TEST(CaptureMerge, FilesOutOfTimeOrderDecodeAsEachDoesAlone) {
    // What each capture finds alone, it finds named with another from years before or after it.
    const auto summary = [](const std::string& files) {
        const auto j = nlohmann::json::parse(
            mbscope::test::run(std::string(MBSCOPE_BINARY) + " decode --json " + files + " 2>/dev/null"));
        return j.back();
    };
    const std::string eit = "'" + captures + "zeek__zeek/modbus-eit.pcap'";
    const std::string big = "'" + captures + "zeek__zeek/modbusBig.pcap'";
    const auto alone_eit = summary(eit), alone_big = summary(big);
    for (const auto& both : {summary(eit + " " + big), summary(big + " " + eit)}) {
        EXPECT_EQ(both["transactions"],
                  alone_eit["transactions"].get<int>() + alone_big["transactions"].get<int>());
        for (const char* code : {"pair.no_response", "pair.unsolicited_response"})
            EXPECT_EQ(both["findings"].value(code, 0),
                      alone_eit["findings"].value(code, 0) + alone_big["findings"].value(code, 0))
                << code;
    }
}

// A capture split by tshark into its two directions decodes as the capture did.
TEST(CaptureMerge, ACaptureSplitByDirectionDecodesAsAWhole) {
    if (!mbscope::test::have("tshark")) GTEST_SKIP() << "tshark not installed";
    const std::string whole = captures + "zeek__zeek/modbusSmall.pcap";
    const std::string requests = ::testing::TempDir() + "capture_merge_requests.pcap";
    const std::string responses = ::testing::TempDir() + "capture_merge_responses.pcap";
    ASSERT_EQ(std::system(("tshark -r '" + whole + "' -F pcap -Y 'tcp.dstport == 502' -w '" + requests +
                           "' 2>/dev/null")
                              .c_str()),
              0);
    ASSERT_EQ(std::system(("tshark -r '" + whole + "' -F pcap -Y 'tcp.srcport == 502' -w '" + responses +
                           "' 2>/dev/null")
                              .c_str()),
              0);
    const auto pairs = [](const std::vector<nlohmann::json>& rs) {
        std::vector<nlohmann::json> out;
        for (const auto& r : rs)
            if (r["type"] == "transaction" || r["type"] == "finding") out.push_back(r);
        return out;
    };
    const auto expected = pairs(records("'" + whole + "'"));
    ASSERT_EQ(expected.size(), 16u);  // 16 transactions, no finding
    EXPECT_EQ(pairs(records("'" + responses + "' '" + requests + "'")), expected);
}

}  // namespace

}  // namespace test_analyzer_capture_merge_test
