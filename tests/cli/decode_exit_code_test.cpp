// `mbscope decode`'s exit code when part of the input is not decoded, and when the input is read whole but
// is not as a capture should be. A capture of a link type mbscope does not read decoded to nothing and
// exited 0, as a quiet network would; a log whose clock goes back was listed as an "input error" and
// exited 0 all the same.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "tests/cli/cli_run.hpp"

namespace test_cli_decode_exit_code_test {

using mbscope::test::run_mbscope;

namespace {

void put32(std::string& out, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
        out.push_back(static_cast<char>(v >> (8 * i)));
}

// A classic pcap (little-endian, microseconds) of `linktype` with one record per packet, a second apart.
std::string pcap(const std::string& name, std::uint32_t linktype, const std::vector<std::string>& packets) {
    std::string f;
    put32(f, 0xA1B2C3D4);
    f += std::string("\x02\x00\x04\x00", 4);
    put32(f, 0);
    put32(f, 0);
    put32(f, 65535);
    put32(f, linktype);
    std::uint32_t second = 1000;
    for (const auto& p : packets) {
        put32(f, second++);
        put32(f, 0);
        put32(f, static_cast<std::uint32_t>(p.size()));
        put32(f, static_cast<std::uint32_t>(p.size()));
        f += p;
    }
    const std::string path = ::testing::TempDir() + name;
    std::ofstream(path, std::ios::binary) << f;
    return path;
}

}  // namespace

// 802.11 (link type 105): nothing decoded, the file and link type named, exit 2.
TEST(DecodeExitCode, ALinkTypeNotDecodedFailsTheRun) {
    const auto path = pcap("decode-exit-wifi.pcap", 105, {std::string(40, '\0')});
    const auto r = run_mbscope("decode " + path);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope decode: " + path + ": link type 105 is not one mbscope decodes"),
              std::string::npos)
        << r.out;
}

// USER0 (147) carries what the capturing tool put there: without --user-dlt the RTU request in it is not
// decoded, and the run says how to decode it and fails; with --user-dlt rtu it decodes.
TEST(DecodeExitCode, AUserLinkTypeNotToldFailsTheRun) {
    const auto path =
        pcap("decode-exit-user0.pcap", 147, {std::string("\x11\x03\x00\x60\x00\x03\x07\x45", 8)});
    const auto untold = run_mbscope("decode " + path);
    EXPECT_EQ(untold.exit_code, 2) << untold.out;
    EXPECT_NE(untold.out.find("--user-dlt rtu|ascii|serial says what it carries"), std::string::npos)
        << untold.out;
    const auto told = run_mbscope("decode --user-dlt rtu " + path);
    EXPECT_EQ(told.exit_code, 0) << told.out;  // a request still unanswered at the end is no error
    EXPECT_NE(told.out.find("FC3 read 96+3"), std::string::npos) << told.out;
}

// Two sessions' logs joined (the second's clock earlier): every frame is decoded, so the run succeeds, and
// the step back is an input note, in the summary, on standard error and in JSON, not an input error.
TEST(DecodeExitCode, AClockGoingBackIsANoteNotAnError) {
    const std::string request = "11 03 00 60 00 03 07 45", reply = "11 03 06 02 2B 00 00 00 64 C8 BA";
    const std::string path = ::testing::TempDir() + "decode-exit-clock.txt";
    std::ofstream(path) << "100.000 " << request << "\n100.020 " << reply << "\n5.000 " << request
                        << "\n5.020 " << reply << "\n";
    const auto text = run_mbscope("decode " + path);
    EXPECT_EQ(text.exit_code, 0) << text.out;
    EXPECT_EQ(text.out.find("input error"), std::string::npos) << text.out;
    EXPECT_NE(text.out.find("  input note: " + path +
                            ": packet 3, the chunk stamped 5.000000 s: the capture's clock goes back"),
              std::string::npos)
        << text.out;
    EXPECT_NE(text.out.find("mbscope decode: note: " + path + ": packet 3, the chunk stamped 5.000000 s"),
              std::string::npos)
        << text.out;
    const auto json = run_mbscope("decode --json " + path);
    EXPECT_EQ(json.exit_code, 0) << json.out;
    EXPECT_NE(json.out.find("\"input_notes\""), std::string::npos) << json.out;
    EXPECT_EQ(json.out.find("\"input_errors\""), std::string::npos) << json.out;
}

// A Modbus/TCP request in UDP datagrams to port 1502, not a port decoded: the summary's hint named it, and
// the run said 0 (no fault) for a capture of which nothing was decoded. It fails now, the hint still given;
// with --udp-port 1502 the request is decoded.
TEST(DecodeExitCode, ModbusOnlyOnAPortNotDecodedFailsTheRun) {
    const std::string adu("\x00\x01\x00\x00\x00\x06\x11\x03\x00\x6B\x00\x03", 12);
    std::string datagram("\x45\x00\x00\x28\x00\x01\x00\x00\x40\x11\x00\x00\x0A\x00\x00\x01\x0A\x00\x00\x02",
                         20);  // IPv4, 40 bytes, UDP, 10.0.0.1 -> 10.0.0.2
    datagram += std::string("\x9C\x40\x05\xDE\x00\x14\x00\x00", 8);  // 40000 -> 1502, 20 bytes
    datagram += adu;
    const auto path = pcap("decode-exit-udp1502.pcap", 101, {datagram, datagram});
    const auto r = run_mbscope("decode " + path);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(
        r.out.find("hint: 2 UDP packets on port 1502 hold Modbus/TCP ADUs; decode them with --udp-port 1502"),
        std::string::npos)
        << r.out;
    EXPECT_NE(
        r.out.find("mbscope decode: no Modbus frame decoded, while packets on ports not decoded hold Modbus"),
        std::string::npos)
        << r.out;
    const auto told = run_mbscope("decode --udp-port 1502 " + path);
    EXPECT_NE(told.out.find("FC3 read 107+3"), std::string::npos) << told.out;
    EXPECT_NE(told.exit_code, 2) << told.out;
}

}  // namespace test_cli_decode_exit_code_test
