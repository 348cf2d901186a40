// `mbscope profile` end to end on a profile directory written for the test.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_profile_command_test {

namespace {

using mbscope::test::run_mbscope;

const std::string fixtures = std::string(MBSCOPE_SOURCE_DIR) + "/tests/fixtures";
const std::string dir = " --profile-dir " + fixtures + "/profiles ";

// An empty directory of the test's own under the system's temporary one.
std::filesystem::path fresh_directory(const std::string& name) {
    namespace fs = std::filesystem;
    const fs::path d = fs::temp_directory_path() / ("mbscope-" + name + "-" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

// The fixture profile with its "models" replaced, written to `path`.
void write_fixture_with_models(const std::filesystem::path& path, const nlohmann::json& models) {
    std::ifstream in(fixtures + "/profiles/test-device.json");
    auto doc = nlohmann::json::parse(in);
    doc["models"] = models;
    std::ofstream(path) << doc.dump(1);
}

}  // namespace

TEST(ProfileCommand, ListShowsTheUsersProfile) {
    auto r = run_mbscope("profile" + dir + "list --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    auto j = nlohmann::json::parse(r.out);
    bool found = false;
    for (const auto& e : j)
        if (e["id"] == "test-device") {
            found = true;
            EXPECT_EQ(e["points"]["holding_registers"], 3);
            EXPECT_EQ(e["aliases"], nlohmann::json::array({"td-1"}));
        }
    EXPECT_TRUE(found) << r.out;
}

TEST(ProfileCommand, EnvironmentPathWorksLikeProfileDir) {
    auto r = run_mbscope("profile list", "MBSCOPE_PROFILE_PATH=" + fixtures + "/profiles");
    EXPECT_NE(r.out.find("test-device"), std::string::npos) << r.out;
}

TEST(ProfileCommand, ShowByAliasAnyCase) {
    auto r = run_mbscope("profile" + dir + "show TD-1");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("holding_registers (3 points)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("input_registers: same map as holding_registers"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("0.0 a 25.0 segundos"), std::string::npos) << r.out;
    auto j = nlohmann::json::parse(run_mbscope("profile" + dir + "show test-device --json").out);
    EXPECT_EQ(j["tables"]["holding_registers"][2]["encoding"]["decimals"], 1);
}

// Manuals print reference numbers (Walchem's 40001 ..., the HMI convention): `lookup ... holding 40024` said
// "not in the device map" of the register the manual calls 40024. A number with no point at that protocol
// address that reads as a reference of the table asked is looked up as the reference, and the output says
// so; a protocol address in the map is still what it is.
TEST(ProfileCommand, LookupAndDecodeReadAReferenceNumberAndSaySo) {
    auto r = run_mbscope("profile" + dir + "lookup test-device holding 40024");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(
        r.out.find("test-device holding_registers 23 (read as the reference 40024: no point at protocol "
                   "address 40024)"),
        std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("Filtro"), std::string::npos);
    auto j = run_mbscope("profile" + dir + "lookup test-device holding 40024 --json");
    ASSERT_EQ(j.exit_code, 0) << j.out;
    EXPECT_EQ(nlohmann::json::parse(j.out)["read_as_reference"], "40024");
    // Another table's reference is not taken for this one's, nor a reference with no point either.
    EXPECT_EQ(run_mbscope("profile" + dir + "lookup test-device input 40024").exit_code, 1);
    // decode takes a reference as lookup does: 40018 is register 17, with its decimal places.
    auto words = run_mbscope("profile" + dir + "decode test-device holding 40018 0002 04D2");
    ASSERT_EQ(words.exit_code, 0) << words.out;
    EXPECT_NE(words.out.find("read as the reference 40018: no point at protocol address 40018 on"),
              std::string::npos)
        << words.out;
    EXPECT_NE(words.out.find("12.34"), std::string::npos) << words.out;
    auto none = run_mbscope("profile" + dir + "lookup test-device holding 40100");
    EXPECT_EQ(none.exit_code, 1);
    EXPECT_NE(none.out.find("not in the device map (nor the reference 40100, protocol address 99)"),
              std::string::npos)
        << none.out;
}

TEST(ProfileCommand, LookupAndDecode) {
    auto r = run_mbscope("profile" + dir + "lookup test-device holding 23");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("Filtro"), std::string::npos);
    EXPECT_EQ(run_mbscope("profile" + dir + "lookup test-device holding 99").exit_code, 1);
    auto d = run_mbscope("profile" + dir + "decode test-device holding 17 0002 04D2 --json");
    ASSERT_EQ(d.exit_code, 0) << d.out;
    auto j = nlohmann::json::parse(d.out);
    EXPECT_EQ(j[1]["text"], "12.34");  // 0x04D2 = 1234 with 2 decimal places from register 17
    EXPECT_EQ(j[1]["unit"], "m3/h");
    EXPECT_EQ(run_mbscope("profile" + dir + "decode test-device holding 17 XYZ").exit_code, 2);
    EXPECT_EQ(run_mbscope("profile" + dir + "decode nosuch holding 0 0000").exit_code, 2);
    // Two words from 65535 would name the second as register 0: refused.
    auto past = run_mbscope("profile" + dir + "decode test-device holding 65535 0001 0002");
    EXPECT_EQ(past.exit_code, 2) << past.out;
    EXPECT_NE(past.out.find("2 words from address 65535 run past the last address, 65535"), std::string::npos)
        << past.out;
}

// Walchem's processor temperature is a float at 42-43 (cdab). Words from 43 began with the float's second
// half, which was not shown at all; a lone half now shows as the raw word, without the unit and, in JSON,
// without a "value" (it said 17096 °C).
TEST(ProfileCommand, DecodeShowsALoneHalfAsARawWord) {
    auto r = run_mbscope("profile decode walchem-w600 holding 43 42C8 0000");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find(
                  "     43  system controller processor temperature      17096 (second half only)  (partial"),
              std::string::npos)
        << r.out;
    EXPECT_NE(
        r.out.find("     44  system network board temperature             0 (first half only)  (partial"),
        std::string::npos)
        << r.out;
    r = run_mbscope("profile decode walchem-w600 holding 43 42C8 0000 --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.size(), 2u);
    EXPECT_EQ(j[0]["address"], 43);
    EXPECT_EQ(j[0]["partial"], true);
    EXPECT_EQ(j[0]["raw"], nlohmann::json::array({0x42C8}));
    EXPECT_FALSE(j[0].contains("value")) << j.dump();
    // From 42 the float is whole: 0x42C80000 = 100 °C.
    r = run_mbscope("profile decode walchem-w600 holding 42 0000 42C8");
    EXPECT_NE(r.out.find("system controller processor temperature      100 °C"), std::string::npos) << r.out;
}

// Walchem's controllers can be set to send 32-bit values most significant word first (the "inverse" format,
// 002:470-477), and the profile lists that order: --word-order reads them so, in profile decode and in
// decode. It was dropped without a word with a profile given, and 1.5 read as 0. A profile whose manual
// fixes the order keeps it and says so.
TEST(ProfileCommand, AWordOrderTheManualMakesASettingIsApplied) {
    auto r = run_mbscope("profile decode walchem-w600 holding 576 3FC0 0000 --word-order abcd");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("sensor-1-1 primary value                     1.5\n"), std::string::npos) << r.out;
    r = run_mbscope("profile decode walchem-w600 holding 576 3FC0 0000 --word-order dcba");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("walchem-w600's manual gives cdab or abcd (the device's setting), not dcba"),
              std::string::npos)
        << r.out;
    const std::string log = ::testing::TempDir() + "walchem-inverse.txt";
    std::ofstream(log) << "1.000 01 03 02 40 00 02 C4 67\n1.020 01 03 04 3F C0 00 00 F6 1B\n";
    r = run_mbscope("decode --profile walchem-w600 --word-order abcd " + log);
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("576  sensor-1-1 primary value = 1.5"), std::string::npos) << r.out;
    // An order the manual does not list is refused by decode as by profile decode: noted, the values were
    // read in the profile's order all the same.
    r = run_mbscope("decode --profile walchem-w600 --word-order dcba " + log);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope decode: --word-order dcba: walchem-w600's manual gives cdab or abcd"),
              std::string::npos)
        << r.out;
    r = run_mbscope("decode --profile cth2265i --word-order abcd " + log);
    EXPECT_NE(r.out.find("note: --word-order abcd is not applied to cth2265i: cth2265i's manual gives its "
                         "32-bit values one order"),
              std::string::npos)
        << r.out;
}

// A map of 16-bit values has nothing to read in another order: said, as for a manual that fixes the order
// (it was dropped without a word). The generic profile maps nothing: its registers are read two at a time
// as a device's without a profile (the floats of `--word-order abcd` disappeared with `--profile modbus`).
TEST(ProfileCommand, AWordOrderIsNeverDroppedWithoutAWord) {
    const std::string log = ::testing::TempDir() + "word-order-generic.txt";
    // FC3 of 2 registers from 0: 0x40490FDB, pi as a float32 in abcd.
    std::ofstream(log) << "1.000 01 03 00 00 00 02 C4 0B\n1.030 01 03 04 40 49 0F DB 7B 8E\n";
    auto r = run_mbscope("decode --word-order abcd " + log);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const auto pi = r.out.find("3.1415927");
    EXPECT_NE(pi, std::string::npos) << r.out;
    r = run_mbscope("decode --profile modbus --word-order abcd " + log);
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("3.1415927"), std::string::npos) << r.out;
    r = run_mbscope("decode --profile mmk-2030 --word-order abcd " + log);
    EXPECT_NE(r.out.find("mbscope decode: note: --word-order abcd is not applied to mmk-2030: mmk-2030's map "
                         "holds no 32-bit value"),
              std::string::npos)
        << r.out;
    r = run_mbscope("profile decode mmk-2030 holding 0 0001 --word-order abcd");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("note: --word-order abcd is not applied to mmk-2030"), std::string::npos) << r.out;
}

TEST(ProfileCommand, ValidateReportsEveryErrorWithPointer) {
    auto r = run_mbscope("profile validate " + fixtures + "/broken/broken.json");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.out.find("broken.json: /tables/holding_registers/1/access: must be r, w or rw"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("/tables/holding_registers/2: missing \"source\""), std::string::npos) << r.out;
    auto ok = run_mbscope("profile validate " + fixtures + "/profiles/test-device.json");
    EXPECT_EQ(ok.exit_code, 0) << ok.out;
}

// A CI job validates a directory of profiles: every .json file under it, a broken one failing the run;
// JSON that is no profile (a schema beside them) is passed over, but a run that found no profile at all
// fails. A directory named as a file said "read error".
TEST(ProfileCommand, ValidateADirectoryChecksEveryProfileUnderIt) {
    const auto all = run_mbscope("profile validate " + fixtures);
    EXPECT_EQ(all.exit_code, 1) << all.out;
    EXPECT_NE(all.out.find("/tables/holding_registers/1/access: must be r, w or rw"), std::string::npos)
        << all.out;
    EXPECT_NE(all.out.find("test-device.json: test-device ok"), std::string::npos) << all.out;

    const auto bundled = run_mbscope("profile validate " + std::string(MBSCOPE_SOURCE_DIR) + "/profiles");
    EXPECT_EQ(bundled.exit_code, 0) << bundled.out;
    EXPECT_NE(bundled.out.find("profile.schema.json: not a profile document"), std::string::npos)
        << bundled.out;
    EXPECT_NE(bundled.out.find("walchem-w600.json: walchem-w600 ok"), std::string::npos) << bundled.out;

    const auto schema_only =
        run_mbscope("profile validate " + std::string(MBSCOPE_SOURCE_DIR) + "/profiles/schema");
    EXPECT_EQ(schema_only.exit_code, 1) << schema_only.out;
    EXPECT_NE(schema_only.out.find("no profile document among the files"), std::string::npos)
        << schema_only.out;

    const auto frames = run_mbscope("frame --file " + fixtures);
    EXPECT_EQ(frames.exit_code, 2) << frames.out;
    EXPECT_NE(frames.out.find(fixtures + ": is a directory, not a file"), std::string::npos) << frames.out;
}

// The profile search finds a device by its id in lower case, and keeps the first file of a directory that
// defines it: a directory whose second file took an id again ("Dup" after "dup"), a file with two models of
// one id, and an empty id were each "ok" to validate while the search passed over them without a word.
TEST(ProfileCommand, ValidateRefusesADeviceIdTheProfileSearchCouldNotFind) {
    namespace fs = std::filesystem;
    const fs::path d = fresh_directory("validate-ids");
    const auto write = [&](const std::string& name, const nlohmann::json& models) {
        write_fixture_with_models(d / name, models);
    };
    write("a.json", {{{"id", "dup"}, {"name", "first"}}});
    write("b.json", {{{"id", "Dup"}, {"name", "second"}}});
    write("c.json", {{{"id", "two"}, {"name", "x"}}, {{"id", "TWO"}, {"name", "y"}}});
    write("e.json", {{{"id", ""}, {"name", "nameless"}}});

    const auto r = run_mbscope("profile validate " + d.string());
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("a.json: dup ok"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find((d / "b.json").string() + ": device id \"dup\" is defined twice in " + d.string() +
                         " (first in " + (d / "a.json").string() + "): the profile search keeps the first"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("c.json: /models/1/id: device id \"two\" is also /models/0's (ids are compared in "
                         "lower case)"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("e.json: /models/0/id: a device id cannot be empty"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("b.json: dup ok"), std::string::npos) << r.out;

    const auto j =
        nlohmann::json::parse(run_mbscope("profile validate --json " + d.string()).out, nullptr, false);
    ASSERT_FALSE(j.is_discarded());
    ASSERT_EQ(j["files"].size(), 4u);
    EXPECT_EQ(j["files"][0]["status"], "ok");
    for (std::size_t i = 1; i < 4; ++i)
        EXPECT_EQ(j["files"][i]["status"], "errors") << j["files"][i].dump();
    EXPECT_EQ(j["valid"], false);

    // Named one by one, the files are not one directory's: each is validated on its own.
    const auto named =
        run_mbscope("profile validate " + (d / "a.json").string() + " " + (d / "b.json").string());
    EXPECT_EQ(named.exit_code, 0) << named.out;
    fs::remove_all(d);
}

// `validate --json`, which its help lists, printed the text lines: a CI job parsing them failed. Each file
// is an entry with its status and what it holds or why it is refused; `valid` is the exit code's verdict.
// A file to validate that is not there is input the run could not read: exit 2, as frame and decode, the
// others still validated (it was "1 error(s)", exit 1, as a profile found invalid). An empty file is read and
// is no valid profile: exit 1.
TEST(ProfileCommand, ValidateAFileThatCannotBeReadExitsTwo) {
    auto r = run_mbscope("profile validate /nonexistent/x.json " + std::string(MBSCOPE_SOURCE_DIR) +
                         "/profiles/cth2265i.json");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("/nonexistent/x.json: cannot read: No such file or directory"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("cth2265i ok"), std::string::npos) << r.out;
    r = run_mbscope("profile validate --json /nonexistent/x.json 2>/dev/null");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    const auto j = nlohmann::json::parse(r.out, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << r.out;
    EXPECT_EQ(j["files"][0]["status"], "unreadable");
    EXPECT_EQ(j["valid"], false);
    const std::string empty = ::testing::TempDir() + "empty-profile.json";
    std::ofstream{empty};
    EXPECT_EQ(run_mbscope("profile validate " + empty).exit_code, 1);
}

TEST(ProfileCommand, ValidateJsonIsJson) {
    const auto r = run_mbscope("profile validate --json " + fixtures + "/broken/broken.json " + fixtures +
                               "/profiles/test-device.json");
    EXPECT_EQ(r.exit_code, 1) << r.out;
    const auto j = nlohmann::json::parse(r.out);  // throws on text
    EXPECT_FALSE(j["valid"].get<bool>());
    EXPECT_EQ(j["documents"], 2);
    ASSERT_EQ(j["files"].size(), 2u);
    EXPECT_EQ(j["files"][0]["status"], "errors");
    bool pointer = false;
    for (const auto& e : j["files"][0]["errors"])
        pointer |= e.get<std::string>().find("/tables/holding_registers/1/access: must be r, w or rw") !=
                   std::string::npos;
    EXPECT_TRUE(pointer) << j.dump();
    EXPECT_EQ(j["files"][1]["status"], "ok");
    EXPECT_EQ(j["files"][1]["profiles"][0]["id"], "test-device");

    const auto ok = run_mbscope("profile validate --json " + std::string(MBSCOPE_SOURCE_DIR) + "/profiles");
    EXPECT_EQ(ok.exit_code, 0) << ok.out;
    const auto bundled = nlohmann::json::parse(ok.out);
    EXPECT_TRUE(bundled["valid"].get<bool>());
    bool schema_skipped = false;
    for (const auto& f : bundled["files"])
        schema_skipped |= f["status"] == "skipped";
    EXPECT_TRUE(schema_skipped) << "the schema beside the profiles is passed over";
}

TEST(ProfileCommand, HelpOnEverySubcommand) {
    for (const char* sub : {"", " list", " show", " validate", " lookup", " decode"})
        EXPECT_EQ(run_mbscope(std::string("profile") + sub + " --help").exit_code, 0) << sub;
}

TEST(ProfileCommand, ABadConfigFileIsNamedWithWhatIsWrong) {
    const std::string path = ::testing::TempDir() + "profile_command_config.json";
    const auto with_config = [&](const std::string& text) {
        FILE* f = std::fopen(path.c_str(), "w");
        std::fputs(text.c_str(), f);
        std::fclose(f);
        return run_mbscope("profile" + dir + "show test-device --config-file " + path);
    };
    auto r = run_mbscope("profile" + dir + "show test-device --config-file /nonexistent/config.json");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find("/nonexistent/config.json: cannot open"), std::string::npos) << r.out;
    r = with_config("{\"1\": ");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find(path + ": [json.exception.parse_error.101] parse error at line 1"),
              std::string::npos)
        << r.out;
    r = with_config("[\"pH\"]");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find(path + ": must be a JSON object"), std::string::npos) << r.out;
    r = with_config("{\"1\": 3}");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find(path + ": channel '1': the map must be a string"), std::string::npos) << r.out;
}

// A --profile-dir that is not a directory stops the command: a mistyped one would otherwise leave the bundled
// profiles to answer. A file in the directories that cannot be read is warned about, once, with its first
// problem, even when the profile asked for comes from elsewhere: it may be the user's broken copy of it.
TEST(ProfileCommand, AMissingProfileDirStopsAndABrokenFileIsWarnedAbout) {
    auto r = run_mbscope("profile --profile-dir /nonexistent/profiles show mmk-2030");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope profile: --profile-dir '/nonexistent/profiles': not a directory"),
              std::string::npos)
        << r.out;
    // list too: it listed the bundled profiles "from 2 directories" and exited 1.
    r = run_mbscope("profile --profile-dir /nonexistent/profiles list");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope profile: --profile-dir '/nonexistent/profiles': not a directory"),
              std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("profiles from"), std::string::npos) << r.out;
    r = run_mbscope("decode --profile-dir /nonexistent/profiles --profile mmk-2030 " +
                    std::string(MBSCOPE_SOURCE_DIR) + "/captures/pymodbus-socat-rtu.log");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("mbscope decode: --profile-dir"), std::string::npos) << r.out;

    r = run_mbscope("profile --profile-dir " + fixtures + "/broken show mmk-2030");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("mbscope profile: warning: " + fixtures +
                         "/broken/broken.json: /tables/holding_registers/1/access: must be r, w or rw (and "),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("mbscope profile validate " + fixtures + "/broken/broken.json lists them)"),
              std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("warning", r.out.find("warning") + 1), std::string::npos) << "once: " << r.out;
}

// --config chooses the maps of a modular device's channels; given for devices that have none (or with no
// device at all) it would be dropped without a word, so it is refused.
TEST(ProfileCommand, AConfigurationForADeviceWithoutChannelsIsRefused) {
    auto r = run_mbscope("profile" + dir + "show test-device --config sensor-1-1=flow");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("--config 'sensor-1-1': test-device has no modular channels to configure"),
              std::string::npos)
        << r.out;
    const std::string capture = " " + std::string(MBSCOPE_SOURCE_DIR) + "/captures/suricata-modbus.pcap";
    r = run_mbscope("decode --summary --config sensor-1-1=flow" + capture);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("--config configures a device given with --profile or --map"), std::string::npos)
        << r.out;
    r = run_mbscope("decode --summary --profile mmk-2030 --config sensor-1-1=flow" + capture);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    // One modular device among those given is enough: the channels are its own.
    r = run_mbscope("decode --summary --map 1=walchem-w600 --map 2=mmk-2030 --config sensor-1-1=sensor" +
                    capture);
    EXPECT_NE(r.exit_code, 2) << r.out;
}

// list and show cut long vendors and names to their columns by bytes, which split a character ("ç" is two
// bytes): the cut falls before it, and what is printed is still UTF-8.
TEST(ProfileCommand, LongNamesAreCutBetweenCharacters) {
    const auto utf8 = [](const std::string& s) {
        for (std::size_t i = 0; i < s.size();) {
            const auto c = static_cast<unsigned char>(s[i]);
            const std::size_t n = c < 0x80             ? 1
                                  : (c & 0xE0) == 0xC0 ? 2
                                  : (c & 0xF0) == 0xE0 ? 3
                                  : (c & 0xF8) == 0xF0 ? 4
                                                       : 0;
            if (n == 0 || i + n > s.size()) return false;
            for (std::size_t k = 1; k < n; ++k)
                if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return false;
            i += n;
        }
        return true;
    };
    const std::string profiles = ::testing::TempDir() + "utf8-profiles";
    std::filesystem::create_directories(profiles);
    // The vendor's 14th and 15th bytes are "õ"; the name's 43rd and 44th are "ç".
    std::ofstream(profiles + "/utf8.json")
        << R"({"format": "mbscope-profile/1", "family": "u", "vendor": "Instrumentaçõe",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 1, "access": "r", "source": "1",
        "name": "Temperatura do canal de entrada um na posiçãoX de leitura"}]},
      "models": [{"id": "utf8-device"}]})";
    auto r = run_mbscope("profile --profile-dir " + profiles + " list");
    EXPECT_NE(r.out.find("utf8-device            Instrumentaç "), std::string::npos) << r.out;
    EXPECT_TRUE(utf8(r.out)) << r.out;
    r = run_mbscope("profile --profile-dir " + profiles + " show utf8-device");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("Temperatura do canal de entrada um na posi…"), std::string::npos) << r.out;
    EXPECT_TRUE(utf8(r.out)) << r.out;
}

// A file name is the user's bytes, and need not be UTF-8: validate, list and show with --json aborted (exit
// 134, nlohmann's type_error.316 "invalid UTF-8 byte") over a copy of a bundled profile named "c\xFFth.json".
// Each prints its JSON whole, the byte that is not UTF-8 replaced (U+FFFD).
TEST(ProfileCommand, JsonOutputTakesAFileNameThatIsNotUtf8) {
    namespace fs = std::filesystem;
    const fs::path d = fresh_directory("not-utf8");
    const fs::path copy = d / "c\xFFth.json";
    fs::copy_file(fs::path(MBSCOPE_SOURCE_DIR) / "profiles" / "cth2265i.json", copy);
    const std::string shown = (d / "c\xEF\xBF\xBDth.json").string();  // U+FFFD in place of 0xFF
    const auto parsed = [](const mbscope::test::CliRun& r) {
        return nlohmann::json::parse(r.out, nullptr, false);
    };

    const auto validated = run_mbscope("profile validate --json '" + copy.string() + "' 2>/dev/null");
    EXPECT_EQ(validated.exit_code, 0) << validated.out;
    const auto v = parsed(validated);
    ASSERT_FALSE(v.is_discarded()) << validated.out;
    EXPECT_EQ(v["files"][0]["file"], shown);
    EXPECT_EQ(v["files"][0]["status"], "ok");

    const std::string in_dir = "profile --profile-dir " + d.string() + " ";
    const auto listed = run_mbscope(in_dir + "list --json 2>/dev/null");
    EXPECT_EQ(listed.exit_code, 0) << listed.out;
    const auto l = parsed(listed);
    ASSERT_FALSE(l.is_discarded()) << listed.out;
    bool found = false;
    for (const auto& e : l)
        found |= e["id"] == "cth2265i" && e["file"] == shown;
    EXPECT_TRUE(found) << listed.out;

    const auto shown_profile = run_mbscope(in_dir + "show cth2265i --json 2>/dev/null");
    EXPECT_EQ(shown_profile.exit_code, 0) << shown_profile.out;
    const auto s = parsed(shown_profile);
    ASSERT_FALSE(s.is_discarded()) << shown_profile.out;
    EXPECT_EQ(s["file"], shown);
    EXPECT_FALSE(s["tables"]["holding_registers"].empty());
    fs::remove_all(d);
}

// A model's alias equal to another model's id hid that model from the profile search while validate said
// "ok": validate compared ids with ids only. A name that one directory gives two models is an error naming
// both files, and the id is the one the search finds.
TEST(ProfileCommand, AnAliasThatIsAnotherModelsIdIsAnError) {
    namespace fs = std::filesystem;
    const fs::path d = fresh_directory("validate-aliases");
    const auto write = [&](const std::string& name, const nlohmann::json& models) {
        write_fixture_with_models(d / name, models);
    };
    write("a.json", {{{"id", "aaa"}, {"name", "A"}, {"aliases", {"bbb"}}}});
    write("b.json", {{{"id", "bbb"}, {"name", "B"}}});
    auto r = run_mbscope("profile validate " + d.string());
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find((d / "b.json").string() + ": device id \"bbb\" is also an alias of \"aaa\" in " +
                         (d / "a.json").string() + ": the profile search finds the id by it, not \"aaa\""),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("a.json: aaa ok"), std::string::npos) << r.out;
    r = run_mbscope("profile --profile-dir " + d.string() + " show bbb");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("bbb — Test Vendor B"), std::string::npos) << r.out;
    // Standard output alone: the command's 2>&1 applies to cat.
    r = run_mbscope("profile --profile-dir " + d.string() + " list --json 2>/dev/null | cat");
    const auto listed = nlohmann::json::parse(r.out, nullptr, false);
    ASSERT_FALSE(listed.is_discarded()) << r.out;
    std::set<std::string> ids;
    for (const auto& e : listed)
        ids.insert(e["id"].get<std::string>());
    EXPECT_EQ(ids.count("aaa"), 1u);
    EXPECT_EQ(ids.count("bbb"), 1u);
    // Across directories: a user's alias "cth2265i" hid the bundled cth2265i. The id is found.
    fresh_directory("validate-aliases");
    write("mine.json", {{{"id", "my-meter"}, {"name", "Mine"}, {"aliases", {"cth2265i"}}}});
    r = run_mbscope("profile --profile-dir " + d.string() + " show cth2265i");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(r.out.rfind("cth2265i — CTH", 0), 0u) << r.out;
    fs::remove_all(d);
}

// A FIFO opened for reading waits for a writer: `profile validate` of one never returned, and one among a
// directory's files was passed over without a word, by validate and by the profile search. A path that is
// not a regular file is said to be one, and not read: input the run could not read (exit 2) for validate,
// a warning for the search.
TEST(ProfileCommand, AFileThatIsNotARegularFileIsSaidNotWaitedFor) {
    namespace fs = std::filesystem;
    const fs::path d = fresh_directory("validate-fifo");
    fs::copy_file(fixtures + "/profiles/test-device.json", d / "a.json");
    ASSERT_EQ(::mkfifo((d / "pipe.json").c_str(), 0600), 0);
    const std::string limit = "timeout 20";  // the run waited for ever: 124 when it still does
    auto r = run_mbscope("profile validate " + (d / "pipe.json").string(), limit);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find((d / "pipe.json").string() + ": not a regular file"), std::string::npos) << r.out;
    r = run_mbscope("profile validate " + d.string(), limit);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find((d / "pipe.json").string() + ": not a regular file"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("a.json: test-device ok"), std::string::npos) << r.out;
    r = run_mbscope("profile validate --json /dev/null", limit);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("not a regular file"), std::string::npos) << r.out;
    r = run_mbscope("profile --profile-dir " + d.string() + " list", limit);
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("mbscope profile: " + (d / "pipe.json").string() + ": not a regular file"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("test-device"), std::string::npos) << r.out;
    fs::remove_all(d);
}

// The help said "1 something is missing or invalid, 2 could not run" while an unknown id or table exited 2;
// README.md's convention, the same for every subcommand, is that 2 is a run that could not complete, and the
// tests hold the commands to it. The help says which is which.
TEST(ProfileCommand, TheHelpGivesTheExitCodesTheCommandsUse) {
    const auto help = run_mbscope("profile --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_EQ(help.out.find("1 something is missing or invalid"), std::string::npos) << help.out;
    EXPECT_NE(help.out.find("1 faults found"), std::string::npos) << help.out;
    EXPECT_NE(help.out.find("2 the run could not complete"), std::string::npos) << help.out;
    EXPECT_NE(help.out.find("an id or alias no directory defines"), std::string::npos) << help.out;
    EXPECT_EQ(run_mbscope("profile show nope").exit_code, 2);
    EXPECT_EQ(run_mbscope("profile decode mmk-2030 bogus 0 0001").exit_code, 2);
    EXPECT_EQ(run_mbscope("profile lookup mmk-2030 holding 9999").exit_code, 1);
}

// analyzer/README.md: a profile whose manual fixes the 32-bit order keeps it under --word-order, with a note
// on standard error, in `decode` and `profile decode` alike. `profile decode` stopped instead (exit 2, no
// values); it now says the note and decodes in the profile's order.
TEST(ProfileCommand, AWordOrderTheManualFixesIsKeptWithANote) {
    const std::string words = "profile decode cth2265i holding 4012 0001 0000";
    const auto plain = run_mbscope(words);
    ASSERT_EQ(plain.exit_code, 0) << plain.out;
    const auto stdout_only = run_mbscope(words + " --word-order abcd 2>/dev/null | cat");
    EXPECT_EQ(stdout_only.out, plain.out);
    const auto r = run_mbscope(words + " --word-order abcd");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("mbscope profile: note: --word-order abcd is not applied to cth2265i: cth2265i's "
                         "manual gives its 32-bit values one order"),
              std::string::npos)
        << r.out;
}

}  // namespace test_cli_profile_command_test
