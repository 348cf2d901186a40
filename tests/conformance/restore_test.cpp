// The restore promises to put back what the run changed, and only that: a point whose write the device
// refused, or that was written with the value it held, is not the run's to put back, and a value the device
// set itself is not overwritten and called restored. What did not go back says what it was left holding and
// why. A device that refuses connections for a moment (a reboot) is waited for, not given up in
// milliseconds; a target whose every reply comes late is not judged.
#include <gtest/gtest.h>

#include <atomic>
#include <sstream>
#include <thread>

#include "conformance/context.hpp"
#include "conformance/report.hpp"
#include "conformance/session.hpp"
#include "modbus/transport/socket.hpp"
#include "tests/conformance/runner_support.hpp"
#include "tests/support/map_device.hpp"

namespace mbscope::conformance::test_conformance_restore_test {
namespace {

using namespace mbscope::conformance::test;

using mbscope::test::MapDevice;

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
}  // namespace mbscope::conformance::test_conformance_restore_test
