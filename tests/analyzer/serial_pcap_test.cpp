// Serial traffic inside pcap files: link types USER0..15 holding line bytes (--user-dlt rtu|ascii, with the
// records' capture times as the line's timing) and Wireshark exported PDUs (link type 252) named "mbrtu" or
// "mbtcp". Frames are the MK manual's FC3 example (000:356-370) in RTU and ASCII; the exported-PDU bytes in
// ExportedPdu.TextToPcapRecord are copied from a file text2pcap 4.0 wrote.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "analyzer/exported_pdu.hpp"
#include "analyzer/serial_input.hpp"
#include "test_packets.hpp"

namespace test_analyzer_serial_pcap_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;
using mbscope::test::bytes;
using mbscope::test::Collect;
using mbscope::test::decode_pcap;
using mbscope::test::pcap_file;
using mbscope::test::PcapRecord;

namespace {

constexpr int link_user0 = 147, link_user15 = 162, link_upper_pdu = 252;

const auto rtu_request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
const auto rtu_response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});

std::vector<std::uint8_t> text(const std::string& s) {
    return {s.begin(), s.end()};
}

an::AnalyzerOptions user_dlt(mb::Framing framing) {
    an::AnalyzerOptions o;
    o.user_dlt = framing;
    return o;
}

enum class Addresses { None, ClientToServer, ServerToClient };

// An exported-PDU record: the dissector name padded to 4 bytes as Wireshark writes it, optionally the IPv4
// addresses and ports of client 10.0.0.1:40000 and server 10.0.0.2:502 in either direction, the
// end-of-options tag, then the PDU.
std::vector<std::uint8_t> exported(const std::string& dissector, const std::vector<std::uint8_t>& pdu,
                                   Addresses addresses = Addresses::None) {
    std::vector<std::uint8_t> r;
    auto tag = [&r](std::uint16_t type, std::vector<std::uint8_t> value) {
        r.insert(r.end(),
                 {static_cast<std::uint8_t>(type >> 8), static_cast<std::uint8_t>(type),
                  static_cast<std::uint8_t>(value.size() >> 8), static_cast<std::uint8_t>(value.size())});
        r.insert(r.end(), value.begin(), value.end());
    };
    auto name = text(dissector);
    name.resize((name.size() + 3) / 4 * 4, 0);
    tag(12, name);
    const std::vector<std::uint8_t> client = {10, 0, 0, 1}, server = {10, 0, 0, 2};
    const std::vector<std::uint8_t> client_port = {0, 0, 0x9C, 0x40}, server_port = {0, 0, 0x01, 0xF6};
    if (addresses != Addresses::None) {
        const bool to_server = addresses == Addresses::ClientToServer;
        tag(20, to_server ? client : server);
        tag(21, to_server ? server : client);
        tag(25, to_server ? client_port : server_port);
        tag(26, to_server ? server_port : client_port);
    }
    tag(0, {});
    r.insert(r.end(), pdu.begin(), pdu.end());
    return r;
}

}  // namespace

TEST(UserLinkType, RtuChunksAreFramedWithTheirCaptureTimes) {
    // 9600 8N1: a character takes 1.0417 ms; the request arrives in two chunks back to back (less than t1.5
    // apart), the response 50 ms after the request's last byte.
    const std::vector<PcapRecord> records = {
        {1000ms, {rtu_request.begin(), rtu_request.begin() + 4}},
        {1000ms + 4167us, {rtu_request.begin() + 4, rtu_request.end()}},
        {1054167us, rtu_response},
    };
    auto d = decode_pcap(pcap_file(link_user0, records), user_dlt(mb::Framing::Rtu));
    ASSERT_EQ(d->sink.frames.size(), 2u);
    EXPECT_EQ(d->sink.frames[0].frame.length, 8u);
    EXPECT_EQ(d->sink.frames[0].direction, mb::Direction::Request);
    EXPECT_EQ(d->sink.frames[0].carrier, an::Carrier::Serial);
    EXPECT_EQ(d->sink.frames[1].direction, mb::Direction::Response);
    // Each names the packet its first byte came in (they said 0, unlike the same bytes from a text log).
    EXPECT_EQ(d->sink.frames[0].packet, 1u);
    EXPECT_EQ(d->sink.frames[1].packet, 3u);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    ASSERT_TRUE(d->sink.transactions[0].latency);
    EXPECT_EQ(*d->sink.transactions[0].latency, 50ms);
    EXPECT_TRUE(d->sink.findings.empty());
    EXPECT_TRUE(d->summary.input_errors.empty());
}

// A frame on a timed line ends with the silence after it, seen when the line's next bytes arrive: a reply
// 50 ms after its request, with the next poll 1.2 s later, was held until then, and the request was timed out
// first (a no_response, then the reply "50 ms after it, past the 1000 ms timeout"). The same when the next
// record is another line's (two serial captures decoded together).
TEST(UserLinkType, AReplyHeldForItsSilenceIsPairedBeforeRequestsTimeOut) {
    std::vector<PcapRecord> records;
    for (int i = 0; i < 3; ++i) {
        records.push_back({1s + i * 1200ms, rtu_request});
        records.push_back({1s + i * 1200ms + 50ms, rtu_response});
    }
    auto d = decode_pcap(pcap_file(link_user0, records), user_dlt(mb::Framing::Rtu));
    ASSERT_EQ(d->sink.transactions.size(), 3u);
    for (const auto& t : d->sink.transactions) {
        ASSERT_TRUE(t.latency);
        EXPECT_EQ(*t.latency, 50ms);
        EXPECT_FALSE(t.timed_out);
    }
    EXPECT_TRUE(d->sink.findings.empty());

    Collect sink;
    an::Analyzer a(user_dlt(mb::Framing::Rtu), sink);
    std::uint64_t number = 0;
    // A USER0 record of `source` to analyzer `to`.
    const auto record = [&number](an::Analyzer& to, const char* source, mb::Timestamp t,
                                  const std::vector<std::uint8_t>& bytes) {
        an::Packet p;
        p.number = ++number;
        p.time = t;
        p.linktype = link_user0;
        p.data = bytes;
        p.original_length = static_cast<std::uint32_t>(bytes.size());
        to.packet(source, p);
    };
    record(a, "a.pcap", 1s, rtu_request);
    record(a, "a.pcap", 1s + 50ms, rtu_response);
    record(a, "b.pcap", 2500ms, rtu_request);  // past a.pcap's deadline for its request, 2 s
    record(a, "b.pcap", 2550ms, rtu_response);
    record(a, "a.pcap", 3s, rtu_request);
    a.finish();
    EXPECT_EQ(a.summary().devices.at("serial a.pcap unit 17").responses, 1u);
    EXPECT_EQ(a.summary().devices.at("serial a.pcap unit 17").timeouts, 0u);
    EXPECT_EQ(a.summary().devices.at("serial b.pcap unit 17").responses, 1u);
    for (const auto& f : sink.findings)
        EXPECT_EQ(f.code, mb::FindingCode::PairNoResponseAtEnd) << f.message;

    // Another input's record says nothing of a line's silence: a reply read in two records, the second
    // stamped at its last byte (six bytes, 6.25 ms at 9600 baud, after the first), with another capture's
    // record between them, is one frame, not two damaged ones.
    const std::vector<std::uint8_t> head(rtu_response.begin(), rtu_response.begin() + 5),
        tail(rtu_response.begin() + 5, rtu_response.end());
    Collect split_sink;
    an::Analyzer b(user_dlt(mb::Framing::Rtu), split_sink);
    record(b, "a.pcap", 1s, rtu_request);
    record(b, "a.pcap", 1050ms, head);
    record(b, "b.pcap", 1054500us, {0x05, 0x03, 0x00, 0x60, 0x00, 0x01, 0x85, 0x90});
    record(b, "a.pcap", 1056500us, tail);
    b.finish();
    EXPECT_EQ(b.summary().devices.at("serial a.pcap unit 17").responses, 1u);
    EXPECT_EQ(b.summary().devices.at("serial a.pcap unit 17").checksum_errors, 0u);
    EXPECT_EQ(split_sink.count(mb::FindingCode::RtuCrcMismatch), 0);
}

TEST(UserLinkType, AnyOfTheSixteenCarriesAscii) {
    const std::vector<PcapRecord> records = {
        {1s, text(":1103006000038")},  // LRC 0x89 split over two records
        {1s + 1ms, text("9\r\n")},
        {1s + 40ms, text(":110306022B0000006455\r\n")},
    };
    auto d = decode_pcap(pcap_file(link_user15, records), user_dlt(mb::Framing::Ascii));
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    const auto& t = d->sink.transactions[0];
    EXPECT_EQ(t.request.frame.framing, mb::Framing::Ascii);
    ASSERT_TRUE(t.response);
    EXPECT_EQ(t.response->frame.unit_id(), 17);
    EXPECT_TRUE(d->sink.findings.empty());
}

TEST(UserLinkType, WithoutUserDltNothingIsDecodedAndTheInputSaysWhyOnce) {
    auto d = decode_pcap(pcap_file(link_user0, {{1s, rtu_request}, {1s + 50ms, rtu_response}}));
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_EQ(d->summary.packets, 2u);
    ASSERT_EQ(d->summary.input_errors.size(), 1u);
    EXPECT_NE(d->summary.input_errors[0].find("USER0"), std::string::npos);
    EXPECT_NE(d->summary.input_errors[0].find("--user-dlt"), std::string::npos);
}

TEST(ExportedPdu, TextToPcapRecord) {
    // text2pcap -P mbrtu writes the dissector name unpadded: tag 12, length 5, "mbrtu", end of options.
    const auto record = bytes({0x00, 0x0C, 0x00, 0x05, 'm',  'b',  'r',  't',  'u',  0x00, 0x00,
                               0x00, 0x00, 0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    auto p = an::parse_exported_pdu(record);
    ASSERT_TRUE(p);
    EXPECT_EQ(p->dissector, "mbrtu");
    EXPECT_FALSE(p->source);
    EXPECT_EQ(std::vector<std::uint8_t>(p->pdu.begin(), p->pdu.end()), rtu_request);
}

TEST(ExportedPdu, TruncatedTagsAreRejected) {
    EXPECT_FALSE(
        an::parse_exported_pdu(bytes({0x00, 0x0C, 0x00, 0x09, 'm', 'b'})));  // value runs past the end
    EXPECT_FALSE(an::parse_exported_pdu(bytes({0x00, 0x0C, 0x00, 0x00})));   // no end-of-options tag
    EXPECT_FALSE(an::parse_exported_pdu(bytes({0x00})));
}

TEST(ExportedPdu, MbrtuRecordsWithAddressesPairByLinkAndFlagABadCrc) {
    auto bad = rtu_response;
    bad.back() ^= 0x01;
    const std::vector<PcapRecord> records = {
        {1s, exported("mbrtu", rtu_request, Addresses::ClientToServer)},
        {1s + 30ms, exported("mbrtu", bad, Addresses::ServerToClient)},
        {2s,
         exported("mbrtu", bytes({0x11, 0x03}), Addresses::ClientToServer)},  // too short to be an RTU frame
    };
    auto d = decode_pcap(pcap_file(link_upper_pdu, records));
    ASSERT_EQ(d->sink.frames.size(), 2u);
    EXPECT_EQ(d->sink.frames[0].link, "10.0.0.1:40000 -> 10.0.0.2:502");
    EXPECT_EQ(d->sink.frames[0].carrier, an::Carrier::ExportedPdu);
    EXPECT_EQ(d->sink.frames[1].packet, 2u);
    EXPECT_FALSE(d->sink.frames[1].frame.checksum_ok);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    ASSERT_TRUE(d->sink.transactions[0].latency);
    EXPECT_EQ(*d->sink.transactions[0].latency, 30ms);
    EXPECT_EQ(d->sink.count(mb::FindingCode::RtuCrcMismatch), 1);
    EXPECT_EQ(d->summary.devices.at("10.0.0.2:502 unit 17").checksum_errors, 1u);
    ASSERT_EQ(d->sink.unparsed_records.size(), 1u);
    EXPECT_EQ(d->sink.unparsed_records[0].length, 2u);
    EXPECT_EQ(d->sink.unparsed_records[0].reason, mb::UnparsedReason::TooShort);
    EXPECT_EQ(d->sink.unparsed_records[0].direction, mb::Direction::Request);
}

TEST(ExportedPdu, MbtcpRecordsWithoutAddressesPairByTransactionId) {
    // TCP §4.4 style ADUs: tid 7, unit 17, FC3 from 0x6B for 3 registers; the reply holds 3 registers.
    const auto q = bytes({0x00, 0x07, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03});
    const auto a =
        bytes({0x00, 0x07, 0x00, 0x00, 0x00, 0x09, 0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64});
    auto d = decode_pcap(
        pcap_file(link_upper_pdu, {{1s, exported("mbtcp", q)}, {1s + 5ms, exported("mbtcp", a)}}));
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    const auto& t = d->sink.transactions[0];
    EXPECT_EQ(t.request.frame.transaction_id(), 7);
    EXPECT_EQ(t.request.direction, mb::Direction::Request);
    ASSERT_TRUE(t.response);
    EXPECT_EQ(t.response->direction, mb::Direction::Response);
    ASSERT_TRUE(t.latency);
    EXPECT_EQ(*t.latency, 5ms);
    EXPECT_TRUE(d->sink.findings.empty());
}

TEST(ExportedPdu, OtherDissectorsAreNotModbus) {
    auto d = decode_pcap(pcap_file(link_upper_pdu, {{1s, exported("sip", text("INVITE sip:a@b SIP/2.0\r\n"))},
                                                    {2s, bytes({0x00, 0x0C, 0x00, 0x40})}}));
    EXPECT_EQ(d->summary.packets, 2u);
    EXPECT_TRUE(d->sink.frames.empty());
    EXPECT_TRUE(d->sink.findings.empty());
}

TEST(ExportedPdu, CaptureWrittenByText2pcap) {
    if (std::system("command -v text2pcap >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "text2pcap not installed (Debian: wireshark-common)";
    const std::string dir = ::testing::TempDir();
    const std::string dump = dir + "mbrtu_dump.txt", capture = dir + "mbrtu_dump.pcapng";
    std::ofstream(dump) << "0000 11 03 00 60 00 03 07 45\n\n"
                           "0000 11 03 06 02 2B 00 00 00 64 C8 BA\n\n"
                           "0000 11 06 00 01 00 03 9A 9B\n\n"  // SL §2.5.1.2 style FC6, CRC 0x9B9A
                           "0000 11 06 00 01 00 03 9A 9B\n";
    ASSERT_EQ(std::system(("text2pcap -q -P mbrtu " + dump + " " + capture + " 2>/dev/null").c_str()), 0);
    mbscope::test::Collect sink;
    an::Analyzer a({}, sink);
    EXPECT_TRUE(an::read_input(a, capture, an::InputFormat::Auto));
    a.finish();
    ASSERT_EQ(sink.transactions.size(), 2u);
    EXPECT_EQ(sink.transactions[0].request.frame.unit_id(), 17);
    ASSERT_TRUE(sink.transactions[0].response);
    ASSERT_TRUE(sink.transactions[0].response->pdu);
    ASSERT_TRUE(sink.transactions[1].response);  // FC6 answered by its echo
    EXPECT_EQ(sink.transactions[1].request.pdu->function_code(), 6);
    EXPECT_TRUE(sink.findings.empty());
    EXPECT_EQ(a.summary().frames, 4u);
}

}  // namespace test_analyzer_serial_pcap_test
