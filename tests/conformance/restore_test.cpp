// The restore promises to put back what the run changed, and only that: a point whose write the device
// refused, or that was written with the value it held, is not the run's to put back, and a value the device
// set itself is not overwritten and called restored. What did not go back says what it was left holding and
// why. A device that refuses connections for a moment (a reboot) is waited for, not given up in
// milliseconds; a target whose every reply comes late is not judged.
#include <gtest/gtest.h>

#include <poll.h>
#include <sys/socket.h>

#include <array>
#include <atomic>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

#include "conformance/context.hpp"
#include "conformance/report.hpp"
#include "conformance/session.hpp"
#include "modbus/transport/socket.hpp"
#include "tests/conformance/runner_support.hpp"

namespace mbscope::conformance {
namespace {

using namespace mbscope::conformance::test;

// A Modbus/TCP device on 127.0.0.1 with 200 points in each table (coil i is i % 3 == 0, holding register i
// is 1000 + i, so a value left behind shows), serving one connection at a time. `hook` sees each request's
// PDU first: it may change the map (the device's own process), answer otherwise (nullopt inside: silence),
// or ask for a reboot after the reply (reboot_for()).
class MapDevice {
  public:
    static constexpr unsigned points = 200;
    using Reply = std::optional<std::vector<std::uint8_t>>;
    using Hook = std::function<std::optional<Reply>(MapDevice&, const std::vector<std::uint8_t>&)>;

    explicit MapDevice(Hook hook, std::uint16_t port = 0) : hook_(std::move(hook)), port_(port) {
        for (unsigned i = 0; i < points; ++i) {
            hr[i] = static_cast<std::uint16_t>(1000 + i);
            co[i] = i % 3 == 0;
        }
        listen();
        thread_ = std::thread([this] { serve(); });
    }
    ~MapDevice() { stop(); }
    MapDevice(const MapDevice&) = delete;
    MapDevice& operator=(const MapDevice&) = delete;
    void stop() {
        done_ = true;
        if (thread_.joinable()) thread_.join();
    }
    std::uint16_t port() const { return port_; }
    // After this reply, the connection closes and connections are refused for `down` (a reboot).
    void reboot_for(std::chrono::milliseconds down) { reboot_ = down; }

    std::array<std::uint16_t, points> hr{};
    std::array<bool, points> co{};

  private:
    void listen() {
        auto l = tp::listen_tcp("127.0.0.1", port_);
        EXPECT_TRUE(l.has_value()) << (l ? "" : l.error());
        if (!l) return;
        listener_ = std::move(l).value();
        port_ = tp::bound_port(listener_.get());
    }
    static std::vector<std::uint8_t> exception(std::uint8_t fc, std::uint8_t code) {
        return {static_cast<std::uint8_t>(fc | 0x80), code};
    }
    std::vector<std::uint8_t> answer(const std::vector<std::uint8_t>& pdu) {
        if (pdu.size() < 5) return exception(pdu.empty() ? 0 : pdu[0], 0x03);
        const std::uint8_t fc = pdu[0];
        const unsigned a = (pdu[1] << 8) | pdu[2];
        const unsigned q = (pdu[3] << 8) | pdu[4];
        switch (fc) {
            case 1:
            case 2: {
                if (q < 1 || q > 2000) return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>((q + 7) / 8)};
                r.resize(2 + r[1], 0);
                for (unsigned i = 0; i < q; ++i)
                    if (fc == 1 && co[a + i]) r[2 + i / 8] |= static_cast<std::uint8_t>(1u << (i % 8));
                return r;
            }
            case 3:
            case 4: {
                if (q < 1 || q > 125) return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>(2 * q)};
                for (unsigned i = 0; i < q; ++i) {
                    const std::uint16_t v = fc == 3 ? hr[a + i] : 0;
                    r.push_back(static_cast<std::uint8_t>(v >> 8));
                    r.push_back(static_cast<std::uint8_t>(v));
                }
                return r;
            }
            case 5:
                if (q != 0 && q != 0xFF00) return exception(fc, 0x03);
                if (a >= points) return exception(fc, 0x02);
                co[a] = q != 0;
                return pdu;
            case 6:
                if (a >= points) return exception(fc, 0x02);
                hr[a] = static_cast<std::uint16_t>(q);
                return pdu;
            case 15:
            case 16: {
                const unsigned max = fc == 15 ? 1968 : 123;
                const std::size_t bytes = fc == 15 ? (q + 7) / 8 : 2 * q;
                if (q < 1 || q > max || pdu.size() < 6 || pdu[5] != bytes || pdu.size() != 6 + bytes)
                    return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                for (unsigned i = 0; i < q; ++i) {
                    if (fc == 15)
                        co[a + i] = (pdu[6 + i / 8] >> (i % 8)) & 1;
                    else
                        hr[a + i] = static_cast<std::uint16_t>((pdu[6 + 2 * i] << 8) | pdu[7 + 2 * i]);
                }
                return {pdu.begin(), pdu.begin() + 5};
            }
            default:
                return exception(fc, 0x01);
        }
    }
    void serve() {
        while (!done_) {
            pollfd incoming{listener_.get(), POLLIN, 0};
            if (::poll(&incoming, 1, 50) != 1) continue;
            serve_connection(tp::UniqueFd(::accept(listener_.get(), nullptr, nullptr)));
            if (reboot_.count() > 0) {
                // Closed and not listening: connections are refused until the device is back.
                listener_.reset();
                std::this_thread::sleep_for(std::exchange(reboot_, std::chrono::milliseconds(0)));
                listen();
            }
        }
    }
    void serve_connection(tp::UniqueFd fd) {
        if (!fd) return;
        std::uint8_t header[7];
        for (;;) {
            pollfd p{fd.get(), POLLIN, 0};
            if (::poll(&p, 1, 50) != 1) {
                if (done_) return;
                continue;
            }
            if (::recv(fd.get(), header, 7, MSG_WAITALL) != 7) break;
            const std::size_t length = (header[4] << 8) | header[5];
            std::vector<std::uint8_t> pdu(length > 1 ? length - 1 : 0);
            if (!pdu.empty() && ::recv(fd.get(), pdu.data(), pdu.size(), MSG_WAITALL) != ssize_t(pdu.size()))
                break;
            Reply reply;
            if (auto hooked = hook_(*this, pdu))
                reply = *hooked;
            else
                reply = answer(pdu);
            if (reply) {
                std::vector<std::uint8_t> adu(header, header + 7);
                adu[4] = static_cast<std::uint8_t>((reply->size() + 1) >> 8);
                adu[5] = static_cast<std::uint8_t>(reply->size() + 1);
                adu.insert(adu.end(), reply->begin(), reply->end());
                (void)::send(fd.get(), adu.data(), adu.size(), MSG_NOSIGNAL);
            }
            if (reboot_.count() > 0) break;
        }
    }

  public:
    // Serves a request as the device's map says (for hooks that change only part of the answer).
    std::vector<std::uint8_t> serve_normally(const std::vector<std::uint8_t>& pdu) { return answer(pdu); }

  private:
    Hook hook_;
    std::uint16_t port_;
    tp::UniqueFd listener_;
    std::atomic<bool> done_{false};
    std::chrono::milliseconds reboot_{0};
    std::thread thread_;
};

tp::Client connect_to(const MapDevice& device) {
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(device.port())));
    EXPECT_TRUE(client.has_value()) << (client ? "" : client.error());
    return std::move(client).value();
}

std::uint16_t word_at(const std::vector<std::uint8_t>& pdu, std::size_t at) {
    return static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]);
}

// The tester's `latchreq=50@230`: quantity.fc15.max_plus_one read coils 0-99 into the ledger and sent an
// FC15 the device refused with exception 03 (nothing written); the device's own process then set coil 50.
// The restore's FC15 of every coil from the snapshot forced it back to 0 and the report said "101 points
// written and restored". quantity.fc16.max writes the registers' current values: a register the device
// changed after it was put back too. Nothing the run changed: nothing written back, nothing listed.
TEST(Restore, APointTheRunDidNotChangeIsLeftAsTheDeviceSetIt) {
    MapDevice device(
        [](MapDevice& d, const std::vector<std::uint8_t>& pdu) -> std::optional<MapDevice::Reply> {
            if (pdu.size() >= 5 && pdu[0] == 15 && word_at(pdu, 3) > 1968) {
                d.co[50] = true;  // the device's own process, while the refused write is answered
                return std::vector<std::uint8_t>{0x8F, 0x03};
            }
            if (pdu.size() >= 5 && pdu[0] == 16 && word_at(pdu, 3) == 123) {
                auto reply = d.serve_normally(pdu);
                d.hr[7] = 4242;  // likewise, right after the write of the values it held
                return reply;
            }
            return std::nullopt;
        });
    Report report;
    {
        auto client = connect_to(device);
        auto options = options_for();
        options.run.rule_globs = {"quantity.fc15.max_plus_one", "quantity.fc16.max"};
        report = run_check(client, slave::test::profile("modbus"), options);
    }
    device.stop();
    std::map<std::string, RuleResult> by_id;
    for (const auto& r : report.results)
        by_id[r.rule.id] = r;
    ASSERT_TRUE(by_id.count("quantity.fc15.max_plus_one"));
    EXPECT_EQ(by_id["quantity.fc15.max_plus_one"].outcome, Outcome::Pass) << failures(report);
    ASSERT_TRUE(by_id.count("quantity.fc16.max"));
    EXPECT_EQ(by_id["quantity.fc16.max"].outcome, Outcome::Pass) << failures(report);
    EXPECT_TRUE(device.co[50]) << "the restore undid the device's own change";
    EXPECT_EQ(device.hr[7], 4242) << "the restore undid the device's own change";
    EXPECT_TRUE(report.restored.empty()) << "listed as written: " << report.restored.size() << " points";
    EXPECT_EQ(verdict_text(report), "pass") << failures(report);
}

// What the run changed goes back; a write the device refused (exception 01-03, 06) or one of the value a
// point held is not a change; a point holding neither its original nor what the run wrote after a write the
// device did not acknowledge was changed by the device, and is left and reported (not as restored). What does
// not go back says what it holds and the exception the device answered the restore's write with (the tester's
// `refuse_restore`: "coils 0: original 1, reads 0 after restoring 1" without a word of exception 04).
TEST(Restore, OnlyWhatTheRunChangedGoesBackAndWhatDidNotSaysWhy) {
    MapDevice device(
        [](MapDevice& d, const std::vector<std::uint8_t>& pdu) -> std::optional<MapDevice::Reply> {
            if (pdu.size() < 5 || pdu[0] != 6) return std::nullopt;
            const auto address = word_at(pdu, 1);
            const auto value = word_at(pdu, 3);
            if (address == 10 && value == 1010)
                return std::vector<std::uint8_t>{0x86, 0x04};  // restore refused
            if (address == 11 && value == 8) {
                d.hr[11] = 8;
                return MapDevice::Reply{};  // executed, never acknowledged
            }
            if (address == 14) return std::vector<std::uint8_t>{0x86, 0x03};  // refused: nothing written
            if (address == 15 && value == 9) {
                d.hr[15] = 9;  // written, then a failure (AP §7: 04, "while attempting to perform" it)
                return std::vector<std::uint8_t>{0x86, 0x04};
            }
            return std::nullopt;
        });
    std::vector<Touched> ledger;
    {
        auto client = connect_to(device);
        Session session(client, options_for(std::chrono::milliseconds(100)).session,
                        &slave::test::profile("modbus"));
        session.watch_writes();
        ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 10, 6));
        const auto write = [&](std::uint16_t a, std::uint16_t v) {
            return session.request(modbus::encode_pdu(modbus::make_write_single_register(a, v)), "write");
        };
        EXPECT_TRUE(is_normal(write(10, 7), 6));
        (void)write(11, 8);
        device.hr[11] = 99;  // the device's own change after the unacknowledged write
        const std::uint16_t own[1] = {1012};
        EXPECT_TRUE(is_normal(
            session.request(modbus::encode_pdu(modbus::make_write_multiple_registers(12, own)), "own value"),
            16));
        EXPECT_TRUE(is_normal(write(13, 5), 6));
        EXPECT_TRUE(is_exception(write(14, 6), 6, 0x03));
        EXPECT_TRUE(is_exception(write(15, 9), 6, 0x04));
        ledger = session.restore();
    }
    device.stop();
    std::map<std::uint16_t, Touched> by_address;
    for (const auto& t : ledger)
        by_address[t.address] = t;
    EXPECT_EQ(by_address.count(12), 0u) << "written with the value it held";
    EXPECT_EQ(by_address.count(14), 0u) << "its write was refused";
    ASSERT_EQ(by_address.count(10), 1u);
    const Touched& refused = by_address[10];
    EXPECT_FALSE(refused.restored);
    EXPECT_EQ(refused.restore_refused, "exception 04 (Server Device Failure)");
    EXPECT_EQ(refused.left, std::optional<std::uint16_t>(7));
    EXPECT_EQ(refused.left_from, "read");
    EXPECT_NE(refused.problem.find("left holding 7"), std::string::npos) << refused.problem;
    EXPECT_NE(refused.problem.find("exception 04"), std::string::npos) << refused.problem;
    ASSERT_EQ(by_address.count(11), 1u);
    EXPECT_FALSE(by_address[11].restored);
    EXPECT_TRUE(by_address[11].device_changed);
    EXPECT_EQ(device.hr[11], 99) << "the device's own value was overwritten";
    ASSERT_EQ(by_address.count(13), 1u);
    EXPECT_TRUE(by_address[13].restored) << by_address[13].problem;
    EXPECT_EQ(device.hr[13], 1013);
    // Exception 04 is no refusal: the write may have been done (the reference slave's exception-for-valid
    // writes, then answers 04), and was here; it goes back.
    ASSERT_EQ(by_address.count(15), 1u);
    EXPECT_TRUE(by_address[15].restored) << by_address[15].problem;
    EXPECT_EQ(device.hr[15], 1015);
    // The JSON ledger carries the same facts.
    Report report;
    report.restored = ledger;
    const auto json = to_json(report)["restored"];
    bool seen = false;
    for (const auto& entry : json)
        if (entry["address"] == 10) {
            seen = true;
            EXPECT_EQ(entry["written"], 7);
            EXPECT_EQ(entry["write_acknowledged"], true);
            EXPECT_EQ(entry["left"], 7);
            EXPECT_EQ(entry["left_from"], "read");
            EXPECT_EQ(entry["restore_refused"], "exception 04 (Server Device Failure)");
        }
    EXPECT_TRUE(seen);
}

// A device that stops answering mid-run (the tester's crash-after=400): the point the run wrote says it was
// left holding the run's value ("holding_registers 57: original 0, not restored: no reply ..." hid the
// 20019 left there), and the points it only read are not listed as at risk.
TEST(Restore, APointLeftOnAGoneDeviceSaysTheValueTheRunLeft) {
    std::atomic<bool> gone{false};
    MapDevice device([&](MapDevice&, const std::vector<std::uint8_t>&) -> std::optional<MapDevice::Reply> {
        if (gone) return MapDevice::Reply{};
        return std::nullopt;
    });
    std::vector<Touched> ledger;
    {
        auto client = connect_to(device);
        Session session(client, options_for(std::chrono::milliseconds(50)).session,
                        &slave::test::profile("modbus"));
        session.watch_writes();
        ASSERT_TRUE(session.remember(modbus::Table::Coils, 0, 10, 10));
        ASSERT_TRUE(session.remember(modbus::Table::HoldingRegisters, 57, 1));
        EXPECT_TRUE(is_normal(
            session.request(modbus::encode_pdu(modbus::make_write_single_register(57, 20019)), "write"), 6));
        gone = true;
        ledger = session.restore();
    }
    device.stop();
    ASSERT_EQ(ledger.size(), 1u);
    EXPECT_EQ(ledger[0].address, 57);
    EXPECT_FALSE(ledger[0].restored);
    EXPECT_EQ(ledger[0].left, std::optional<std::uint16_t>(20019));
    EXPECT_EQ(ledger[0].left_from, "run");
    EXPECT_NE(ledger[0].problem.find("left holding 20019"), std::string::npos) << ledger[0].problem;
    EXPECT_NE(ledger[0].problem.find("acknowledged"), std::string::npos) << ledger[0].problem;
}

// The tester's `reboot_after_write=8@2`: the device closes after a write and refuses connections for a
// while. One attempt to connect again was made: the next requests went nowhere ("timed out" after 0.27 ms),
// the rules failed, the restore gave up in milliseconds and left the device changed. Connecting is tried
// until a request's timeout; a rule whose request could not be sent is in error, and the restore waits the
// device out.
TEST(Restore, ADeviceRefusingConnectionsForAWhileIsWaitedFor) {
    std::atomic<int> coil_writes{0};
    MapDevice device(
        [&](MapDevice& d, const std::vector<std::uint8_t>& pdu) -> std::optional<MapDevice::Reply> {
            if (!pdu.empty() && pdu[0] == 5 && coil_writes++ == 0) {
                auto reply = d.serve_normally(pdu);
                d.reboot_for(std::chrono::milliseconds(1000));
                return reply;
            }
            return std::nullopt;
        },
        48201);
    Report report;
    {
        auto client = connect_to(device);
        auto options = options_for(std::chrono::milliseconds(300));
        options.run.rule_globs = {"echo.fc5", "echo.fc6"};
        report = run_check(client, slave::test::profile("mmk-2030"), options);
    }
    device.stop();
    std::map<std::string, RuleResult> by_id;
    for (const auto& r : report.results)
        by_id[r.rule.id] = r;
    ASSERT_TRUE(by_id.count("echo.fc6"));
    EXPECT_EQ(by_id["echo.fc6"].outcome, Outcome::Error) << by_id["echo.fc6"].observed;
    EXPECT_NE(by_id["echo.fc6"].reason.find("could not connect"), std::string::npos)
        << by_id["echo.fc6"].reason;
    for (const auto& r : report.results)
        for (const auto& e : r.evidence)
            if (e.note.find("not sent") != std::string::npos) {
                EXPECT_FALSE(e.timed_out) << e.note;
            }
    EXPECT_FALSE(report.restored.empty());
    EXPECT_TRUE(report.all_restored()) << failures(report);
    for (unsigned i = 0; i < MapDevice::points; ++i) {
        EXPECT_EQ(device.co[i], i % 3 == 0) << "coil " << i;
        EXPECT_EQ(device.hr[i], 1000 + i) << "register " << i;
    }
}

// Every reply after the timeout: the command said "could not run" (exit 2) while the JSON report's verdict
// was "fail" with every rule failed, and JUnit had a <failure> each. Not judged, as a silent target is.
TEST(Runner, ATargetAnsweringOnlyLateIsNotJudged) {
    MapDevice device(
        [](MapDevice& d, const std::vector<std::uint8_t>& pdu) -> std::optional<MapDevice::Reply> {
            // Past the 100 ms timeout, and within the next request's wait: seen as a late reply, not silence.
            std::this_thread::sleep_for(std::chrono::milliseconds(150));
            return d.serve_normally(pdu);
        });
    Report report;
    {
        auto client = connect_to(device);
        auto options = options_for(std::chrono::milliseconds(100));
        options.run.rule_globs = {"fc.supported.*"};
        report = run_check(client, slave::test::profile("mmk-2030"), options);
    }
    device.stop();
    ASSERT_GT(report.late_replies, 0u);
    EXPECT_EQ(report.count(Outcome::Fail), 0u) << failures(report);
    EXPECT_NE(report.unanswered.find("raise --timeout"), std::string::npos) << report.unanswered;
    ASSERT_FALSE(report.results.empty());
    EXPECT_EQ(report.results[0].rule.id, "target.answered");
    EXPECT_EQ(verdict_text(report), "error");
    EXPECT_EQ(to_json(report)["summary"]["verdict"], "error");
    std::ostringstream junit;
    write_junit(junit, report);
    EXPECT_EQ(junit.str().find("<failure"), std::string::npos) << junit.str();
    EXPECT_NE(junit.str().find("<error"), std::string::npos) << junit.str();
    std::ostringstream text;
    write_text(text, report, false);
    EXPECT_NE(text.str().find("nothing judged"), std::string::npos) << text.str();
}

}  // namespace
}  // namespace mbscope::conformance
