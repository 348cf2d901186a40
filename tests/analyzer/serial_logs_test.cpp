// Logs of other serial tools as inputs: jpnevulator --read --timing-print and socat -x -v. The logs below
// were written by the tools themselves (jpnevulator 2.3.6 and socat 1.7.4.4, Debian 12) over socat pty
// pairs, with the MK manual's FC3 example (000:356-370), its FC1 request and exception 02 (000:330, 484)
// written into the ptys; expected times and directions are worked out by hand from the log lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <tuple>

#include "analyzer/serial_input.hpp"
#include "analyzer/serial_logs.hpp"
#include "modbus/storage/text_file.hpp"
#include "test_packets.hpp"

namespace test_analyzer_serial_logs_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;
using mbscope::test::Collect;
using mbscope::test::write_temp;
using namespace std::chrono_literals;

namespace {

// 2026-11-30 06:22:57 UTC (date -u -d ... +%s)
constexpr std::int64_t jpnevulator_second = 1796019777;
// jpnevulator --read --pass --timing-print --ascii --tty /tmp/jp_m2:master --tty /tmp/jp_s2:slave, the
// master writing the FC3 request (the second time in two writes 10 ms apart), the slave answering (the
// second time twice in one write); jpnevulator was stopped with SIGTERM, so its last line has no ASCII.
const std::string jpnevulator_log =
    "2026-11-30 06:22:57.009496: master\n"
    "11 03 00 6B 00 03 76 87                        \t...k..v.\n"
    "2026-11-30 06:22:57.028670: slave\n"
    "11 03 06 02 2B 00 00 00 64 C8 BA               \t....+...d..\n"
    "2026-11-30 06:22:57.333966: master\n"
    "11 03 00 6B 00 03 76 87                        \t...k..v.\n"
    "2026-11-30 06:22:57.372110: slave\n"
    "11 03 06 02 2B 00 00 00 64 C8 BA 11 03 06 02 2B\t....+...d......+\n"
    "00 00 00 64 C8 BA";

// 2026-11-30 06:29:31 UTC
constexpr std::int64_t socat_second = 1796020171;
// socat -d -d -x -v pty,raw,echo=0,link=/tmp/sx_m pty,raw,echo=0,link=/tmp/sx_s (standard error), the
// master on sx_m, the slave on sx_s; cut after the fourth block.
const std::string socat_log =
    "2026/11/30 06:29:30 socat[25059] N PTY is /dev/pts/0\n"
    "2026/11/30 06:29:30 socat[25059] N PTY is /dev/pts/1\n"
    "2026/11/30 06:29:30 socat[25059] N starting data transfer loop with FDs [5,5] and [7,7]\n"
    "> 2026/11/30 06:29:31.000429684  length=8 from=0 to=7\n"
    " 11 03 00 6b 00 03 76 87                          ...k..v.\n"
    "--\n"
    "< 2026/11/30 06:29:31.000451484  length=11 from=0 to=10\n"
    " 11 03 06 02 2b 00 00 00 64 c8 ba                 ....+...d..\n"
    "--\n"
    "> 2026/11/30 06:29:31.000503159  length=8 from=8 to=15\n"
    " 11 01 00 13 00 15 0e 90                          ........\n"
    "--\n"
    "< 2026/11/30 06:29:31.000524845  length=5 from=11 to=15\n"
    " 11 81 02 c0 54                                   ....T\n"
    "--\n"
    "2026/11/30 06:29:31 socat[25059] N socat_signal(): handling signal 15\n"
    "2026/11/30 06:29:31 socat[25059] W exiting on signal 15\n";

const auto fc3_request = bytes({0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87});
const auto fc3_response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});

struct Parsed {
    std::vector<an::SerialChunk> chunks;
    std::vector<std::string> errors;
    bool ok = false;
};

using Reader = bool (*)(std::istream&, const std::string&, const an::SerialLogOptions&,
                        const an::ChunkCallback&, const an::LogErrorCallback&);

Parsed parse(Reader reader, const std::string& name, const std::string& log,
             const an::SerialLogOptions& options) {
    Parsed p;
    std::istringstream in(log);
    p.ok = reader(
        in, name, options, [&](const an::SerialChunk& c) { p.chunks.push_back(c); },
        [&](const std::string& e) { p.errors.push_back(e); });
    return p;
}

Parsed jpnevulator(const std::string& log, const an::SerialLogOptions& options = {}) {
    return parse(an::read_jpnevulator_log, "jp.log", log, options);
}

Parsed socat(const std::string& log, const an::SerialLogOptions& options = {}) {
    return parse(an::read_socat_log, "socat.log", log, options);
}

mb::Timestamp at(std::int64_t second, std::int64_t us) {
    return std::chrono::seconds(second) + std::chrono::microseconds(us);
}

struct Run {
    Collect sink;
    an::Summary summary;
    bool ok = false;
};

std::unique_ptr<Run> decode(const std::string& path, an::InputFormat format,
                            const an::SerialLogOptions& logs = {}, an::AnalyzerOptions options = {}) {
    auto r = std::make_unique<Run>();
    an::Analyzer a(std::move(options), r->sink);
    r->ok = an::read_input(a, path, format, logs);
    a.finish();
    r->summary = a.summary();
    return r;
}

}  // namespace

TEST(JpnevulatorLog, RunsBecomeChunksWithTheAliasesDirection) {
    const auto p = jpnevulator(jpnevulator_log);
    ASSERT_TRUE(p.ok) << (p.errors.empty() ? "" : p.errors[0]);
    ASSERT_EQ(p.chunks.size(), 4u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_request);
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
    EXPECT_EQ(p.chunks[2].bytes, fc3_request);  // two writes 10 ms apart: one run (under --timing-delta)
    ASSERT_EQ(p.chunks[3].bytes.size(), 22u);
    const mb::Direction expected[] = {mb::Direction::Request, mb::Direction::Response, mb::Direction::Request,
                                      mb::Direction::Response};
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(p.chunks[i].direction, expected[i]) << i;
    }
    // The stamp is the run's first read; 9600 8N1 puts 7 more characters of 1041.667 us after it.
    EXPECT_EQ(p.chunks[0].received, at(jpnevulator_second, 9496) + 7 * 1041666ns);
    EXPECT_EQ(p.chunks[1].received, at(jpnevulator_second, 28670) + 10 * 1041666ns);
}

TEST(JpnevulatorLog, UserAliasesNameTheMasterAndTheOtherTtyIsTheSlave) {
    std::string log = jpnevulator_log;
    for (auto [from, to] : {std::pair{"master", "/dev/ttyS0"}, std::pair{"slave", "/dev/ttyUSB0"}})
        for (auto pos = log.find(from); pos != std::string::npos; pos = log.find(from, pos))
            log.replace(pos, std::string(from).size(), to);
    EXPECT_EQ(jpnevulator(log).chunks[0].direction, mb::Direction::Unknown);  // nothing says who is who
    an::SerialLogOptions o;
    o.master_alias = "/dev/ttyUSB0";
    const auto p = jpnevulator(log, o);
    ASSERT_EQ(p.chunks.size(), 4u);
    EXPECT_EQ(p.chunks[0].direction, mb::Direction::Response);
    EXPECT_EQ(p.chunks[1].direction, mb::Direction::Request);
}

// An alias the log never names ("ttyUSB0" for "/dev/ttyUSB0") made every tty the slave's: each request was
// decoded as a malformed response, the devices blamed for byte counts and quantities, exit 1, and nothing
// said the alias matched nothing. It is an input error naming the log's ttys.
TEST(JpnevulatorLog, AnAliasTheLogNeverNamesIsAnError) {
    std::string log = jpnevulator_log;
    for (auto [from, to] : {std::pair{"master", "/dev/ttyS0"}, std::pair{"slave", "/dev/ttyUSB0"}})
        for (auto pos = log.find(from); pos != std::string::npos; pos = log.find(from, pos))
            log.replace(pos, std::string(from).size(), to);
    for (const bool master : {true, false}) {
        an::SerialLogOptions o;
        (master ? o.master_alias : o.slave_alias) = "ttyUSB0";
        const auto p = jpnevulator(log, o);
        EXPECT_FALSE(p.ok);
        ASSERT_EQ(p.errors.size(), 1u);
        EXPECT_EQ(p.errors[0], std::string("jp.log: ") + (master ? "--master-alias" : "--slave-alias") +
                                   " 'ttyUSB0' names no tty of the log, so every tty would be taken for the "
                                   "other side; the log's ttys: '/dev/ttyS0', '/dev/ttyUSB0'");
    }
    an::SerialLogOptions named;
    named.slave_alias = "/dev/ttyS0";
    EXPECT_TRUE(jpnevulator(log, named).ok);
}

TEST(JpnevulatorLog, ByteCountBinaryControlAndAliasLinesAreRead) {
    // Formats of jpnevulator.c: --byte-count "%08lX\t", --base 2, --control "le=%d, dtr=%d, ...", and several
    // ttys without --timing-print (a line with the tty name before its bytes: no timing).
    const auto p = jpnevulator(
        "2026-11-30 06:22:57.009496: M\n"
        "00000000\t11 03 00 6B 00 03 76 87\t...k..v.\n"
        "le=0, dtr=1, rts=1, st=0, sr=0, cts=0, cd=0, ri=0, dsr=0\n"
        "2026-11-30 06:22:57.028670: S\n"
        "00010001 00000011\n");
    ASSERT_TRUE(p.ok) << (p.errors.empty() ? "" : p.errors[0]);
    ASSERT_EQ(p.chunks.size(), 2u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_request);
    EXPECT_EQ(p.chunks[1].bytes, bytes({0x11, 0x03}));
    EXPECT_EQ(p.chunks[1].direction, mb::Direction::Response);

    const auto untimed = jpnevulator("/dev/ttyS0\n11 03 00 6B\n/dev/ttyUSB0\n11 03\n");
    ASSERT_EQ(untimed.chunks.size(), 2u);
    EXPECT_EQ(untimed.chunks[0].received.count(), 0);
}

// --ascii's column after its tab became spaces (a log pasted from a page or re-indented, as the analyzer
// README's own example): it was "not a jpnevulator timestamp or data line", exit 2. The column is the
// rendering of the line's bytes, whatever stands before it: padding, one space after sixteen bytes, an
// offset followed by spaces (read as a binary byte before), an indentation.
TEST(JpnevulatorLog, AnAsciiColumnAfterSpacesIsLeftAside) {
    const auto p = jpnevulator(
        "2026-11-30 06:22:57.009496: master\n"
        "11 03 00 6B 00 03 76 87                         ...k..v.\n"
        "2026-11-30 06:22:57.028670: slave\n"
        "11 03 06 02 2B 00 00 00 64 C8 BA                ....+...d..\n");
    ASSERT_TRUE(p.ok) << (p.errors.empty() ? "" : p.errors[0]);
    ASSERT_EQ(p.chunks.size(), 2u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_request);
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
    const auto full = jpnevulator(
        "2026-11-30 06:22:57.009496: M\n"
        "11 03 0C 41 42 43 44 45 46 47 48 49 4A 4B 4C 4D ...ABCDEFGHIJKLM\n"
        "00000010        4E 4F                           NO\n"
        "    41 42  AB\n"
        "11 03  11 03\n");
    ASSERT_TRUE(full.ok) << (full.errors.empty() ? "" : full.errors[0]);
    ASSERT_EQ(full.chunks.size(), 1u);
    EXPECT_EQ(full.chunks[0].bytes,
              bytes({0x11, 0x03, 0x0C, 0x41, 0x42, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49,
                     0x4A, 0x4B, 0x4C, 0x4D, 0x4E, 0x4F, 0x41, 0x42, 0x11, 0x03, 0x11, 0x03}));
    // Something after the bytes that is not their column is no data line.
    const auto bad = jpnevulator("2026-11-30 06:22:57.009496: M\n11 03  xyz\n");
    EXPECT_FALSE(bad.ok);
}

TEST(JpnevulatorLog, BadLinesAreNamedAndTheRestRead) {
    const auto p = jpnevulator(
        "2026-11-30 06:22:57.009496: master\n"
        "11 03 00 6B 00 03 76 87\n"
        "2026-13-30 06:22:57.028670: slave\n"
        "11 0G\n"
        "2026-11-30 06:22:57.333966: slave\n"
        "11 03 06 02 2B 00 00 00 64 C8 BA\n");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 2u);
    EXPECT_EQ(p.errors[0].rfind("jp.log:3: ", 0), 0u) << p.errors[0];  // month 13
    EXPECT_EQ(p.errors[1].rfind("jp.log:4: ", 0), 0u) << p.errors[1];
    ASSERT_EQ(p.chunks.size(), 2u);
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
}

TEST(JpnevulatorLog, DecodesIntoTransactionsWithARepeatedResponse) {
    auto r = decode(write_temp("jp.log", jpnevulator_log), an::InputFormat::Auto);
    ASSERT_TRUE(r->ok) << (r->summary.input_errors.empty() ? "" : r->summary.input_errors[0]);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    for (const auto& t : r->sink.transactions) {
        EXPECT_TRUE(t.response.has_value());
        EXPECT_EQ(t.request.direction, mb::Direction::Request);
    }
    // the slave's second answer in the last run is the first again: one request answered twice
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairDuplicateResponse), 1);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairUnsolicitedResponse), 0);
    EXPECT_EQ(r->sink.count(mb::FindingCode::RtuCrcMismatch), 0);
}

TEST(SocatLog, BlocksBecomeChunksStampedWhenRead) {
    const auto p = socat(socat_log);
    ASSERT_TRUE(p.ok) << (p.errors.empty() ? "" : p.errors[0]);
    ASSERT_EQ(p.chunks.size(), 4u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_request);
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
    EXPECT_EQ(p.chunks[3].bytes, bytes({0x11, 0x81, 0x02, 0xC0, 0x54}));
    EXPECT_EQ(p.chunks[0].direction, mb::Direction::Request);
    EXPECT_EQ(p.chunks[1].direction, mb::Direction::Response);
    // socat 1.7.4: ".000429684" is 429684 us (the blocks were written 20 and 50 ms apart)
    EXPECT_EQ(p.chunks[0].received, at(socat_second, 429684));
    EXPECT_EQ(p.chunks[2].received, at(socat_second, 503159));

    an::SerialLogOptions right;
    right.socat_master_left = false;
    EXPECT_EQ(socat(socat_log, right).chunks[0].direction, mb::Direction::Response);
}

TEST(SocatLog, HexLinesAlsoBreakAfterANewlineByte) {
    // pymodbus's FC3 request through socat -x -v: its 0x0A quantity ends the first hex line
    const auto p = socat(
        "> 2026/11/30 06:35:36.000247483  length=8 from=8 to=15\n"
        " 11 03 00 7a 00 0a                                ...z..\n"
        " e6 84                                            ..\n"
        "--\n");
    ASSERT_TRUE(p.ok) << (p.errors.empty() ? "" : p.errors[0]);
    ASSERT_EQ(p.chunks.size(), 1u);
    EXPECT_EQ(p.chunks[0].bytes, bytes({0x11, 0x03, 0x00, 0x7A, 0x00, 0x0A, 0xE6, 0x84}));
}

TEST(SocatLog, NineDigitsAreNanosecondsWhenTheyDoNotAllStartWithZeros) {
    const auto p = socat(
        "> 2026/11/30 06:29:31.123456789  length=1 from=0 to=0\n 11\n--\n"
        "> 2026/11/30 06:29:31.000000100  length=1 from=1 to=1\n 03\n--\n"
        "> 2026/11/30 06:29:32.250000  length=1 from=2 to=2\n 00\n");
    ASSERT_TRUE(p.ok);
    ASSERT_EQ(p.chunks.size(), 3u);
    EXPECT_EQ(p.chunks[0].received, std::chrono::seconds(socat_second) + 123456789ns);
    EXPECT_EQ(p.chunks[1].received, std::chrono::seconds(socat_second) + 100ns);
    EXPECT_EQ(p.chunks[2].received, at(socat_second + 1, 250000));
}

TEST(SocatLog, TextDumpWithoutHexIsRefusedWithTheFix) {
    // socat -v alone over the same ptys: the bytes as text, non-printable ones as '.'
    const auto p = socat(
        "> 2026/11/30 06:23:28.000617474  length=8 from=0 to=7\n"
        "...k..v.< 2026/11/30 06:23:28.000641852  length=11 from=0 to=10\n"
        "....+...d..");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 1u);
    EXPECT_NE(p.errors[0].find("socat.log:2: "), std::string::npos);
    EXPECT_NE(p.errors[0].find("socat -x -v"), std::string::npos);
    EXPECT_TRUE(p.chunks.empty());
}

TEST(SocatLog, ShortBlocksAndStrayLinesAreNamedAndTheRestRead) {
    const auto p = socat(
        "> 2026/11/30 06:29:31.000429684  length=8 from=0 to=7\n"
        " 11 03 00 6b\n"
        "< 2026/11/30 06:29:31.000451484  length=11 from=0 to=10\n"
        " 11 03 06 02 2b 00 00 00 64 c8 ba                 ....+...d..\n"
        "garbage\n");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 2u);
    EXPECT_EQ(p.errors[0].rfind("socat.log:1: ", 0), 0u) << p.errors[0];  // 4 of 8 bytes
    EXPECT_EQ(p.errors[1].rfind("socat.log:5: ", 0), 0u) << p.errors[1];
    ASSERT_EQ(p.chunks.size(), 2u);
    EXPECT_EQ(p.chunks[0].bytes.size(), 4u);  // what there was, still decoded
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
}

// A data line holding more bytes than its header announced (a log edited, two blocks run together): the
// announced bytes are the block, and the rest are an error naming the line, not dropped unseen. An ASCII
// column that reads as hex ("ab" for 61 62) is no such bytes.
TEST(SocatLog, BytesPastTheAnnouncedLengthAreNamedNotDropped) {
    const auto p = socat(
        "> 2026/11/30 06:29:31.000429684  length=8 from=0 to=7\n"
        " 11 03 00 6b 00 03 76 87                          ...k..v.\n"
        "--\n"
        "< 2026/11/30 06:29:31.000451484  length=11 from=0 to=10\n"
        " 11 03 06 02 2b 00 00 00 64 c8 ba 99 98\n"
        "--\n"
        "> 2026/11/30 06:29:31.000503159  length=2 from=8 to=9\n"
        " 61 62                                            ab\n"
        "--\n");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 1u);
    EXPECT_EQ(p.errors[0].rfind("socat.log:5: ", 0), 0u) << p.errors[0];
    EXPECT_NE(p.errors[0].find("2 more, not decoded: 99 98"), std::string::npos) << p.errors[0];
    ASSERT_EQ(p.chunks.size(), 3u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_request);
    EXPECT_EQ(p.chunks[1].bytes, fc3_response);
    EXPECT_EQ(p.chunks[2].bytes, bytes({0x61, 0x62}));
}

// After its hex pairs a socat -x line holds nothing, or (-x -v) spaces to column 50 and one character a byte.
// Anything else (a log edited by hand) is named, not dropped unseen: the pairs before it are still read.
TEST(SocatLog, TextAfterThePairsThatIsNoAsciiColumnIsNamed) {
    const auto p = socat(
        "> 2026/11/30 06:29:31.000429684  length=2 from=0 to=1\n"
        " 11 03 zz\n"
        "--\n"
        "> 2026/11/30 06:29:31.000451484  length=2 from=2 to=3\n"
        " 11 03                                            ..xyz\n"
        "--\n"
        "> 2026/11/30 06:29:31.000503159  length=2 from=4 to=5\n"
        " 61 62                                            ab\n"
        "--\n");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 2u);
    EXPECT_EQ(p.errors[0].rfind("socat.log:2: ", 0), 0u) << p.errors[0];
    EXPECT_NE(p.errors[0].find("not decoded: 'zz'"), std::string::npos) << p.errors[0];
    EXPECT_EQ(p.errors[1].rfind("socat.log:5: ", 0), 0u) << p.errors[1];
    ASSERT_EQ(p.chunks.size(), 3u);
    EXPECT_EQ(p.chunks[0].bytes, bytes({0x11, 0x03}));
    EXPECT_EQ(p.chunks[1].bytes, bytes({0x11, 0x03}));
    EXPECT_EQ(p.chunks[2].bytes, bytes({0x61, 0x62}));
}

// A header and "--" with no data line between (a log cut or edited) is a block whose bytes are missing,
// named at its header; it was taken for socat's text mode and the rest of the log was not read.
TEST(SocatLog, ABlockWithoutDataLinesIsNamedAsMissingItsBytes) {
    const auto p = socat(
        "> 2026/11/30 06:29:31.000429684  length=8 from=0 to=7\n"
        "--\n"
        "< 2026/11/30 06:29:31.000451484  length=11 from=0 to=10\n"
        " 11 03 06 02 2b 00 00 00 64 c8 ba                 ....+...d..\n"
        "--\n");
    EXPECT_FALSE(p.ok);
    ASSERT_EQ(p.errors.size(), 1u);
    EXPECT_EQ(p.errors[0].rfind("socat.log:1: block announces 8 bytes and the log holds none of them", 0), 0u)
        << p.errors[0];
    EXPECT_EQ(p.errors[0].find("-x -v"), std::string::npos) << p.errors[0];
    ASSERT_EQ(p.chunks.size(), 1u);
    EXPECT_EQ(p.chunks[0].bytes, fc3_response);
}

TEST(SocatLog, DecodesRequestsExceptionsAndLatency) {
    auto r = decode(write_temp("socat.log", socat_log), an::InputFormat::Auto);
    ASSERT_TRUE(r->ok) << (r->summary.input_errors.empty() ? "" : r->summary.input_errors[0]);
    ASSERT_EQ(r->sink.transactions.size(), 2u);
    ASSERT_TRUE(r->sink.transactions[0].latency.has_value());
    // both chunks stamped at their last byte: 451484 - 429684 us
    EXPECT_EQ(*r->sink.transactions[0].latency, 21800us);
    EXPECT_EQ(r->sink.count(mb::FindingCode::PairExceptionResponse), 1);
    EXPECT_EQ(r->summary.unparsed_bytes, 0u);
}

TEST(SerialLogs, FormatDetection) {
    auto d = [](const std::string& s) {
        return an::detect_input_format({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()});
    };
    EXPECT_EQ(d(jpnevulator_log), an::InputFormat::Jpnevulator);
    EXPECT_EQ(d(socat_log), an::InputFormat::Socat);
    EXPECT_EQ(d(socat_log.substr(socat_log.find("> "))), an::InputFormat::Socat);
    EXPECT_EQ(d("1.000 > 11 03 00 60\n"), an::InputFormat::Text);
    EXPECT_EQ(an::parse_input_format("jpnevulator"), an::InputFormat::Jpnevulator);
    EXPECT_EQ(an::parse_input_format("socat"), an::InputFormat::Socat);
}

// Times are nanoseconds since 1970 in 64 bits: a text log whose time parses as a double but is not a
// representable time (found by fuzzing: "1e300" overflowed the conversion) is a named bad line.
TEST(TextLog, TimesThatAreNotRepresentableAreNamedAndTheRestRead) {
    const auto path = write_temp("mbscope-text-times.txt",
                                 "1e300 > 11 03 00 6B 00 03 76 87\n"
                                 "nan > 11 03 00 6B 00 03 76 87\n"
                                 "inf > 11 03 00 6B 00 03 76 87\n"
                                 "9300000000 > 11 03 00 6B 00 03 76 87\n"
                                 "1.5 > 11 03 00 6B 00 03 76 87\n");
    const auto r = decode(path, an::InputFormat::Text);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 4u);
    EXPECT_NE(r->summary.input_errors[0].find(":1: not a time"), std::string::npos)
        << r->summary.input_errors[0];
    EXPECT_NE(r->summary.input_errors[3].find(":4: not a time"), std::string::npos)
        << r->summary.input_errors[3];
    ASSERT_EQ(r->sink.frames.size(), 1u);
    EXPECT_EQ(r->sink.frames[0].time, mb::Timestamp(1'500'000'000));
}

// A line longer than a line may hold (a file without newlines, a binary file named .log) is a named error,
// cut and read past, and the lines after it are read: no reader holds a whole hostile file in one string.
TEST(SerialLogs, LinesLongerThanTheBoundAreNamedAndTheRestRead) {
    const std::string huge(mbscope::modbus::storage::max_line_length + 5, '7');
    const auto jp = jpnevulator("2026-11-30 06:22:57.009496: master\n" + huge +
                                "\n"
                                "2026-11-30 06:22:57.028670: slave\n"
                                "11 03 06 02 2B 00 00 00 64 C8 BA\n");
    EXPECT_FALSE(jp.ok);
    ASSERT_EQ(jp.errors.size(), 1u);
    EXPECT_EQ(jp.errors[0].rfind("jp.log:2: line of " + std::to_string(huge.size()) + " bytes is longer", 0),
              0u)
        << jp.errors[0].substr(0, 200);
    ASSERT_EQ(jp.chunks.size(), 1u);
    EXPECT_EQ(jp.chunks[0].bytes, fc3_response);

    const auto sc = socat(huge +
                          "\n"
                          "< 2026/11/30 06:29:31.000451484  length=11 from=0 to=10\n"
                          " 11 03 06 02 2b 00 00 00 64 c8 ba                 ....+...d..\n");
    EXPECT_FALSE(sc.ok);
    ASSERT_EQ(sc.errors.size(), 1u);
    EXPECT_EQ(sc.errors[0].rfind("socat.log:1: line of ", 0), 0u) << sc.errors[0].substr(0, 200);
    ASSERT_EQ(sc.chunks.size(), 1u);
    EXPECT_EQ(sc.chunks[0].bytes, fc3_response);

    const auto path = write_temp("mbscope-text-long-line.txt", "1.0 > " + huge +
                                                                   "\n"
                                                                   "1.5 > 11 03 00 6B 00 03 76 87\n");
    const auto r = decode(path, an::InputFormat::Text);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 1u);
    EXPECT_NE(r->summary.input_errors[0].find(":1: line of "), std::string::npos)
        << r->summary.input_errors[0].substr(0, 200);
    EXPECT_LT(r->summary.input_errors[0].size(), 300u);  // the line is not quoted whole
    ASSERT_EQ(r->sink.frames.size(), 1u);
    EXPECT_EQ(r->sink.frames[0].time, mb::Timestamp(1'500'000'000));
}

// An input from which not one data byte was read (comments alone, a log's header alone, socat -d
// diagnostics alone) decodes to nothing, as an empty file does: an input error naming it, not a quiet line.
TEST(SerialLogs, InputsWithoutADataByteAreInputErrors) {
    for (const auto& [name, content] :
         {std::pair{"mbscope-no-bytes.txt", "# only a comment\n"},
          std::pair{"mbscope-no-bytes-jp.log", "2026-11-30 06:22:57.009496: master\n"},
          std::pair{"mbscope-no-bytes-socat.log",
                    "2026/11/30 06:29:30 socat[25059] N PTY is /dev/pts/0\n"}}) {
        SCOPED_TRACE(name);
        const auto path = write_temp(name, content);
        const auto r = decode(path, an::InputFormat::Auto);
        EXPECT_FALSE(r->ok);
        ASSERT_EQ(r->summary.input_errors.size(), 1u);
        EXPECT_EQ(r->summary.input_errors[0], path + ": no data bytes in it, nothing to decode");
    }
}

// "TIME [DIR] HEX...": a time and a direction with no bytes is a malformed line, named, not a packet of
// nothing; the lines after it still decode.
TEST(TextLog, ATimeWithoutBytesIsAMalformedLine) {
    const auto path = write_temp("mbscope-text-no-bytes.txt",
                                 "1.0 > \n"
                                 "1.2\n"
                                 "1.5 > 11 03 00 6B 00 03 76 87\n");
    const auto r = decode(path, an::InputFormat::Text);
    EXPECT_FALSE(r->ok);
    ASSERT_EQ(r->summary.input_errors.size(), 2u);
    EXPECT_EQ(r->summary.input_errors[0].rfind(path + ":1: a time and no bytes after it", 0), 0u)
        << r->summary.input_errors[0];
    EXPECT_EQ(r->summary.input_errors[1].rfind(path + ":2: a time and no bytes after it", 0), 0u)
        << r->summary.input_errors[1];
    EXPECT_EQ(r->summary.packets, 1u);
    ASSERT_EQ(r->sink.frames.size(), 1u);
    EXPECT_EQ(r->sink.frames[0].time, mb::Timestamp(1'500'000'000));
}

// A progress line for a serial log moves within the file: the readers report the offset they reached every
// so many records, in order, never past the end.
TEST(SerialLogs, ProgressReportsOffsetsWithinAFile) {
    std::string text, raw;
    for (int i = 0; i < 5000; ++i)
        text += std::to_string(i) + ".000 > 11 03 00 6B 00 03 76 87\n";
    raw.assign(300000, '\x11');
    for (const auto& [name, content, format] :
         {std::tuple{"mbscope-progress.txt", text, an::InputFormat::Text},
          std::tuple{"mbscope-progress.bin", raw, an::InputFormat::RtuRaw}}) {
        SCOPED_TRACE(name);
        const auto path = write_temp(name, content);
        std::vector<std::uint64_t> offsets;
        an::AnalyzerOptions options;
        options.progress = [&](const an::Summary&, std::uint64_t offset) { offsets.push_back(offset); };
        decode(path, format, {}, options);
        ASSERT_GE(offsets.size(), 4u);
        EXPECT_TRUE(std::is_sorted(offsets.begin(), offsets.end()));
        EXPECT_GT(offsets.front(), 0u);
        EXPECT_LE(offsets.back(), content.size());
        EXPECT_GT(offsets.back(), content.size() / 2);
    }
}

}  // namespace test_analyzer_serial_logs_test
