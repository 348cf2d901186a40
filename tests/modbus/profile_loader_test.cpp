// The profile loader on small documents written for the test: structure, model variants, overrides, queries
// and error reporting with JSON pointers. The real device profiles have their own coverage tests.
#include "modbus/profile_loader.hpp"
#include "modbus/profile_json.hpp"
#include "modbus/storage/profile_store.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>

namespace test_modbus_profile_loader_test {

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

// A small document for the rules below: these tables, then the rest of its members (its models).
std::string doc(const std::string& tables, const std::string& rest = R"("models": [{"id": "m"}])") {
    return R"({"format": "mbscope-profile/1", "family": "t", "vendor": "T", "line": {"transports": ["tcp"]},
               "functions": {"supported": [1, 2, 3, 4]}, "tables": )" +
           tables + ", " + rest + "}";
}

mb::LoadedProfiles load(const std::string& text) {
    return mb::parse_profiles(text, "test.json", {}, {});
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
    auto v = mb::decode_registers(p, mb::Table::HoldingRegisters, 0, {1234}, {{{17, 2}}});
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
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 71, {0x3FC0}, {{{70, 0x0000}}});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_FALSE(v[0].partial);
    EXPECT_DOUBLE_EQ(*v[0].number, 1.5);
    EXPECT_EQ(v[0].raw, (std::vector<std::uint16_t>{0x0000, 0x3FC0}));
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(70));
    EXPECT_EQ(mb::named_value_to_json(v[0])["other_half_earlier"], 70);
    // So does a first half completed from an earlier reply, and a decimal split's other register.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 70, {0x0000}, {{{71, 0x3FC0}}});
    EXPECT_DOUBLE_EQ(*v[0].number, 1.5);
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(71));
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 60, {1234}, {{{61, 5678}}});
    EXPECT_DOUBLE_EQ(*v[0].number, 12345678.0);
    EXPECT_EQ(v[0].other_half_earlier, std::optional<std::uint16_t>(61));
    // Inside a block that holds the first half, the second is still taken with it, from this block.
    v = mb::decode_registers(p, mb::Table::HoldingRegisters, 69, {1, 0x0000, 0x3FC0}, {{{70, 9}, {71, 9}}});
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
    EXPECT_TRUE(has("/functions/supported/1"));
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

// A model's id and aliases are typed on command lines and named in reports and file names: words of
// letters and digits joined by '-', as the schema says; "a<b&c" was accepted and served. Upper case is
// taken as lower case, as before.
TEST(ProfileLoader, ModelIdsAndAliasesAreWordsJoinedByDashes) {
    const auto errors = [](const std::string& models) {
        const std::string text = R"({"format": "mbscope-profile/1", "family": "x", "vendor": "y",
          "line": {"transports": ["rtu"]}, "functions": {"supported": [3]},
          "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
          "models": )" + models + "}";
        return pointers_and_messages(load(text.c_str()));
    };
    const std::string rule = "must be letters and digits in words joined by '-' (\"mmk-2030\")";
    EXPECT_EQ(errors(R"([{"id": "a<b&c"}])"),
              (std::vector<std::pair<std::string, std::string>>{{"/models/0/id", rule}}));
    EXPECT_EQ(errors(R"([{"id": "MMK-2030", "aliases": ["ok-1", "-x", "a--b", "a b", ""]}])"),
              (std::vector<std::pair<std::string, std::string>>{{"/models/0/aliases/1", rule},
                                                                {"/models/0/aliases/2", rule},
                                                                {"/models/0/aliases/3", rule},
                                                                {"/models/0/aliases/4", rule}}));
    EXPECT_TRUE(errors(R"([{"id": "ty-2095-tc-rtd", "aliases": ["dmy-2030"]}])").empty());
}

// Line and function limits that cannot be: a quantity past what the one-byte byte count describes (the
// reference slave served 200 registers with a byte count of 144 in a 403-byte reply), a key that is no
// function with a quantity, baud rates and parities that were dropped without a word, a unit range upside
// down. A limit past the specification's that a frame can still carry (Walchem's FC16 125, in the 256-byte
// PDU its manual allows) is kept; 2040 coils fit the byte count but no PDU.
TEST(ProfileLoader, LimitsNoFrameCanCarryAreErrors) {
    const char* wrong = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y",
      "line": {"transports": ["rtu"], "baud_rates": [9600, "19200", 0], "parity": ["even", "E"],
               "unit_id": {"min": 50, "max": 10}, "pdu_max_bytes": 256},
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
        {"/functions/max_quantity/15",
         "a request or reply of 2040 needs a PDU of 261 bytes, more than the 256 the device takes "
         "(line.pdu_max_bytes; AP §4.1: 253)"},
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
    EXPECT_EQ(l.profiles[0].functions.max_for(15), 1968);  // the specification's: 2040 fits no PDU
}

// A PDU holds 253 bytes (AP §4.1) unless the manual says more (Walchem: 256, 002:219): a quantity whose
// request or reply would not fit is an error, since the device could never take or send it; the limit
// itself is one a Modbus/TCP frame here can carry (MBAP length 257 at most).
TEST(ProfileLoader, QuantitiesMustFitTheLongestPdu) {
    const char* spec = R"({
      "format": "mbscope-profile/1", "family": "x", "vendor": "y", "line": {"transports": ["tcp"]},
      "functions": {"supported": [1, 3, 15, 16, 23], "max_quantity": {"1": 2000, "3": 126, "15": 1968, "16": 124,
                                                                   "23": 125, "23w": 122}},
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "000:1"}]},
      "models": [{"id": "m"}]
    })";
    const std::string tail = " the device takes (line.pdu_max_bytes; AP §4.1: 253)";
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/functions/max_quantity/16",
         "a request or reply of 124 needs a PDU of 254 bytes, more than the 253" + tail},
        {"/functions/max_quantity/23w",
         "a request or reply of 122 needs a PDU of 254 bytes, more than the 253" + tail},
        {"/functions/max_quantity/3",
         "a request or reply of 126 needs a PDU of 254 bytes, more than the 253" + tail},
    };
    const auto l = load(spec);
    EXPECT_EQ(pointers_and_messages(l), expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    EXPECT_EQ(l.profiles[0].line.pdu_max_bytes, 253u);
    EXPECT_EQ(l.profiles[0].functions.max_for(23), 125);

    std::string longer = spec;
    longer.replace(longer.find("\"tcp\"]"), 6, "\"tcp\"], \"pdu_max_bytes\": 256");
    EXPECT_TRUE(pointers_and_messages(load(longer)).empty());
    std::string too_long = spec;
    too_long.replace(too_long.find("\"tcp\"]"), 6, "\"tcp\"], \"pdu_max_bytes\": 257");
    const auto errors = pointers_and_messages(load(too_long));
    EXPECT_NE(
        std::find(errors.begin(), errors.end(),
                  std::pair<std::string, std::string>{"/line/pdu_max_bytes", "must be between 2 and 256"}),
        errors.end());
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
    auto v = mb::decode_registers(l.profiles[0], mb::Table::HoldingRegisters, 1, {1234},
                                  {{{7, 1}, {8, 2}, {9, 1}}});
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
    // A status code that is no register value threw std::invalid_argument out of the loader (std::stoi):
    // an error naming the maps file and the key, the codes that are values still read.
    std::string odd = maps;
    const std::string last_code = R"("1": {"text": "Alarme"})";
    odd.replace(odd.find(last_code), last_code.size(), last_code + R"(, "x1": {"text": "?"})");
    auto coded = load(device, [&](const std::string&) -> std::optional<std::string> { return odd; });
    ASSERT_EQ(coded.errors.size(), 1u);
    EXPECT_EQ(coded.errors[0].file, "maps.json");
    EXPECT_EQ(coded.errors[0].pointer, "/status_codes/x1");
    EXPECT_NE(coded.errors[0].message.find("from 0 to 65535"), std::string::npos) << coded.errors[0].message;
    // A key given twice in the maps file (status code 1 with two texts): which text a status 1 shows is not
    // defined, so neither is used. Named in the maps file at its object, and the device told on /maps_file.
    std::string twice = maps;
    twice.replace(twice.find(last_code), last_code.size(), last_code + R"(, "1": {"text": "Falha"})");
    auto repeated = load(device, [&](const std::string&) -> std::optional<std::string> { return twice; });
    ASSERT_EQ(repeated.errors.size(), 2u) << mb::to_string(repeated.errors[0]);
    EXPECT_EQ(repeated.errors[0].file, "maps.json");
    EXPECT_EQ(repeated.errors[0].pointer, "/status_codes");
    EXPECT_EQ(repeated.errors[0].message, "key \"1\" is given twice: which one counts is not defined");
    EXPECT_EQ(repeated.errors[1].pointer, "/maps_file");
    EXPECT_NE(repeated.errors[1].message.find("maps.json gives a key twice in one object"), std::string::npos)
        << repeated.errors[1].message;
}

// A two-register value's second register listed as a point of its own: Profile::find named register 11 by
// whichever point came first and the slave's writes of one clobbered the other. Checked on each model after
// its overrides, which can widen a u16 to a u32; the models a fault holds for are named once.
TEST(ProfileLoader, TwoPointsOnOneRegisterAreErrors) {
    const auto u32_10 = R"({"address": 10, "name": "a", "access": "r", "encoding": "u32", "source": "1"})";
    const auto u16_11 = R"({"address": 11, "name": "b", "access": "r", "source": "2"})";
    const auto u16_12 = R"({"address": 12, "name": "b", "access": "r", "source": "2"})";
    auto l = load(doc(std::string(R"({"holding_registers": [)") + u32_10 + ", " + u16_11 + "]}",
                      R"("models": [{"id": "m"}, {"id": "n"}])"));
    const std::vector<std::pair<std::string, std::string>> overlap{
        {"/tables/holding_registers/1/address",
         "m, n: register 11 is the second register of holding_registers 10 (a u32, "
         "/tables/holding_registers/0): "
         "it cannot be another point as well"}};
    EXPECT_EQ(pointers_and_messages(l), overlap);
    // In a bit table as in a register table.
    l = load(
        doc(R"({"coils": [{"address": 0, "name": "a", "access": "r", "encoding": {"type": "u16", "words": 2},
                                "source": "1"}, {"address": 1, "name": "b", "access": "r", "source": "2"}]})"));
    ASSERT_EQ(l.errors.size(), 1u);
    EXPECT_EQ(l.errors[0].pointer, "/tables/coils/1/address");
    // An override that widens the point at 10 onto the point at 11.
    l = load(
        doc(R"({"holding_registers": [{"address": 10, "name": "a", "access": "r", "source": "1"}, )" +
                std::string(u16_11) + "]}",
            R"("models": [{"id": "m"}, {"id": "w", "overrides": [{"table": "holding_registers", "address": 10,
                                                                       "encoding": "u32"}]}])"));
    const std::vector<std::pair<std::string, std::string>> widened{
        {"/models/1/overrides/0/encoding",
         "w: register 11 is the second register of holding_registers 10, which this override makes a u32, "
         "and "
         "another point (/tables/holding_registers/1)"}};
    EXPECT_EQ(pointers_and_messages(l), widened);
    // The neighbour: a u32 at 10 and a u16 at 12 share nothing.
    l = load(doc(std::string(R"({"holding_registers": [)") + u32_10 + ", " + u16_12 + "]}"));
    EXPECT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
}

// parse_point refuses a two-register value at 65535 (its second register would wrap round to 0); a model's
// override that makes one there is refused the same way.
TEST(ProfileLoader, AnOverrideCannotPutATwoRegisterValueAt65535) {
    const auto tables =
        R"({"holding_registers": [{"address": 65534, "name": "a", "access": "r", "source": "1"},
                                                   {"address": 65535, "name": "b", "access": "r", "source": "2"}]})";
    auto l = load(doc(tables, R"("models": [{"id": "m", "overrides": [{"table": "holding_registers",
                                              "address": 65535, "encoding": "f32"}]}])"));
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/models/0/overrides/0/encoding", "a two-register value at 65535 has no second register"}};
    EXPECT_EQ(pointers_and_messages(l), expected);
    l = load(doc(R"({"holding_registers": [{"address": 65534, "name": "a", "access": "r", "source": "1"}]})",
                 R"("models": [{"id": "m", "overrides": [{"table": "holding_registers", "address": 65534,
                                                           "encoding": "f32"}]}])"));
    EXPECT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    EXPECT_EQ(l.profiles[0].find(mb::Table::HoldingRegisters, 65535)->address, 65534);
}

// A signal's values are written to its point: past what the point's encoding holds they were cut to 16 bits
// (70000 read 4464), outside the point's range they were values the device never shows; a total's last
// count is the one below the max it wraps at. A point no model has is an error; the neighbour loads.
TEST(ProfileLoader, SimulationSignalsMustFitTheirPoints) {
    const auto tables = R"({"holding_registers": [
        {"address": 5, "name": "pv", "access": "r", "range": {"min": 0, "max": 1000}, "source": "1"},
        {"address": 6, "name": "t", "access": "r", "encoding": "u32", "source": "2"},
        {"address": 8, "name": "lo", "access": "r", "encoding": {"type": "digits4_low", "pair": 9}, "source": "3"},
        {"address": 9, "name": "hi", "access": "r", "encoding": {"type": "digits4_high", "pair": 8}, "source": "4"}]})";
    const auto with = [&](const std::string& signals) {
        return load(doc(tables, R"("models": [{"id": "m"}], "simulation": {"signals": [)" + signals + "]}"));
    };
    auto l =
        with(R"({"id": "pv", "model": "walk", "point": 5, "start": 500, "min": 0, "max": 1000, "step": 5},
                     {"id": "t", "model": "integrate", "of": "pv", "point": 6, "per_second": 1, "max": 4294967296},
                     {"id": "d", "model": "integrate", "of": "pv", "point": 8, "per_second": 1, "max": 100000000})");
    EXPECT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    l = with(R"({"id": "pv", "model": "walk", "point": 5, "start": 500, "min": -3, "max": 70000, "step": 5},
                {"id": "c", "model": "constant", "point": 5, "value": 1001},
                {"id": "t", "model": "integrate", "of": "pv", "point": 6, "per_second": 1, "max": 4294967297},
                {"id": "d", "model": "integrate", "of": "pv", "point": 9, "per_second": 1, "max": 100000001},
                {"id": "x", "model": "walk", "point": 99, "start": 0, "min": 0, "max": 1, "step": 1},
                {"id": "y", "model": "walk", "point": 7, "start": 0, "min": 0, "max": 1, "step": 1})");
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/simulation/signals/0/min",
         "m: -3 is more than holding_registers 5's u16 register can hold (0 to 65535)"},
        {"/simulation/signals/0/max",
         "m: 70000 is more than holding_registers 5's u16 register can hold (0 to 65535)"},
        {"/simulation/signals/1/value", "m: 1001 is outside holding_registers 5's range (0 to 1000)"},
        {"/simulation/signals/2/max",
         "m: 4294967296 (the last count before the total wraps at 4294967297) is more than holding_registers "
         "6's u32 registers can hold (0 to 4294967295)"},
        {"/simulation/signals/3/max",
         "m: 100000000 (the last count before the total wraps at 100000001) is more than the 8 digits "
         "holding_registers 9 and 8 make can hold (0 to 99999999)"},
        {"/simulation/signals/5/point",
         "m: register 7 is the second register of holding_registers 6: a signal names the value's first "
         "register"},
        {"/simulation/signals/4/point",
         "holding_registers 99 is no point of any model: the signal would never run"},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
}

// An enumeration value the register cannot carry (70000 or -3 on a u16) is a text no reply shows and a
// write that would go out cut to 16 bits; a signed register carries -3, a byte of bytes2 0 to 255.
TEST(ProfileLoader, EnumValuesMustFitTheRegister) {
    auto l = load(doc(R"({"holding_registers": [
        {"address": 1, "name": "a", "access": "rw", "source": "1", "encoding": {"type": "enum",
         "values": [{"value": 0, "text": "x"}, {"value": 70000, "text": "y"}, {"value": -3, "text": "z"}]}},
        {"address": 2, "name": "b", "access": "rw", "source": "2", "encoding": {"type": "bytes2",
         "values": [{"value": 256, "text": "y"}]}}]})"));
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/tables/holding_registers/0/encoding/values/1/value",
         "70000 is not a value its enum register can carry (0 to 65535)"},
        {"/tables/holding_registers/0/encoding/values/2/value",
         "-3 is not a value its enum register can carry (0 to 65535)"},
        {"/tables/holding_registers/1/encoding/values/0/value",
         "256 is not a value a byte can carry (0 to 255)"},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
    l = load(doc(R"({"holding_registers": [{"address": 1, "name": "a", "access": "rw", "source": "1",
        "encoding": {"type": "enum", "signed": true, "values": [{"value": -3, "text": "z"}, {"value": 32767, "text": "y"}]}}]})"));
    EXPECT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
}

// Integers that were read as int and wrapped (4294967299 was function 3, unit 3, address 3, 3 ms), and
// exception codes no exception response can carry: each refused at its pointer.
TEST(ProfileLoader, IntegersThatWouldWrapAreErrors) {
    const std::string text = R"({"format": "mbscope-profile/1", "family": "t", "vendor": "T",
      "line": {"transports": ["tcp"], "unit_id": {"min": 1, "max": 247, "disabled": [0, 4294967296]},
               "response_timeout_ms": 4294967299, "min_poll_interval_ms": 100, "ascii_inter_char_timeout_ms": -1},
      "functions": {"supported": [3, 4294967299, 0, 128], "broadcast": [-1], "diagnostics": [65536],
                    "exceptions": {"bad_address": 2, "bad_value": 0, "bad_quantity": 256, "write_read_only": -3,
                                   "unsupported_function": 4294967297, "a/b": {"code": 300}, "x": "3", "y": null}},
      "tables": {"holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "1"},
                                       {"address": 5, "name": "b", "access": "r", "source": "2"}]},
      "models": [{"id": "m", "exclude": {"holding_registers": [70000, 4294967301, [9, 6], [10, 70000]], "registers": [1]},
                  "overrides": [{"table": "holding_registers", "addresses": [[1, 18446744073709551615]], "unit": "s"},
                                {"table": "holding_registers", "address": -4294967295, "unit": "s"}]}]})";
    const auto l = load(text);
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/line/unit_id/disabled/1", "must be a unit id from 0 to 255"},
        {"/line/response_timeout_ms", "must be between 0 and 2147483647"},
        {"/line/ascii_inter_char_timeout_ms", "must be between 0 and 2147483647"},
        {"/functions/supported/1", "must be a number from 1 to 127"},
        {"/functions/supported/2", "must be a number from 1 to 127"},
        {"/functions/supported/3", "must be a number from 1 to 127"},
        {"/functions/broadcast/0", "must be a number from 1 to 127"},
        {"/functions/diagnostics/0", "must be a number from 0 to 65535"},
        {"/functions/exceptions/a~1b/code", "must be an exception code from 1 to 255"},
        {"/functions/exceptions/bad_quantity", "must be an exception code from 1 to 255"},
        {"/functions/exceptions/bad_value", "must be an exception code from 1 to 255"},
        {"/functions/exceptions/unsupported_function", "must be an exception code from 1 to 255"},
        {"/functions/exceptions/write_read_only", "must be an exception code from 1 to 255"},
        {"/functions/exceptions/x", "must be an exception code, null or {\"code\", ...}"},
        {"/models/0/exclude/holding_registers/0", "must be an address from 0 to 65535"},
        {"/models/0/exclude/holding_registers/1", "must be an address from 0 to 65535"},
        {"/models/0/exclude/holding_registers/2", "first is above last"},
        {"/models/0/exclude/holding_registers/3/1", "must be an address from 0 to 65535"},
        {"/models/0/exclude/registers", "unknown table"},
        {"/models/0/overrides/0/addresses/0/1", "must be an address from 0 to 65535"},
        {"/models/0/overrides/0", "override matches no point of the table"},
        {"/models/0/overrides/1/address", "must be an address from 0 to 65535"},
        {"/models/0/overrides/1", "override matches no point of the table"},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
    ASSERT_EQ(l.profiles.size(), 1u);
    const auto& p = l.profiles[0];
    EXPECT_EQ(p.functions.supported, std::vector<std::uint8_t>{3});
    EXPECT_EQ(p.line.unit_disabled, std::vector<int>{0});
    EXPECT_EQ(p.functions.exceptions.at("bad_address"), 2);
    EXPECT_EQ(p.functions.exceptions.at("y"), std::nullopt);
    EXPECT_EQ(p.line.min_poll_interval_ms, 100);
    EXPECT_NE(p.find(mb::Table::HoldingRegisters, 5), nullptr);  // kept: 4294967301 is no longer read as 5
}

// same_as names the table whose points this one serves: one of its kind (FC2 answers from the coils' map,
// FC4 from the holding registers'), not itself, and one that lists points rather than serving a third.
TEST(ProfileLoader, SameAsNamesAnotherTableOfItsKindWithPoints) {
    const auto hr =
        std::string(R"("holding_registers": [{"address": 1, "name": "a", "access": "r", "source": "1"}])");
    const auto co = std::string(R"("coils": [{"address": 1, "name": "c", "access": "r", "source": "1"}])");
    const std::pair<std::string, std::pair<std::string, std::string>> cases[] = {
        {"{" + hr + R"(, "input_registers": {"same_as": "input_registers"}})",
         {"/tables/input_registers/same_as", "a table cannot serve its own map"}},
        {"{" + hr + ", " + co + R"(, "discrete_inputs": {"same_as": "holding_registers"}})",
         {"/tables/discrete_inputs/same_as",
          "\"holding_registers\" is not a bit table: coils and discrete_inputs serve each other's map, "
          "holding_registers and input_registers each other's"}},
        {"{" + hr + ", " + co + R"(, "input_registers": {"same_as": "coils"}})",
         {"/tables/input_registers/same_as",
          "\"coils\" is not a register table: coils and discrete_inputs serve each other's map, "
          "holding_registers and input_registers each other's"}},
        {"{" + co + R"(, "input_registers": {"same_as": "holding_registers"}})",
         {"/tables/input_registers/same_as", "\"holding_registers\" is not among this profile's tables"}},
    };
    for (const auto& [tables, error] : cases)
        EXPECT_EQ(pointers_and_messages(load(doc(tables))), (std::vector{error})) << tables;
    const auto cycle = load(doc(
        R"({"holding_registers": {"same_as": "input_registers"}, "input_registers": {"same_as": "holding_registers"}})"));
    const std::vector<std::pair<std::string, std::string>> both{
        {"/tables/input_registers/same_as",
         "\"holding_registers\" serves another table's map itself: name the table that lists the points"},
        {"/tables/holding_registers/same_as",
         "\"input_registers\" serves another table's map itself: name the table that lists the points"}};
    EXPECT_EQ(pointers_and_messages(cycle), both);
    const auto good = load(doc("{" + hr + ", " + co +
                               R"(, "input_registers": {"same_as": "holding_registers"},
                                   "discrete_inputs": {"same_as": "coils"}})"));
    EXPECT_TRUE(good.errors.empty()) << mb::to_string(good.errors[0]);
    EXPECT_EQ(good.profiles[0].find(mb::Table::DiscreteInputs, 1),
              good.profiles[0].find(mb::Table::Coils, 1));
}

// The halves of a value split over two points name each other: a u32_low its u32_high, a digits4_high its
// digits4_low, in the same table and model. Itself, a point of another type, no point, or a half that
// pairs with a third point are errors at the pair; the neighbour loads.
TEST(ProfileLoader, APairNamesItsOtherHalf) {
    const auto half = [](int address, const char* type, int pair) {
        return R"({"address": )" + std::to_string(address) + R"(, "name": "h", "access": "r", "source": "1",
                   "encoding": {"type": ")" +
               type + R"(", "pair": )" + std::to_string(pair) + "}}";
    };
    auto l = load(doc(R"({"holding_registers": [)" + half(1, "u32_low", 2) + ", " + half(2, "u32_high", 1) +
                      ", " + half(3, "digits4_high", 4) + ", " + half(4, "digits4_low", 3) + "]}"));
    EXPECT_TRUE(l.errors.empty()) << mb::to_string(l.errors[0]);
    l = load(doc(R"({"holding_registers": [)" + half(1, "u32_low", 1) + ", " + half(2, "u32_high", 3) + ", " +
                 half(3, "digits4_low", 4) + ", " + half(4, "u32_low", 2) + ", " + half(5, "u32_high", 9) +
                 "]}"));
    const std::vector<std::pair<std::string, std::string>> expected{
        {"/tables/holding_registers/0/encoding/pair",
         "m: names the point itself: a u32_low's pair is the address of its u32_high half"},
        {"/tables/holding_registers/1/encoding/pair",
         "m: holding_registers 3 is a digits4_low, not the u32_low half: a u32_high's pair is the address of "
         "its "
         "u32_low half"},
        {"/tables/holding_registers/2/encoding/pair",
         "m: holding_registers 4 is a u32_low, not the digits4_high half: a digits4_low's pair is the "
         "address of "
         "its digits4_high half"},
        {"/tables/holding_registers/3/encoding/pair", "m: holding_registers 2 pairs with 3, not with 4"},
        {"/tables/holding_registers/4/encoding/pair",
         "m: holding_registers 9 is no point of the model: a u32_high's pair is the address of its u32_low "
         "half"},
    };
    EXPECT_EQ(pointers_and_messages(l), expected);
}

// A model's alias equal to another model's id made that model disappear: the store asked whether an earlier
// directory had the id with find(), which also matches aliases (and this directory's own entries), so
// b.json's "bbb" was passed over for a.json's alias "bbb", and a user's alias "theirs" hid the bundled
// "theirs". An id is now shadowed by an earlier directory's id only, an exact id is never hidden by an alias,
// and one name taken twice in one directory is an error naming both files.
TEST(ProfileStore, AnAliasNeverHidesAnId) {
    namespace fs = std::filesystem;
    const fs::path root = fs::temp_directory_path() / ("mbscope-store-aliases-" + std::to_string(::getpid()));
    fs::remove_all(root);
    const auto write = [](const fs::path& file, const std::string& models) {
        fs::create_directories(file.parent_path());
        std::ofstream(file) << doc(R"({"holding_registers": [{"address": 0, "name": "a", "access": "r",
                                                               "source": "000:1"}]})",
                                   R"("models": )" + models);
    };
    write(root / "one" / "a.json", R"([{"id": "aaa", "aliases": ["bbb"]}])");
    write(root / "one" / "b.json", R"([{"id": "bbb"}])");
    const mb::storage::ProfileStore one({(root / "one").string()});
    EXPECT_EQ(one.entries().size(), 2u);
    ASSERT_NE(one.find("bbb"), nullptr);
    EXPECT_EQ(one.find("bbb")->id, "bbb");
    ASSERT_EQ(one.errors().size(), 1u);
    EXPECT_EQ(one.errors()[0].file, (root / "one" / "b.json").string());
    EXPECT_EQ(one.errors()[0].message, "device id \"bbb\" is also an alias of \"aaa\" in " +
                                           (root / "one" / "a.json").string() +
                                           ": the profile search finds the id by it, not \"aaa\"");

    write(root / "two" / "a.json", R"([{"id": "p", "aliases": ["x"]}])");
    write(root / "two" / "b.json", R"([{"id": "q", "aliases": ["X", "p"]}])");
    const mb::storage::ProfileStore two({(root / "two").string()});
    EXPECT_EQ(two.entries().size(), 2u);
    ASSERT_NE(two.find("x"), nullptr);
    EXPECT_EQ(two.find("x")->id, "p");
    EXPECT_EQ(two.find("p")->id, "p");
    const std::string a = (root / "two" / "a.json").string();
    ASSERT_EQ(two.errors().size(), 2u);
    EXPECT_EQ(two.errors()[0].message, "alias \"x\" of \"q\" is also an alias of \"p\" in " + a +
                                           ": the profile search finds \"p\" by it");
    EXPECT_EQ(two.errors()[1].message, "alias \"p\" of \"q\" is also a device id, in " + a +
                                           ": the profile search finds that device by it, not \"q\"");

    // Across directories an alias is no error (a user's directory names its devices as it likes), and no id
    // is hidden by it; of two aliases, the earlier directory's answers.
    write(root / "user" / "mine.json", R"([{"id": "my-meter", "aliases": ["theirs", "shared"]}])");
    write(root / "bundled" / "theirs.json", R"([{"id": "theirs", "aliases": ["shared"]}])");
    const mb::storage::ProfileStore both({(root / "user").string(), (root / "bundled").string()});
    EXPECT_TRUE(both.errors().empty()) << mb::to_string(both.errors()[0]);
    EXPECT_EQ(both.entries().size(), 2u);
    ASSERT_NE(both.find("theirs"), nullptr);
    EXPECT_EQ(both.find("theirs")->id, "theirs");
    EXPECT_EQ(both.find("shared")->id, "my-meter");
    EXPECT_EQ(both.load("theirs")->id, "theirs");
    fs::remove_all(root);
}

// JSON leaves a key given twice to the reader (RFC 8259 §4), and nlohmann kept the last: a point with
// "address": 0, "address": 99 loaded as 99 and validated. Either value may be the one meant: the document is
// refused, at the pointer of the object, naming the key.
TEST(ProfileLoader, AKeyGivenTwiceInOneObjectIsAnError) {
    const auto only_error = [](const std::string& text) {
        const auto l = load(text);
        EXPECT_TRUE(l.profiles.empty());
        EXPECT_EQ(l.errors.size(), 1u);
        for (const auto& e : l.errors)
            EXPECT_EQ(e.file, "test.json");
        return pointers_and_messages(l);
    };
    using Errors = std::vector<std::pair<std::string, std::string>>;
    EXPECT_EQ(only_error(doc(R"({"holding_registers": [
                {"address": 0, "name": "a", "access": "r", "source": "000:1", "address": 99}]})")),
              (Errors{{"/tables/holding_registers/0",
                       "key \"address\" is given twice: which one counts is not defined"}}));
    EXPECT_EQ(
        only_error(doc(R"({"holding_registers": [{"address": 0, "name": "a", "access": "r", "source": "1"},
                {"address": 1, "name": "b", "access": "r", "source": "2",
                 "encoding": {"type": "u16", "type": "s16"}}]})")),
        (Errors{{"/tables/holding_registers/1/encoding",
                 "key \"type\" is given twice: which one counts is not defined"}}));
    EXPECT_EQ(only_error(doc(R"({"holding_registers": []})",
                             R"("x/y~": {"k": 1, "k": 1}, "models": [{"id": "m"}])")),
              (Errors{{"/x~1y~0", "key \"k\" is given twice: which one counts is not defined"}}));
    EXPECT_EQ(only_error(doc(R"({"holding_registers": []})", R"("models": [{"id": "m"}], "vendor": "U")")),
              (Errors{{"", "key \"vendor\" is given twice: which one counts is not defined"}}));
    // The same key in different objects is no repeat.
    EXPECT_TRUE(load(doc(R"({"holding_registers": [{"address": 0, "name": "a", "access": "r", "source": "1"},
                      {"address": 1, "name": "a", "access": "r", "source": "1"}]})"))
                    .errors.empty());
}

// A formula that does not parse is named in its error: all of it, which for a hostile 200 kB "expr" was a
// 200 kB line. An excerpt is quoted, its first 40 characters.
TEST(ProfileLoader, AFormulaErrorQuotesAnExcerptOfTheExpression) {
    const auto error_of = [](const std::string& expr) {
        const auto l =
            load(doc(R"({"holding_registers": [{"address": 0, "name": "a", "access": "r", "source": "1",
                                     "encoding": {"type": "formula", "expr": ")" +
                     expr + R"("}}]})"));
        EXPECT_EQ(l.errors.size(), 1u);
        return l.errors.empty() ? std::string() : l.errors[0].message;
    };
    EXPECT_EQ(error_of(std::string(200000, '1')),
              "\"" + std::string(40, '1') + "…\": longer than 256 characters");
    EXPECT_EQ(error_of("I = R * " + std::string(60, '2') + " +"),
              "\"I = R * " + std::string(32, '2') + "…\": expression ends early at character 71");
    // Cut between characters, not inside one: "ã" is two bytes, the 40th and 41st.
    EXPECT_EQ(error_of(std::string(39, '1') + "ã" + std::string(300, '1')),
              "\"" + std::string(39, '1') + "…\": longer than 256 characters");
    EXPECT_EQ(error_of("I = 4 + * R"), "\"I = 4 + * R\": unexpected '*' at character 9");
}

}  // namespace test_modbus_profile_loader_test
