// The slave's connections and its serial line, seen from outside: a TCP client that says nothing is
// disconnected after the idle timeout and one that stops in the middle of a frame (half-open) after the
// frame timeout, while a client that keeps talking keeps its connection; on an RTU line the answer never
// starts before the request's t3.5 silence (SL §2.5.1.1) and a frame with a bad CRC is never answered.
//
// The timeouts are asserted from below (a connection is never closed early) and from above only with a wide
// margin (closed within seconds of a timeout of a few hundred milliseconds), so that a loaded machine
// cannot make them fail.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <termios.h>

#include <thread>

#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_connections_test {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr std::string_view kReadOneRegister = "000100000006010300000001";  // MBAP tid 1, FC3 0 x1

// A whole FC3 reply (11 bytes) to a read of one register.
bool answered(Client& c) {
    c.send(bytes(kReadOneRegister));
    return c.read(11).size() == 11;
}

TEST(Connections, AnIdleClientIsClosedAfterTheIdleTimeoutWhileATalkingOneStays) {
    ServerOptions o;
    o.idle_timeout = 1000ms;
    RunningServer s({});
    const auto port = s.serve("tcp://127.0.0.1:0", o).port();
    const auto connected = Clock::now();
    Client idle(port);
    Client talking(port);
    ASSERT_TRUE(talking.connected());

    // The talking client asks about every 50 ms until the idle one is closed (at most 10 s), and is
    // answered each time.
    bool closed = false;
    int asked = 0, replies = 0;
    while (!closed && Clock::now() - connected < 10s) {
        ++asked;
        if (answered(talking)) ++replies;
        closed = idle.closed_within(50ms);
    }
    const auto elapsed = Clock::now() - connected;
    EXPECT_TRUE(closed) << "a client silent for 10 s with a 1 s idle timeout is still connected";
    EXPECT_GE(elapsed, o.idle_timeout) << "closed before its idle timeout";
    EXPECT_EQ(replies, asked);
    EXPECT_TRUE(answered(talking)) << "the talking client lost its connection";
    s.stop();
    EXPECT_EQ(s.server().stats().closed_idle, 1u);
}

TEST(Connections, AHalfOpenClientIsClosedAfterTheFrameTimeoutLongBeforeTheIdleTimeout) {
    ServerOptions o;
    o.idle_timeout = 60s;
    o.frame_timeout = 200ms;
    RunningServer s({});
    const auto port = s.serve("tcp://127.0.0.1:0", o).port();
    Client half_open(port);
    Client quiet(port);
    ASSERT_TRUE(quiet.connected());
    ASSERT_TRUE(answered(quiet));

    // Seven bytes of a twelve-byte request, then nothing: a client that died in the middle of a frame.
    half_open.send(bytes(kReadOneRegister.substr(0, 14)));
    EXPECT_TRUE(half_open.closed_within(10s)) << "half a frame held for 10 s with a 200 ms frame timeout";
    // A client that finished its frames and stays quiet is not half-open: it keeps its connection.
    EXPECT_TRUE(answered(quiet));
    s.stop();
    EXPECT_EQ(s.server().stats().closed_idle, 1u);
}

// A second slave on a UDP port in use is refused, not bound beside the first (where the kernel would hand
// the first one's datagrams to it); the same for TCP.
TEST(Connections, ASecondSlaveOnAPortInUseIsRefused) {
    for (const std::string scheme : {"udp", "tcp"}) {
        SCOPED_TRACE(scheme);
        RunningServer first({});
        const auto port = std::to_string(first.start(scheme));
        auto endpoint = mb::transport::parse_endpoint(scheme + "://127.0.0.1:" + port);
        ASSERT_TRUE(endpoint.has_value());
        FaultSet faults;
        Device device(profile("modbus"), 1, &faults);
        Server second(*endpoint, {&device}, faults, ServerOptions{});
        auto opened = second.open();
        ASSERT_FALSE(opened.has_value()) << scheme << " port " << port << " bound twice";
        EXPECT_NE(opened.error().find(port), std::string::npos) << opened.error();
    }
}

// Waits for the first byte of a reply; the time from `sent` to it, or nothing within `timeout`.
std::optional<Clock::duration> first_byte_after(int fd, Clock::time_point sent,
                                                std::chrono::milliseconds timeout) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return std::nullopt;
    return Clock::now() - sent;
}

TEST(SerialLine, RtuAnswersOnlyAfterTheRequestsT35SilenceAndNeverABadCrc) {
    // 1200 baud, 8N1: a character is 8.3 ms, t3.5 29 ms, long enough to measure from below on any machine.
    ServerOptions o;
    o.create_pty = true;
    RunningServer s({});
    s.serve("rtu:pty?baud=1200&parity=N", o);
    auto line = mb::transport::parse_endpoint("rtu:pty?baud=1200&parity=N");
    ASSERT_TRUE(line.has_value());
    const auto t35 = line->line.t3_5();
    const int fd = open_terminal(s.server().address());
    ASSERT_GE(fd, 0);

    // FC3, address 0, one register, to unit 1 (CRC 840A), its last byte flipped: never answered.
    const auto bad = bytes("01030000000184 0B");
    ASSERT_EQ(::write(fd, bad.data(), bad.size()), static_cast<ssize_t>(bad.size()));
    EXPECT_FALSE(first_byte_after(fd, Clock::now(), 300ms).has_value())
        << "a frame with a bad CRC was answered";

    for (int round = 0; round < 3; ++round) {
        const auto good = bytes("010300000001840A");
        const auto sent = Clock::now();
        ASSERT_EQ(::write(fd, good.data(), good.size()), static_cast<ssize_t>(good.size()));
        const auto after = first_byte_after(fd, sent, 2000ms);
        ASSERT_TRUE(after.has_value()) << "round " << round << ": no answer";
        EXPECT_GE(*after, t35) << "round " << round
                               << ": the answer started before the request's t3.5 silence";
        const auto reply = read_terminal(fd, 7);
        ASSERT_EQ(reply.size(), 7u);
        EXPECT_EQ(hex(std::span<const std::uint8_t>(reply.data(), 3)), "01 03 02");
        std::this_thread::sleep_for(50ms);
    }
    ::close(fd);
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_connections_test
