// The slave's state file (slave/state_file.hpp): what a round trip keeps, that the replacement is atomic
// (written beside and renamed, no .tmp left), and that a damaged or foreign file is refused by name.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "slave/state_file.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_state_file_test {
namespace {

namespace fs = std::filesystem;
using mb::Table;

class StateFile : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ =
            fs::temp_directory_path() / ("mbscope-state-" + std::to_string(::getpid()) + "-" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        path_ = (dir_ / "slave.json").string();
    }
    void TearDown() override { fs::remove_all(dir_); }

    void write_file(const std::string& text) const { std::ofstream(path_, std::ios::binary) << text; }
    std::string read_file() const {
        std::ifstream in(path_, std::ios::binary);
        std::stringstream s;
        s << in.rdbuf();
        return s.str();
    }

    fs::path dir_;
    std::string path_;
};

TEST_F(StateFile, RoundTripKeepsEveryWrittenValue) {
    Device before(profile("mmk-2030"), 1);
    Device other(profile("walchem-w600"), 2);
    EXPECT_EQ(ask(before, "06 00 54 FC 19"), "06 00 54 FC 19");
    EXPECT_EQ(ask(before, "05 00 01 FF 00"), "05 00 01 FF 00");
    EXPECT_EQ(ask(other, "10 00 94 00 02 04 00 00 40 E0"), "10 00 94 00 02");
    ASSERT_TRUE(save_state(path_, {&before, &other}).has_value());

    Device after(profile("mmk-2030"), 1);
    Device other_after(profile("walchem-w600"), 2);
    auto loaded = load_state(path_, {&after, &other_after});
    ASSERT_TRUE(loaded.has_value()) << loaded.error();
    EXPECT_EQ(ask(after, "03 00 54 00 01"), "03 02 FC 19");
    EXPECT_EQ(ask(after, "01 00 01 00 01"), "01 01 01");
    EXPECT_EQ(ask(other_after, "03 00 94 00 02"), "03 04 00 00 40 E0");
    EXPECT_EQ(after.image().changes(), before.image().changes());
}

// Only what differs from the initial image is kept: an untouched device saves no table.
// A device moved by a write to its address register (MK ENDER) is still saved as the unit it was made
// with, and after a restart answers at the address written, as a device keeps it in its memory.
TEST_F(StateFile, AWrittenAddressIsKeptAcrossARestart) {
    {
        Device device(profile("mmk-2030"), 1);
        EXPECT_EQ(ask(device, "06 00 07 00 05"), "06 00 07 00 05");
        EXPECT_EQ(ask(device, "06 00 17 00 0A"), "06 00 17 00 0A");
        ASSERT_EQ(device.unit(), 5);
        ASSERT_TRUE(save_state(path_, {&device}).has_value());
    }
    EXPECT_NE(read_file().find("\"1\""), std::string::npos) << read_file();
    Device restarted(profile("mmk-2030"), 1);
    const auto loaded = load_state(path_, {&restarted});
    ASSERT_TRUE(loaded.has_value()) << loaded.error();
    EXPECT_TRUE(loaded->is_null()) << loaded->dump();  // nothing saved for a unit not served
    EXPECT_EQ(restarted.unit(), 5);
    EXPECT_EQ(restarted.configured_unit(), 1);
    EXPECT_EQ(ask(restarted, "03 00 17 00 01"), "03 02 00 0A");
}

TEST_F(StateFile, KeepsOnlyChanges) {
    Device device(profile("cth2265i"), 1);
    ASSERT_TRUE(save_state(path_, {&device}).has_value());
    EXPECT_EQ(read_file(),
              "{\n \"format\": \"mbscope-slave-state/1\",\n \"units\": {\n  \"1\": {\n   \"profile\": "
              "\"cth2265i\"\n  }\n }\n}\n");
}

TEST_F(StateFile, MissingFileIsAFirstStart) {
    Device device(profile("modbus"), 1);
    EXPECT_TRUE(load_state((dir_ / "absent.json").string(), {&device}).has_value());
}

// Written to FILE.tmp and renamed over FILE: the old contents are replaced whole and no .tmp survives.
TEST_F(StateFile, ReplacementIsAtomic) {
    write_file("old contents");
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "06 00 05 00 2A"), "06 00 05 00 2A");
    ASSERT_TRUE(save_state(path_, {&device}).has_value());
    EXPECT_FALSE(fs::exists(path_ + ".tmp"));
    EXPECT_EQ(read_file().find("old contents"), std::string::npos);
    EXPECT_NE(read_file().find("\"5\": 42"), std::string::npos) << read_file();
    std::size_t entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_))
        ++entries;
    EXPECT_EQ(entries, 1u);
}

// A .tmp left by a save that was killed before its rename is not read: the last complete image is.
TEST_F(StateFile, LeftoverTmpFromAnInterruptedSaveIsIgnored) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "06 00 05 00 2A"), "06 00 05 00 2A");
    ASSERT_TRUE(save_state(path_, {&device}).has_value());
    std::ofstream(path_ + ".tmp") << "{\"format\": \"mbscope-slave-st";  // torn write
    Device after(profile("modbus"), 1);
    ASSERT_TRUE(load_state(path_, {&after}).has_value());
    EXPECT_EQ(after.image().reg(Table::HoldingRegisters, 5), 42);
}

TEST_F(StateFile, SaveErrorNamesTheFile) {
    Device device(profile("modbus"), 1);
    const std::string nowhere = (dir_ / "no-such-dir" / "slave.json").string();
    auto saved = save_state(nowhere, {&device});
    ASSERT_FALSE(saved.has_value());
    EXPECT_NE(saved.error().find(nowhere + ".tmp: open"), std::string::npos) << saved.error();
}

struct Damage {
    const char* name;
    std::string contents;
    std::string says;  // part of the error, after the file's name
};

void PrintTo(const Damage& c, std::ostream* os) {
    *os << c.name;
}

class DamagedStateFile : public StateFile, public ::testing::WithParamInterface<Damage> {};

TEST_P(DamagedStateFile, IsRefusedNamingTheFile) {
    write_file(GetParam().contents);
    Device device(profile("mmk-2030"), 1);
    auto loaded = load_state(path_, {&device});
    ASSERT_FALSE(loaded.has_value());
    EXPECT_EQ(loaded.error().rfind(path_ + ": ", 0), 0u) << loaded.error();
    EXPECT_NE(loaded.error().find(GetParam().says), std::string::npos) << loaded.error();
}

INSTANTIATE_TEST_SUITE_P(
    StateFile, DamagedStateFile,
    ::testing::Values(
        Damage{"Truncated", R"({"format": "mbscope-slave-state/1", "units": {"1": {"prof)", "not valid JSON"},
        Damage{"Empty", "", "not valid JSON"},
        Damage{"OtherFormat", R"({"format": "something-else", "units": {}})",
               "not an mbscope slave state file"},
        Damage{"UnitsNotAnObject", R"({"format": "mbscope-slave-state/1", "units": []})",
               "not an mbscope slave state file"},
        // Fields of the wrong type: refused, not thrown (nlohmann's value() throws on a type mismatch).
        Damage{"FormatNotAString", R"({"format": 1, "units": {}})", "not an mbscope slave state file"},
        Damage{"NotAnObject", R"(["mbscope-slave-state/1"])", "not an mbscope slave state file"},
        Damage{"ProfileNotAString", R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": 7}}})",
               "was saved with profile \"?\""},
        Damage{"UnitNotAnObject", R"({"format": "mbscope-slave-state/1", "units": {"1": "mmk-2030"}})",
               "unit 1: not an object of the unit's profile and tables (string)"},
        // A table the slave knows, holding something else than address → value: named for what it is.
        Damage{
            "TableNotAnObject",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": [1, 2]}}})",
            "unit 1 holding_registers: not an object of address → value (array)"},
        Damage{"UnknownTable",
               R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "nope": {}}}})",
               "unknown table \"nope\""},
        // Quoted text from the file is escaped: a damaged file must not drive the terminal.
        Damage{
            "UnknownTableWithAnEscape",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "\u001b[2J": {}}}})",
            "unknown table \"\\x1B[2J\""},
        Damage{"ProfileWithAnEscape",
               R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "\u001b[2J"}}})",
               "was saved with profile \"\\x1B[2J\""},
        Damage{
            "AddressOutOfRange",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"70000": 1}}}})",
            "bad entry"},
        Damage{
            "ValueOutOfRange",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"5": 70000}}}})",
            "bad entry"},
        Damage{
            "NegativeValue",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"5": -1}}}})",
            "bad entry"},
        // 2^32 + 5: read as 32 bits it would be 5 and pass.
        Damage{
            "ValueBeyond32Bits",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"5": 4294967301}}}})",
            "bad entry"},
        // A coil holds 0 or 1; the slave never saves another value for one.
        Damage{
            "CoilNotABit",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "coils": {"1": 2}}}})",
            "unit 1 coils/1: bad entry"},
        Damage{
            "AddressWithASign",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"+5": 1}}}})",
            "bad entry"},
        Damage{
            "AddressNotANumber",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"x5": 1}}}})",
            "bad entry"},
        // What no write could have left: ENDER at 300 where the manual allows 0 to 99 (000:500), a register
        // the map does not have. Loaded before, the slave then answered at an address no MK device takes.
        Damage{
            "AValueNoWriteCouldLeave",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"7": 300}}}})",
            "unit 1 holding_registers/7: 300, which the map does not allow (value 300 above maximum 99)"},
        Damage{
            "AnAddressTheMapDoesNotHave",
            R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030", "holding_registers": {"5000": 1}}}})",
            "unit 1 holding_registers/5000: 1, an address the map of mmk-2030 does not have"}),
    [](const auto& info) { return std::string(info.param.name); });

// A file is applied whole or not at all: the good entries before a bad one are not stored either.
TEST_F(StateFile, RefusedFileChangesNothing) {
    write_file(R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "mmk-2030",)"
               R"( "coils": {"1": 1}, "holding_registers": {"23": 10, "24": -1}}}})");
    Device device(profile("mmk-2030"), 1);
    const auto made = device.image().modifications();
    auto loaded = load_state(path_, {&device});
    ASSERT_FALSE(loaded.has_value());
    EXPECT_NE(loaded.error().find("holding_registers/24: bad entry"), std::string::npos) << loaded.error();
    EXPECT_EQ(device.image().modifications(), made);
    EXPECT_TRUE(device.image().changes().empty());
}

// A state file that exists but cannot be read is an error, not a first start: starting from the initial
// image would overwrite the saved one at the first write.
TEST_F(StateFile, UnreadableFileIsAnError) {
    fs::create_directories(path_);  // a folder where the file should be
    Device device(profile("modbus"), 1);
    auto loaded = load_state(path_, {&device});
    ASSERT_FALSE(loaded.has_value());
    EXPECT_EQ(loaded.error(), path_ + ": not a regular file (a state file is one, written by mbscope slave)");
}

// A fixed value the file contradicts (CTH2265I's 4037 reads 0x55AA, 003:639) is refused; the read-only
// values a process model moved are loaded as saved.
TEST_F(StateFile, AFixedValueTheFileContradictsIsRefused) {
    write_file(R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "cth2265i",)"
               R"( "holding_registers": {"4037": 1234}}}})");
    Device device(profile("cth2265i"), 1);
    auto loaded = load_state(path_, {&device});
    ASSERT_FALSE(loaded.has_value());
    EXPECT_NE(loaded.error().find("unit 1 holding_registers/4037: 1234, where the map fixes 21930"),
              std::string::npos)
        << loaded.error();
    write_file(R"({"format": "mbscope-slave-state/1", "units": {"1": {"profile": "cth2265i",)"
               R"( "holding_registers": {"4000": 1234, "4001": 2}}}})");
    loaded = load_state(path_, {&device});
    ASSERT_TRUE(loaded.has_value()) << loaded.error();
    EXPECT_EQ(ask(device, "03 0F A0 00 02"), "03 04 04 D2 00 02");
}

// state_text is what save_state writes, and apply_state reads it back to the same image.
TEST_F(StateFile, TextHalvesMatchTheFile) {
    Device device(profile("walchem-w600"), 1);
    EXPECT_EQ(ask(device, "10 00 94 00 02 04 00 00 40 E0"), "10 00 94 00 02");
    ASSERT_TRUE(save_state(path_, {&device}).has_value());
    EXPECT_EQ(read_file(), state_text({&device}));
    Device after(profile("walchem-w600"), 1);
    auto applied = apply_state(read_file(), "saved", {&after});
    ASSERT_TRUE(applied.has_value()) << applied.error();
    EXPECT_EQ(after.image().changes(), device.image().changes());
    EXPECT_FALSE(after.image().changes().empty());
}

// A unit saved with one profile and now served with another is refused, naming both.
TEST_F(StateFile, ProfileMismatchIsRefused) {
    Device saved(profile("mmk-2030"), 1);
    EXPECT_EQ(ask(saved, "06 00 17 00 0A"), "06 00 17 00 0A");
    ASSERT_TRUE(save_state(path_, {&saved}).has_value());
    Device now(profile("ty-2090"), 1);
    auto loaded = load_state(path_, {&now});
    ASSERT_FALSE(loaded.has_value());
    EXPECT_EQ(loaded.error(),
              path_ + ": unit 1 was saved with profile \"mmk-2030\", now served as \"ty-2090\"");
    EXPECT_EQ(now.image().reg(Table::HoldingRegisters, 23), 0);
}

// A unit the file holds and this run does not serve is written back as it was saved: serving fewer units
// for a while loses none of the others' values.
TEST_F(StateFile, UnitsNotServedStayInTheFile) {
    Device one(profile("modbus"), 1);
    Device two(profile("mmk-2030"), 2);
    EXPECT_EQ(ask(one, "06 00 00 00 07"), "06 00 00 00 07");
    EXPECT_EQ(ask(two, "06 00 17 00 0A"), "06 00 17 00 0A");
    ASSERT_TRUE(save_state(path_, {&one, &two}).has_value());

    Device alone(profile("modbus"), 1);
    auto loaded = load_state(path_, {&alone});
    ASSERT_TRUE(loaded.has_value()) << loaded.error();
    ASSERT_TRUE(loaded.value().is_object());
    EXPECT_EQ(loaded.value().size(), 1u);
    EXPECT_TRUE(loaded.value().contains("2"));
    EXPECT_EQ(ask(alone, "06 00 01 00 08"), "06 00 01 00 08");
    ASSERT_TRUE(save_state(path_, {&alone}, loaded.value()).has_value());

    Device one_again(profile("modbus"), 1);
    Device two_again(profile("mmk-2030"), 2);
    auto again = load_state(path_, {&one_again, &two_again});
    ASSERT_TRUE(again.has_value()) << again.error();
    EXPECT_TRUE(again.value().is_null());
    EXPECT_EQ(one_again.image().changes(), alone.image().changes());
    EXPECT_EQ(two_again.image().changes(), two.image().changes());
    EXPECT_EQ(two_again.image().reg(Table::HoldingRegisters, 23), 10);
}

// Units are matched by id: a unit the file does not hold starts from the initial image.
TEST_F(StateFile, UnitsAreMatchedById) {
    Device one(profile("modbus"), 1);
    EXPECT_EQ(ask(one, "06 00 00 00 07"), "06 00 00 00 07");
    ASSERT_TRUE(save_state(path_, {&one}).has_value());
    Device two(profile("modbus"), 2);
    ASSERT_TRUE(load_state(path_, {&two}).has_value());
    EXPECT_EQ(two.image().reg(Table::HoldingRegisters, 0), 0);
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_state_file_test
