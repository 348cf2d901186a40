// The simulated process behind the reference slave (slave/process.cpp), driven by the profiles'
// "simulation" blocks: deterministic for a seed, walks within their limits, totals that integrate the flow
// across both halves of a split value, alarms that trip at the set-point a client writes and release past
// the hysteresis, points frozen by the stuck-value fault left alone, and the loader's errors.
#include <gtest/gtest.h>

#include "modbus/profile_loader.hpp"
#include "slave/process.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test {
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

TEST(ProcessModel, RelayTripsAtTheSetPointAClientWritesAndReleasesPastTheHysteresis) {
    Device d(profile("mmk-2030"), 1);
    Process p(d, 1);
    // Channel 1 wanders around 500: a set-point of 300 trips relay 1 (coil 58) ...
    EXPECT_EQ(ask(d, "06 00 39 01 2C"), "06 00 39 01 2C");  // register 57 = 300
    EXPECT_EQ(ask(d, "06 00 1D 00 0A"), "06 00 1D 00 0A");  // register 29 (hysteresis) = 10
    p.step(5);
    EXPECT_EQ(ask(d, "01 00 3A 00 01"), "01 01 01");
    // ... a set-point above the value but within the hysteresis keeps it tripped ...
    const auto pv = [&] { return static_cast<int>(d.image().reg(Table::HoldingRegisters, 0)); };
    char write[32];
    std::snprintf(write, sizeof write, "06 00 39 %02X %02X", (pv() + 100) >> 8, (pv() + 100) & 0xFF);
    EXPECT_EQ(ask(d, "06 00 1D 00 FA"), "06 00 1D 00 FA");  // hysteresis 250
    EXPECT_EQ(ask(d, write), std::string(write));
    p.step(1);
    EXPECT_EQ(ask(d, "01 00 3A 00 01"), "01 01 01") << "released inside the hysteresis";
    // ... without hysteresis the same set-point releases it ...
    EXPECT_EQ(ask(d, "06 00 1D 00 00"), "06 00 1D 00 00");
    p.step(1);
    EXPECT_EQ(ask(d, "01 00 3A 00 01"), "01 01 00");
    // ... and it trips again once the value is above the set-point.
    EXPECT_EQ(ask(d, "06 00 39 00 00"), "06 00 39 00 00");
    p.step(1);
    EXPECT_EQ(ask(d, "01 00 3A 00 01"), "01 01 01");
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
    Device d(profile("dcy-2050"), 1);
    Process p(d, 1);
    p.step(100);
    EXPECT_TRUE(d.image().changes().empty());
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

}  // namespace
}  // namespace mbscope::slave::test
