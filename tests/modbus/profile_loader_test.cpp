// The profile loader on small documents written for the test: structure, model variants, overrides, queries
// and error reporting with JSON pointers. The real device profiles have their own coverage tests.
#include "modbus/profile_loader.hpp"
#include "modbus/profile_json.hpp"
#include "modbus/storage/profile_store.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <utility>

namespace mb = mbscope::modbus;

namespace {

// A cut-down MK-style section: two models, a per-model exclusion, a range override, FC4 = FC3's map.
const char* mk_like = R"({
  "format": "mbscope-profile/1", "family": "test-3.8", "vendor": "MK Controle",
  "source": {"manual": "000", "section": "3.8", "lines": "000:486-721"},
  "line": {"transports": ["rtu", "ascii"], "baud_rates": [9600], "unit_id": {"min": 0, "max": 99, "disabled": [0]}},
  "functions": {"supported": [1, 3, 4, 5, 6, 8, 15, 16], "max_quantity": {"1": 30, "3": 15, "4": 15, "15": 30, "16": 15},
                "broadcast": [5, 6, 15, 16], "exceptions": {"bad_value": 3, "write_read_only": null}},
  "tables": {
    "holding_registers": [
      {"address": 0, "name": "Variável de Processo do canal 1", "name_en": "channel 1 PV", "access": "r",
       "encoding": {"type": "scaled", "decimals_from": {"table": "holding_registers", "address": 17}, "signed": true},
       "source": "000:493"},
      {"address": 2, "name": "Primeiro caracter do TAG", "access": "rw",
       "encoding": {"type": "ascii_char", "allowed": "-._ 0123456789abcdefghijklnopqrstuy"}, "source": "000:495"},
      {"address": 8, "name": "Modo de Transmissão", "access": "rw",
       "encoding": {"type": "enum", "values": [{"value": 0, "text": "ASCII"}, {"value": 1, "text": "RTU"}]},
       "source": "000:501"},
      {"address": 17, "name": "Número de casas decimais", "access": "rw", "range": {"min": 0, "max": 4},
       "source": "000:510"},
      {"address": 23, "name": "Filtro do canal 1", "access": "rw", "encoding": {"type": "fixed", "decimals": 1},
       "range": {"min": 0, "max": 250}, "range_text": "0.0 a 25.0 segundos", "unit": "s", "source": "000:516"},
      {"address": 45, "name": "Histerese led 1", "access": "rw", "range": {"min": 0, "max": 250}, "source": "000:538"},
      {"address": 57, "name": "Setpoint", "access": "rw", "encoding": "s16", "range": {"min": -1009, "max": 20019},
       "source": "000:550"},
      {"address": 60, "name": "Total alto", "access": "r", "encoding": {"type": "digits4_high", "pair": 61}, "source": "x:1"},
      {"address": 61, "name": "Total baixo", "access": "r", "encoding": {"type": "digits4_low", "pair": 60}, "source": "x:2"},
      {"address": 70, "name": "Vazão", "access": "r", "encoding": {"type": "f32", "word_order": "cdab"}, "source": "x:3"}
    ],
    "input_registers": {"same_as": "holding_registers"},
    "coils": [{"address": 1, "name": "Habilita senha", "access": "rw", "source": "000:640"}]
  },
  "models": [
    {"id": "MMK-2030", "name": "MMK-2030", "aliases": ["dmy-2030"], "source": "000:486"},
    {"id": "ty-2090", "name": "TY-2090", "exclude": {"holding_registers": [[45, 56]]},
     "overrides": [{"table": "holding_registers", "addresses": [[57, 57]], "range": {"min": -9999, "max": 30000},
                    "range_text": "-9999 a 30000 U.E.", "source": "000:621"}]}
  ]
})";

mb::LoadedProfiles load(const char* text, const mb::IncludeFn& include = {},
                        const mb::ProfileConfig& config = {}) {
    return mb::parse_profiles(text, "test.json", include, config);
}

// Each error as (JSON pointer, message), in the order reported.
std::vector<std::pair<std::string, std::string>> pointers_and_messages(const mb::LoadedProfiles& l) {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& e : l.errors)
        out.emplace_back(e.pointer, e.message);
    return out;
}

}  // namespace

TEST(ProfileLoader, ModelsResolveWithExclusionsAndOverrides) {
    auto l = load(mk_like);
    ASSERT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    ASSERT_EQ(l.profiles.size(), 2u);
    const auto& mmk = l.profiles[0];
    const auto& ty = l.profiles[1];
    EXPECT_EQ(mmk.id, "mmk-2030");  // ids are lower case
    EXPECT_EQ(mmk.aliases, std::vector<std::string>{"dmy-2030"});
    EXPECT_NE(mmk.find(mb::Table::HoldingRegisters, 45), nullptr);
    EXPECT_EQ(ty.find(mb::Table::HoldingRegisters, 45), nullptr);
    EXPECT_EQ(*mmk.find(mb::Table::HoldingRegisters, 57)->min, -1009);
    EXPECT_EQ(*ty.find(mb::Table::HoldingRegisters, 57)->min, -9999);
    EXPECT_EQ(ty.find(mb::Table::HoldingRegisters, 57)->range_text, "-9999 a 30000 U.E.");
    EXPECT_EQ(mmk.point_count(mb::Table::HoldingRegisters), 10u);
    EXPECT_EQ(ty.point_count(mb::Table::HoldingRegisters), 9u);
}

TEST(ProfileLoader, SameAsTablesServeTheOtherMap) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    EXPECT_TRUE(p.implements(mb::Table::InputRegisters));
    EXPECT_FALSE(p.implements(mb::Table::DiscreteInputs));
    EXPECT_EQ(p.find(mb::Table::InputRegisters, 23), p.find(mb::Table::HoldingRegisters, 23));
    EXPECT_EQ(p.functions.max_for(3), 15);
    EXPECT_EQ(p.functions.max_for(2), 2000);  // not in the manual: the specification's limit
    EXPECT_TRUE(p.functions.supports(8));
    EXPECT_FALSE(p.functions.supports(2));
}

TEST(ProfileLoader, DecodesNamedScaledValues) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    // PV 1234 with PT.DEC 2 given as context, filter 10 → 1.0 s, setpoint 0xFC19 = -999.
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 0, {1234}, {{17, 2}});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_DOUBLE_EQ(*v[0].number, 12.34);
    EXPECT_EQ(v[0].text, "12.34");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 23, {10});
    EXPECT_EQ(v[0].text, "1.0");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 57, {0xFC19});
    EXPECT_EQ(*v[0].number, -999);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 8, {1});
    EXPECT_EQ(v[0].text, "RTU");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 2, {0x61});
    EXPECT_EQ(v[0].text, "'a'");
}

TEST(ProfileLoader, DecodesSplitAndWideValues) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 60, {1234, 5678});
    ASSERT_EQ(v.size(), 2u);
    EXPECT_DOUBLE_EQ(*v[0].number, 12345678.0);  // MK-ENC-04: a decimal split, high*10^4 + low
    // f32 1.5 = 0x3FC00000; word order cdab puts the low word first.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 70, {0x0000, 0x3FC0});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_DOUBLE_EQ(*v[0].number, 1.5);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 70, {0x0000});
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].text, "0 (first half only)");
    EXPECT_EQ(v[0].number, std::nullopt);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 60, {1234});
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].text, "1234 (one half only)");
    EXPECT_EQ(v[0].number, std::nullopt);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 0, {1234});  // decimal point register 17 unknown
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].text, "1234 (unscaled: decimal point unknown)");
    EXPECT_EQ(v[0].number, std::nullopt);
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 100, {7});
    EXPECT_EQ(v[0].point, nullptr);
}

// A block that starts at a value's second register (a read from the middle of a float, a write of one
// register) dropped that word without a trace; it is shown alone, or whole when the first half is known.
TEST(ProfileLoader, ABlockStartingAtASecondHalfShowsIt) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 71, {0x3FC0, 7});
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v[0].address, 71);
    ASSERT_NE(v[0].point, nullptr);
    EXPECT_EQ(v[0].point->address, 70);
    EXPECT_TRUE(v[0].partial);
    EXPECT_EQ(v[0].text, "16320 (second half only)");
    EXPECT_EQ(v[0].number, std::nullopt);  // half a float is no value (its JSON had "value": 16320)
    EXPECT_EQ(v[0].raw, (std::vector<std::uint16_t>{0x3FC0}));
    EXPECT_EQ(v[1].address, 72);
    EXPECT_EQ(v[1].point, nullptr);
    // The first half known from elsewhere (an earlier read): the whole value, 1.5 in cdab order, which says
    // where its other half came from (that half may have changed since: a value glued from halves read
    // minutes apart was shown as the device's).
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 71, {0x3FC0}, {{70, 0x0000}});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_FALSE(v[0].partial);
    EXPECT_DOUBLE_EQ(*v[0].number, 1.5);
    EXPECT_EQ(v[0].raw, (std::vector<std::uint16_t>{0x0000, 0x3FC0}));
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(70));
    EXPECT_EQ(mb::named_value_to_json(v[0])["other_half_earlier"], 70);
    // So does a first half completed from an earlier reply, and a decimal split's other register.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 70, {0x0000}, {{71, 0x3FC0}});
    EXPECT_DOUBLE_EQ(*v[0].number, 1.5);
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(71));
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 60, {1234}, {{61, 5678}});
    EXPECT_DOUBLE_EQ(*v[0].number, 12345678.0);
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(61));
    // Inside a block that holds the first half, the second is still taken with it, from this block.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 69, {1, 0x0000, 0x3FC0}, {{70, 9}, {71, 9}});
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v[1].address, 70);
    EXPECT_DOUBLE_EQ(*v[1].number, 1.5);
    EXPECT_EQ(v[1].other_half_earlier, std::nullopt);
    EXPECT_FALSE(mb::named_value_to_json(v[1]).contains("other_half_earlier"));
}

// Addresses end at 65535: a block that runs past it names nothing there (wrapped round, its words would be
// named as the registers at 0, 1, ...), and a profile cannot place a value's second register past it.
TEST(ProfileLoader, NothingWrapsRoundPastAddress65535) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    ASSERT_NE(p.find(mb::Table::HoldingRegisters, 0), nullptr);
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 65535, {1234, 5678});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].address, 65535);
    EXPECT_EQ(v[0].point, nullptr);

    std::string wide = mk_like;
    const std::string f32_at_70 = "\"address\": 70";
    ASSERT_NE(wide.find(f32_at_70), std::string::npos);
    wide.replace(wide.find(f32_at_70), f32_at_70.size(), "\"address\": 65535");
    const auto refused = load(wide.c_str());
    ASSERT_FALSE(refused.errors.empty());
    EXPECT_NE(mb::to_string(refused.errors[0]).find("a two-register value at 65535 has no second register"),
              std::string::npos)
        << mb::to_string(refused.errors[0]);
}

TEST(ProfileLoader, WriteChecksGiveTheManualsExceptions) {
    auto l = load(mk_like);
    const auto& p = l.profiles[0];
    using T = mb::Table;
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 23, 250), std::nullopt);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 23, 251), 3);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 57, static_cast<std::uint16_t>(-1009)), std::nullopt);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 57, static_cast<std::uint16_t>(-1010)), 3);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 8, 2), 3);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 2, 'm'), 3);  // MK-ENC-03: 'm' is not allowed
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 2, 'a'), std::nullopt);
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 0, 1), 2);   // read-only; the manual is silent → 02
    EXPECT_EQ(mb::check_write(p, T::HoldingRegisters, 99, 1), 2);  // not in the map
}

TEST(ProfileLoader, ReportsEveryErrorWithItsPointer) {
    const char* broken = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["rtu", "carrier-pigeon"]},
      "functions": {"supported": [3, 300]},
      "tables": {
        "holding_registers": [
          {"address": 1, "name": "a", "access": "rx", "source": "000:1"},
          {"address": 70000, "name": "b", "access": "r", "source": "000:2"},
          {"address": 2, "name": "c", "access": "r", "encoding": {"type": "float"}, "source": "000:3"},
          {"address": 3, "name": "d", "access": "r"},
          {"address": 1, "name": "e", "access": "r", "source": "000:5"}
        ],
        "registers": []
      },
      "models": [{"id": "m"}]
    })";
    auto l = load(broken);
    std::vector<std::string> pointers;
    for (const auto& e : l.errors)
        pointers.push_back(e.pointer);
    auto has = [&](const std::string& p) {
        return std::find(pointers.begin(), pointers.end(), p) != pointers.end();
    };
    EXPECT_TRUE(has("/line/transports"));
    EXPECT_TRUE(has("/functions/supported"));
    EXPECT_TRUE(has("/tables/holding_registers/0/access"));
    EXPECT_TRUE(has("/tables/holding_registers/1/address"));
    EXPECT_TRUE(has("/tables/holding_registers/2/encoding/type"));
    EXPECT_TRUE(has("/tables/holding_registers/3"));  // missing source
    EXPECT_TRUE(has("/tables/holding_registers"));    // address 1 twice
    EXPECT_TRUE(has("/tables/registers"));
    for (const auto& e : l.errors)
        EXPECT_EQ(e.file, "test.json");
    EXPECT_GE(l.errors.size(), 8u);
}

// Line and function limits that cannot be: a quantity past what the one-byte byte count describes (the
// reference slave served 200 registers with a byte count of 144 in a 403-byte reply), a key that is no
// function with a quantity, baud rates and parities that were dropped without a word, a unit range upside
// down. A limit past the specification's that a frame can still carry (Walchem's FC16 125) is kept.
TEST(ProfileLoader, LimitsNoFrameCanCarryAreErrors) {
    const char* wrong = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["rtu"], "baud_rates": [9600, "19200", 0], "parity": ["even", "E"],
               "unit_id": {"min": 50, "max": 10}},
      "functions": {"supported": [1, 3, 16], "max_quantity": {"3": 500, "1": 2041, "16": 125, "5": 1, "16w": 2,
                                                             "x": 3, "15": 2040}},
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
      "models": [{"id": "m"}]
    })";
    const auto l = load(wrong);
    const auto errors = pointers_and_messages(l);
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/line/baud_rates/1", "must be a baud rate from 50 to 10000000"},
        {"/line/baud_rates/2", "must be a baud rate from 50 to 10000000"},
        {"/line/parity/1", "must be \"none\", \"even\" or \"odd\""},
        {"/line/unit_id", "min is above max"},
        {"/functions/max_quantity/1",
         "above 2040, the most a one-byte byte count can describe (the specification allows 2000)"},
        {"/functions/max_quantity/16w",
         "not a function with a quantity (1, 2, 3, 4, 15, 16, 23, or 23w for FC23's write)"},
        {"/functions/max_quantity/3",
         "above 127, the most a one-byte byte count can describe (the specification allows 125)"},
        {"/functions/max_quantity/5",
         "not a function with a quantity (1, 2, 3, 4, 15, 16, 23, or 23w for FC23's write)"},
        {"/functions/max_quantity/x",
         "not a function with a quantity (1, 2, 3, 4, 15, 16, 23, or 23w for FC23's write)"},
    };
    EXPECT_EQ(errors, expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    EXPECT_EQ(l.profiles[0].functions.max_for(16), 125);
    EXPECT_EQ(l.profiles[0].functions.max_for(15), 2040);
}

// The character a manual fixes (MK-CHR-01: 8 data bits in RTU, 7 in ASCII; MK-CHR-02: 2 stop bits in
// ASCII without parity, else 1) is read from line.data_bits and line.stop_bits, which the profiles carried
// and the loader ignored; the most specific stop-bit key wins, a list of several fixes nothing, and values
// that cannot be are errors.
TEST(ProfileLoader, TheCharacterTheManualFixesIsLoaded) {
    const char* mk_like = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["rtu", "ascii"], "data_bits": {"rtu": 8, "ascii": 7},
               "stop_bits": {"rtu": [1, 2], "ascii_no_parity": [2], "ascii": [1]}},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
      "models": [{"id": "m"}]
    })";
    const auto good = load(mk_like);
    EXPECT_TRUE(good.errors.empty());
    ASSERT_EQ(good.profiles.size(), 1u);
    const auto& line = good.profiles[0].line;
    EXPECT_EQ(line.data_bits_for(mb::Framing::Rtu), 8);
    EXPECT_EQ(line.data_bits_for(mb::Framing::Ascii), 7);
    EXPECT_FALSE(line.data_bits_for(mb::Framing::Tcp).has_value());
    EXPECT_EQ(line.stop_bits_for(mb::Framing::Ascii, mb::Parity::None), 2);
    EXPECT_EQ(line.stop_bits_for(mb::Framing::Ascii, mb::Parity::Odd), 1);
    EXPECT_FALSE(line.stop_bits_for(mb::Framing::Rtu, mb::Parity::None).has_value());  // 1 or 2

    const char* wrong = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["rtu"], "data_bits": {"rtu": 9, "tcp": 8},
               "stop_bits": {"rtu": [3], "ascii_even": [1], "ascii": 1}},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
      "models": [{"id": "m"}]
    })";
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/line/data_bits/rtu", "must be 5 to 8 data bits"},
        {"/line/data_bits/tcp", "unknown framing (rtu or ascii)"},
        {"/line/stop_bits/ascii", "must be a list of 1 and/or 2"},
        {"/line/stop_bits/ascii_even", "unknown key (rtu, ascii, each also _parity or _no_parity)"},
        {"/line/stop_bits/rtu", "must be a list of 1 and/or 2"},
    };
    EXPECT_EQ(pointers_and_messages(load(wrong)), expected);
    // A bundled MK profile says what MK-CHR-01 and MK-CHR-02 say.
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto mk = store.load("mmk-2030");
    ASSERT_TRUE(mk.has_value());
    EXPECT_EQ(mk->line.stop_bits_for(mb::Framing::Ascii, mb::Parity::None), 2);
    EXPECT_EQ(mk->line.stop_bits_for(mb::Framing::Rtu, mb::Parity::None), 1);
    EXPECT_EQ(mk->line.data_bits_for(mb::Framing::Ascii), 7);
}

// A line the device's manual does not allow is said, one sentence per departure (the slave serves it as
// asked and says so): MK's 8N1 RTU at 9600 departs in nothing, 19200 baud 8N2 and a TCP transport do.
TEST(ProfileLoader, ALineTheManualDoesNotAllowIsSaid) {
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto mk = store.load("mmk-2030");
    ASSERT_TRUE(mk.has_value());
    mb::SerialLine line{9600, 8, mb::Parity::None, 1};
    EXPECT_TRUE(mb::line_departures(mk->line, mb::Framing::Rtu, &line).empty());
    line = {9600, 7, mb::Parity::None, 2};  // MK-CHR-02: ASCII without parity, 7N2
    EXPECT_TRUE(mb::line_departures(mk->line, mb::Framing::Ascii, &line).empty());
    line = {19200, 8, mb::Parity::None, 2};
    const std::vector<std::string> expected{
        "19200 baud is not among the manual's (300, 600, 1200, 2400, 4800, 9600)",
        "2 stop bits where the manual allows 1 for rtu without parity"};
    EXPECT_EQ(mb::line_departures(mk->line, mb::Framing::Rtu, &line), expected);
    EXPECT_EQ(mb::line_departures(mk->line, mb::Framing::Tcp, nullptr),
              std::vector<std::string>{"the manual lists no tcp transport (rtu, ascii)"});
    line = {9600, 8, mb::Parity::Even, 1};
    EXPECT_EQ(mb::line_departures(mk->line, mb::Framing::Ascii, &line),
              std::vector<std::string>{"8 data bits where the manual fixes 7 for ascii"});
}

// A range is in raw units, so each limit must fit the point's registers: a maximum of 70000 on one register
// was accepted, and the conformance runner then wrote it as 4464 and called that "the maximum". Checked
// after a model's overrides, which may give a point its range; a float's range is in engineering units.
// (Address 5 is written "u32", the shorthand, which used to make a one-register value of it.)
TEST(ProfileLoader, RangesPastWhatThePointsRegistersHoldAreErrors) {
    const char* wrong = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3, 6, 16]},
      "tables": {"holding_registers": [
        {"address": 1, "name": "a", "access": "rw", "range": {"min": 0, "max": 70000}, "source": "000:1"},
        {"address": 2, "name": "b", "access": "rw", "range": {"min": -5, "max": 9}, "source": "000:2"},
        {"address": 3, "name": "c", "access": "rw", "encoding": "s16", "range": {"min": -32768, "max": 32767},
         "source": "000:3"},
        {"address": 4, "name": "d", "access": "rw", "encoding": {"type": "fixed", "decimals": 1, "signed": true},
         "range": {"min": -40000, "max": 0}, "source": "000:4"},
        {"address": 5, "name": "e", "access": "rw", "encoding": "u32", "range": {"min": 0, "max": 4294967295},
         "source": "000:5"},
        {"address": 7, "name": "f", "access": "rw", "encoding": "s32", "range": {"min": -1, "max": 4294967295},
         "source": "000:7"},
        {"address": 9, "name": "g", "access": "rw", "encoding": "f32", "range": {"min": -1, "max": 1000000000},
         "source": "000:9"},
        {"address": 11, "name": "h", "access": "rw", "source": "000:11"}
      ]},
      "models": [{"id": "m", "overrides": [{"table": "holding_registers", "address": 11,
                                            "range": {"min": 0, "max": 65536}}]}]
    })";
    const auto l = load(wrong);
    std::vector<std::string> messages;
    for (const auto& e : l.errors)
        messages.push_back(e.message);
    const std::vector<std::string> expected{
        "m: holding_registers 1 has the range maximum 70000, which its u16 register cannot hold (0 to 65535)",
        "m: holding_registers 2 has the range minimum -5, which its u16 register cannot hold (0 to 65535)",
        "m: holding_registers 4 has the range minimum -40000, which its fixed register cannot hold "
        "(-32768 to 32767)",
        "m: holding_registers 7 has the range maximum 4294967295, which its s32 registers cannot hold "
        "(-2147483648 to 2147483647)",
        "m: holding_registers 11 has the range maximum 65536, which its u16 register cannot hold (0 to "
        "65535)",
    };
    EXPECT_EQ(messages, expected);
    for (const auto& e : l.errors)
        EXPECT_EQ(e.pointer, "/models/0");
}

// A function code listed twice is a slip of the transcription. An enumeration value listed twice has two
// meanings (a manual may give one by the device's type or mode, as Walchem's alarm bits): the decoding
// showed only whichever came last; it shows both.
TEST(ProfileLoader, FunctionsListedTwiceAreErrorsAndAValueWithTwoMeaningsShowsBoth) {
    const char* text = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3, 6, 3], "broadcast": [6, 6]},
      "tables": {"holding_registers": [
        {"address": 1, "name": "a", "access": "rw", "source": "000:1",
         "encoding": {"type": "enum", "values": [{"value": 0, "text": "desligado"}, {"value": 1, "text": "ligado"},
                                                 {"value": 1, "text": "alarme", "text_en": "alarm"}]}}
      ]},
      "models": [{"id": "m"}]
    })";
    const auto l = load(text);
    const auto errors = pointers_and_messages(l);
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/functions/supported", "3 is listed twice"},
        {"/functions/broadcast", "6 is listed twice"},
    };
    EXPECT_EQ(errors, expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    EXPECT_EQ(l.profiles[0].functions.supported, (std::vector<std::uint8_t>{3, 6}));
    const auto v = mb::decode_registers(l.profiles[0], mb::Table::HoldingRegisters, 1, {1});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].text, "ligado or alarme (alarm)");
}

// The shorthand "u32" made a one-register value, and "scaled", "enum" and the paired halves were taken
// without the fields they cannot work without.
TEST(ProfileLoader, ShorthandEncodingsAreWholeOrRefused) {
    const char* text = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [
        {"address": 1, "name": "a", "access": "r", "encoding": "u32", "source": "000:1"},
        {"address": 3, "name": "b", "access": "r", "encoding": "f32", "source": "000:3"},
        {"address": 5, "name": "c", "access": "r", "encoding": "scaled", "source": "000:5"},
        {"address": 6, "name": "d", "access": "r", "encoding": "enum", "source": "000:6"},
        {"address": 7, "name": "e", "access": "r", "encoding": "u32_low", "source": "000:7"},
        {"address": 8, "name": "f", "access": "r", "encoding": {"type": "s32", "words": 1}, "source": "000:8"},
        {"address": 10, "name": "g", "access": "r", "encoding": "formula", "source": "000:10"},
        {"address": 11, "name": "h", "access": "r", "encoding": {"type": "formula"}, "source": "000:11"},
        {"address": 12, "name": "i", "access": "r", "encoding": {"type": "formula", "expr": "I = 4 + * R"},
         "source": "000:12"},
        {"address": 13, "name": "j", "access": "r", "encoding": {"type": "formula", "expr": "I = 4 + 16 * R / 65536"},
         "source": "000:13"},
        {"address": 14, "name": "k", "access": "r", "encoding": {"type": "formula", "expr": "R * 1000"}, "source": "000:14"},
        {"address": 15, "name": "l", "access": "r", "encoding": {"type": "formula", "expr": "-R"}, "source": "000:15"},
        {"address": 16, "name": "m", "access": "r", "encoding": {"type": "formula", "expr": "0 / R"}, "source": "000:16"}
      ]},
      "models": [{"id": "m"}]
    })";
    const auto l = load(text);
    const auto errors = pointers_and_messages(l);
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/tables/holding_registers/2/encoding", "\"scaled\" needs an object with its \"decimals_from\""},
        {"/tables/holding_registers/3/encoding", "\"enum\" needs an object with its \"values\""},
        {"/tables/holding_registers/4/encoding", "\"u32_low\" needs an object with its \"pair\""},
        {"/tables/holding_registers/5/encoding/words", "a 32-bit value takes two registers"},
        {"/tables/holding_registers/6/encoding", "\"formula\" needs an object with its \"expr\""},
        {"/tables/holding_registers/7/encoding", "\"formula\" needs \"expr\""},
        {"/tables/holding_registers/8/encoding/expr", "\"I = 4 + * R\": unexpected '*' at character 9"},
    };
    EXPECT_EQ(errors, expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    const auto& p = l.profiles[0];
    ASSERT_NE(p.find(mb::Table::HoldingRegisters, 1), nullptr);
    EXPECT_EQ(p.find(mb::Table::HoldingRegisters, 1)->encoding.words, 2);
    EXPECT_EQ(p.find(mb::Table::HoldingRegisters, 2), p.find(mb::Table::HoldingRegisters, 1));
    EXPECT_EQ(p.find(mb::Table::HoldingRegisters, 4), p.find(mb::Table::HoldingRegisters, 3));
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 13, {32768, 65535, 0, 0});
    ASSERT_EQ(v.size(), 4u);
    EXPECT_EQ(v[0].text, "12");
    EXPECT_EQ(v[1].text, "65535000");  // in full, not 6.5535e+07
    EXPECT_EQ(v[2].text, "0");         // not -0
    EXPECT_EQ(v[3].text, "undefined (the formula divides by zero)");
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 13, {1});
    EXPECT_EQ(v[0].text, "4.000244");
}

// A decimal point chosen by another register (TY-2090, 000:627): a selector without choices, one beside
// "decimals_from", a choice naming a register the model lacks and an address out of range are errors with
// their pointers; a well-formed one loads and scales by the choice the selector's value names.
TEST(ProfileLoader, DecimalsSelectedByAnotherRegisterAreChecked) {
    const char* text = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [
        {"address": 1, "name": "a", "access": "r", "source": "000:1", "encoding": {"type": "scaled",
         "decimals_selected_by": {"address": 9, "choices": [{"value": 0, "address": 7}, {"value": 1, "address": 8}]}}},
        {"address": 2, "name": "b", "access": "r", "source": "000:2", "encoding": {"type": "scaled",
         "decimals_selected_by": {"address": 9}}},
        {"address": 3, "name": "c", "access": "r", "source": "000:3", "encoding": {"type": "scaled",
         "decimals_from": 7, "decimals_selected_by": {"address": 9, "choices": [{"value": 0, "address": 7}]}}},
        {"address": 4, "name": "d", "access": "r", "source": "000:4", "encoding": {"type": "scaled",
         "decimals_selected_by": {"address": 9, "choices": [{"value": 0, "address": 70000}]}}},
        {"address": 5, "name": "e", "access": "r", "source": "000:5", "encoding": {"type": "scaled",
         "decimals_selected_by": {"address": 9, "choices": [{"value": 0, "address": 6}]}}},
        {"address": 7, "name": "p1", "access": "rw", "source": "000:7"},
        {"address": 8, "name": "p2", "access": "rw", "source": "000:8"},
        {"address": 9, "name": "sel", "access": "rw", "source": "000:9"}
      ]},
      "models": [{"id": "m"}]
    })";
    const auto l = load(text);
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/tables/holding_registers/1/encoding/decimals_selected_by",
         "needs \"choices\": [{\"value\", \"address\"}, ...]"},
        {"/tables/holding_registers/1/encoding",
         "\"scaled\" needs \"decimals_from\" or \"decimals_selected_by\""},
        {"/tables/holding_registers/2/encoding/decimals_selected_by",
         "give \"decimals_from\" or \"decimals_selected_by\", not both"},
        {"/tables/holding_registers/3/encoding/decimals_selected_by/choices/0/address",
         "must be between 0 and 65535"},
        {"/tables/holding_registers/3/encoding",
         "\"scaled\" needs \"decimals_from\" or \"decimals_selected_by\""},
        {"/models/0", "m: holding_registers 5 refers to holding_registers 6, which this model does not have"},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    auto v =
        mb::decode_registers(l.profiles[0], mb::Table::HoldingRegisters, 1, {1234}, {{7, 1}, {8, 2}, {9, 1}});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].text, "12.34");
}

// The orders a device can be set to send 32-bit values in (Walchem, 002:470-477): the default first, then
// the alternatives; an order that is none of the four, or alternatives without a default, are errors.
TEST(ProfileLoader, TheWordOrdersADeviceCanBeSetToAreLoaded) {
    const std::string head = R"({"format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 0, "name": "f", "access": "r", "source": "000:1",
        "encoding": {"type": "f32", "word_order": "cdab"}}]}, "models": [{"id": "m"}], "words": )";
    auto l = load((head + R"({"word_order": "cdab", "word_order_alternatives": ["abcd"]}})").c_str());
    ASSERT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    ASSERT_EQ(l.profiles.size(), 1u);
    EXPECT_EQ(l.profiles[0].word_orders,
              (std::vector<mb::WordOrder>{mb::WordOrder::Cdab, mb::WordOrder::Abcd}));
    auto p = l.profiles[0];
    EXPECT_FALSE(mb::set_word_order(p, mb::WordOrder::Abcd).has_value());
    EXPECT_EQ(p.find(mb::Table::HoldingRegisters, 0)->encoding.word_order, mb::WordOrder::Abcd);
    EXPECT_EQ(mb::set_word_order(p, mb::WordOrder::Dcba),
              "m's manual gives cdab or abcd (the device's setting), not dcba");
    l = load((head + R"({"word_order": "cdba", "word_order_alternatives": [3]}})").c_str());
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/words/word_order", "must be abcd, badc, cdab or dcba"},
        {"/words/word_order_alternatives", "alternatives need the default \"word_order\""},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
}

// Fields of the wrong type where the loader used to take a default with nlohmann's value(), which throws on
// a type mismatch: each is an error with its pointer, and the rest still loads (found by the profile fuzz
// target, fuzz/regressions/profile/implied-not-a-boolean).
TEST(ProfileLoader, WrongTypesAreErrorsNotExceptions) {
    const char* wrong = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3], "exceptions": {"3": {"code": 2, "implied": "yes"}}},
      "notes": [{"text": 5, "source": "000:1"}, {"text": "kept", "source": ["000:2"], "kind": {}}],
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
      "models": [{"id": "m"}]
    })";
    mb::LoadedProfiles l;
    ASSERT_NO_THROW(l = load(wrong));
    std::vector<std::string> pointers;
    for (const auto& e : l.errors)
        pointers.push_back(e.pointer);
    EXPECT_EQ(pointers, (std::vector<std::string>{"/functions/exceptions/3/implied", "/notes/0/text",
                                                  "/notes/1/source", "/notes/1/kind"}));
    ASSERT_EQ(l.profiles.size(), 1u);
    EXPECT_NE(l.profiles[0].find(mb::Table::HoldingRegisters, 1), nullptr);
}

// Profile text is printed on terminals and in reports: a control character anywhere (a value, a key) is an
// error at its pointer; a document nested deeper than any profile is refused where it goes too deep.
TEST(ProfileLoader, ControlCharactersAndDeepNestingAreErrors) {
    const char* hostile = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["rtu"]},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 1, "name": "a\u001b[2J", "access": "r", "unit": "\r",
                                        "source": "000:1"}]},
      "x-extra": {"a/b\u0007": "", "c1": "a\u009b2J", "deep": [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]},
      "models": [{"id": "m", "name": "caf\u00e9"}]
    })";
    auto l = load(hostile);
    std::vector<std::string> pointers;
    for (const auto& e : l.errors) {
        pointers.push_back(e.pointer);
        EXPECT_EQ(e.file, "test.json");
        for (char c : e.message)
            EXPECT_GE(static_cast<unsigned char>(c), 0x20) << e.message;
    }
    const std::string deep = "/x-extra/deep" + [] {
        std::string s;
        for (int i = 0; i < 31; ++i)
            s += "/0";
        return s;
    }();
    EXPECT_EQ(pointers, (std::vector<std::string>{"/tables/holding_registers/0/name",
                                                  "/tables/holding_registers/0/unit", "/x-extra/a~1b\\x07",
                                                  "/x-extra/c1", deep}));
}

TEST(ProfileLoader, InvalidJsonAndOtherDocuments) {
    auto bad = load("{ \"format\": ");
    ASSERT_EQ(bad.errors.size(), 1u);
    EXPECT_NE(bad.errors[0].message.find("not valid JSON"), std::string::npos);
    // A number too large for a double is nlohmann's out_of_range, not a parse_error: still an error record.
    auto overflow = load("8888e8888");
    ASSERT_EQ(overflow.errors.size(), 1u);
    EXPECT_NE(overflow.errors[0].message.find("not valid JSON"), std::string::npos);
    auto schema = load(R"({"$schema": "https://json-schema.org/draft/2020-12/schema"})");
    EXPECT_FALSE(schema.is_profile);
    EXPECT_TRUE(schema.errors.empty());
    auto future = load(R"({"format": "mbscope-profile/9"})");
    ASSERT_EQ(future.errors.size(), 1u);
    EXPECT_EQ(future.errors[0].pointer, "/format");
}

TEST(ProfileLoader, ModularDeviceExpandsItsConfiguration) {
    const char* device = R"({
      "format": "mbscope-profile/1", "family": "wal", "vendor": "Walchem", "maps_file": "maps.json",
      "line": {"transports": ["tcp"]},
      "functions": {"supported": [1, 2, 3, 4, 5, 6, 16], "address_check": "first"},
      "tables": {"input_registers": {"same_as": "holding_registers"}, "discrete_inputs": {"same_as": "coils"}},
      "modular": {"block_size": 36,
        "channels": [{"id": "sensor-1-1", "start": 576, "maps": ["sensor", "flow"], "default_map": "sensor", "source": "002:509"},
                     {"id": "relay-1", "start": 8928, "maps": ["onoff"], "source": "002:523"}],
        "default_config": {"relay-1": "onoff"}},
      "models": [{"id": "w"}]
    })";
    const char* maps = R"({"format": "mbscope-walchem-maps/1",
      "maps": {
        "sensor": {"fields": [{"index": 0, "name": "Valor primário", "access": "r", "encoding": {"type": "f32", "word_order": "abcd"}, "source": "002:870"},
                              {"index": 28, "name": "Alarme Baixa", "access": "r", "encoding": {"type": "bool"}, "coil": true, "source": "002:898"},
                              {"index": 34, "name": "Status", "access": "r", "encoding": {"type": "status"}, "source": "002:906"}]},
        "flow": {"fields": [{"index": 0, "name": "Vazão", "access": "r", "encoding": {"type": "f32"}, "source": "002:915"}]},
        "onoff": {"fields": [{"index": 6, "name": "Setpoint", "access": "rw", "encoding": {"type": "f32"}, "source": "002:1480"}]}},
      "status_codes": {"0": {"text": "Normal"}, "1": {"text": "Alarme"}}})";
    auto include = [&](const std::string& name) -> std::optional<std::string> {
        if (name == "maps.json") return std::string(maps);
        return std::nullopt;
    };
    auto l = load(device, include);
    ASSERT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    const auto& p = l.profiles[0];
    EXPECT_EQ(p.functions.address_check, mb::AddressCheck::First);
    EXPECT_TRUE(p.modular);
    EXPECT_FALSE(load(mk_like).profiles[0].modular);
    ASSERT_NE(p.find(mb::Table::HoldingRegisters, 576), nullptr);
    EXPECT_EQ(p.find(mb::Table::HoldingRegisters, 577),
              p.find(mb::Table::HoldingRegisters, 576));  // f32 second word
    EXPECT_NE(p.find(mb::Table::Coils, 604), nullptr);
    EXPECT_NE(p.find(mb::Table::DiscreteInputs, 604), nullptr);
    EXPECT_EQ(p.find(mb::Table::Coils, 576), nullptr);  // floats are not coil-accessible
    EXPECT_NE(p.find(mb::Table::HoldingRegisters, 8934), nullptr);
    auto status = mb::decode_registers(p, mb::Table::InputRegisters, 610, {1});
    EXPECT_EQ(status[0].text, "Alarme");
    auto flow = load(device, include, {{"sensor-1-1", "flow"}});
    ASSERT_TRUE(flow.errors.empty());
    EXPECT_EQ(flow.profiles[0].find(mb::Table::Coils, 604), nullptr);
    EXPECT_EQ(flow.profiles[0].configuration.at("sensor-1-1"), "flow");
    auto wrong = load(device, include, {{"relay-1", "sensor"}, {"nosuch", "x"}});
    EXPECT_EQ(wrong.errors.size(), 2u);
    // A channel whose map runs past 65535 (the sensor map's float at index 0 at 65535, its status at 65569)
    // is an error for each point placed there, not points wrapped round onto registers 0, 1, ...
    std::string high = device;
    high.replace(high.find("\"start\": 576"), 12, "\"start\": 65535");
    auto past = load(high.c_str(), include);
    ASSERT_EQ(past.errors.size(), 3u) << mb::to_string(past.errors[0]);
    EXPECT_EQ(past.errors[0].pointer, "/modular/channels/0/start");
    EXPECT_NE(past.errors[0].message.find("puts \"Valor primário\" at 65536, past the last address 65535"),
              std::string::npos)
        << past.errors[0].message;
    // A maps file that is JSON but not an object, and one that is not JSON: each named on /maps_file.
    const std::pair<const char*, const char*> broken[] = {{"[1, 2]", "maps.json is not a JSON object"},
                                                          {R"({"maps": )", "maps.json is not valid JSON"}};
    for (const auto& [text, message] : broken) {
        auto b =
            load(device, [&](const std::string&) -> std::optional<std::string> { return std::string(text); });
        ASSERT_FALSE(b.errors.empty()) << text;
        EXPECT_EQ(b.errors[0].pointer, "/maps_file") << text;
        EXPECT_NE(b.errors[0].message.find(message), std::string::npos) << b.errors[0].message;
    }
}
