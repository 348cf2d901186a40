// Values decoded with the bundled profiles as the manuals give them: the CTH2265I's current output by its
// formula (003:592-594, CTH-ENC-04), its registers of two 8-bit fields (003:620-637, CTH-ENC-05..08), and
// the MK totalizers' 8-digit totals with the decimal point the totalization's PT.DEC register gives
// (PT.DEC "três casas decimais" puts three digits after the point).
#include <gtest/gtest.h>

#include "modbus/storage/profile_store.hpp"

namespace test_profiles_profile_values_test {

namespace mb = mbscope::modbus;

namespace {

const mb::Profile& bundled(const std::string& id) {
    static const mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    static std::map<std::string, mb::Profile> loaded;
    auto it = loaded.find(id);
    if (it == loaded.end()) it = loaded.emplace(id, store.load(id).value()).first;
    return it->second;
}

mb::NamedValue one(const std::string& id, std::uint16_t address, std::uint16_t word) {
    const auto v = mb::decode_registers(bundled(id), mb::Table::HoldingRegisters, address, {word});
    EXPECT_EQ(v.size(), 1u);
    return v.empty() ? mb::NamedValue{} : v[0];
}

}  // namespace

TEST(CthValues, TheCurrentOutputIsTheManualsFormulaInMilliamperes) {
    // R = 0 → 4 mA, 32768 → 12 mA, 65535 → 19.99976 mA (the manual's three examples)
    EXPECT_EQ(one("cth2265i", 4011, 0).text, "4");
    EXPECT_DOUBLE_EQ(*one("cth2265i", 4011, 0).number, 4.0);
    EXPECT_EQ(one("cth2265i", 4011, 32768).text, "12");
    EXPECT_EQ(one("cth2265i", 4011, 65535).text, "19.999756");  // the manual rounds to 19,99976
    EXPECT_EQ(one("cth2265i", 4011, 0).point->unit, "mA");
}

TEST(CthValues, TwoEightBitFieldsAreShownEachOnItsOwn) {
    // Alarm types 3 = HI and 4 = SHI (003:621); which alarm is in which byte the manual does not say.
    EXPECT_EQ(one("cth2265i", 4021, 0x0304).text, "alarm 1 or 2: 3 (HI), alarm 2 or 1: 4 (SHI)");
    // Time base 2 = hour, volume unit 16 = m³ (003:631), bytes not named by the manual.
    EXPECT_EQ(one("cth2265i", 4029, 0x0210).text, "high byte: 2 (hour), low byte: 16 (m³)");
    // TAG characters, "8 bits ascii" each (003:634).
    EXPECT_EQ(one("cth2265i", 4032, 0x4142).text, "Tag 0: 65 'A', Tag 1: 66 'B'");
    EXPECT_EQ(one("cth2265i", 4035, 0x2001).text, "Tag 6: 32 ' ', Tag 7: 1");
    // K-factor points and digital filter (003:632): numbers.
    EXPECT_EQ(one("cth2265i", 4030, 0x0A05).text, "high byte: 10, low byte: 5");
    // The register's number stays the register's.
    EXPECT_DOUBLE_EQ(*one("cth2265i", 4021, 0x0304).number, 0x0304);
}

// Each byte of the alarm types takes 0 to 4 (003:621); a write with another in either byte is a value out of
// range, exception 03 (003:574). It was acknowledged (0x0105, 0xFFFF), the two bytes' list never looked at.
TEST(CthValues, EachByteOfTheAlarmTypesTakesOnlyTheListedValues) {
    const auto& p = bundled("cth2265i");
    const auto write = [&](std::uint16_t value) {
        return mb::check_writes(p, mb::Table::HoldingRegisters, 4021, {value});
    };
    EXPECT_FALSE(write(0x0304).has_value());
    EXPECT_FALSE(write(0x0000).has_value());
    for (const std::uint16_t bad : {0x0105, 0x0501, 0xFFFF, 0x0400 | 0x05}) {
        const auto r = write(bad);
        ASSERT_TRUE(r.has_value()) << bad;
        EXPECT_EQ(r->exception_code, 3) << bad;
        EXPECT_EQ(r->address, 4021) << bad;
    }
    EXPECT_EQ(write(0x0105)->reason, "low byte 5 not among the values each byte takes");
}

// A value made of a Low and a High register (003:600-601: flow, Low at 4000) gives its registers in address
// order, as every other value does: raw[0] is the register at the first address. It gave {High, Low}, so a
// reader of the JSON took 4000's word for 4001's.
TEST(CthValues, APairsRegistersAreGivenInAddressOrder) {
    const auto& p = bundled("cth2265i");
    const auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4000, {60418, 1});
    ASSERT_EQ(v.size(), 2u);
    for (const auto& x : v) {
        EXPECT_EQ(x.raw, (std::vector<std::uint16_t>{60418, 1})) << x.address;
        EXPECT_EQ(x.text, "1259.54") << x.address;  // 1 × 65536 + 60418 = 125954, two decimals
    }
    // MK's four first digits are at the lower address (000:1243): the same order is theirs.
    const auto mk = mb::decode_registers(bundled("mmk-2030-tot"), mb::Table::HoldingRegisters, 2,
                                         {1234, 5678}, {{{125, 0}}});
    ASSERT_FALSE(mk.empty());
    EXPECT_EQ(mk[0].raw, (std::vector<std::uint16_t>{1234, 5678}));
}

// The K-factors (003:644-683) have their decimal point in register 4036, "Ponto decimal do fator k"
// (003:638), kept as the manual keeps variable points (003:578): the value sent as a positive integer, the
// point apart. The points said so in a note but carried no decimal point, so 12345 with two places read
// 12345.
TEST(CthValues, AKFactorTakesTheDecimalPointOfRegister4036) {
    const auto& p = bundled("cth2265i");
    for (std::uint16_t k = 0; k < 20; ++k) {
        const auto low = static_cast<std::uint16_t>(4042 + 2 * k);
        SCOPED_TRACE(low);
        auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, low, {12345, 0}, {{{4036, 0x0202}}});
        ASSERT_EQ(v.size(), 2u);
        EXPECT_EQ(v[0].text, "123.45");
        EXPECT_FALSE(v[0].partial);
        v = mb::decode_registers(p, mb::Table::HoldingRegisters, low, {12345, 0});
        ASSERT_EQ(v.size(), 2u);
        EXPECT_TRUE(v[0].partial);
        EXPECT_EQ(v[0].number, std::nullopt);
    }
}

TEST(MkValues, ATotalTakesTheDecimalPointOfItsTotalization) {
    struct Case {
        const char* id;
        std::uint16_t total;     // the first four digits of channel 1's total; the last four follow
        std::uint16_t decimals;  // the totalization's PT.DEC
    };
    // 3.13: registers 2-3 and 125 (000:1243, 1355); 3.22: registers 0-1 and 32 (000:3859, 3894).
    for (const Case c : {Case{"mmk-2030-tot", 2, 125}, Case{"mmk-2030-tot-fcs", 0, 32}}) {
        SCOPED_TRACE(c.id);
        const auto& p = bundled(c.id);
        auto v =
            mb::decode_registers(p, mb::Table::HoldingRegisters, c.total, {1234, 5678}, {{{c.decimals, 3}}});
        ASSERT_EQ(v.size(), 2u);
        EXPECT_DOUBLE_EQ(*v[0].number, 12345.678);
        EXPECT_EQ(v[0].text, "12345.678");
        EXPECT_FALSE(v[0].partial);
        // With register 125 not known, the digits are shown, said to be unscaled, and carry no number.
        v = mb::decode_registers(p, mb::Table::HoldingRegisters, c.total, {1234, 5678});
        EXPECT_TRUE(v[0].partial);
        EXPECT_EQ(v[0].text, "12345678 (unscaled: decimal point unknown)");
        EXPECT_EQ(v[0].number, std::nullopt);
        // A PT.DEC its own enumeration does not allow (0 to 7 places, 000:1358) is no number of places.
        v = mb::decode_registers(p, mb::Table::HoldingRegisters, c.total, {1234, 5678}, {{{c.decimals, 8}}});
        EXPECT_TRUE(v[0].partial);
        EXPECT_EQ(v[0].text, "12345678 (unscaled: its decimal point register " + std::to_string(c.decimals) +
                                 " holds 8, no number of places)");
        // Four digits a register (000:1243): a half above 9999 is no total. Before, 10000 and 0 read as
        // 100000000.
        v = mb::decode_registers(p, mb::Table::HoldingRegisters, c.total, {10000, 0}, {{{c.decimals, 3}}});
        EXPECT_EQ(v[0].number, std::nullopt);
        EXPECT_EQ(v[0].text, "10000 0 (not digits: each half holds four, 0 to 9999)");
        v = mb::decode_registers(p, mb::Table::HoldingRegisters, c.total, {1, 65535}, {{{c.decimals, 3}}});
        EXPECT_EQ(v[0].number, std::nullopt);
    }
}

// Walchem's float32 values (002:455-462, low word first) in full: three decimals made 0.000123, 1e-10 and
// the smallest normal float "0.000", a measurement not told from zero, and 1.2345679 "1.235".
TEST(WalchemValues, AFloatIsShownInFull) {
    const auto& p = bundled("walchem-w600");
    const auto text = [&](std::uint16_t low, std::uint16_t high) {
        const auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 576, {low, high});
        return v.empty() ? std::string() : v[0].text;
    };
    EXPECT_EQ(text(0xF990, 0x3900), "0.000123");
    EXPECT_EQ(text(0xE6FF, 0x2EDB), "1e-10");
    EXPECT_EQ(text(0x0000, 0x0080), "1.1754944e-38");
    EXPECT_EQ(text(0x0652, 0x3F9E), "1.2345679");
    EXPECT_EQ(text(0x0000, 0x3FC0), "1.5");
    EXPECT_EQ(text(0x0000, 0x7FC0), "nan");
    // A write just above the range says by how much: "value 90 above maximum 90" contradicted itself.
    const auto refused = mb::check_writes(p, mb::Table::HoldingRegisters, 588, {0x0001, 0x42B4});
    ASSERT_TRUE(refused.has_value());
    EXPECT_EQ(refused->reason, "value 90.00001 above maximum 90");
}

// An alarm bit field with a bit the manual does not name set (the fields are 8 bits, 002:440-443) is not
// "none": that read as "no alarm" with a bit set.
TEST(WalchemValues, ABitTheMapDoesNotNameIsShownByItsNumber) {
    EXPECT_EQ(one("walchem-w600", 611, 0x0000).text, "none");
    EXPECT_EQ(one("walchem-w600", 611, 0x0100).text, "bit 8 (not in the map)");
    EXPECT_EQ(one("walchem-w600", 611, 0x0101).text, "low, bit 8 (not in the map)");
    EXPECT_EQ(one("walchem-w600", 71, 0x8000).text, "bit 15 (not in the map)");
}

// TY-2090's retransmission limits take the decimals of the input register 27 (97, 99) or 28 (98, 100)
// associates with the output (footnote vii, 000:627): with channel 1 at one decimal, channel 2 at three and
// output 1 on channel 2, a raw 1234 in 97 is 1.234, not 123.4 (channel 1's, a hundredfold wrong). Until the
// selector is seen the value is unscaled, and said to be.
TEST(MkValues, TyRetransmissionLimitsTakeTheDecimalsOfTheInputTheirOutputFollows) {
    const auto& p = bundled("ty-2090");
    const mb::RegisterContext seen{{{17, 1}, {18, 3}, {27, 1}, {28, 0}}};
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 97, {1234, 1234, 1234, 1234}, seen);
    ASSERT_EQ(v.size(), 4u);
    EXPECT_EQ(v[0].text, "1.234");
    EXPECT_EQ(v[1].text, "123.4");
    EXPECT_EQ(v[2].text, "1.234");
    EXPECT_EQ(v[3].text, "123.4");
    EXPECT_FALSE(v[0].partial);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 97, {1234}, {{{17, 1}, {18, 3}}});
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].text, "1234 (unscaled: decimal point unknown, register 27 that selects it not seen)");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 98, {1234}, {{{17, 1}, {18, 3}, {28, 5}}});
    EXPECT_EQ(v[0].text, "1234 (unscaled: register 28 holds 5, which selects no decimal point register)");
    // The -F model alike; the MMK-2030's 97 stays on channel 1 (000:626).
    v = mb::decode_registers(bundled("ty-2090-f"), mb::Table::HoldingRegisters, 97, {1234}, seen);
    EXPECT_EQ(v[0].text, "1.234");
    v = mb::decode_registers(bundled("mmk-2030"), mb::Table::HoldingRegisters, 97, {1234}, seen);
    EXPECT_EQ(v[0].text, "123.4");
}

// DCY-2050 Light's register 9 lists input types 2 and 4 as "não permitido" (000:1097): read, they are named;
// written, refused as a value out of range. They were acknowledged, being listed.
TEST(MkValues, AValueTheManualListsAsNotAllowedIsRefused) {
    const auto& p = bundled("dcy-2050-light");
    for (const std::uint16_t v : {2, 4}) {
        const auto refused = mb::check_writes(p, mb::Table::HoldingRegisters, 9, {v});
        ASSERT_TRUE(refused.has_value()) << v;
        EXPECT_EQ(refused->exception_code, 3);
        EXPECT_EQ(refused->reason,
                  "value " + std::to_string(v) + " is one the manual does not allow (\"não permitido\")");
        EXPECT_EQ(one("dcy-2050-light", 9, v).text, "não permitido (not allowed)");
    }
    EXPECT_FALSE(mb::check_writes(p, mb::Table::HoldingRegisters, 9, {3}).has_value());
    EXPECT_TRUE(mb::check_writes(p, mb::Table::HoldingRegisters, 9, {6}).has_value());
}

// The CTH2265I sends values of a variable decimal point as integers, the point in a register apart
// (003:578-581): one 8-bit field of 4010, 4020 or 4026, which one the manual does not say. A set-point of
// 100000 with point 2 is 1000.00; it was shown as 100000, plainly. Scaled when both bytes hold the same
// point, else unscaled and said to be; the total at 4006-4007, whose point no register is named for, alike.
TEST(CthValues, AVariableDecimalPointIsTakenFromItsRegisterOrSaidUnknown) {
    const auto& p = bundled("cth2265i");
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4012, {0x86A0, 0x0001}, {{{4020, 0x0202}}});
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v[0].text, "1000.00");
    EXPECT_DOUBLE_EQ(*v[0].number, 1000.0);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4012, {0x86A0, 0x0001}, {{{4020, 0x0203}}});
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].number, std::nullopt);
    EXPECT_EQ(v[0].text,
              "100000 (unscaled: register 4020 holds the decimal points 2 and 3, one a byte, and the "
              "manual does not say which is this value's)");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4022, {0x86A0, 0x0001});
    EXPECT_EQ(v[0].text, "100000 (unscaled: decimal point unknown, register 4026 not seen)");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4006, {0x001A, 0x0F1B}, {{{4010, 0x0303}}});
    EXPECT_TRUE(v[0].partial);
    EXPECT_NE(v[0].text.find("(unscaled: the manual names no register for its decimal point"),
              std::string::npos)
        << v[0].text;
    // The fixed two decimals of 4000-4005 stay as they were.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 4000, {0x1234, 0x0001});
    EXPECT_EQ(v[0].text, "701.96");  // 0x00011234
}

// Walchem's "Gravar 1 para ..." points are commands (002:412-417: reset buttons) and carry `momentary`, which
// the loader keeps: the conformance runner and the network fuzzer pick no such point to write.
TEST(WalchemProfiles, WriteOneToActCommandsAreMomentary) {
    struct Case {
        const char* id;
        std::uint16_t command;  // 002:851 (W900's ad-hoc session), 002:992 (DI-1's total time reset)
    };
    for (const auto& c : {Case{"walchem-w900", 170}, Case{"walchem-w600", 320}}) {
        const auto& p = bundled(c.id);
        for (const auto table : {mb::Table::Coils, mb::Table::HoldingRegisters}) {
            const auto* point = p.find(table, c.command);
            ASSERT_NE(point, nullptr) << c.id;
            EXPECT_TRUE(point->momentary) << c.id << ' ' << point->name;
        }
        const auto* setpoint = p.find(mb::Table::HoldingRegisters, 148);
        ASSERT_NE(setpoint, nullptr);
        EXPECT_FALSE(setpoint->momentary) << setpoint->name;
    }
}

}  // namespace test_profiles_profile_values_test
