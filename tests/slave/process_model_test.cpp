// The simulated process behind the reference slave (slave/process.cpp), driven by the profiles'
// "simulation" blocks: deterministic for a seed, walks within their limits, totals that integrate the flow
// across both halves of a split value, alarms that trip at the set-point a client writes and release past
// the hysteresis, points frozen by the stuck-value fault left alone, and the loader's errors.
#include <gtest/gtest.h>

#include <cstring>

#include "modbus/profile_loader.hpp"
#include "slave/process.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_process_model_test {
namespace {

using mb::Table;

std::uint32_t low_high(const RegisterImage& image, std::uint16_t low_address) {
    return (std::uint32_t{image.reg(Table::HoldingRegisters, static_cast<std::uint16_t>(low_address + 1))}
            << 16) |
           image.reg(Table::HoldingRegisters, low_address);
}

TEST(ProcessModel, SameSeedSameValuesOtherSeedOtherValues) {
    Device a(profile("cth2265i"), 1), b(profile("cth2265i"), 1), c(profile("cth2265i"), 1);
    Process pa(a, 42), pb(b, 42), pc(c, 43);
    pa.step(500);
    pb.step(200);
    pb.step(300);  // the same number of steps in other chunks
    pc.step(500);
    EXPECT_EQ(low_high(a.image(), 4000), low_high(b.image(), 4000));
    EXPECT_EQ(low_high(a.image(), 4002), low_high(b.image(), 4002));
    EXPECT_NE(low_high(a.image(), 4000), low_high(c.image(), 4000));
    EXPECT_EQ(pa.steps(), 500u);
}

TEST(ProcessModel, FlowWandersWithinItsLimitsAndTheTotalsIntegrateIt) {
    Device d(profile("cth2265i"), 1);
    Process p(d, 7);
    const std::uint32_t accumulated0 = low_high(d.image(), 4004);
    double integral = 0;  // flow x time, by the same steps, from what a client reads
    std::uint32_t previous_total = low_high(d.image(), 4002);
    bool moved = false;
    for (int i = 0; i < 3000; ++i) {  // 300 s
        p.step();
        const std::uint32_t flow = low_high(d.image(), 4000);
        ASSERT_LE(flow, 500000u);  // 0.00 .. 5000.00, the profile's limits
        moved |= flow != 125000;
        integral += flow * 0.1 / 3600.0;
        const std::uint32_t total = low_high(d.image(), 4002);
        ASSERT_GE(total, previous_total) << "a total never runs backwards before it rolls over";
        previous_total = total;
    }
    EXPECT_TRUE(moved);
    // The total is the integral of the flow (floored to whole counts of 0.01).
    EXPECT_NEAR(static_cast<double>(low_high(d.image(), 4002)), integral, 1.0);
    EXPECT_NEAR(static_cast<double>(low_high(d.image(), 4004) - accumulated0), integral, 1.0);
    EXPECT_GT(integral, 300 * 1000 * 100 / 3600.0 * 0.5);  // about 1250.00 per hour for 300 s
}

// FC6 `value` to holding register `address`, echoed.
void write_register(Device& d, std::uint16_t address, std::uint16_t value) {
    char pdu[32];
    std::snprintf(pdu, sizeof pdu, "06 %02X %02X %02X %02X", address >> 8, address & 0xFF, value >> 8,
                  value & 0xFF);
    EXPECT_EQ(ask(d, pdu), std::string(pdu));
}

// Coil `address` as FC1 reads it.
bool coil(Device& d, std::uint16_t address) {
    char pdu[32];
    std::snprintf(pdu, sizeof pdu, "01 %02X %02X 00 01", address >> 8, address & 0xFF);
    return ask(d, pdu) == "01 01 01";
}

// A relay that is tripped by the high alarm of register 0 (the process value): a set-point just above the
// value holds it while the hysteresis covers the gap, releases it without hysteresis, and set-point 0 trips
// it again.
void expect_release_past_the_hysteresis(Device& d, Process& p, std::uint16_t setpoint,
                                        std::uint16_t hysteresis, std::uint16_t relay) {
    ASSERT_TRUE(coil(d, relay));
    write_register(d, hysteresis, 250);
    write_register(d, setpoint, static_cast<std::uint16_t>(d.image().reg(Table::HoldingRegisters, 0) + 100));
    p.step(1);
    EXPECT_TRUE(coil(d, relay)) << "released inside the hysteresis";
    write_register(d, hysteresis, 0);
    p.step(1);
    EXPECT_FALSE(coil(d, relay)) << "held without hysteresis";
    write_register(d, setpoint, 0);
    p.step(1);
    EXPECT_TRUE(coil(d, relay)) << "not tripped again below the value";
}

TEST(ProcessModel, RelayTripsAtTheSetPointAClientWritesAndReleasesPastTheHysteresis) {
    Device d(profile("mmk-2030"), 1);
    Process p(d, 1);
    // Channel 1 wanders around 500: a set-point of 300 (register 57) trips relay 1 (coil 58) ...
    write_register(d, 57, 300);
    write_register(d, 29, 10);
    p.step(5);
    EXPECT_TRUE(coil(d, 58));
    // ... a set-point above the value but within the hysteresis (register 29) keeps it tripped, no
    // hysteresis releases it, and it trips again once the value is above the set-point.
    expect_release_past_the_hysteresis(d, p, 57, 29, 58);
}

TEST(ProcessModel, StuckValueFaultFreezesThePoint) {
    FaultSet faults(std::vector<FaultSpec>{*parse_fault("stuck-value=0")}, 1);
    Device d(profile("mmk-2030"), 1, &faults);
    Process p(d, 1);
    const auto frozen = d.image().reg(Table::HoldingRegisters, 0);
    const auto other = d.image().reg(Table::HoldingRegisters, 1);
    p.step(200);
    EXPECT_EQ(d.image().reg(Table::HoldingRegisters, 0), frozen);
    EXPECT_NE(d.image().reg(Table::HoldingRegisters, 1), other) << "channel 2 still moves";
}

TEST(ProcessModel, ProfilesWithoutASimulationStayStill) {
    Device d(profile("modbus"), 1);
    Process p(d, 1);
    p.step(100);
    EXPECT_TRUE(d.image().changes().empty());
}

// DCY-2050 (000:722-950): both inputs wander within their limits, and relays 2, 3 and 4 (coils 15-17) each
// follow input 1's high alarm with their own set-point (52-54) and hysteresis (49-51).
TEST(ProcessModel, Dcy2050RelaysTwoToFourEachTripAtTheirOwnSetPointAndReleasePastTheirHysteresis) {
    Device a(profile("dcy-2050"), 1), b(profile("dcy-2050"), 1);
    Process pa(a, 9), pb(b, 9);
    pa.step(300);
    pb.step(300);
    const auto pv = [&] { return static_cast<int>(a.image().reg(Table::HoldingRegisters, 0)); };
    EXPECT_EQ(pv(), static_cast<int>(b.image().reg(Table::HoldingRegisters, 0))) << "same seed, same value";
    EXPECT_EQ(a.image().reg(Table::HoldingRegisters, 1), b.image().reg(Table::HoldingRegisters, 1));
    for (int i = 0; i < 1000; ++i) {
        pa.step();
        ASSERT_LE(pv(), 1000);
        ASSERT_LE(a.image().reg(Table::HoldingRegisters, 1), 1000);
    }
    // Set-points start at 0: all three relays follow input 1 (about 500) into alarm.
    EXPECT_EQ(ask(a, "01 00 0F 00 03"), "01 01 07");
    // Each relay by its own registers: relay 2's set-point far above the value releases relay 2 alone ...
    write_register(a, 52, 9999);
    pa.step(1);
    EXPECT_EQ(ask(a, "01 00 0F 00 03"), "01 01 06");
    // ... and relays 3 and 4 hold and release past their own hysteresis.
    expect_release_past_the_hysteresis(a, pa, 53, 50, 16);
    expect_release_past_the_hysteresis(a, pa, 54, 51, 17);
    EXPECT_FALSE(coil(a, 15)) << "relay 2 stays released";
}

// MMK-2030-TOT-FCS (000:3852-4080): the map shows totals only; the pulse rates are hidden signals, and the
// totals (8 digits over two registers, high half first) count them. Nothing but the totals moves.
TEST(ProcessModel, MmkTotFcsTotalsCountAHiddenPulseRate) {
    Device a(profile("mmk-2030-tot-fcs"), 1), b(profile("mmk-2030-tot-fcs"), 1);
    Process pa(a, 3), pb(b, 3);
    const auto digits8 = [](const Device& d, std::uint16_t high) {
        return std::uint32_t{d.image().reg(Table::HoldingRegisters, high)} * 10000 +
               d.image().reg(Table::HoldingRegisters, static_cast<std::uint16_t>(high + 1));
    };
    EXPECT_EQ(digits8(a, 4), 1000000u) << "accumulated totals start at 1000000";
    std::uint32_t previous = 0;
    for (int i = 0; i < 6000; ++i) {  // 600 s
        pa.step();
        const std::uint32_t total = digits8(a, 0);
        ASSERT_GE(total, previous) << "a total never runs backwards before it rolls over";
        ASSERT_LT(a.image().reg(Table::HoldingRegisters, 1), 10000) << "each half holds four digits";
        previous = total;
    }
    pb.step(6000);
    EXPECT_EQ(digits8(a, 0), digits8(b, 0)) << "same seed, same totals";
    // Channel 1 counts about 20 pulses a second, channel 2 about 10.
    EXPECT_GT(digits8(a, 0), 600u * 20 / 2);
    EXPECT_LT(digits8(a, 0), 600u * 50);
    EXPECT_GT(digits8(a, 2), 600u * 10 / 2);
    EXPECT_LT(digits8(a, 2), digits8(a, 0));
    // The accumulated totals count the same pulses from their own start.
    EXPECT_NEAR(static_cast<double>(digits8(a, 4) - 1000000u), digits8(a, 0), 1.0);
    EXPECT_NEAR(static_cast<double>(digits8(a, 6) - 1000000u), digits8(a, 2), 1.0);
    for (const auto& [table, changed] : a.image().changes())
        for (const auto& [address, value] : changed) {
            EXPECT_TRUE(table == Table::HoldingRegisters && address <= 7)
                << "the hidden rate shows nowhere: " << address << " = " << value;
        }
}

// DMY-2031-FCS (000:4083-4258): one register per total; totals roll over at 10^4 (the four digits of
// TRIP's range 0-9999, 000:4094).
TEST(ProcessModel, DmyFcsTotalsCountAHiddenPulseRateAndRollOverAtFourDigits) {
    Device d(profile("dmy-2031-fcs"), 1);
    Process p(d, 5);
    const auto reg = [&](std::uint16_t a) { return d.image().reg(Table::HoldingRegisters, a); };
    EXPECT_EQ(reg(2), 1000) << "accumulated totals start at 1000";
    bool rolled = false;
    std::uint16_t previous = reg(2);
    for (int i = 0; i < 250000; ++i) {  // about 7 hours: 0.5 pulses a second pass 9000 counts
        p.step();
        ASSERT_LT(reg(0), 10000);
        ASSERT_LT(reg(2), 10000);
        rolled |= reg(2) < previous;
        previous = reg(2);
    }
    EXPECT_TRUE(rolled) << "the accumulated total rolled over";
    EXPECT_NE(reg(1), 0) << "channel 2 counts too";
}

// A float as FC16 writes it to a Walchem point (least significant word first, 002:461-468).
std::string write_float_cdab(std::uint16_t address, float value) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &value, sizeof bits);
    char pdu[64];
    std::snprintf(pdu, sizeof pdu, "10 %04X 0002 04 %04X %04X", address, bits & 0xFFFF, bits >> 16);
    return pdu;
}

// Walchem W600 (002:509-510, 866-908): sensor 1-1 (conductivity) and 1-2 (temperature) drift as IEEE 754
// floats; sensor 1-1's low and high alarm states trip at their set-points and release past the deadband.
TEST(ProcessModel, WalchemSensorsDriftAsFloatsAndTheirAlarmsFollowSetPointsAndDeadband) {
    Device d(profile("walchem-w600"), 1);
    Process p(d, 11);
    const auto f = [&](std::uint16_t a) {
        return d.image().f32(Table::HoldingRegisters, a, mb::WordOrder::Cdab);
    };
    EXPECT_FLOAT_EQ(f(576), 1500.0f);
    EXPECT_FLOAT_EQ(f(612), 25.0f);
    bool fraction = false;
    for (int i = 0; i < 2000; ++i) {
        p.step();
        ASSERT_GE(f(576), 0.0f);
        ASSERT_LE(f(576), 5000.0f);
        ASSERT_GE(f(612), 0.0f);
        ASSERT_LE(f(612), 60.0f);
        fraction |= f(612) != static_cast<float>(static_cast<int>(f(612)));
    }
    EXPECT_TRUE(fraction) << "a temperature keeps its fractions";
    Device again(profile("walchem-w600"), 1);
    Process pa(again, 11);
    pa.step(2000);
    EXPECT_EQ(again.image().reg(Table::HoldingRegisters, 576), d.image().reg(Table::HoldingRegisters, 576));
    // Set-points start at 0.0: high alarm (index 29, PDU 605) active, low alarm (604) not; the coil view of
    // an alarm state reads the same (002:493).
    EXPECT_EQ(ask(d, "03 02 5C 00 02"), "03 04 00 00 00 01");
    EXPECT_EQ(ask(d, "01 02 5D 00 01"), "01 01 01");
    // A high set-point above the value releases the high alarm; a low one above it trips the low alarm.
    const float pv = f(576);
    EXPECT_EQ(ask(d, write_float_cdab(594, pv + 1000)), "10 02 52 00 02");
    EXPECT_EQ(ask(d, write_float_cdab(592, pv + 1000)), "10 02 50 00 02");
    p.step(1);
    EXPECT_EQ(ask(d, "03 02 5C 00 02"), "03 04 00 01 00 00");
    // The low alarm holds while the value is within the deadband above its set-point ...
    EXPECT_EQ(ask(d, write_float_cdab(586, 2000.0f)), "10 02 4A 00 02");  // deadband
    EXPECT_EQ(ask(d, write_float_cdab(592, f(576) - 500)), "10 02 50 00 02");
    p.step(1);
    EXPECT_EQ(ask(d, "03 02 5C 00 01"), "03 02 00 01") << "released inside the deadband";
    // ... and releases without it.
    EXPECT_EQ(ask(d, write_float_cdab(586, 0.0f)), "10 02 4A 00 02");
    p.step(1);
    EXPECT_EQ(ask(d, "03 02 5C 00 01"), "03 02 00 00");
}

// The same addresses belong to another channel in another configuration: on the W900, analog outputs 1-1
// and 1-2 (an analog-output card in slot 1) start where sensors 1-1 and 1-2 do (002:540-541, 606-607), and
// the simulation keeps its hands off them.
TEST(ProcessModel, WalchemSignalsExistOnlyInTheConfigurationTheyName) {
    auto w900 = store().load("walchem-w900");
    ASSERT_TRUE(w900.has_value());
    EXPECT_EQ(w900->simulation.signals.size(), 5u);
    auto card = store().load(
        "walchem-w900",
        {{"sensor-1-1", "none"}, {"sensor-1-2", "none"}, {"ao-1-1", "ao-manual"}, {"ao-1-2", "ao-manual"}});
    ASSERT_TRUE(card.has_value());
    EXPECT_TRUE(card->find(Table::HoldingRegisters, 1152)) << "analog output 1-1 takes sensor 1-1's address";
    ASSERT_EQ(card->simulation.signals.size(), 1u) << "the system map's firmware version is in every one";
    EXPECT_EQ(card->simulation.signals[0].id, "firmware");
    Device d(*card, 1);
    Process p(d, 1);
    p.step(100);
    const auto changes = d.image().changes();
    ASSERT_EQ(changes.count(Table::HoldingRegisters), 1u);
    EXPECT_EQ(changes.at(Table::HoldingRegisters).size(), 2u) << "the firmware version's two registers only";
    EXPECT_TRUE(changes.at(Table::HoldingRegisters).count(38));
    auto flowmeter = store().load("walchem-w900", {{"sensor-1-1", "sensor-ai-flowmeter"}});
    ASSERT_TRUE(flowmeter.has_value());
    ASSERT_EQ(flowmeter->simulation.signals.size(), 2u) << "sensor 1-2 still drifts";
    EXPECT_EQ(flowmeter->simulation.signals[0].id, "temperature");
}

// The Walchem manual covers controller software 3.01 and later (002:158); the reference slave's firmware
// version (system map index 2, read as FC4 30039-30040 in the manual's own example, 002:495) read 0.0. It is
// a constant 3.01, the same after any number of steps, least significant word first (002:461-468).
TEST(ProcessModel, WalchemFirmwareVersionIsAConstantTheManualCovers) {
    for (const char* id : {"walchem-w600", "walchem-w900", "walchem-intuition9"}) {
        Device d(profile(id), 1);
        Process p(d, 3);
        // 3.01f is 0x4040A3D7: low word A3D7 first.
        EXPECT_EQ(ask(d, "04 00 26 00 02"), "04 04 A3 D7 40 40") << id;
        p.step(500);
        EXPECT_EQ(ask(d, "04 00 26 00 02"), "04 04 A3 D7 40 40") << id;
    }
}

TEST(ProcessModel, FloatPointsCarryTheValueAsAnIeee754Float) {
    const std::string text = R"({
      "format": "mbscope-profile/1", "family": "test", "vendor": "test",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3]},
      "tables": {"holding_registers": [
        {"address": 10, "name": "pv", "access": "r", "source": "test",
         "encoding": {"type": "f32", "word_order": "cdab"}}]},
      "simulation": {"signals": [
        {"id": "pv", "model": "walk", "point": 10, "start": 7.25, "min": 0, "max": 14, "step": 0.5}]},
      "models": [{"id": "test"}]
    })";
    auto loaded = mb::parse_profiles(text, "test.json", nullptr, {});
    ASSERT_TRUE(loaded.errors.empty()) << mb::to_string(loaded.errors.front());
    ASSERT_EQ(loaded.profiles.size(), 1u);
    Device d(loaded.profiles[0], 1);
    Process p(d, 1);
    EXPECT_FLOAT_EQ(d.image().f32(Table::HoldingRegisters, 10, mb::WordOrder::Cdab), 7.25f);
    bool fraction = false;
    for (int i = 0; i < 100; ++i) {
        p.step();
        const float v = d.image().f32(Table::HoldingRegisters, 10, mb::WordOrder::Cdab);
        ASSERT_GE(v, 0.0f);
        ASSERT_LE(v, 14.0f);
        fraction |= v != static_cast<float>(static_cast<int>(v));
    }
    EXPECT_TRUE(fraction) << "a float walk keeps its fractions";
}

TEST(ProcessModel, LoaderNamesEveryMistakeInASimulationBlock) {
    const std::string text = R"({
      "format": "mbscope-profile/1", "family": "test", "vendor": "test",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 0, "name": "pv", "access": "r", "encoding": "u16"}]},
      "simulation": {"signals": [
        {"id": "pv", "model": "walk", "point": 0, "start": 5, "min": 10, "max": 20, "step": 1},
        {"id": "t", "model": "integrate", "of": "nothing", "point": 0, "per_second": 1, "max": 100},
        {"id": "a", "model": "alarm", "of": "pv", "direction": "sideways", "point": 0},
        {"id": "x", "model": "spin", "point": 0}
      ]},
      "models": [{"id": "test"}]
    })";
    const auto loaded = mb::parse_profiles(text, "test.json", nullptr, {});
    std::string all;
    for (const auto& e : loaded.errors)
        all += e.pointer + ": " + e.message + "\n";
    EXPECT_NE(all.find("/simulation/signals/0: needs min <= start <= max"), std::string::npos) << all;
    EXPECT_NE(all.find("/simulation/signals/1/of"), std::string::npos) << all;
    EXPECT_NE(all.find("/simulation/signals/2/direction"), std::string::npos) << all;
    EXPECT_NE(all.find("/simulation/signals/2: missing required field \"setpoint\""), std::string::npos)
        << all;
    EXPECT_NE(all.find("/simulation/signals/3/model: unknown model \"spin\""), std::string::npos) << all;
}

// A one-register test profile with the given simulation signals.
mb::LoadedProfiles with_signals(const std::string& signals) {
    const std::string text = R"({
      "format": "mbscope-profile/1", "family": "test", "vendor": "test",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3]},
      "tables": {"holding_registers": [
        {"address": 0, "name": "total", "access": "r", "encoding": "u16", "source": "test"}]},
      "simulation": {"signals": [)" +
                             signals + R"(]},
      "models": [{"id": "test"}]
    })";
    return mb::parse_profiles(text, "test.json", nullptr, {});
}

TEST(ProcessModel, AHiddenSignalHasNoPointButDrivesTheSignalsThatFollowIt) {
    auto loaded = with_signals(R"(
        {"id": "rate", "model": "walk", "start": 5, "min": 5, "max": 5, "step": 0},
        {"id": "total", "model": "integrate", "of": "rate", "point": 0, "per_second": 1, "max": 60000})");
    ASSERT_TRUE(loaded.errors.empty()) << mb::to_string(loaded.errors.front());
    ASSERT_EQ(loaded.profiles.size(), 1u);
    Device d(loaded.profiles[0], 1);
    Process p(d, 1);
    p.step(100);  // 10 s of 5 a second
    EXPECT_EQ(d.image().reg(Table::HoldingRegisters, 0), 50);

    const auto bad = with_signals(R"(
        {"id": "rate", "model": "walk", "start": 5, "min": 5, "max": 5, "step": 0},
        {"id": "a", "model": "alarm", "of": "rate", "direction": "high", "setpoint": 0},
        {"id": "b", "model": "walk", "point": 0, "start": 0, "min": 0, "max": 1, "step": 0,
         "configuration": ["sensor"]})");
    std::string all;
    for (const auto& e : bad.errors)
        all += e.pointer + ": " + e.message + "\n";
    EXPECT_EQ(bad.errors.size(), 2u) << all;
    EXPECT_NE(all.find("/simulation/signals/1: missing required field \"point\""), std::string::npos) << all;
    EXPECT_NE(all.find("/simulation/signals/2/configuration"), std::string::npos) << all;
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_process_model_test
