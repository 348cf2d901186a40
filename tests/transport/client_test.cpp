// The shared master side: responses found where each framing ends them, silence reported as such, bytes
// and times kept. The far end is a scripted peer on loopback or a pseudo-terminal, so these tests depend
// on nothing but the codec.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <thread>

#include "modbus/adu.hpp"
#include "modbus/transport/client.hpp"
#include "modbus/transport/serial_port.hpp"
#include "modbus/transport/socket.hpp"

namespace mbscope::modbus::transport::test_transport_client_test {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

// Accepts one client, reads one request, then writes each chunk of `reply` with `pause` between them.
class ScriptedPeer {
  public:
    ScriptedPeer(std::vector<Bytes> reply, std::chrono::milliseconds pause, bool close_after = false)
        : listener_(listen_tcp("127.0.0.1", 0).value()) {
        port_ = bound_port(listener_.get());
        thread_ = std::thread([this, reply = std::move(reply), pause, close_after] {
            pollfd p{listener_.get(), POLLIN, 0};
            if (::poll(&p, 1, 5000) != 1) return;
            UniqueFd c(::accept(listener_.get(), nullptr, nullptr));
            std::uint8_t buf[512];
            pollfd q{c.get(), POLLIN, 0};
            if (::poll(&q, 1, 5000) != 1) return;
            const ssize_t n = ::read(c.get(), buf, sizeof buf);
            if (n > 0) request_.assign(buf, buf + n);
            for (const auto& chunk : reply) {
                ::send(c.get(), chunk.data(), chunk.size(), MSG_NOSIGNAL);
                std::this_thread::sleep_for(pause);
            }
            if (!close_after) std::this_thread::sleep_for(300ms);
        });
    }
    ~ScriptedPeer() { thread_.join(); }
    std::uint16_t port() const { return port_; }
    Bytes request() {
        thread_.join();
        thread_ = std::thread([] {});
        return request_;
    }

  private:
    UniqueFd listener_;
    std::uint16_t port_ = 0;
    std::thread thread_;
    Bytes request_;
};

Endpoint endpoint(const std::string& uri) {
    return parse_endpoint(uri).value();
}

const Bytes read_hr_pdu = {0x03, 0x00, 0x6B, 0x00, 0x03};

TEST(Client, TcpResponseSplitAcrossSegmentsIsOneFrame) {
    // TCP §4.2 example: reply to "read 3 registers from 0x6B", sent in two segments.
    const Bytes reply = {0x00, 0x01, 0x00, 0x00, 0x00, 0x09, 0x11, 0x03,
                         0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64};
    ScriptedPeer peer({Bytes(reply.begin(), reply.begin() + 5), Bytes(reply.begin() + 5, reply.end())}, 20ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.transact(0x11, read_hr_pdu, 2000ms);
    ASSERT_TRUE(ex.response);
    EXPECT_FALSE(ex.timed_out);
    EXPECT_EQ(ex.received, reply);
    EXPECT_EQ(ex.response->transaction_id(), 1);
    EXPECT_EQ(ex.sent, (Bytes{0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03}));
    EXPECT_GE(ex.elapsed, ex.first_byte);
    EXPECT_EQ(client.next_transaction_id(), 2);
}

TEST(Client, SilenceIsATimeoutWithNothingReceived) {
    ScriptedPeer peer({}, 0ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.transact(1, read_hr_pdu, 150ms);
    EXPECT_TRUE(ex.timed_out);
    EXPECT_FALSE(ex.response);
    EXPECT_TRUE(ex.received.empty());
    EXPECT_GE(ex.elapsed, 150ms);
}

// A device that never falls silent cannot hold a drain: it waits for `quiet` without a byte, and no longer
// than twice that and half a second in all. This one sends a byte every 10 ms for three seconds.
TEST(Client, ADrainEndsWhileTheDeviceChattersOn) {
    ScriptedPeer peer(std::vector<Bytes>(300, Bytes{0x55}), 10ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    ASSERT_TRUE(client.write(Bytes{0x00}));
    const auto heard = client.drain(50ms);
    EXPECT_FALSE(heard.empty());
    EXPECT_LT(heard.size(), 300u);
}

TEST(Client, PeerClosingIsReported) {
    ScriptedPeer peer({}, 0ms, true);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.transact(1, read_hr_pdu, 2000ms);
    EXPECT_TRUE(ex.closed);
    EXPECT_TRUE(ex.timed_out);
}

TEST(Client, RtuOverTcpFrameEndsByContentBeforeAnySilence) {
    const Bytes pdu = {0x03, 0x06, 0xAE, 0x41, 0x56, 0x52, 0x43, 0x40};  // SL §2.5.1 example reply
    ScriptedPeer peer({encode_rtu(0x11, pdu)}, 0ms);
    auto client = Client::open(endpoint("rtu-tcp://127.0.0.1:" + std::to_string(peer.port())),
                               ClientOptions{2000ms, 1000ms})
                      .value();
    const Exchange ex = client.transact(0x11, read_hr_pdu, 3000ms);
    ASSERT_TRUE(ex.response);
    EXPECT_TRUE(ex.response->checksum_ok);
    // Found by its predicted length and CRC, not by waiting for the 1 s settle time.
    EXPECT_LT(ex.elapsed, 900ms);
    EXPECT_EQ(peer.request(), encode_rtu(0x11, read_hr_pdu));
}

TEST(Client, RtuOverTcpBadCrcEndsAtSilenceAndIsKept) {
    Bytes adu = encode_rtu(0x11, Bytes{0x03, 0x02, 0x00, 0x07});
    adu.back() ^= 0xFF;
    ScriptedPeer peer({adu}, 0ms);
    auto client = Client::open(endpoint("rtu-tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.transact(0x11, read_hr_pdu, 2000ms);
    ASSERT_TRUE(ex.response);
    EXPECT_FALSE(ex.response->checksum_ok);
    EXPECT_EQ(ex.received, adu);
}

TEST(Client, AsciiOverTcpFrameEndsAtCrLf) {
    const std::string reply = encode_ascii(0x11, Bytes{0x03, 0x02, 0x00, 0x07});
    ScriptedPeer peer({Bytes(reply.begin(), reply.end())}, 0ms);
    auto client = Client::open(endpoint("ascii-tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.transact(0x11, read_hr_pdu, 2000ms);
    ASSERT_TRUE(ex.response);
    EXPECT_EQ(ex.response->pdu().size(), 4u);
    const std::string sent(ex.sent.begin(), ex.sent.end());
    EXPECT_EQ(sent, encode_ascii(0x11, read_hr_pdu));
}

TEST(Client, PipelinedRepliesAreCountedFrameByFrame) {
    Bytes both = encode_tcp(7, 1, Bytes{0x06, 0x00, 0x01, 0x00, 0x03});
    const Bytes second = encode_tcp(8, 1, Bytes{0x86, 0x02});
    both.insert(both.end(), second.begin(), second.end());
    ScriptedPeer peer({both}, 0ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    const Exchange ex = client.raw(client.frame(1, read_hr_pdu), 2000ms, 2);
    EXPECT_FALSE(ex.timed_out);
    EXPECT_EQ(ex.received, both);
    ASSERT_TRUE(ex.response);
    EXPECT_EQ(ex.response->transaction_id(), 7);  // the first frame
}

// Modbus/TCP: a reply with an earlier request's transaction id before this request's own is a late one,
// set aside; its bytes stay in `received`, and own_received() is what came for this request. After the own
// reply nothing is set aside: bytes there are this request's (trailing) whatever they say.
TEST(Client, ALateReplyToAnEarlierRequestIsSetAsideBeforeTheOwnOnly) {
    const Bytes late = encode_tcp(4, 1, Bytes{0x83, 0x02});
    const Bytes own = encode_tcp(5, 1, Bytes{0x03, 0x02, 0x00, 0x07});
    const Bytes after = encode_tcp(3, 1, Bytes{0x83, 0x02});
    Bytes all = late;
    all.insert(all.end(), own.begin(), own.end());
    all.insert(all.end(), after.begin(), after.end());
    ScriptedPeer peer({all}, 0ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    client.set_transaction_id(5);
    const Exchange ex = client.raw(client.frame(1, read_hr_pdu), 300ms, 0);
    EXPECT_EQ(ex.received, all);
    ASSERT_EQ(ex.stale_replies.size(), 1u);
    EXPECT_EQ(ex.stale_replies[0].transaction_id(), 4);
    ASSERT_TRUE(ex.response);
    EXPECT_EQ(ex.response->transaction_id(), 5);
    Bytes mine = own;
    mine.insert(mine.end(), after.begin(), after.end());
    EXPECT_EQ(Bytes(ex.own_received().begin(), ex.own_received().end()), mine);
}

// A slow device's reply to the request given up, then after a pause its reply to this one: the exchange's
// first_byte is when this one's began (the network fuzzer's latency and --slow judge it), not when the late
// one came. The peer's pause before the own reply is the lower bound.
TEST(Client, FirstByteIsWhenTheOwnReplyBeganNotALateOne) {
    const Bytes late = encode_tcp(4, 1, Bytes{0x83, 0x02});
    const Bytes own = encode_tcp(5, 1, Bytes{0x03, 0x02, 0x00, 0x07});
    ScriptedPeer peer({late, own}, 150ms);
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(peer.port()))).value();
    client.set_transaction_id(5);
    const Exchange ex = client.raw(client.frame(1, read_hr_pdu), 2000ms, 1);
    ASSERT_EQ(ex.stale_replies.size(), 1u);
    ASSERT_TRUE(ex.response);
    EXPECT_GE(ex.first_byte, 150ms);

    // RTU: the late reply is told by what it answers (an owed FC4 read), and split from the own reply
    // mid-frame, so that the set-aside frame completes in the read that brings the own reply's first bytes.
    const Bytes owed_pdu{0x04, 0x00, 0x00, 0x00, 0x01};
    const Bytes late_rtu = encode_rtu(1, Bytes{0x04, 0x02, 0x00, 0x09});
    const Bytes own_rtu = encode_rtu(1, Bytes{0x03, 0x06, 0, 1, 0, 2, 0, 3});
    Bytes second(late_rtu.begin() + 3, late_rtu.end());
    second.insert(second.end(), own_rtu.begin(), own_rtu.end());
    ScriptedPeer serial_peer({Bytes(late_rtu.begin(), late_rtu.begin() + 3), second}, 150ms);
    auto rtu = Client::open(endpoint("rtu-tcp://127.0.0.1:" + std::to_string(serial_peer.port()))).value();
    const std::vector<OwedRequest> owed{{1, owed_pdu, {}}};
    const Exchange serial = rtu.raw(rtu.frame(1, read_hr_pdu), 2000ms, 1, {}, owed);
    ASSERT_EQ(serial.stale_replies.size(), 1u);
    ASSERT_TRUE(serial.response);
    EXPECT_EQ(serial.response->pdu()[0], 0x03);
    EXPECT_GE(serial.first_byte, 150ms);
}

TEST(Client, UdpDatagramIsOneResponse) {
    auto server = bind_udp("127.0.0.1", 0).value();
    const auto port = bound_port(server.get());
    std::thread peer([&] {
        pollfd p{server.get(), POLLIN, 0};
        ASSERT_EQ(::poll(&p, 1, 5000), 1);
        std::uint8_t buf[512];
        sockaddr_storage from{};
        socklen_t len = sizeof from;
        const ssize_t n =
            ::recvfrom(server.get(), buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &len);
        ASSERT_GT(n, 7);
        const Bytes reply =
            encode_tcp(static_cast<std::uint16_t>((buf[0] << 8) | buf[1]), buf[6], Bytes{0x83, 0x02});
        ::sendto(server.get(), reply.data(), reply.size(), 0, reinterpret_cast<sockaddr*>(&from), len);
    });
    auto client = Client::open(endpoint("udp://127.0.0.1:" + std::to_string(port))).value();
    const Exchange ex = client.transact(5, read_hr_pdu, 2000ms);
    peer.join();
    ASSERT_TRUE(ex.response);
    EXPECT_EQ(ex.response->unit_id(), 5);
    EXPECT_EQ(ex.response->pdu()[0], 0x83);
}

TEST(Client, SerialRtuOverPseudoTerminal) {
    SerialLine line;
    line.baud = 19200;
    auto pty = open_pty(line).value();
    auto client = Client::open(endpoint("rtu:" + pty.slave_path + "?baud=19200&parity=N")).value();
    std::thread peer([&] {
        pollfd p{pty.master.get(), POLLIN, 0};
        ASSERT_EQ(::poll(&p, 1, 5000), 1);
        std::uint8_t buf[512];
        ASSERT_GT(::read(pty.master.get(), buf, sizeof buf), 0);
        const Bytes reply = encode_rtu(0x11, Bytes{0x03, 0x02, 0x12, 0x34});
        ASSERT_EQ(::write(pty.master.get(), reply.data(), reply.size()), static_cast<ssize_t>(reply.size()));
    });
    const Exchange ex = client.transact(0x11, read_hr_pdu, 2000ms);
    peer.join();
    ASSERT_TRUE(ex.response);
    EXPECT_TRUE(ex.response->checksum_ok);
    EXPECT_EQ(ex.response->pdu()[3], 0x34);
}

TEST(Client, UnreachableEndpointIsAnErrorNamingIt) {
    auto listener = listen_tcp("127.0.0.1", 0).value();
    const auto port = bound_port(listener.get());
    listener.reset();  // nobody listens there now
    auto client = Client::open(endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_FALSE(client);
    EXPECT_NE(client.error().find(std::to_string(port)), std::string::npos);
}

}  // namespace
}  // namespace mbscope::modbus::transport::test_transport_client_test
