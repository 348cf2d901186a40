// The slave as a whole process (the mbscope binary), the way integrators and CI run it:
//  - an acknowledged write survives kill -9: writes are answered, the process is killed without warning,
//    a new process started on the same --state file serves every written value;
//  - 100 clients at once, each with its own requests, every one answered with its own data, while a
//    client sending garbage is disconnected without disturbing them.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <thread>

#include "tests/cli/cli_run.hpp"
#include "tests/slave/slave_process.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_process_test {
namespace {

namespace fs = std::filesystem;

std::string mbap(std::uint16_t tid, std::string_view pdu_hex) {
    const auto pdu = bytes(pdu_hex);
    char head[32];
    std::snprintf(head, sizeof head, "%04X 0000 %04X 01 ", tid, static_cast<unsigned>(pdu.size() + 1));
    return std::string(head) + std::string(pdu_hex);
}

// A new directory for one test's state file, and the file's path in it.
std::pair<fs::path, std::string> state_in_new_directory(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("mbscope-" + name + "-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    return {dir, (dir / "mmk-2030.json").string()};
}

TEST(SlaveProcess, AnAcknowledgedWriteSurvivesKill9) {
    const auto [dir, state] = state_in_new_directory("durability");
    // Write values the manual allows, each acknowledged, then kill -9 before the process can do anything
    // else.
    {
        SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
        ASSERT_NE(slave.port(), 0);
        Client c(slave.port());
        ASSERT_TRUE(c.connected());
        // MMK-2030 holding register 21 (square-root cut-off, 0-5 %), 29 (high alarm hysteresis, 0-250) and
        // coil 1 (password by value), written and echoed.
        EXPECT_EQ(c.exchange(mbap(1, "06 00 15 00 03"), 12), "00 01 00 00 00 06 01 06 00 15 00 03");
        EXPECT_EQ(c.exchange(mbap(2, "06 00 1D 00 2A"), 12), "00 02 00 00 00 06 01 06 00 1D 00 2A");
        EXPECT_EQ(c.exchange(mbap(3, "05 00 01 FF 00"), 12), "00 03 00 00 00 06 01 05 00 01 FF 00");
        slave.kill(SIGKILL);
    }
    SlaveProcess again({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
    ASSERT_NE(again.port(), 0);
    Client c(again.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(4, "03 00 15 00 01"), 11), "00 04 00 00 00 05 01 03 02 00 03");
    EXPECT_EQ(c.exchange(mbap(6, "03 00 1D 00 01"), 11), "00 06 00 00 00 05 01 03 02 00 2A");
    EXPECT_EQ(c.exchange(mbap(5, "01 00 01 00 01"), 10), "00 05 00 00 00 04 01 01 01 01");
    fs::remove_all(dir);
}

TEST(SlaveProcess, KilledInTheMiddleOfAStreamOfWritesLosesNoAcknowledgedOne) {
    const auto [dir, state] = state_in_new_directory("stream");
    // Hysteresis registers 29..32 (0-250 each) take turns, each write a new value; the writer remembers the
    // last value acknowledged per register and the one in flight when the process died.
    int acked[4] = {-1, -1, -1, -1}, in_flight[4] = {-1, -1, -1, -1};
    {
        SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
        ASSERT_NE(slave.port(), 0);
        Client c(slave.port());
        ASSERT_TRUE(c.connected());
        // The kill waits for the stream to be under way rather than for a fixed time: a sanitizer build on a
        // loaded machine acknowledges only a few writes in 300 ms, and a stream of a few proves nothing. It
        // is sent from another thread, so it lands wherever the writer happens to be: between a request and
        // its acknowledgement, or between the slave's save and its reply.
        std::atomic<bool> killed{false};
        std::atomic<int> written{0};
        std::thread killer([&] {
            const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
            while (written < 200 && std::chrono::steady_clock::now() < give_up)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            slave.kill(SIGKILL);
            killed = true;
        });
        for (std::uint16_t tid = 1; !killed && tid < 60000; ++tid) {
            const int r = tid % 4;
            const int value = (tid / 4) % 251;
            char pdu[32];
            std::snprintf(pdu, sizeof pdu, "06 00 %02X 00 %02X", 29 + r, value);
            in_flight[r] = value;
            c.send(bytes(mbap(tid, pdu)));
            if (c.read(12, std::chrono::milliseconds(500)).size() != 12)
                break;  // no ack: the process is gone
            acked[r] = value;
            in_flight[r] = -1;
            ++written;
        }
        killer.join();
        EXPECT_GE(written, 200) << "the stream was too short to mean anything";
    }
    SlaveProcess again({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
    ASSERT_NE(again.port(), 0);
    Client c(again.port());
    for (int r = 0; r < 4; ++r) {
        if (acked[r] < 0) continue;
        char pdu[32];
        std::snprintf(pdu, sizeof pdu, "03 00 %02X 00 01", 29 + r);
        const auto reply = bytes(c.exchange(mbap(static_cast<std::uint16_t>(100 + r), pdu), 11));
        ASSERT_EQ(reply.size(), 11u);
        const int now = reply[9] << 8 | reply[10];
        // The acknowledged value, or the one written after it whose acknowledgement was lost with the
        // process.
        EXPECT_TRUE(now == acked[r] || now == in_flight[r])
            << "register " << 29 + r << ": reads " << now << ", last acknowledged " << acked[r];
    }
    fs::remove_all(dir);
}

// Starts `mbscope slave ARGS` and returns its exit status and what it printed, for a start that must fail.
std::pair<int, std::string> refused_start(const std::string& args) {
    FILE* p = ::popen((std::string(MBSCOPE_BINARY) + " slave " + args + " 2>&1").c_str(), "r");
    if (!p) return {-1, ""};
    std::string out;
    char buf[512];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p))
        out.append(buf, n);
    return {WEXITSTATUS(::pclose(p)), out};
}

// A write the slave cannot save is not acknowledged (exception 04, slave device failure) and is taken back: a
// refused request leaves the registers as they were (AP §7), so a master that retries later finds the old
// value, not one that would vanish at the next restart. A --state whose directory is missing stops the
// slave at once.
TEST(SlaveProcess, AWriteThatCannotBeSavedIsRefusedAndTakenBack) {
    const auto [dir, state] = state_in_new_directory("unsaved");
    SlaveProcess slave({"--profile", "mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
    ASSERT_NE(slave.port(), 0);
    Client c(slave.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(1, "06 00 1D 00 2A"), 12), "00 01 00 00 00 06 01 06 00 1D 00 2A");
    fs::remove_all(dir);  // the state file can no longer be saved
    EXPECT_EQ(c.exchange(mbap(2, "06 00 1D 00 63"), 9), "00 02 00 00 00 03 01 86 04");
    EXPECT_EQ(c.exchange(mbap(3, "10 00 1D 00 02 04 00 07 00 08"), 9), "00 03 00 00 00 03 01 90 04");
    EXPECT_EQ(c.exchange(mbap(4, "03 00 1D 00 02"), 13), "00 04 00 00 00 07 01 03 04 00 2A 00 00");

    const std::string missing = (dir / "gone" / "state.json").string();
    const auto [status, refused] =
        refused_start("--profile mmk-2030 --listen tcp://127.0.0.1:0 --state " + missing);
    EXPECT_EQ(status, 2) << refused;
    EXPECT_NE(refused.find("mbscope slave: --state " + missing + ": cannot be saved"), std::string::npos)
        << refused;
}

// Two slaves on one state file each wrote back their own view of it: the one that saved last dropped the
// writes the other had acknowledged (unit 1's register, acknowledged by the first, gone once the second
// saved unit 2's). The second now refuses to start while the first runs, and starts once it has stopped.
// A FIFO given as the state file held the start forever, silent; it is refused.
TEST(SlaveProcess, AStateFileServesOneSlaveAtATime) {
    const auto [dir, state] = state_in_new_directory("shared");
    {
        SlaveProcess first(
            {"--profile", "modbus", "--unit", "1", "--listen", "tcp://127.0.0.1:0", "--state", state});
        ASSERT_NE(first.port(), 0);
        Client c(first.port());
        ASSERT_TRUE(c.connected());
        EXPECT_EQ(c.exchange(mbap(1, "06 00 0A 00 6F"), 12), "00 01 00 00 00 06 01 06 00 0A 00 6F");
        const auto [status, out] =
            refused_start("--profile modbus --unit 2 --listen tcp://127.0.0.1:0 --state " + state);
        EXPECT_EQ(status, 2) << out;
        EXPECT_NE(out.find("mbscope slave: --state " + state + ": in use by another mbscope slave"),
                  std::string::npos)
            << out;
    }
    SlaveProcess again(
        {"--profile", "modbus", "--unit", "1", "--listen", "tcp://127.0.0.1:0", "--state", state});
    ASSERT_NE(again.port(), 0);
    Client c(again.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(2, "03 00 0A 00 01"), 11), "00 02 00 00 00 05 01 03 02 00 6F");

    const auto fifo = (dir / "fifo.json").string();
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const auto [status, out] = refused_start("--profile modbus --listen tcp://127.0.0.1:0 --state " + fifo);
    EXPECT_EQ(status, 2) << out;
    EXPECT_NE(out.find(fifo + ": not a regular file"), std::string::npos) << out;
    fs::remove_all(dir);
}

// The write taken back was never acknowledged: the comm event counter (FC11, AP §6.9: successful
// completions only) does not count it, and the bus exception count (FC8 sub-function 0x0D) does.
TEST(SlaveProcess, AWriteTakenBackCountsAsAnExceptionNotAsACompletedMessage) {
    const auto [dir, state] = state_in_new_directory("uncounted");
    SlaveProcess slave({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0", "--state", state});
    ASSERT_NE(slave.port(), 0);
    Client c(slave.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(1, "06 00 00 00 2A"), 12), "00 01 00 00 00 06 01 06 00 00 00 2A");
    EXPECT_EQ(c.exchange(mbap(2, "0B"), 12), "00 02 00 00 00 06 01 0B 00 00 00 01");
    fs::remove_all(dir);  // the state file can no longer be saved
    EXPECT_EQ(c.exchange(mbap(3, "06 00 00 00 63"), 9), "00 03 00 00 00 03 01 86 04");
    EXPECT_EQ(c.exchange(mbap(4, "0B"), 12), "00 04 00 00 00 06 01 0B 00 00 00 01");
    EXPECT_EQ(c.exchange(mbap(5, "08 00 0D 00 00"), 12), "00 05 00 00 00 06 01 08 00 0D 00 01");
}

// A TCP buffer size of this machine: net.ipv4.tcp_wmem or tcp_rmem, `field` 1 the initial size, 2 the most
// it grows to.
std::size_t tcp_buffer(const char* which, int field) {
    std::ifstream in(std::string("/proc/sys/net/ipv4/") + which);
    std::size_t sizes[3] = {};
    in >> sizes[0] >> sizes[1] >> sizes[2];
    return sizes[field];
}

// A client that pipelines requests and never reads the replies: the slave stops reading its requests once
// 64 KiB of replies wait for it (TCP then holds the client back), so what it holds is bounded by that and by
// the kernel's socket buffers. It read and answered every request: a reply to a read of 125 registers is 21
// times its request, and such a client grew the slave by a gigabyte in 20 s and slowed the others. The bus
// message count (FC8 0x0B, AP §6.8.1) tells how many requests the slave took in: all of them before, here no
// more than the replies the buffers hold.
TEST(SlaveProcess, AClientThatNeverReadsItsRepliesIsNoLongerReadFrom) {
    constexpr std::size_t reply_size = 7 + 2 + 250;
    // The slave's send buffer grows to its most; the client's receive buffer, never read, keeps its initial
    // size.
    const std::size_t buffered =
        (tcp_buffer("tcp_wmem", 2) + tcp_buffer("tcp_rmem", 1) + 128 * 1024) / reply_size + 1000;
    const std::size_t requests = buffered + 10000;
    if (requests > 65000) GTEST_SKIP() << "this machine's TCP buffers hold more replies than FC8 counts";
    // Replies held for their time (slow-reply) count as unsent too: they were read past.
    for (const char* fault : {"", "slow-reply=2000"}) {
        SCOPED_TRACE(fault);
        std::vector<std::string> args{"--profile", "modbus", "--listen", "tcp://127.0.0.1:0"};
        if (*fault) args.insert(args.end(), {"--fault", fault});
        SlaveProcess slave(args);
        ASSERT_NE(slave.port(), 0);
        Client flood(slave.port());
        ASSERT_TRUE(flood.connected());
        std::string burst;
        for (std::size_t i = 0; i < requests; ++i)
            burst += (i ? " " : "") + mbap(static_cast<std::uint16_t>(i), "03 00 00 00 7D");
        flood.send(
            bytes(burst));  // 12 bytes each: the kernel's buffers take them whether the slave reads or not
        std::this_thread::sleep_for(std::chrono::seconds(1));
        Client other(slave.port());
        ASSERT_TRUE(other.connected());
        const auto count = bytes(other.exchange(mbap(1, "08 00 0B 00 00"), 12, std::chrono::seconds(5)));
        ASSERT_EQ(count.size(), 12u);
        const std::size_t taken = count[10] << 8 | count[11];
        EXPECT_LT(taken, buffered) << "requests the slave read from a client that reads nothing, of "
                                   << requests;
        // What it holds back is answered once the client reads.
        const auto replies = flood.read(reply_size * 100, std::chrono::seconds(10));
        EXPECT_EQ(replies.size(), reply_size * 100);
    }
}

TEST(SlaveProcess, HundredClientsAtOnceAreEachAnsweredWithTheirOwnData) {
    SlaveProcess slave({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0"});
    ASSERT_NE(slave.port(), 0);
    constexpr int clients = 100;
    std::vector<std::unique_ptr<Client>> all;
    for (int i = 0; i < clients; ++i) {
        all.push_back(std::make_unique<Client>(slave.port()));
        ASSERT_TRUE(all.back()->connected()) << "client " << i;
    }
    // A client that sends garbage: it may be disconnected; nobody else may notice.
    Client noisy(slave.port());
    ASSERT_TRUE(noisy.connected());
    noisy.send(std::string_view("\xde\xad\xbe\xef\x00\x00\xff\xff garbage garbage garbage", 28));
    // Every client writes its own register, all first, then reads it back: the values cannot mix.
    for (int i = 0; i < clients; ++i) {
        char pdu[32];
        std::snprintf(pdu, sizeof pdu, "06 %04X %04X", 100 + i, 1000 + i);
        all[i]->send(bytes(mbap(static_cast<std::uint16_t>(i), pdu)));
    }
    for (int i = 0; i < clients; ++i) {
        char expected[64];
        std::snprintf(expected, sizeof expected, "%02X %02X 00 00 00 06 01 06 %02X %02X %02X %02X", i >> 8,
                      i & 0xFF, (100 + i) >> 8, (100 + i) & 0xFF, (1000 + i) >> 8, (1000 + i) & 0xFF);
        EXPECT_EQ(hex(all[i]->read(12)), expected) << "client " << i;
    }
    for (int i = 0; i < clients; ++i) {
        char pdu[32];
        std::snprintf(pdu, sizeof pdu, "03 %04X 0001", 100 + i);
        char expected[64];
        std::snprintf(expected, sizeof expected, "%02X %02X 00 00 00 05 01 03 02 %02X %02X", (i + 500) >> 8,
                      (i + 500) & 0xFF, (1000 + i) >> 8, (1000 + i) & 0xFF);
        EXPECT_EQ(all[i]->exchange(mbap(static_cast<std::uint16_t>(i + 500), pdu), 11), expected)
            << "client " << i;
    }
}

// `--fault stuck-value=1 --fault stuck-value=2` announced both as planted and froze register 2 only. Both
// are announced, and both act.
TEST(SlaveProcess, StuckValueGivenAtTwoRegistersFreezesBoth) {
    SlaveProcess slave(
        {"--listen", "tcp://127.0.0.1:0", "--fault", "stuck-value=1", "--fault", "stuck-value=2"}, true);
    ASSERT_NE(slave.port(), 0);
    const std::string said = slave.read_until("planted fault stuck-value=2");
    EXPECT_NE(said.find("planted fault stuck-value=1\n"), std::string::npos) << said;
    Client c(slave.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(1, "06 00 01 00 AA"), 12), "00 01 00 00 00 06 01 06 00 01 00 AA");
    EXPECT_EQ(c.exchange(mbap(2, "06 00 02 00 BB"), 12), "00 02 00 00 00 06 01 06 00 02 00 BB");
    EXPECT_EQ(c.exchange(mbap(3, "03 00 01 00 02"), 13), "00 03 00 00 00 07 01 03 04 00 00 00 00");
}

// A fault that acts once (one reply delay, one exception code, one rate, one count), given twice, kept the
// last argument while the slave announced both. The second is refused as other bad fault input is: exit 2,
// the slave not started, nothing announced. (Under `timeout`: a slave that starts anyway serves until
// killed.)
TEST(SlaveProcess, AFaultThatActsOnceIsRefusedASecondTime) {
    for (const std::string faults : {"--fault slow-reply=100 --fault slow-reply=300",
                                     "--fault wrong-exception=2 --fault wrong-exception=3",
                                     "--fault no-reply=0.5 --fault crash-after=9 --fault no-reply=0.2",
                                     "--fault stuck-value=4 --fault stuck-value=4"}) {
        SCOPED_TRACE(faults);
        const auto run =
            mbscope::test::run_mbscope("slave --listen tcp://127.0.0.1:0 " + faults, "timeout 20");
        EXPECT_EQ(run.exit_code, 2) << run.out;
        EXPECT_NE(run.out.find("mbscope slave: --fault "), std::string::npos) << run.out;
        EXPECT_TRUE(run.out.find("is already planted") != std::string::npos ||
                    run.out.find("is already stuck") != std::string::npos)
            << run.out;
        EXPECT_EQ(run.out.find("planted fault"), std::string::npos) << run.out;
    }
}

// The serial port goes away under the slave (the far end of its pseudo-terminal closed, as a USB adapter
// unplugged): poll said so for ever with a read of nothing, and the slave spun a core without a word. It
// ends saying so, exit 2.
TEST(SlaveProcess, ASerialPortThatHangsUpEndsTheSlave) {
    int master = -1, slave_end = -1;
    char path[64] = {};
    ASSERT_EQ(::openpty(&master, &slave_end, path, nullptr, nullptr), 0);
    ::close(slave_end);                    // the slave opens its own
    ::fcntl(master, F_SETFD, FD_CLOEXEC);  // and does not inherit the far end, which would keep it up
    SlaveProcess slave({"--listen", std::string("rtu:") + path}, true);
    ASSERT_FALSE(slave.address().empty());
    ::close(master);
    const auto said = slave.read_until("the port hung up");
    EXPECT_NE(said.find(std::string("mbscope slave: ") + path + ": the port hung up"), std::string::npos)
        << said;
    if (said.find("the port hung up") != std::string::npos) {
        EXPECT_EQ(slave.wait_exit(), 2);
    }
}

// Out of file descriptors, accept() failed and left the client queued while poll said the listener was
// ready, for ever: a core spun and a new client was neither served nor closed. It is closed at once, as
// one over --max-clients is, and the clients already connected keep their service.
TEST(SlaveProcess, AClientBeyondTheDescriptorLimitIsClosedAtOnce) {
    rlimit before{};
    ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &before), 0);
    rlimit low = before;
    low.rlim_cur = 32;  // inherited by the slave spawned now
    ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
    SlaveProcess slave({"--listen", "tcp://127.0.0.1:0"});
    ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &before), 0);
    ASSERT_NE(slave.port(), 0);
    std::vector<std::unique_ptr<Client>> clients;
    for (int i = 0; i < 40; ++i) {
        clients.push_back(std::make_unique<Client>(slave.port()));
        ASSERT_TRUE(clients.back()->connected());
    }
    EXPECT_TRUE(clients.back()->closed_within(std::chrono::seconds(5)));
    EXPECT_EQ(clients.front()->exchange(mbap(1, "03 00 00 00 01"), 11), "00 01 00 00 00 05 01 03 02 00 00");
}

// A --state that is a symbolic link keeps the file it names: saved by a rename over the path, the link became
// a file of its own and the file it named stayed as it was; and a second slave given the file's own name,
// whose lock is named after it, was not refused beside the first.
TEST(SlaveProcess, AStateFileReachedByALinkIsTheFileItNames) {
    const auto [dir, real] = state_in_new_directory("link");
    {
        SlaveProcess first({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0", "--state", real});
        ASSERT_NE(first.port(), 0);
        Client c(first.port());
        ASSERT_TRUE(c.connected());
        EXPECT_EQ(c.exchange(mbap(1, "06 00 0A 00 01"), 12), "00 01 00 00 00 06 01 06 00 0A 00 01");
    }
    ASSERT_TRUE(fs::exists(real));
    const std::string link = (dir / "link.json").string();
    fs::create_symlink(real, link);
    {
        SlaveProcess slave({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0", "--state", link});
        ASSERT_NE(slave.port(), 0);
        Client c(slave.port());
        ASSERT_TRUE(c.connected());
        EXPECT_EQ(c.exchange(mbap(1, "06 00 0A 00 6F"), 12), "00 01 00 00 00 06 01 06 00 0A 00 6F");
        // (Under `timeout`: a second slave that starts serves until killed.)
        const auto second = mbscope::test::run_mbscope(
            "slave --profile modbus --listen tcp://127.0.0.1:0 --state " + real, "timeout 10");
        EXPECT_EQ(second.exit_code, 2) << second.out;
        EXPECT_NE(second.out.find("in use by another mbscope slave"), std::string::npos) << second.out;
    }
    EXPECT_TRUE(fs::is_symlink(link));
    SlaveProcess again({"--profile", "modbus", "--listen", "tcp://127.0.0.1:0", "--state", real});
    ASSERT_NE(again.port(), 0);
    Client c(again.port());
    ASSERT_TRUE(c.connected());
    EXPECT_EQ(c.exchange(mbap(2, "03 00 0A 00 01"), 11), "00 02 00 00 00 05 01 03 02 00 6F");
    fs::remove_all(dir);
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_process_test
