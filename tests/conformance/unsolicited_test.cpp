// A slave only answers, and answers each request once (SL §2.1; MK-MS-01, 000:246-248; WA-GEN-02,
// 002:164). A scripted loopback server (Modbus/TCP or RTU over TCP) that serves FC3 reads of one register
// and misbehaves on cue: it sends its first reply again (in the same write, or later), or speaks with no
// request. The runner's session must see a reply that came twice however it came (reply.once) and never
// take the copy for the next request's reply; silence.idle must hear a device that speaks unasked.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <optional>
#include <thread>
#include <vector>

#include "conformance/runner.hpp"
#include "conformance/session.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "modbus/transport/client.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::conformance::test_conformance_unsolicited_test {
namespace {

namespace tp = modbus::transport;
using namespace std::chrono_literals;

struct Script {
    bool rtu = false;  // RTU over TCP, else Modbus/TCP
    std::optional<std::chrono::milliseconds>
        repeat;  // the first reply again, this long after it (0: same write)
    std::optional<std::chrono::milliseconds> speak;  // a reply nobody asked for, this long after connecting
};

class ScriptedServer {
  public:
    explicit ScriptedServer(Script script) : script_(script) {
        listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        ::bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a);
        ::listen(listener_, 1);
        socklen_t len = sizeof a;
        ::getsockname(listener_, reinterpret_cast<sockaddr*>(&a), &len);
        port_ = ntohs(a.sin_port);
        thread_ = std::thread([this] { serve(); });
    }
    ~ScriptedServer() {
        stop_ = true;
        thread_.join();
        ::close(listener_);
    }
    ScriptedServer(const ScriptedServer&) = delete;
    ScriptedServer& operator=(const ScriptedServer&) = delete;

    std::string uri() const {
        return (script_.rtu ? "rtu-tcp" : "tcp") + std::string("://127.0.0.1:") + std::to_string(port_);
    }

    // The value register `address` reads.
    static std::uint16_t value(std::uint16_t address) { return static_cast<std::uint16_t>(0x1000 + address); }

  private:
    std::vector<std::uint8_t> reply(std::uint16_t tid, std::uint16_t address) const {
        const std::uint16_t v = value(address);
        const std::vector<std::uint8_t> pdu = {0x03, 0x02, static_cast<std::uint8_t>(v >> 8),
                                               static_cast<std::uint8_t>(v)};
        return script_.rtu ? modbus::encode_rtu(1, pdu) : modbus::encode_tcp(tid, 1, pdu);
    }

    void send(int fd, const std::vector<std::uint8_t>& bytes) {
        (void)::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    }

    void serve() {
        pollfd l{listener_, POLLIN, 0};
        while (!stop_ && ::poll(&l, 1, 20) == 0) {
        }
        if (stop_) return;
        const int fd = ::accept(listener_, nullptr, nullptr);
        const auto connected = std::chrono::steady_clock::now();
        std::vector<std::uint8_t> in;
        std::optional<std::pair<std::chrono::steady_clock::time_point, std::vector<std::uint8_t>>> later;
        bool first = true;
        const std::size_t request_size = script_.rtu ? 8 : 12;  // FC3 of one register
        while (!stop_) {
            const auto now = std::chrono::steady_clock::now();
            if (script_.speak && now - connected >= *script_.speak) {
                send(fd, reply(0x0777, 99));
                script_.speak.reset();
            }
            if (later && now >= later->first) {
                send(fd, later->second);
                later.reset();
            }
            pollfd p{fd, POLLIN, 0};
            if (::poll(&p, 1, 2) <= 0) continue;
            std::uint8_t buf[256];
            const ssize_t n = ::read(fd, buf, sizeof buf);
            if (n <= 0) break;
            in.insert(in.end(), buf, buf + n);
            while (in.size() >= request_size) {
                const std::span<const std::uint8_t> request(in.data(), request_size);
                const std::size_t at = script_.rtu ? 2 : 8;
                const auto address = static_cast<std::uint16_t>((request[at] << 8) | request[at + 1]);
                const auto tid = static_cast<std::uint16_t>((request[0] << 8) | request[1]);
                auto r = reply(tid, address);
                if (first && script_.repeat) {
                    if (*script_.repeat == 0ms) {
                        const auto once = r;
                        r.insert(r.end(), once.begin(), once.end());
                    } else {
                        later.emplace(std::chrono::steady_clock::now() + *script_.repeat, r);
                    }
                }
                first = false;
                send(fd, r);
                in.erase(in.begin(), in.begin() + static_cast<std::ptrdiff_t>(request_size));
            }
        }
        ::close(fd);
    }

    Script script_;
    int listener_ = -1;
    std::uint16_t port_ = 0;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

std::vector<std::uint8_t> read_one(std::uint16_t address) {
    return modbus::encode_pdu(
        modbus::make_read_request(modbus::FunctionCode::ReadHoldingRegisters, address, 1));
}

std::optional<std::uint16_t> value_of(const tp::Exchange& ex) {
    if (!ex.response || !ex.response->checksum_ok) return std::nullopt;
    const auto pdu = ex.response->pdu();
    if (pdu.size() != 4 || pdu[0] != 0x03) return std::nullopt;
    return static_cast<std::uint16_t>((pdu[2] << 8) | pdu[3]);
}

struct RepeatCase {
    bool rtu;
    std::chrono::milliseconds repeat;
};

void PrintTo(const RepeatCase& c, std::ostream* os) {
    *os << (c.rtu ? "rtu-tcp" : "tcp") << ", the copy " << c.repeat.count() << " ms after the reply";
}

class RepeatedReply : public ::testing::TestWithParam<RepeatCase> {};

// The copy comes in the same read as the reply (0 ms), or later: before the next request (RTU: found
// waiting; Modbus/TCP: set aside by its transaction id while the next one waits). Either way it is counted
// once, with the request it answered, and the next request gets its own reply.
TEST_P(RepeatedReply, IsCountedOnceAndNeverTakenForTheNextRequestsReply) {
    ScriptedServer server({GetParam().rtu, GetParam().repeat, std::nullopt});
    auto client = tp::Client::open(*tp::parse_endpoint(server.uri()));
    ASSERT_TRUE(client.has_value()) << client.error();
    SessionOptions options;
    options.timeout = 500ms;
    Session session(*client, options);
    const auto first = session.request(read_one(10), "first");
    EXPECT_EQ(value_of(first), ScriptedServer::value(10));
    std::this_thread::sleep_for(GetParam().repeat + 50ms);
    const auto second = session.request(read_one(20), "second");
    EXPECT_EQ(value_of(second), ScriptedServer::value(20));
    const auto third = session.request(read_one(30), "third");
    EXPECT_EQ(value_of(third), ScriptedServer::value(30));
    const auto& repeated = session.repeated_replies();
    ASSERT_EQ(repeated.size(), 1u);
    EXPECT_EQ(repeated.front().sent, first.sent);
    ASSERT_TRUE(first.response.has_value());
    const auto copy = first.response->adu();
    ASSERT_GE(repeated.front().received.size(), copy.size());
    EXPECT_TRUE(std::search(repeated.front().received.begin(), repeated.front().received.end(), copy.begin(),
                            copy.end()) != repeated.front().received.end());
}

INSTANTIATE_TEST_SUITE_P(Scripted, RepeatedReply,
                         ::testing::Values(RepeatCase{false, 0ms}, RepeatCase{false, 30ms},
                                           RepeatCase{true, 0ms}, RepeatCase{true, 30ms}),
                         [](const auto& info) {
                             return std::string(info.param.rtu ? "RtuOverTcp" : "Tcp") +
                                    (info.param.repeat == 0ms ? "SameWrite" : "Later");
                         });

Report check(ScriptedServer& server, std::vector<std::string> rules, std::chrono::milliseconds idle) {
    auto client = tp::Client::open(*tp::parse_endpoint(server.uri()));
    EXPECT_TRUE(client.has_value());
    if (!client) return {};
    CheckOptions o;
    o.session.timeout = 500ms;
    o.run.rule_globs = std::move(rules);
    o.run.idle = idle;
    // A map with no open address space: nothing is probed before the rules.
    return run_check(*client, slave::test::profile("mmk-2030"), o);
}

const RuleResult* result(const Report& r, const std::string& id) {
    for (const auto& x : r.results)
        if (x.rule.id == id) return &x;
    return nullptr;
}

TEST(SilenceIdle, HearsADeviceThatSpeaksUnasked) {
    ScriptedServer server({false, std::nullopt, 50ms});
    const Report r = check(server, {"silence.idle", "reply.once"}, 300ms);
    const auto* idle = result(r, "silence.idle");
    ASSERT_NE(idle, nullptr);
    EXPECT_EQ(idle->outcome, Outcome::Fail);
    EXPECT_NE(idle->observed.find("1 whole frames"), std::string::npos) << idle->observed;
    ASSERT_EQ(idle->evidence.size(), 1u);
    EXPECT_EQ(idle->evidence.front().received,
              modbus::encode_tcp(0x0777, 1, std::vector<std::uint8_t>{0x03, 0x02, 0x10, 0x63}));
    const auto* once = result(r, "reply.once");
    ASSERT_NE(once, nullptr);
    EXPECT_EQ(once->outcome, Outcome::Pass);
    EXPECT_EQ(verdict(r), 1);
}

TEST(SilenceIdle, PassesADeviceThatOnlyAnswers) {
    ScriptedServer server({true, std::nullopt, std::nullopt});
    const Report r = check(server, {"silence.idle"}, 200ms);
    const auto* idle = result(r, "silence.idle");
    ASSERT_NE(idle, nullptr);
    EXPECT_EQ(idle->outcome, Outcome::Pass) << idle->observed;
    ASSERT_EQ(idle->evidence.size(), 1u);
    EXPECT_TRUE(idle->evidence.front().received.empty());
    EXPECT_GE(idle->evidence.front().elapsed, 200ms);
}

}  // namespace
}  // namespace mbscope::conformance::test_conformance_unsolicited_test
