// `mbscope frame` end to end: the real binary, its output and its exit codes.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_frame_command_test {

namespace {

using mbscope::test::run_mbscope;

}  // namespace

TEST(FrameCommand, DecodesTheManualsFc3Request) {
    auto r = run_mbscope("frame --rtu 11 03 00 60 00 03 07 45");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("Read Holding Registers"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("starting_address"), std::string::npos);
    EXPECT_NE(r.out.find("40097"), std::string::npos);
    EXPECT_NE(r.out.find("ok (sent low byte first)"), std::string::npos);
}

TEST(FrameCommand, BadCrcExitsOneAndSaysWhat) {
    auto r = run_mbscope("frame --rtu 11 03 00 60 00 03 07 46");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.out.find("rtu.crc_mismatch"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("computed 0x4507"), std::string::npos) << r.out;
}

// Exit 1 is for a rule broken at error severity, as in decode: a note (a function code that is not public)
// or a warning (lowercase ASCII hex) is shown and exits 0. frame exited 1 on them, decode 0 on the same
// bytes.
TEST(FrameCommand, NotesAndWarningsAreShownAndExitZero) {
    const auto user_function = run_mbscope("frame --rtu 11 41 01 02 D5 5D");
    EXPECT_EQ(user_function.exit_code, 0) << user_function.out;
    EXPECT_NE(user_function.out.find("pdu.unknown_function (note)"), std::string::npos) << user_function.out;
    const auto lowercase = run_mbscope("frame --ascii ':11100060000204000a01026c'");
    EXPECT_EQ(lowercase.exit_code, 0) << lowercase.out;
    EXPECT_NE(lowercase.out.find("ascii.lowercase_hex (warning)"), std::string::npos) << lowercase.out;
    // A warning beside an error still exits 1.
    const auto both = run_mbscope("frame --ascii ':11100060000204000a01026d'");
    EXPECT_EQ(both.exit_code, 1) << both.out;
}

TEST(FrameCommand, UndecodableExitsTwo) {
    EXPECT_EQ(run_mbscope("frame --rtu 11 03").exit_code, 2);
    EXPECT_EQ(run_mbscope("frame --rtu 11 0G").exit_code, 2);
    EXPECT_EQ(run_mbscope("frame --tcp 00 01 00 00 00 01 11 03").exit_code, 2);
    EXPECT_EQ(run_mbscope("frame 11 03").exit_code, 2);
}

TEST(FrameCommand, AsciiTextAndJson) {
    auto r = run_mbscope("frame --ascii :11100060000204000A01026C --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["framing"], "ascii");
    EXPECT_EQ(j["function_code"], 16);
    EXPECT_EQ(j["checksum_ok"], true);
    bool found = false;
    for (const auto& f : j["fields"])
        if (f["name"] == "registers_value") {
            EXPECT_EQ(f["value"], nlohmann::json::array({10, 258}));
            found = true;
        }
    EXPECT_TRUE(found) << r.out;
}

TEST(FrameCommand, EncodeReadHoldingGivesTheManualsFrame) {
    auto r = run_mbscope("frame --encode --rtu --unit 17 read-holding 96 3 --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(nlohmann::json::parse(r.out)["wire"], "11 03 00 60 00 03 07 45");
    auto w = run_mbscope("frame --encode --rtu --unit 17 write-registers 96 10 258 --json");
    EXPECT_EQ(nlohmann::json::parse(w.out)["wire"], "11 10 00 60 00 02 04 00 0A 01 02 01 14");
    auto a = run_mbscope("frame --encode --ascii --unit 17 write-registers 0x60 0x0A 0x0102 --json");
    EXPECT_EQ(nlohmann::json::parse(a.out)["wire"], ":11100060000204000A01026C\r\n");
    auto t = run_mbscope("frame --encode --tcp --tid 1 --unit 17 read-holding 107 3 --json");
    EXPECT_EQ(nlohmann::json::parse(t.out)["wire"], "00 01 00 00 00 06 11 03 00 6B 00 03");
}

// What --encode cannot encode faithfully is refused (exit 2, the value named): the byte count of 130
// registers (260) wrapped round to 04 in a 269-byte frame, a coil given as 2 became 1, and a function or
// exception code past 255 was cut to its low byte. Counts past the specification's that a frame can still
// carry are encoded, and the decoding names the broken limit (exit 1).
TEST(FrameCommand, EncodeRefusesWhatTheFrameCannotHold) {
    std::string many;
    for (int i = 0; i < 130; ++i)
        many += " 1";
    const struct {
        std::string args, message;
    } cases[] = {
        {"write-registers 0" + many,
         "write-registers: the PDU would be 266 bytes; a Modbus PDU holds at most 253"},
        {"read-write 0 1 0" + many, "read-write: the PDU would be 270 bytes"},
        {"write-coils 0 1 0 2", "write-coils: a coil is 0 or 1, not '2'"},
        {"exception 300 2", "exception: not a number from 0 to 255: '300'"},
        {"exception 3 256", "exception: not a number from 0 to 255: '256'"},
        {"raw 0x103", "raw: not a number from 0 to 255: '0x103'"},
        {"read-device-id 1 999", "read-device-id: not a number from 0 to 255: '999'"},
    };
    for (const auto& c : cases) {
        const auto r = run_mbscope("frame --encode --rtu " + c.args);
        EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.out;
        EXPECT_NE(r.out.find(c.message), std::string::npos) << c.args << "\n" << r.out;
    }
    std::string most;  // 123 registers: the specification's limit, 252 bytes of PDU
    for (int i = 0; i < 123; ++i)
        most += " 7";
    EXPECT_EQ(run_mbscope("frame --encode --tcp write-registers 0" + most).exit_code, 0);
    std::string coils;  // 1,969 coils: one past the specification's 1,968, in 247 bytes (a 253-byte PDU)
    for (int i = 0; i < 1969; ++i)
        coils += " 1";
    const auto over = run_mbscope("frame --encode --tcp write-coils 0" + coils);
    EXPECT_EQ(over.exit_code, 1) << over.out;
    EXPECT_NE(over.out.find("1969"), std::string::npos) << over.out;
}

// An option that cannot act where it is given is a usage error (exit 2), not dropped: `--encode --rtu --tid
// 5` printed an RTU frame and exit 0, as if the transaction id were in it.
TEST(FrameCommand, OptionsThatCannotActAreRefused) {
    const struct {
        std::string args, message;
    } cases[] = {
        {"frame --encode --rtu --tid 5 read-holding 96 3", "--tid requires --tcp"},
        {"frame --tcp --tid 5 00 01 00 00 00 06 11 03 00 6B 00 03", "--tid requires --encode"},
        {"frame --rtu --unit 5 11 03 00 60 00 03 07 45", "--unit requires --encode"},
        {"frame --encode --tcp --direction response read-holding 1 1", "--encode excludes --direction"},
        {"frame --file captures/manual-examples.txt --encode read-holding 1 1", "--encode excludes --file"},
        {"frame --file captures/manual-examples.txt 11 03", "--file excludes bytes"},
    };
    for (const auto& c : cases) {
        const auto r = run_mbscope(c.args);
        EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.out;
        EXPECT_NE(r.out.find(c.message), std::string::npos) << c.args << "\n" << r.out;
    }
    EXPECT_EQ(run_mbscope("frame --encode --tcp --tid 5 --unit 17 read-holding 96 3").exit_code, 0);
}

TEST(FrameCommand, EchoIsNamedAsSuch) {
    auto r = run_mbscope("frame --rtu 11 06 00 54 03 9E 4B D2");
    EXPECT_NE(r.out.find("echo response"), std::string::npos) << r.out;
}

TEST(FrameCommand, FileOfManualExamplesDecodesClean) {
    auto r = run_mbscope(std::string("frame --file ") + MBSCOPE_SOURCE_DIR +
                         "/captures/manual-examples.txt --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.size(), 13u);
    for (const auto& f : j) {
        EXPECT_TRUE(f["checksum_ok"].get<bool>()) << f.dump();
        EXPECT_TRUE(f["findings"].empty()) << f.dump();
    }
}

TEST(FrameCommand, HelpOnTheSubcommand) {
    auto r = run_mbscope("frame --help");
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("--encode"), std::string::npos);
    EXPECT_NE(r.out.find("Exit codes"), std::string::npos);
    EXPECT_EQ(run_mbscope("--help").exit_code, 0);
    EXPECT_EQ(run_mbscope("nosuchcommand").exit_code, 2);
}

// A capture given to --file by mistake is not a frames file: an error for every line, the first hundred
// listed and the rest counted; a file with no frame at all says so. Both exit 2.
TEST(FrameCommand, AFileThatIsNotAFramesFileIsNamedNotFlooded) {
    const std::string dir = ::testing::TempDir();
    const std::string binary = dir + "/mbscope-not-frames.bin";
    {
        std::FILE* f = std::fopen(binary.c_str(), "wb");
        ASSERT_NE(f, nullptr);
        static constexpr char line[] = "\xd4\xc3\xb2\xa1\x02\x00\n";  // a pcap's magic, a NUL
        for (int i = 0; i < 250; ++i)
            std::fwrite(line, 1, sizeof line - 1, f);
        std::fclose(f);
    }
    auto r = run_mbscope("frame --file " + binary);
    EXPECT_EQ(r.exit_code, 2);
    std::size_t lines = 0;
    for (char c : r.out)
        lines += c == '\n';
    EXPECT_EQ(lines, 101u) << r.out;  // a hundred errors and the count
    EXPECT_NE(r.out.find("150 more lines in error, not listed"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("\\x02\\x00"), std::string::npos) << r.out;  // escaped, not written to the terminal

    const std::string comments = dir + "/mbscope-no-frames.txt";
    {
        std::FILE* f = std::fopen(comments.c_str(), "wb");
        ASSERT_NE(f, nullptr);
        std::fputs("# nothing but a comment\n", f);
        std::fclose(f);
    }
    auto none = run_mbscope("frame --file " + comments);
    EXPECT_EQ(none.exit_code, 2);
    EXPECT_NE(none.out.find("holds no frames"), std::string::npos) << none.out;
}

// A frames file is read whole, so it is bounded: a file over the limit (here sparse, 65 MiB of zeros) is an
// error naming it, not memory for all of it.
TEST(FrameCommand, AFramesFileOverTheLimitIsRefused) {
    const std::string path = ::testing::TempDir() + "frame_command_huge.txt";
    ASSERT_EQ(std::system(("truncate -s 65M " + path).c_str()), 0);
    const auto r = run_mbscope("frame --file " + path);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find(path + ": larger than 67108864 bytes"), std::string::npos) << r.out;
    std::remove(path.c_str());
}

// `--file --json` printed an object for a file of one frame and an array for a file of several: a consumer
// had to handle both. A file's frames are always an array; a frame given on the command line is one object.
TEST(FrameCommand, AFileIsAnArrayInJsonHoweverManyFramesItHolds) {
    const std::string path = ::testing::TempDir() + "frame_command_one_frame.txt";
    {
        std::FILE* f = std::fopen(path.c_str(), "wb");
        ASSERT_NE(f, nullptr);
        std::fputs("rtu 11 03 00 60 00 03 07 45  # 000:356 FC3 read registers 96..98 (request)\n", f);
        std::fclose(f);
    }
    const auto one = run_mbscope("frame --file " + path + " --json");
    ASSERT_EQ(one.exit_code, 0) << one.out;
    const auto file = nlohmann::json::parse(one.out);
    ASSERT_TRUE(file.is_array()) << one.out;
    ASSERT_EQ(file.size(), 1u);
    EXPECT_EQ(file[0]["wire"], "11 03 00 60 00 03 07 45");
    EXPECT_EQ(file[0]["function_code"], 3);

    const auto given = run_mbscope("frame --rtu 11 03 00 60 00 03 07 45 --json");
    ASSERT_EQ(given.exit_code, 0) << given.out;
    const auto frame = nlohmann::json::parse(given.out);
    ASSERT_TRUE(frame.is_object()) << given.out;
    EXPECT_EQ(frame["wire"], "11 03 00 60 00 03 07 45");
    std::remove(path.c_str());
}

}  // namespace test_cli_frame_command_test
