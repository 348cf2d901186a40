// mbscope sniff as a process on two taps of a serial line: two socat pty pairs stand for the master's and
// the slaves' transmit lines, the MK manual's FC3 exchange (000:356-370), an FC6 write with its echo and an
// exception reply are written into their far ends, and sniff decodes them and writes them (--write
// bus.pcapng: pcapng, one interface a port, nanosecond timestamps). The written file, decoded again with
// --user-dlt rtu-dir, must give the same frames in the same directions at the same times and the same
// transactions. Skipped when socat is not installed.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "test_packets.hpp"
#include "tests/support/process_support.hpp"

namespace test_analyzer_sniff_socat_test {

using namespace mbscope::test;

namespace {

// The frames and transactions of a --jsonl output, without what names the input (source, link, device), and
// the summary's packet count.
struct Records {
    std::vector<nlohmann::json> frames, transactions;
    std::int64_t packets = -1;
};
Records records(const std::string& jsonl) {
    Records r;
    std::istringstream in(jsonl);
    for (std::string line; std::getline(in, line);) {
        auto j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded()) continue;
        if (j["type"] == "frame") {
            r.frames.push_back({{"ts", j["ts"]},
                                {"direction", j["direction"]},
                                {"raw", j["raw"]},
                                {"function", j.value("function", -1)}});
        } else if (j["type"] == "transaction") {
            r.transactions.push_back({{"ts", j["ts"]},
                                      {"request_frame", j["request_frame"]},
                                      {"response_frame", j.value("response_frame", 0)},
                                      {"unit_id", j["unit_id"]},
                                      {"function", j["function"]},
                                      {"exception_code", j.value("exception_code", 0)},
                                      {"timeout", j.value("timeout", false)}});
        } else if (j["type"] == "summary") {
            r.packets = j.value("packets", -1);
        }
    }
    return r;
}

// The Enhanced Packet Blocks of a pcapng file written whole so far (a block cut short is not counted).
std::size_t packet_blocks(const std::string& path) {
    const std::string f = slurp(path);
    const auto u32 = [&f](std::size_t at) {
        std::uint32_t v = 0;
        for (int i = 3; i >= 0; --i)
            v = v << 8 | static_cast<unsigned char>(f[at + static_cast<std::size_t>(i)]);
        return v;
    };
    std::size_t count = 0;
    for (std::size_t at = 0; at + 12 <= f.size();) {
        const std::uint32_t length = u32(at + 4);
        if (length < 12 || at + length > f.size()) break;
        count += u32(at) == 6;
        at += length;
    }
    return count;
}

// One sniff session: `line`'s chunks written in turn into the master's (true) or the slaves' tap, then
// the written file decoded again with --user-dlt `user_dlt`.
struct Session {
    std::string dir, written, err;
    Records live, again;
};
Session sniffed(const std::string& name, const std::vector<std::pair<bool, std::vector<std::uint8_t>>>& line,
                const std::string& user_dlt) {
    Session s;
    s.dir = ::testing::TempDir() + name;
    SocatTaps taps(s.dir);
    EXPECT_TRUE(taps.ready());
    if (!taps.ready()) return s;
    s.written = s.dir + "/bus.pcapng";
    Child sniff({MBSCOPE_BINARY, "sniff", "--serial", s.dir + "/m2", "--serial2", s.dir + "/s2", "--baud",
                 "19200", "--write", s.written, "--jsonl"},
                s.dir + "/sniff.jsonl", s.dir + "/sniff.err");
    const bool opened = wait_for([&] { return std::filesystem::exists(s.written); });
    EXPECT_TRUE(opened) << slurp(s.dir + "/sniff.err");
    if (!opened) return s;
    // Each chunk written once sniff has recorded the one before (it flushes every serial record): the
    // order of the two taps is the order on the line.
    for (std::size_t i = 0; i < line.size(); ++i) {
        const auto& [master, chunk] = line[i];
        const int fd = master ? taps.master_end : taps.slave_end;
        EXPECT_EQ(::write(fd, chunk.data(), chunk.size()), static_cast<ssize_t>(chunk.size()));
        const bool recorded = wait_for([&] { return packet_blocks(s.written) > i; });
        EXPECT_TRUE(recorded) << slurp(s.dir + "/sniff.err");
        if (!recorded) return s;
    }
    sniff.stop();  // SIGTERM: sniff drains, prints its summary and closes the file
    s.err = slurp(s.dir + "/sniff.err");
    s.live = records(slurp(s.dir + "/sniff.jsonl"));
    s.again = records(run(std::string(MBSCOPE_BINARY) + " decode --baud 19200 --user-dlt " + user_dlt +
                          " --jsonl '" + s.written + "'"));
    return s;
}

}  // namespace

TEST(SniffSocat, WrittenSessionDecodesToTheSameTransactions) {
    if (!have("socat")) GTEST_SKIP() << "needs socat";
    const Session s =
        sniffed("sniff_socat",
                {
                    {true, bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45})},
                    {false, bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA})},
                    {true, bytes({0x11, 0x06, 0x00, 0x01, 0x00, 0x03, 0x9A, 0x9B})},
                    {false, bytes({0x11, 0x06, 0x00, 0x01, 0x00, 0x03, 0x9A, 0x9B})},
                    {true, bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45})},
                    {false, bytes({0x11, 0x83, 0x02, 0xC1, 0x34})},
                },
                "rtu-dir");
    EXPECT_NE(s.err.find("--user-dlt rtu-dir"), std::string::npos) << s.err;
    ASSERT_EQ(s.live.frames.size(), 6u) << slurp(s.dir + "/sniff.jsonl");
    ASSERT_EQ(s.live.transactions.size(), 3u);
    EXPECT_EQ(s.live.frames, s.again.frames);
    EXPECT_EQ(s.live.transactions, s.again.transactions);
    // Each read of a port is a packet, as each is a record of the file (live it was "0 packets").
    EXPECT_EQ(s.live.packets, 6);
    EXPECT_EQ(s.again.packets, 6);
    for (std::size_t i = 0; i < s.live.frames.size(); ++i) {
        EXPECT_EQ(s.live.frames[i]["direction"], i % 2 ? "response" : "request") << i;
    }
    EXPECT_EQ(s.live.transactions[2]["exception_code"], 2);

    // A second reader: tshark sees one interface a port, named after it, the records alternating.
    if (!have("tshark")) return;
    const std::string names =
        run("tshark -r '" + s.written + "' -T fields -e frame.interface_name 2>/dev/null");
    std::string expected;
    for (int i = 0; i < 3; ++i)
        expected += s.dir + "/m2\n" + s.dir + "/s2\n";
    EXPECT_EQ(names, expected);
}

// An ASCII line (the MK manual's FC3 exchange in ASCII, MK-ASC-02, 000:304-309): sniff reads it as ASCII
// from its bytes, and says to read the file back with --user-dlt ascii-dir, which gives the same records.
TEST(SniffSocat, AnAsciiLineIsReadAndWrittenAsAscii) {
    if (!have("socat")) GTEST_SKIP() << "needs socat";
    const auto chars = [](const std::string& text) {
        return std::vector<std::uint8_t>(text.begin(), text.end());
    };
    const Session s = sniffed(
        "sniff_socat_ascii",
        {{true, chars(":11030060000389\r\n")}, {false, chars(":110306022B0000006455\r\n")}}, "ascii-dir");
    EXPECT_NE(s.err.find("--user-dlt ascii-dir"), std::string::npos) << s.err;
    ASSERT_EQ(s.live.transactions.size(), 1u) << slurp(s.dir + "/sniff.jsonl");
    EXPECT_EQ(s.live.transactions[0]["function"], 3);
    EXPECT_EQ(s.live.frames, s.again.frames);
    EXPECT_EQ(s.live.transactions, s.again.transactions);
    // Read back without saying the framing: the records' bytes tell it.
    const Records told =
        records(run(std::string(MBSCOPE_BINARY) + " decode --baud 19200 --user-dlt serial-dir --jsonl '" +
                    s.written + "'"));
    EXPECT_EQ(s.live.frames, told.frames);
    EXPECT_EQ(s.live.transactions, told.transactions);
}

// A port that goes away (a USB adapter unplugged; here the pseudo-terminal's other end closed) ended nothing:
// poll reported the hang-up at once, again and again, and sniff spun at full CPU in silence until its
// --duration ran out, then exited 0 as if the line had been quiet. It ends the capture with the port named,
// what it read still decoded, and exit 2.
TEST(SniffSocat, APortThatGoesAwayEndsTheCaptureWithAnError) {
    if (!have("socat")) GTEST_SKIP() << "needs socat";
    const std::string dir = ::testing::TempDir() + "sniff_port_gone";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    Child pair({"socat", "pty,raw,echo=0,link=" + dir + "/a", "pty,raw,echo=0,link=" + dir + "/b"},
               "/dev/null", dir + "/socat.err");
    ASSERT_TRUE(
        wait_for([&] { return std::filesystem::exists(dir + "/a") && std::filesystem::exists(dir + "/b"); }));
    const std::string written = dir + "/line.pcapng";
    Child sniff(
        {MBSCOPE_BINARY, "sniff", "--serial", dir + "/a", "--duration", "30s", "--write", written, "--jsonl"},
        dir + "/sniff.jsonl", dir + "/sniff.err");
    ASSERT_TRUE(wait_for([&] { return std::filesystem::exists(written); })) << slurp(dir + "/sniff.err");
    const int far_end = ::open((dir + "/b").c_str(), O_RDWR | O_NOCTTY);
    ASSERT_GE(far_end, 0);
    const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    EXPECT_EQ(::write(far_end, request.data(), request.size()), static_cast<ssize_t>(request.size()));
    EXPECT_TRUE(wait_for([&] { return packet_blocks(written) == 1; }));
    ::close(far_end);
    pair.stop();  // the port's other end is gone
    EXPECT_EQ(sniff.wait_exit(), 2);
    const std::string err = slurp(dir + "/sniff.err");
    EXPECT_NE(err.find("mbscope sniff: " + dir + "/a: the port hung up; the capture ends here"),
              std::string::npos)
        << err;
    const Records live = records(slurp(dir + "/sniff.jsonl"));
    ASSERT_EQ(live.frames.size(), 1u);
    EXPECT_EQ(live.frames[0]["function"], 3);
}

// A reader of sniff's output that went away (`sniff ... | head -1`) stops the capture as SIGTERM does: sniff
// died of SIGPIPE before (exit status 141, none of the documented ones), and a network capture file it was
// writing was left without its packets. It ends with a documented exit code and the file whole.
TEST(SniffSocat, AReaderThatWentAwayStopsTheCaptureAndKeepsTheFile) {
    if (!have("socat") || !have("bash")) GTEST_SKIP() << "needs socat and bash";
    const std::string dir = ::testing::TempDir() + "sniff_reader_gone";
    SocatTaps taps(dir);
    ASSERT_TRUE(taps.ready());
    const std::string written = dir + "/bus.pcapng";
    const std::string status = dir + "/status";
    Child pipeline({"bash", "-c",
                    std::string(MBSCOPE_BINARY) + " sniff --serial " + taps.master_tap() +
                        " --duration 30s --jsonl --write " + written + " 2>" + dir +
                        "/sniff.err | head -c 1 >/dev/null; echo ${PIPESTATUS[0]} > " + status},
                   "/dev/null", dir + "/bash.err");
    ASSERT_TRUE(wait_for([&] { return std::filesystem::exists(written); })) << slurp(dir + "/sniff.err");
    const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    // Each request is a frame record on the pipe once a silence ends it: the first fills head, the next
    // writes into a pipe nobody reads.
    for (int i = 0; i < 3 && !std::filesystem::exists(status); ++i) {
        EXPECT_EQ(::write(taps.master_end, request.data(), request.size()),
                  static_cast<ssize_t>(request.size()));
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    ASSERT_TRUE(wait_for([&] { return !slurp(status).empty(); })) << slurp(dir + "/sniff.err");
    pipeline.wait_exit();
    // Exit 1: the run's verdict (a request followed by another with no reply between is pair.no_response).
    EXPECT_EQ(slurp(status), "1\n") << slurp(dir + "/sniff.err");
    EXPECT_GE(packet_blocks(written), 2u);
}

// A request whose timeout ran out before sniff stopped was a timeout live (pair.no_response, exit 1) but
// "unanswered when the capture ended" (a note, exit 0) in a decode of the file sniff wrote: no packet says
// when the capture ended. The pcapng file says it now (Interface Statistics Blocks), and both agree.
TEST(SniffSocat, ARequestThatTimedOutLiveTimesOutInTheWrittenFile) {
    if (!have("socat")) GTEST_SKIP() << "needs socat";
    const std::string dir = ::testing::TempDir() + "sniff_end";
    SocatTaps taps(dir);
    ASSERT_TRUE(taps.ready());
    const std::string written = dir + "/bus.pcapng";
    Child sniff({MBSCOPE_BINARY, "sniff", "--serial", taps.master_tap(), "--timeout", "0.3", "--write",
                 written, "--jsonl"},
                dir + "/sniff.jsonl", dir + "/sniff.err");
    ASSERT_TRUE(wait_for([&] { return std::filesystem::exists(written); })) << slurp(dir + "/sniff.err");
    const auto request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
    EXPECT_EQ(::write(taps.master_end, request.data(), request.size()), static_cast<ssize_t>(request.size()));
    // Stopped once the live run has said the timeout (its record is on the way as it happens).
    EXPECT_TRUE(
        wait_for([&] { return slurp(dir + "/sniff.jsonl").find("pair.no_response") != std::string::npos; }));
    sniff.stop();
    const auto timeouts = [](const std::string& jsonl) {
        std::istringstream in(jsonl);
        for (std::string line; std::getline(in, line);) {
            const auto j = nlohmann::json::parse(line, nullptr, false);
            if (!j.is_discarded() && j["type"] == "summary")
                for (const auto& [name, device] : j["devices"].items())
                    return device.value("timeouts", -1);
        }
        return -1;
    };
    EXPECT_EQ(timeouts(slurp(dir + "/sniff.jsonl")), 1) << slurp(dir + "/sniff.jsonl");
    const std::string again =
        run(std::string(MBSCOPE_BINARY) + " decode --timeout 0.3 --user-dlt rtu --jsonl '" + written + "'");
    EXPECT_EQ(timeouts(again), 1) << again;
}

}  // namespace test_analyzer_sniff_socat_test
