// The conformance runner against a slave that answers anything: a loopback Modbus/TCP server that, drawn
// from a seeded generator for every request, replies correctly, with a random exception code, a random PDU,
// another transaction or unit id, a length it never sends, a protocol id other than 0, twice, not at all, or
// closes the connection. A firmware team's device under development can do any of these. The run must
// finish, certify nothing, say for every rule what it expected and what it saw, account for every point it
// wrote (restored, or why not), and write its JSON and JUnit reports whole.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

#include "conformance/report.hpp"
#include "conformance/runner.hpp"
#include "conformance/session.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance::test_conformance_hostile_slave_test {
namespace {

namespace tp = modbus::transport;

class HostileServer {
  public:
    // `honest_for`: answer that many requests as a correct slave would, then none at all (a device that
    // hung mid-run, its connection still open).
    // A slave that answers as a correct one would, but in one way:
    enum class Lapse : std::uint8_t {
        None,
        DropsOnePointReads,  // a read of one point is never answered (a device or an RS-485 line losing some)
        SetsPaddingBits,     // a reply to FC1 or FC2 has every bit set, past the quantity asked too
        AcknowledgesOneMore,  // FC15 and FC16 replies carry a quantity one more than written
    };
    explicit HostileServer(unsigned seed, std::optional<std::size_t> honest_for = std::nullopt,
                           Lapse lapse = Lapse::None)
        : random_(seed), honest_for_(honest_for), lapse_(lapse) {
        listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        ::bind(listener_, reinterpret_cast<sockaddr*>(&a), sizeof a);
        ::listen(listener_, 8);
        socklen_t len = sizeof a;
        ::getsockname(listener_, reinterpret_cast<sockaddr*>(&a), &len);
        port_ = ntohs(a.sin_port);
        thread_ = std::thread([this] { serve(); });
    }
    ~HostileServer() {
        stop_ = true;
        thread_.join();
        for (auto& c : connections_)
            ::close(c.fd);
        ::close(listener_);
    }
    HostileServer(const HostileServer&) = delete;
    HostileServer& operator=(const HostileServer&) = delete;

    std::uint16_t port() const { return port_; }
    std::size_t requests() const { return requests_; }
    // The table and (first) address of each write (FC5, FC6, FC15, FC16, FC22, FC23) acknowledged so far.
    std::vector<std::pair<modbus::Table, std::uint16_t>> writes() const {
        std::lock_guard lock(mutex_);
        return writes_;
    }

  private:
    struct Connection {
        int fd;
        std::vector<std::uint8_t> in;
    };

    void serve() {
        while (!stop_) {
            std::vector<pollfd> fds{{listener_, POLLIN, 0}};
            for (const auto& c : connections_)
                fds.push_back({c.fd, POLLIN, 0});
            if (::poll(fds.data(), fds.size(), 10) <= 0) continue;
            if (fds[0].revents & POLLIN) {
                const int fd = ::accept(listener_, nullptr, nullptr);
                if (fd >= 0) connections_.push_back({fd, {}});
            }
            for (std::size_t i = 1; i < fds.size(); ++i) {
                if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
                Connection& c = connections_[i - 1];
                std::uint8_t buf[1024];
                const ssize_t n = ::read(c.fd, buf, sizeof buf);
                if (n <= 0) {
                    ::close(c.fd);
                    c.fd = -1;
                    continue;
                }
                c.in.insert(c.in.end(), buf, buf + n);
                answer(c);
            }
            std::erase_if(connections_, [](const Connection& c) { return c.fd < 0; });
        }
    }

    // Every complete MBAP request in the buffer gets its answer; a connection that sends more than a
    // request could hold without completing one is closed.
    void answer(Connection& c) {
        while (c.fd >= 0 && c.in.size() >= 6) {
            const std::size_t total = 6u + ((std::size_t{c.in[4]} << 8) | c.in[5]);
            if (c.in.size() < total) {
                if (c.in.size() > 300) {
                    ::close(c.fd);
                    c.fd = -1;
                }
                return;
            }
            const std::vector<std::uint8_t> request(c.in.begin(), c.in.begin() + static_cast<long>(total));
            c.in.erase(c.in.begin(), c.in.begin() + static_cast<long>(total));
            ++requests_;
            reply_to(c, request);
        }
    }

    std::uint8_t byte() { return static_cast<std::uint8_t>(random_() & 0xFF); }

    void send(Connection& c, std::uint16_t tid, std::uint16_t protocol, std::uint8_t unit,
              const std::vector<std::uint8_t>& pdu, std::size_t claimed_extra = 0) {
        const std::size_t length = pdu.size() + 1 + claimed_extra;
        std::vector<std::uint8_t> adu{static_cast<std::uint8_t>(tid >> 8),
                                      static_cast<std::uint8_t>(tid),
                                      static_cast<std::uint8_t>(protocol >> 8),
                                      static_cast<std::uint8_t>(protocol),
                                      static_cast<std::uint8_t>(length >> 8),
                                      static_cast<std::uint8_t>(length),
                                      unit};
        adu.insert(adu.end(), pdu.begin(), pdu.end());
        (void)::send(c.fd, adu.data(), adu.size(), MSG_NOSIGNAL);
    }

    // A reply a correct slave could give: the read's values (random), a write's echo, anything else echoed.
    std::vector<std::uint8_t> plausible(const std::vector<std::uint8_t>& pdu) {
        if (pdu.empty()) return {0x80, 0x01};
        const std::uint8_t fc = pdu[0];
        if (fc >= 1 && fc <= 4 && pdu.size() >= 5) {
            const unsigned quantity = (pdu[3] << 8) | pdu[4];
            const std::size_t count = fc <= 2 ? (quantity + 7) / 8 : quantity * 2u;
            std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>(count)};
            for (std::size_t i = 0; i < std::min<std::size_t>(count, 250); ++i)
                r.push_back(byte());
            return r;
        }
        if ((fc == 15 || fc == 16) && pdu.size() >= 5) return {pdu.begin(), pdu.begin() + 5};
        return pdu;
    }

    void reply_to(Connection& c, const std::vector<std::uint8_t>& request) {
        const auto tid = static_cast<std::uint16_t>((request[0] << 8) | request[1]);
        const std::uint8_t unit = request[6];
        const std::vector<std::uint8_t> pdu(request.begin() + 7, request.end());
        if (honest_for_) {
            if (requests_ <= *honest_for_) send(c, tid, 0, unit, plausible(pdu));
            return;
        }
        if (lapse_ != Lapse::None) {
            const std::uint8_t fc = pdu.empty() ? 0 : pdu[0];
            if (lapse_ == Lapse::DropsOnePointReads && fc >= 1 && fc <= 4 && pdu.size() == 5 && pdu[3] == 0 &&
                pdu[4] == 1)
                return;
            auto reply = plausible(pdu);
            if (lapse_ == Lapse::SetsPaddingBits && (fc == 1 || fc == 2) && reply.size() > 2)
                std::fill(reply.begin() + 2, reply.end(), std::uint8_t{0xFF});
            if (lapse_ == Lapse::AcknowledgesOneMore && (fc == 15 || fc == 16) && reply.size() == 5 &&
                ++reply[4] == 0)
                ++reply[3];
            // FC23 writes at its second address; the others at their first.
            const std::size_t at = fc == 23 ? 5 : 1;
            if ((fc == 5 || fc == 6 || fc == 15 || fc == 16 || fc == 22 || fc == 23) &&
                pdu.size() >= at + 2) {
                std::lock_guard lock(mutex_);
                writes_.emplace_back(
                    fc == 5 || fc == 15 ? modbus::Table::Coils : modbus::Table::HoldingRegisters,
                    static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]));
            }
            send(c, tid, 0, unit, reply);
            return;
        }
        switch (random_() % 11) {
            case 0:
            case 1:
            case 2:
                send(c, tid, 0, unit, plausible(pdu));
                break;
            case 3:  // an exception with any code
                send(c, tid, 0, unit, {static_cast<std::uint8_t>((pdu.empty() ? 0 : pdu[0]) | 0x80), byte()});
                break;
            case 4: {  // any PDU
                std::vector<std::uint8_t> r(random_() % 254);
                for (auto& b : r)
                    b = byte();
                send(c, tid, 0, unit, r);
                break;
            }
            case 5:
                send(c, static_cast<std::uint16_t>(tid + 1 + random_() % 3), 0, unit, plausible(pdu));
                break;
            case 6:
                send(c, tid, 0, static_cast<std::uint8_t>(unit + 1), plausible(pdu));
                break;
            case 7:  // a length it never sends
                send(c, tid, 0, unit, plausible(pdu), 1 + random_() % 200);
                break;
            case 8:
                send(c, tid, static_cast<std::uint16_t>(1 + random_() % 0xFFFE), unit, plausible(pdu));
                break;
            case 9:
                send(c, tid, 0, unit, plausible(pdu));
                send(c, tid, 0, unit, plausible(pdu));
                break;
            default:
                if (random_() % 4 == 0) {
                    ::close(c.fd);
                    c.fd = -1;
                }
                break;  // silence
        }
    }

    std::mt19937 random_;
    std::optional<std::size_t> honest_for_;
    Lapse lapse_ = Lapse::None;
    mutable std::mutex mutex_;
    std::vector<std::pair<modbus::Table, std::uint16_t>> writes_;
    int listener_ = -1;
    std::uint16_t port_ = 0;
    std::thread thread_;
    std::atomic<bool> stop_{false};
    std::vector<Connection> connections_;
    std::atomic<std::size_t> requests_{0};
};

const modbus::Profile& profile(const std::string& id) {
    static modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    static std::map<std::string, modbus::Profile> loaded;
    auto it = loaded.find(id);
    if (it == loaded.end()) it = loaded.emplace(id, store.load(id).value()).first;
    return it->second;
}

struct Case {
    std::string profile;
    unsigned seed;
};

std::ostream& operator<<(std::ostream& out, const Case& c) {
    return out << c.profile << " seed " << c.seed;
}

class AgainstAHostileSlave : public ::testing::TestWithParam<Case> {};

TEST_P(AgainstAHostileSlave, TheRunFinishesCertifiesNothingAndAccountsForEverything) {
    HostileServer server(GetParam().seed);
    auto endpoint = tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port()));
    ASSERT_TRUE(endpoint.has_value());
    auto client = tp::Client::open(*endpoint);
    ASSERT_TRUE(client.has_value()) << client.error();
    CheckOptions options;
    options.session.unit = 1;
    // Loopback answers in microseconds; a reply that comes later than this is one the server chose not to
    // send in time, and the run must cope with that too.
    options.session.timeout = std::chrono::milliseconds(10);
    options.session.interval = std::chrono::milliseconds(0);
    const Report report = run_check(*client, profile(GetParam().profile), options);

    EXPECT_GT(server.requests(), 50u);
    EXPECT_NE(verdict(report), 0) << "a slave that answers anything was certified";
    EXPECT_GT(report.count(Outcome::Fail) + report.count(Outcome::Error), 0u);
    for (const auto& x : report.results) {
        EXPECT_FALSE(x.rule.id.empty());
        if (x.outcome == Outcome::Fail) {
            EXPECT_FALSE(x.expected.empty()) << x.rule.id;
            EXPECT_FALSE(x.observed.empty()) << x.rule.id;
        }
        if (x.outcome == Outcome::Error || x.outcome == Outcome::Skip) {
            EXPECT_FALSE(x.reason.empty()) << x.rule.id;
        }
    }
    for (const auto& t : report.restored)
        EXPECT_TRUE(t.restored || !t.problem.empty())
            << modbus::to_string(t.table) << ' ' << t.address << ": neither restored nor why not";

    // The reports are whole: the JSON reads back, the JUnit XML closes what it opens.
    const std::string json = to_json(report).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    const auto back = nlohmann::json::parse(json, nullptr, false);
    ASSERT_FALSE(back.is_discarded());
    std::ostringstream junit;
    write_junit(junit, report);
    const std::string xml = junit.str();
    EXPECT_NE(xml.find("<testsuites"), std::string::npos);
    EXPECT_NE(xml.find("</testsuites>"), std::string::npos);
    std::ostringstream text;
    write_text(text, report, true);
    EXPECT_FALSE(text.str().empty());
}

// A device that stops answering during the restore is not waited for point by point: after eight requests
// in a row without a byte back the rest are listed as not restored, with why.
TEST(Restore, StopsWritingToADeviceThatStoppedAnswering) {
    HostileServer server(1, 2);  // answers the read of the originals and the write, then nothing
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port())));
    ASSERT_TRUE(client.has_value()) << client.error();
    SessionOptions options;
    options.timeout = std::chrono::milliseconds(20);
    Session session(*client, options, &profile("modbus"));
    ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 0, 100, 100));
    const std::vector<std::uint16_t> words(100, 0xBEEF);
    ASSERT_FALSE(session.request(modbus::encode_pdu(modbus::make_write_multiple_registers(0, words)), "write")
                     .received.empty());
    const auto before = session.requests();
    const auto ledger = session.restore();
    // The block's write and read, then three points' writes and reads: eight without a reply.
    EXPECT_EQ(session.requests() - before, 8u);
    ASSERT_EQ(ledger.size(), 100u);
    for (const auto& t : ledger) {
        EXPECT_FALSE(t.restored) << t.address;
        EXPECT_FALSE(t.problem.empty()) << t.address;
    }
    // A session that does not see the writes (watch_writes() off) knows no value the point was left with.
    EXPECT_EQ(ledger.back().problem,
              "not restored: no reply to 8 requests in a row; what it holds is unknown");
}

// A rule that writes reads its point first so the end of the run can write it back; where that read went
// unanswered it writes nothing. value.fc5.invalid wrote 0x1234 to its coil anyway (and a device that took it
// was left changed, the report saying everything was restored), as did fc.unsupported.N for a write.
TEST(Restore, NothingIsWrittenWhereTheOriginalCouldNotBeRead) {
    HostileServer server(1, std::nullopt, HostileServer::Lapse::DropsOnePointReads);
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port())));
    ASSERT_TRUE(client.has_value()) << client.error();
    CheckOptions options;
    options.session.unit = 1;
    options.session.timeout = std::chrono::milliseconds(20);
    // FC8 first: a target that answers nothing is not judged at all.
    options.run.rule_globs = {"fc.supported.8", "value.fc5.invalid", "fc.unsupported.22",
                              "fc.unsupported.23"};
    const Report report = run_check(*client, profile("cth2265i"), options);
    ASSERT_FALSE(report.results.empty());
    std::set<std::pair<modbus::Table, std::uint16_t>> kept;
    for (const auto& t : report.restored)
        kept.insert({t.table, t.address});
    for (const auto& [table, address] : server.writes())
        EXPECT_TRUE(kept.count({table, address}))
            << modbus::to_string(table) << ' ' << address << " written without its value kept";
    for (const auto& x : report.results)
        if (x.rule.id == "value.fc5.invalid") {
            EXPECT_EQ(x.outcome, Outcome::Error);
            EXPECT_EQ(x.reason, "the coil's value could not be read, so nothing was written");
        } else if (x.rule.id != "fc.supported.8") {
            EXPECT_EQ(x.outcome, Outcome::Error) << x.rule.id;
            EXPECT_EQ(x.reason,
                      "address 0 of the table it would write could not be read, so nothing was sent");
        }
    EXPECT_EQ(report.results.size(), 4u);
}

// The bits of a reply to FC1 or FC2 past the quantity asked are zero (AP §6.1, §6.2): a slave that sets them
// fails data.padding.fcN; the reference slave passes it (runner_test's clean runs).
TEST(Padding, BitsSetPastTheQuantityAskedFailTheRule) {
    HostileServer server(1, std::nullopt, HostileServer::Lapse::SetsPaddingBits);
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port())));
    ASSERT_TRUE(client.has_value()) << client.error();
    CheckOptions options;
    options.session.timeout = std::chrono::milliseconds(100);
    options.run.rule_globs = {"data.padding.*"};
    const Report report = run_check(*client, profile("mmk-2030"), options);
    ASSERT_EQ(report.results.size(), 1u);  // the MK 3.8 map has coils, no discrete inputs
    const RuleResult& r = report.results[0];
    EXPECT_EQ(r.rule.id, "data.padding.fc1");
    EXPECT_EQ(r.outcome, Outcome::Fail) << r.reason;
    EXPECT_EQ(r.expected, "bits 6 to 7 of the last byte zero");  // 30 coils, the manual's limit
    EXPECT_EQ(r.observed, "last byte 0xFF for 30 points");
}

// FC15 and FC16 are answered with the starting address and quantity written (AP §6.11, §6.12): a slave
// acknowledging one more than it was sent fails the rules that write with them, which used to look at the
// reply's function code only.
TEST(Echo, AWriteAcknowledgedWithAnotherQuantityFailsTheRule) {
    HostileServer server(1, std::nullopt, HostileServer::Lapse::AcknowledgesOneMore);
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port())));
    ASSERT_TRUE(client.has_value()) << client.error();
    CheckOptions options;
    options.session.timeout = std::chrono::milliseconds(100);
    options.run.rule_globs = {"fc.supported.15", "fc.supported.16", "fc.supported.3"};
    const Report report = run_check(*client, profile("mmk-2030"), options);
    ASSERT_EQ(report.results.size(), 3u);
    for (const auto& r : report.results) {
        if (r.rule.id == "fc.supported.3") {
            EXPECT_EQ(r.outcome, Outcome::Pass) << r.observed;
            continue;
        }
        EXPECT_EQ(r.outcome, Outcome::Fail) << r.rule.id << ": " << r.observed;
        EXPECT_NE(r.observed.find("the reply is not an echo of the request's starting address and quantity "
                                  "(AP §6.11-6.12)"),
                  std::string::npos)
            << r.rule.id << ": " << r.observed;
    }
}

// AP §4.1: a PDU holds 253 bytes. A slave that echoes an FC8 query of 254 bytes over Modbus/TCP (the
// reference slave did, in a 261-byte ADU) fails the rule; the reference slave's silence passes it
// (EveryProfileOverTcp, runner_test.cpp).
TEST(PduTooLong, AnEchoOfAnOverLongQueryFailsTheRule) {
    HostileServer server(1, 1000);  // answers as a correct slave would, echoing FC8 whatever its length
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(server.port())));
    ASSERT_TRUE(client.has_value()) << client.error();
    CheckOptions options;
    options.session.timeout = std::chrono::milliseconds(100);
    options.run.rule_globs = {"tcp.pdu_too_long"};
    const Report report = run_check(*client, profile("mmk-2030"), options);
    const auto it = std::find_if(report.results.begin(), report.results.end(),
                                 [](const RuleResult& x) { return x.rule.id == "tcp.pdu_too_long"; });
    ASSERT_NE(it, report.results.end());
    EXPECT_EQ(it->rule.source, "AP §4.1");
    EXPECT_EQ(it->outcome, Outcome::Fail) << it->observed;
    EXPECT_EQ(it->observed, "normal response, function 8");
}

INSTANTIATE_TEST_SUITE_P(Seeds, AgainstAHostileSlave,
                         ::testing::Values(Case{"modbus", 1}, Case{"modbus", 2}, Case{"mmk-2030", 3},
                                           Case{"cth2265i", 4}),
                         [](const auto& info) {
                             std::string n = info.param.profile + "_seed_" + std::to_string(info.param.seed);
                             for (auto& ch : n)
                                 if (ch == '-') ch = '_';
                             return n;
                         });

}  // namespace
}  // namespace mbscope::conformance::test_conformance_hostile_slave_test
