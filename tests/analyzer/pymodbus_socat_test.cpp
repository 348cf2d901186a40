// A serial line nobody here wrote either end of the log of: pymodbus's RTU client (Debian
// python3-pymodbus, tests/peers/pymodbus_serial_session.py) on one pty of a socat -x -v relay, the reference
// slave (mbscope slave --pty, DCY-2050, unit 17) on the other, socat's standard error decoded by mbscope
// decode --format socat --profile dcy-2050. Every request is paired, the values are the ones pymodbus read,
// and a clean run has no finding; with the slave's bad-crc fault the finding appears. The bundled log
// captures/pymodbus-socat-rtu.log (written by this setup) is decoded against a reviewed golden output, so
// that part does not depend on timing (MBSCOPE_UPDATE_GOLDEN=1 rewrites it).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/process_support.hpp"

namespace test_analyzer_pymodbus_socat_test {

namespace {

using namespace mbscope::test;

struct Session {
    std::string client;  // pymodbus's line
    std::vector<nlohmann::json> records;
    std::string log;
};

constexpr int unit = 17, address = 122, value = 30, count = 10;  // loop 1 ramp time to set-point 1.. (min)

// pymodbus → socat -x -v → mbscope slave; returns what pymodbus printed and the decoded records.
Session session(const std::string& name, const std::string& fault) {
    Session s;
    const std::string dir = ::testing::TempDir() + "pymodbus_socat_" + name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::vector<std::string> slave_args = {
        MBSCOPE_BINARY, "slave",    "--listen", "rtu:pty?baud=38400&parity=N", "--pty",
        "--profile",    "dcy-2050", "--unit",   std::to_string(unit),          "-q"};
    if (!fault.empty()) slave_args.insert(slave_args.end(), {"--fault", fault});
    Child slave(slave_args, dir + "/slave.out", dir + "/slave.err");
    std::string device;
    if (!slave.spawned() || !wait_for([&] {
            device = slurp(dir + "/slave.out");
            return device.find('\n') != std::string::npos;
        })) {
        ADD_FAILURE() << "the slave printed no pty: " << slurp(dir + "/slave.err");
        return s;
    }
    device.resize(device.find('\n'));
    const std::string master = dir + "/master";
    Child relay({"socat", "-x", "-v", "pty,raw,echo=0,link=" + master, device + ",raw,echo=0"}, "/dev/null",
                dir + "/socat.log");
    if (!relay.spawned() || !wait_for([&] { return std::filesystem::exists(master); })) {
        ADD_FAILURE() << "socat made no pty: " << slurp(dir + "/socat.log");
        return s;
    }
    s.client =
        run("/usr/bin/python3 " + std::string(MBSCOPE_SOURCE_DIR) +
            "/tests/peers/pymodbus_serial_session.py " + master + " " + std::to_string(unit) + " " +
            std::to_string(address) + " " + std::to_string(value) + " " + std::to_string(count) + " 2>&1");
    while (!s.client.empty() && s.client.back() == '\n')
        s.client.pop_back();
    relay.stop();
    slave.stop();
    s.log = slurp(dir + "/socat.log");
    std::istringstream out(run(std::string(MBSCOPE_BINARY) +
                               " decode --format socat --profile dcy-2050 --baud 38400 --jsonl " + dir +
                               "/socat.log 2>&1"));
    for (std::string line; std::getline(out, line);) {
        auto j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded()) {
            ADD_FAILURE() << "not JSON: " << line;
            continue;
        }
        s.records.push_back(std::move(j));
    }
    return s;
}

bool skip_reason(std::string& why) {
    if (::access("/usr/bin/python3", X_OK) != 0 || !have("socat")) {
        why = "needs /usr/bin/python3 (python3-pymodbus) and socat";
        return true;
    }
    if (std::system("/usr/bin/python3 -c 'import pymodbus' 2>/dev/null") != 0) {
        why = "python3-pymodbus is not installed";
        return true;
    }
    return false;
}

std::vector<nlohmann::json> of_type(const Session& s, const std::string& type) {
    std::vector<nlohmann::json> out;
    for (const auto& r : s.records)
        if (r["type"] == type) out.push_back(r);
    return out;
}

}  // namespace

TEST(PymodbusOverSocat, CleanRunPairsEveryRequestWithTheValuesPymodbusRead) {
    if (std::string why; skip_reason(why)) GTEST_SKIP() << why;
    const auto s = session("clean", "");
    // pymodbus's own account of the exchange
    const std::string prefix = "write=ok regs=" + std::to_string(value) + ",";
    ASSERT_EQ(s.client.rfind(prefix, 0), 0u) << s.client << "\n" << s.log;
    const auto regs_text =
        s.client.substr(s.client.find("regs=") + 5, s.client.find(" coils=") - s.client.find("regs=") - 5);
    std::vector<int> regs;
    std::stringstream rs(regs_text);
    for (std::string v; std::getline(rs, v, ',');)
        regs.push_back(std::stoi(v));
    ASSERT_EQ(regs.size(), static_cast<std::size_t>(count));

    const auto transactions = of_type(s, "transaction");
    ASSERT_EQ(transactions.size(), 3u) << s.log;
    const int functions[] = {6, 3, 1};
    for (std::size_t i = 0; i < 3; ++i) {
        SCOPED_TRACE(i);
        EXPECT_EQ(transactions[i]["function"], functions[i]);
        EXPECT_TRUE(transactions[i].contains("response_frame"));
        EXPECT_FALSE(transactions[i].contains("timeout"));
        EXPECT_FALSE(transactions[i].contains("exception_code"));
    }
    // the FC3 reply as decoded: the registers pymodbus printed, named by the profile
    std::vector<int> decoded;
    for (const auto& f : of_type(s, "frame"))
        if (f["direction"] == "response" && f["function"] == 3)
            decoded = f["fields"]["registers_value"].get<std::vector<int>>();
    EXPECT_EQ(decoded, regs);
    ASSERT_TRUE(transactions[1].contains("values"));
    EXPECT_EQ(transactions[1]["values"][0]["address"], address);
    EXPECT_EQ(transactions[1]["values"][0]["raw"][0], value);

    EXPECT_TRUE(of_type(s, "finding").empty()) << of_type(s, "finding")[0].dump();
    const auto summary = of_type(s, "summary");
    ASSERT_EQ(summary.size(), 1u);
    EXPECT_EQ(summary[0]["unparsed_bytes"], 0);
    EXPECT_FALSE(summary[0].contains("input_errors")) << summary[0].dump();
    EXPECT_EQ(summary[0]["errors"], 0);
}

TEST(PymodbusOverSocat, BadCrcFromTheSlaveIsFound) {
    if (std::string why; skip_reason(why)) GTEST_SKIP() << why;
    const auto s = session("bad_crc", "bad-crc");
    // pymodbus drops every reply: its CRC check fails
    EXPECT_EQ(s.client, "write=error regs=error coils=error") << s.log;
    int crc = 0;
    for (const auto& f : of_type(s, "finding"))
        crc += f["code"] == "rtu.crc_mismatch";
    EXPECT_EQ(crc, 3) << s.log;
}

TEST(PymodbusOverSocat, BundledLogDecodesToTheGoldenOutput) {
    const std::string golden = std::string(MBSCOPE_SOURCE_DIR) + "/tests/golden/pymodbus-socat-rtu.txt";
    const std::string got = run("cd " + std::string(MBSCOPE_SOURCE_DIR) + " && " + MBSCOPE_BINARY +
                                " decode --format socat --profile dcy-2050 --baud 38400 "
                                "captures/pymodbus-socat-rtu.log 2>&1");
    if (const char* update = std::getenv("MBSCOPE_UPDATE_GOLDEN"); update && std::string(update) == "1")
        std::ofstream(golden, std::ios::binary) << got;
    EXPECT_EQ(got, slurp(golden));
}

}  // namespace test_analyzer_pymodbus_socat_test
