// Where mbscope and tshark differ, each case backed by a capture written here through libpcap and read by
// both: tshark 4.0 (`tshark -r FILE -T fields ...`) and the analyzer. Every test asserts what tshark does
// and what mbscope does, so analyzer/README.md's "Where mbscope and tshark differ" stays true; a tshark
// that changes its behaviour fails the test and the README must be revisited. Skipped without tshark.
#include <gtest/gtest.h>
#include <pcap/pcap.h>

#include <map>
#include <sstream>

#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_tshark_divergence_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Collect;
using mbscope::test::PcapRecord;

namespace {

constexpr int link_rtac_serial = 250;
constexpr std::uint8_t tx_start = 1, rx_start = 2;

// A classic pcap file of `linktype` written by libpcap (pcap_open_dead + pcap_dump).
std::string write_pcap(const std::string& name, int linktype, const std::vector<PcapRecord>& records) {
    const std::string path = ::testing::TempDir() + name;
    // pcap_open_dead takes a DLT: raw IP is DLT_RAW (written as link type 101); the others are the same.
    pcap_t* dead = pcap_open_dead(linktype == mbscope::test::link_raw ? DLT_RAW : linktype, 65535);
    pcap_dumper_t* out = pcap_dump_open(dead, path.c_str());
    EXPECT_NE(out, nullptr) << pcap_geterr(dead);
    for (const auto& r : records) {
        if (!out) break;
        const auto us = std::chrono::duration_cast<std::chrono::microseconds>(r.time).count();
        pcap_pkthdr h{};
        h.ts.tv_sec = static_cast<time_t>(us / 1'000'000);
        h.ts.tv_usec = static_cast<suseconds_t>(us % 1'000'000);
        h.caplen = h.len = static_cast<bpf_u_int32>(r.data.size());
        pcap_dump(reinterpret_cast<u_char*>(out), &h, r.data.data());
    }
    if (out) pcap_dump_close(out);
    pcap_close(dead);
    return path;
}

// An SEL RTAC serial record (packet-rtacser.c's layout): seconds, microseconds, event, control lines,
// footer, then the line's bytes.
PcapRecord rtac(mb::Timestamp t, std::uint8_t event, const std::vector<std::uint8_t>& payload) {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(t).count();
    const auto s = static_cast<std::uint32_t>(us / 1'000'000), u = static_cast<std::uint32_t>(us % 1'000'000);
    PcapRecord r{t, {}};
    for (std::uint32_t v : {s, u})
        for (int shift = 24; shift >= 0; shift -= 8)
            r.data.push_back(static_cast<std::uint8_t>(v >> shift));
    r.data.insert(r.data.end(), {event, 0, 0, 0});
    r.data.insert(r.data.end(), payload.begin(), payload.end());
    return r;
}

// tshark's rows, by frame number: the requested fields in order (several occurrences comma-separated).
std::map<int, std::vector<std::string>> tshark(const std::string& path, const std::string& options,
                                               const std::vector<std::string>& fields) {
    std::string command =
        "tshark -r '" + path + "' " + options + " -T fields -E separator=/t -e frame.number";
    for (const auto& f : fields)
        command += " -e " + f;
    std::map<int, std::vector<std::string>> rows;
    std::istringstream in(mbscope::test::run(command + " 2>/dev/null"));
    for (std::string line; std::getline(in, line);) {
        std::vector<std::string> cols;
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, '\t');)
            cols.push_back(c);
        cols.resize(fields.size() + 1);
        rows[std::stoi(cols[0])] = {cols.begin() + 1, cols.end()};
    }
    return rows;
}

struct Decoded {
    Collect sink;
    an::Summary summary;
};
std::unique_ptr<Decoded> mbscope_decode(const std::string& path, an::AnalyzerOptions options = {}) {
    auto d = std::make_unique<Decoded>();
    an::Analyzer a(std::move(options), d->sink);
    a.read_capture(path);
    a.finish();
    d->summary = a.summary();
    return d;
}

class TsharkDivergence : public ::testing::Test {
  protected:
    void SetUp() override {
        if (!mbscope::test::have("tshark")) GTEST_SKIP() << "tshark not installed";
    }
};

// RTU frames of unit 17 (0x11): the MK manual's FC3 example (000:356-370) and an FC6 write with its echo.
const auto read_request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
const auto read_response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
const auto write_single = bytes({0x11, 0x06, 0x00, 0x01, 0x00, 0x03, 0x9A, 0x9B});
const auto broadcast_write = bytes({0x00, 0x06, 0x00, 0x01, 0x00, 0x03, 0x99, 0xDA});

std::vector<std::uint8_t> glue(std::vector<std::uint8_t> a, const std::vector<std::uint8_t>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

mb::Timestamp at(double s) {
    return std::chrono::duration_cast<mb::Timestamp>(std::chrono::duration<double>(1'700'000'000 + s));
}

TEST_F(TsharkDivergence, SerialFc6EchoIsUnclassifiedByTsharkAndPairedByMbscope) {
    const auto path =
        write_pcap("div_fc6.pcap", link_rtac_serial,
                   {rtac(at(1.0), tx_start, write_single), rtac(at(1.02), rx_start, write_single)});
    const auto rows = tshark(path, "-d rtacser.data,mbrtu", {"modbus.func_code", "_ws.col.Info"});
    ASSERT_EQ(rows.size(), 2u);
    for (const auto& [number, cols] : rows) {
        SCOPED_TRACE(number);
        EXPECT_EQ(cols[0], "6");
        EXPECT_NE(cols[1].find("Unable to classify as query or response"), std::string::npos) << cols[1];
    }
    const auto d = mbscope_decode(path);
    ASSERT_EQ(d->sink.frames.size(), 2u);
    EXPECT_EQ(d->sink.frames[0].direction, mb::Direction::Request);
    EXPECT_EQ(d->sink.frames[1].direction, mb::Direction::Response);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_TRUE(d->sink.transactions[0].response.has_value());
}

TEST_F(TsharkDivergence, SerialBroadcastIsDroppedByTsharkAndDecodedByMbscope) {
    const auto path =
        write_pcap("div_broadcast.pcap", link_rtac_serial,
                   {rtac(at(1.0), tx_start, broadcast_write), rtac(at(2.0), tx_start, read_request),
                    rtac(at(2.02), rx_start, read_response)});
    const auto rows = tshark(path, "-d rtacser.data,mbrtu", {"mbrtu.unit_id", "modbus.func_code"});
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows.at(1), (std::vector<std::string>{"", ""}));  // no Modbus RTU at all in the broadcast
    EXPECT_EQ(rows.at(2), (std::vector<std::string>{"17", "3"}));
    const auto d = mbscope_decode(path);
    ASSERT_EQ(d->sink.frames.size(), 3u);
    EXPECT_EQ(d->sink.frames[0].frame.unit_id(), 0);
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    EXPECT_TRUE(d->sink.transactions[0].broadcast);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 0);
}

TEST_F(TsharkDivergence, SerialRecordsSplitOrGluedAreMisframedByTsharkAndReframedByMbscope) {
    // A sniffer's reads rarely end where frames end: USER0 records (tshark told they carry mbrtu) holding a
    // request and its response glued, then a request, its response split in two, the second half glued to
    // the next request, and that request's response.
    const std::vector<std::uint8_t> head(read_response.begin(), read_response.begin() + 5),
        tail(read_response.begin() + 5, read_response.end());
    const auto path = write_pcap("div_split.pcap", 147,
                                 {{at(1.0), glue(read_request, read_response)},
                                  {at(2.0), read_request},
                                  {at(2.03), head},
                                  {at(2.04), glue(tail, read_request)},
                                  {at(2.08), read_response}});
    const auto rows = tshark(path, R"x(-o 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""')x",
                             {"mbrtu.unit_id", "_ws.col.Info"});
    ASSERT_EQ(rows.size(), 5u);
    EXPECT_NE(rows.at(1)[0], "17");  // request and response read as one frame, then garbage frames
    EXPECT_NE(rows.at(1)[1].find("Unreassembled"), std::string::npos) << rows.at(1)[1];
    EXPECT_NE(rows.at(3)[1].find("Unreassembled"), std::string::npos) << rows.at(3)[1];
    EXPECT_EQ(rows.at(4)[0], "");  // the response's tail and the next request: not Modbus to tshark
    const auto d = mbscope_decode(path, [] {
        an::AnalyzerOptions o;
        o.user_dlt = mb::Framing::Rtu;
        return o;
    }());
    ASSERT_EQ(d->sink.frames.size(), 6u);
    for (const auto& f : d->sink.frames) {
        EXPECT_EQ(f.frame.unit_id(), 0x11);
        EXPECT_TRUE(f.frame.checksum_ok);
    }
    ASSERT_EQ(d->sink.transactions.size(), 3u);
    for (const auto& t : d->sink.transactions) {
        EXPECT_TRUE(t.response.has_value());
    }
    EXPECT_EQ(d->summary.unparsed_bytes, 0u);
}

// Modbus/TCP: the MBAP form of the same read (transaction ids 1..4), over raw IPv4 (link type 101).
std::vector<std::uint8_t> mbap(std::uint16_t tid, const std::vector<std::uint8_t>& rtu) {
    const auto pdu_and_unit = rtu.size() - 2;  // the RTU frame without its CRC
    std::vector<std::uint8_t> a(6 + pdu_and_unit);
    a[0] = static_cast<std::uint8_t>(tid >> 8);
    a[1] = static_cast<std::uint8_t>(tid);
    a[5] = static_cast<std::uint8_t>(pdu_and_unit);
    std::copy(rtu.begin(), rtu.end() - 2, a.begin() + 6);
    return a;
}

// Segments between client and server, each `gap` seconds after the one before.
struct Segment {
    bool to_server;
    std::vector<std::uint8_t> payload;
    double gap = 0.01;
};
std::string tcp_capture(const std::string& name, const std::vector<Segment>& segments) {
    mbscope::test::Conversation c;
    double t = 1.0;
    for (const auto& s : segments) {
        t += s.gap;
        c.send(s.to_server, s.payload, at(t));
    }
    return write_pcap(name, mbscope::test::link_raw, c.records);
}

TEST_F(TsharkDivergence, ExceptionIsNotLinkedToItsRequestByTshark) {
    const auto exception = bytes({0x00, 0x02, 0x00, 0x00, 0x00, 0x03, 0x11, 0x83, 0x02});
    const auto path = tcp_capture("div_exception.pcap", {{true, mbap(1, read_request)},
                                                         {false, mbap(1, read_response)},
                                                         {true, mbap(2, read_request)},
                                                         {false, exception}});
    const auto rows = tshark(path, "", {"mbtcp.trans_id", "modbus.request_frame", "modbus.exception_code"});
    ASSERT_EQ(rows.size(), 4u);
    EXPECT_EQ(rows.at(2), (std::vector<std::string>{"1", "1", ""}));  // a normal reply: linked to frame 1
    EXPECT_EQ(rows.at(4), (std::vector<std::string>{"2", "", "2"}));  // the exception: no request frame
    const auto d = mbscope_decode(path);
    ASSERT_EQ(d->sink.transactions.size(), 2u);
    ASSERT_TRUE(d->sink.transactions[1].response.has_value());
    EXPECT_EQ(d->sink.transactions[1].request.packet, 3u);
    EXPECT_EQ(d->sink.transactions[1].response->packet, 4u);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairExceptionResponse), 1);
}

TEST_F(TsharkDivergence, AduStartingInASegmentUnderEightBytesIsMissedByTshark) {
    const auto request = mbap(1, read_request);
    const std::vector<std::uint8_t> first(request.begin(), request.begin() + 5),
        rest(request.begin() + 5, request.end());
    const auto path =
        tcp_capture("div_short_segment.pcap", {{true, first}, {true, rest}, {false, mbap(1, read_response)}});
    const auto rows = tshark(path, "", {"mbtcp.trans_id", "modbus.func_code"});
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows.at(1), (std::vector<std::string>{"", ""}));
    EXPECT_EQ(rows.at(2), (std::vector<std::string>{"", ""}));  // the request is never reassembled
    EXPECT_EQ(rows.at(3), (std::vector<std::string>{"1", "3"}));
    const auto d = mbscope_decode(path);
    ASSERT_EQ(d->sink.frames.size(), 2u);
    EXPECT_EQ(d->sink.frames[0].packet, 2u);  // the request, complete in the second segment
    EXPECT_EQ(d->sink.frames[0].direction, mb::Direction::Request);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_TRUE(d->sink.transactions[0].response.has_value());
}

TEST_F(TsharkDivergence, MissingResponseAndTransactionIdMismatchAreSilentInTshark) {
    // Request 1 is never answered (the next packet comes 9 s later, past the 3 s timeout); request 2, then
    // the only one outstanding, is answered with transaction id 9.
    const auto path = tcp_capture(
        "div_pairing.pcap",
        {{true, mbap(1, read_request)}, {true, mbap(2, read_request), 9.0}, {false, mbap(9, read_response)}});
    const auto rows = tshark(path, "", {"mbtcp.trans_id", "modbus.request_frame", "_ws.expert.message"});
    ASSERT_EQ(rows.size(), 3u);
    for (const auto& [number, cols] : rows) {
        SCOPED_TRACE(number);
        EXPECT_EQ(cols[1], "");  // nothing linked
        EXPECT_EQ(cols[2], "");  // and no expert information
    }
    const auto d = mbscope_decode(path);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairTransactionIdMismatch), 1);
    EXPECT_EQ(d->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
}

TEST_F(TsharkDivergence, ModbusAsciiHasNoTsharkDissector) {
    // tshark's Modbus protocols: Modbus, Modbus RTU, Modbus/TCP, Modbus/UDP (and CIP's Modbus object).
    std::istringstream in(mbscope::test::run("tshark -G protocols 2>/dev/null"));
    int modbus = 0;
    for (std::string line; std::getline(in, line);) {
        if (line.find("Modbus") == std::string::npos) continue;
        ++modbus;
        EXPECT_EQ(line.find("ASCII"), std::string::npos) << line;
    }
    EXPECT_GE(modbus, 4);
    // The MK manual's FC3 request in ASCII (LRC 0x89), as a USER0 record: mbscope reads it with --user-dlt.
    const std::string line = ":11030060000389\r\n";
    const auto path = write_pcap("div_ascii.pcap", 147, {{at(1.0), {line.begin(), line.end()}}});
    an::AnalyzerOptions options;
    options.user_dlt = mb::Framing::Ascii;
    const auto d = mbscope_decode(path, options);
    ASSERT_EQ(d->sink.frames.size(), 1u);
    EXPECT_EQ(d->sink.frames[0].frame.unit_id(), 0x11);
    ASSERT_TRUE(d->sink.frames[0].pdu.has_value());
    EXPECT_EQ(d->sink.frames[0].pdu->function_code(), 3);
}

}  // namespace

}  // namespace test_analyzer_tshark_divergence_test
