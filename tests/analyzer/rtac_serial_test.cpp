// SEL RTAC serial captures (link type 250): pcap files written here through libpcap (pcap_open_dead,
// pcap_dump) with records laid out as Wireshark's packet-rtacser.c reads them (12-byte header: seconds,
// microseconds, event, control lines, footer; then the line's bytes). Frames are the MK manual's FC3 example
// (000:356-370); tshark 4.0, when installed, decodes the same files (-d rtacser.data,mbrtu) as a second
// opinion on every frame.
#include <gtest/gtest.h>
#include <pcap/pcap.h>

#include <array>
#include <cstdio>
#include <map>
#include <sstream>

#include "analyzer/rtac_serial.hpp"
#include "analyzer/serial_input.hpp"
#include "test_packets.hpp"

namespace test_analyzer_rtac_serial_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Collect;

namespace {

constexpr int link_rtac_serial = 250;
constexpr std::uint8_t tx_start = 1, rx_start = 2, tx_end = 3, rx_end = 4, data_lost = 5, parity_error = 8;
constexpr std::uint8_t rts_dtr = 0x18;  // control lines: RTS and DTR asserted

const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
const auto response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});

struct Event {
    std::int64_t us;  // microseconds since the epoch
    std::uint8_t event;
    std::vector<std::uint8_t> payload;
};

// An RTAC record: big-endian seconds and microseconds, event, control lines, footer, payload.
std::vector<std::uint8_t> record(const Event& e) {
    const auto s = static_cast<std::uint32_t>(e.us / 1'000'000),
               u = static_cast<std::uint32_t>(e.us % 1'000'000);
    std::vector<std::uint8_t> r;
    r.reserve(12 + e.payload.size());
    for (int shift = 24; shift >= 0; shift -= 8)
        r.push_back(static_cast<std::uint8_t>(s >> shift));
    for (int shift = 24; shift >= 0; shift -= 8)
        r.push_back(static_cast<std::uint8_t>(u >> shift));
    for (std::uint8_t b : {e.event, rts_dtr, std::uint8_t{0}, std::uint8_t{0}})  // event, lines, footer
        r.push_back(b);
    for (std::uint8_t b : e.payload)
        r.push_back(b);
    return r;
}

// A pcap file of link type 250 written by libpcap; `raw` records go in as they are.
std::string write_pcap(const std::string& name, const std::vector<Event>& events,
                       const std::map<std::size_t, std::vector<std::uint8_t>>& raw = {}) {
    const std::string path = ::testing::TempDir() + name;
    pcap_t* dead = pcap_open_dead(link_rtac_serial, 65535);
    pcap_dumper_t* out = pcap_dump_open(dead, path.c_str());
    EXPECT_NE(out, nullptr) << pcap_geterr(dead);
    for (std::size_t i = 0; out && i < events.size(); ++i) {
        const auto data = raw.count(i) ? raw.at(i) : record(events[i]);
        pcap_pkthdr h{};
        h.ts.tv_sec = static_cast<time_t>(events[i].us / 1'000'000);
        h.ts.tv_usec = static_cast<suseconds_t>(events[i].us % 1'000'000);
        h.caplen = h.len = static_cast<bpf_u_int32>(data.size());
        pcap_dump(reinterpret_cast<u_char*>(out), &h, data.data());
    }
    if (out) pcap_dump_close(out);
    pcap_close(dead);
    return path;
}

struct Run {
    Collect sink;
    an::Summary summary;
    bool ok = false;
};

std::unique_ptr<Run> decode(const std::string& path, std::optional<mb::Direction> rtac_tx = std::nullopt) {
    auto r = std::make_unique<Run>();
    an::AnalyzerOptions o;
    o.rtac_tx = rtac_tx;
    an::Analyzer a(std::move(o), r->sink);
    r->ok = an::read_input(a, path, an::InputFormat::Auto);
    a.finish();
    r->summary = a.summary();
    return r;
}

// The RTAC polls as master: its request (TX), then the device's reply (RX) 20 ms later.
const std::int64_t t0 = 1'796'019'777'000'000;
const std::vector<Event> master_poll = {
    {t0, tx_start, request},
    {t0 + 8'333, tx_end, {}},
    {t0 + 20'000, rx_start, response},
    {t0 + 31'458, rx_end, {}},
};

}  // namespace

TEST(RtacSerial, HeaderFieldsAsPacketRtacserReadsThem) {
    const auto bytes_of_record = record({t0 + 123'456, rx_start, response});
    const auto r = an::parse_rtac_serial(bytes_of_record);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->arrived, std::chrono::microseconds(t0 + 123'456));
    EXPECT_EQ(r->event, rx_start);
    EXPECT_EQ(r->control_lines, rts_dtr);
    EXPECT_EQ(std::vector<std::uint8_t>(r->payload.begin(), r->payload.end()), response);
    EXPECT_EQ(an::to_string(an::RtacEvent::ParityError), "PARITY_ERROR");
    EXPECT_FALSE(an::parse_rtac_serial(bytes({0, 0, 0, 1, 0, 0, 0, 2, 1, 0, 0})).has_value());  // 11 bytes
}

TEST(RtacSerial, MasterPollPairsWithTheRolesDirections) {
    auto r = decode(write_pcap("rtac_master.pcap", master_poll), mb::Direction::Request);
    ASSERT_TRUE(r->ok) << (r->summary.input_errors.empty() ? "" : r->summary.input_errors[0]);
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    const auto& t = r->sink.transactions[0];
    ASSERT_TRUE(t.response.has_value());
    EXPECT_EQ(t.request.direction, mb::Direction::Request);
    EXPECT_EQ(t.response->direction, mb::Direction::Response);
    EXPECT_EQ(t.request.packet, 1u);  // the record with its bytes (the TX end record, 2, completes it)
    EXPECT_EQ(t.response->packet, 3u);
    ASSERT_TRUE(t.latency.has_value());
    EXPECT_EQ(*t.latency, 20ms);  // each frame stamped by the record that carried its last byte
    EXPECT_TRUE(r->sink.findings.empty());
}

TEST(RtacSerial, WithoutARoleTheStateMachinePairs) {
    auto r = decode(write_pcap("rtac_norole.pcap", master_poll));
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());
    EXPECT_TRUE(r->sink.findings.empty());
}

TEST(RtacSerial, SlaveRoleTakesReceivedBytesAsRequests) {
    // The RTAC answers as a slave: the master's request arrives (RX), the RTAC replies (TX).
    const std::vector<Event> slave = {{t0, rx_start, request},
                                      {t0 + 8'333, rx_end, {}},
                                      {t0 + 20'000, tx_start, response},
                                      {t0 + 31'458, tx_end, {}}};
    auto r = decode(write_pcap("rtac_slave.pcap", slave), mb::Direction::Response);
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());
    EXPECT_EQ(r->sink.transactions[0].request.direction, mb::Direction::Request);
    EXPECT_TRUE(r->sink.findings.empty());
}

TEST(RtacSerial, LineErrorsAndLostDataAreFindings) {
    auto events = master_poll;
    events.insert(events.begin() + 2, {t0 + 19'000, parity_error, {}});
    events.push_back({t0 + 40'000, data_lost, {}});
    auto r = decode(write_pcap("rtac_errors.pcap", events), mb::Direction::Request);
    EXPECT_EQ(r->sink.count(mb::FindingCode::StreamLineError), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::StreamGap), 1);
    ASSERT_EQ(r->sink.transactions.size(), 1u);  // the bytes themselves still decode
    for (const auto& f : r->sink.findings) {
        if (f.code == mb::FindingCode::StreamLineError) {
            EXPECT_NE(f.message.find("PARITY_ERROR"), std::string::npos) << f.message;
            EXPECT_EQ(f.packet, 3u);
        }
    }
}

TEST(RtacSerial, ShortRecordIsNamedAndTheRestDecoded) {
    auto events = master_poll;
    events.insert(events.begin() + 2, {t0 + 10'000, tx_end, {}});
    auto r = decode(write_pcap("rtac_short.pcap", events, {{2, bytes({0, 0, 0, 1, 0})}}));
    ASSERT_EQ(r->summary.input_errors.size(), 1u);
    EXPECT_NE(r->summary.input_errors[0].find("packet 3"), std::string::npos) << r->summary.input_errors[0];
    EXPECT_NE(r->summary.input_errors[0].find("rtac_short.pcap"), std::string::npos);
    ASSERT_EQ(r->sink.transactions.size(), 1u);
    EXPECT_TRUE(r->sink.transactions[0].response.has_value());
}

TEST(RtacSerial, TsharkDecodesTheSameFrames) {
    if (std::system("command -v tshark >/dev/null 2>&1") != 0) GTEST_SKIP() << "tshark is not installed";
    // Three polls, the last answered with exception 02 (as 000:484 answers FC1; CRC C1 34 by hand).
    std::vector<Event> events;
    for (int i = 0; i < 3; ++i) {
        const std::int64_t base = t0 + i * 100'000;
        events.push_back({base, tx_start, request});
        events.push_back({base + 8'333, tx_end, {}});
        events.push_back({base + 20'000, rx_start, i < 2 ? response : bytes({0x11, 0x83, 0x02, 0xC1, 0x34})});
        events.push_back({base + 31'458, rx_end, {}});
    }
    const auto path = write_pcap("rtac_tshark.pcap", events);
    std::string fields;
    if (FILE* p = ::popen(("tshark -r '" + path +
                           "' -d rtacser.data,mbrtu -Y mbrtu -T fields -e mbrtu.unit_id -e modbus.func_code "
                           "-e modbus.regval_uint16 2>/dev/null")
                              .c_str(),
                          "r")) {
        std::array<char, 4096> buf{};
        while (std::size_t n = std::fread(buf.data(), 1, buf.size(), p))
            fields.append(buf.data(), n);
        ::pclose(p);
    }
    auto r = decode(path, mb::Direction::Request);
    std::string ours;
    for (const auto& f : r->sink.frames) {
        ours += std::to_string(f.frame.unit_id()) + "\t" + std::to_string(f.frame.pdu()[0] & 0x7F) + "\t";
        if (f.direction == mb::Direction::Response && f.frame.pdu()[0] == 3) ours += "555,0,100";
        ours += "\n";
    }
    EXPECT_EQ(fields, ours);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairExceptionResponse), 1);
}

}  // namespace test_analyzer_rtac_serial_test
