// The header scan a store lists the bundled profiles from: it says what the document parser says of every
// bundled file, and of hostile documents it says what the parser would, or less, never something else.
#include "modbus/profile_headers.hpp"
#include "modbus/profile_loader.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/storage/text_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace test_modbus_profile_headers_test {

namespace mb = mbscope::modbus;
namespace fs = std::filesystem;

namespace {

std::string read(const fs::path& p) {
    std::string error;
    auto text = mb::storage::read_text_file(p.string(), error);
    EXPECT_TRUE(text.has_value()) << p << ": " << error;
    return text.value_or("");
}

mb::IncludeFn sibling(const fs::path& file) {
    return [dir = file.parent_path()](const std::string& name) -> std::optional<std::string> {
        std::string error;
        return mb::storage::read_text_file((dir / name).string(), error);
    };
}

// The headers the document parser gives the same text, for comparison.
void expect_same(const mb::ProfileHeaders& h, const mb::LoadedProfiles& full, const std::string& where) {
    EXPECT_EQ(h.is_profile, full.is_profile) << where;
    ASSERT_EQ(h.models.size(), full.profiles.size()) << where;
    for (std::size_t i = 0; i < h.models.size(); ++i) {
        const auto& p = full.profiles[i];
        EXPECT_EQ(h.models[i].id, p.id) << where;
        EXPECT_EQ(h.models[i].name, p.name) << where;
        EXPECT_EQ(h.models[i].aliases, p.aliases) << where;
        EXPECT_EQ(h.vendor, p.vendor) << where;
        EXPECT_EQ(h.family, p.family) << where;
        EXPECT_EQ(h.transports, p.line.transports) << where;
        EXPECT_EQ(h.modular, p.modular) << where;
    }
}

std::vector<std::string> messages(const std::vector<mb::ProfileError>& errors) {
    std::vector<std::string> out;
    for (const auto& e : errors)
        out.push_back(e.pointer + ": " + e.message);
    return out;
}

// A small profile, varied by replacing one marker.
std::string doc(const std::string& models, const std::string& extra = "") {
    return R"({"format": "mbscope-profile/1", "family": "F", "vendor": "V",)" + extra + R"(
      "line": {"transports": ["rtu", "tcp"]},
      "functions": {"supported": [3]},
      "tables": {"holding_registers": [{"address": 0, "name": "a", "access": "r"}]},
      "models": )" +
           models + "}";
}

}  // namespace

TEST(ProfileHeaders, EveryBundledFileSaysWhatTheParserSays) {
    std::size_t profiles = 0, other = 0;
    for (const auto& entry : fs::recursive_directory_iterator(fs::path(MBSCOPE_SOURCE_DIR) / "profiles")) {
        if (entry.path().extension() != ".json") continue;
        const std::string text = read(entry.path());
        const auto full = mb::parse_profiles(text, entry.path().string(), sibling(entry.path()));
        const auto headers = mb::scan_profile_headers(text, entry.path().string());
        EXPECT_TRUE(full.errors.empty()) << entry.path();
        EXPECT_TRUE(headers.errors.empty()) << entry.path();
        expect_same(headers, full, entry.path().string());
        (headers.is_profile ? profiles : other) += 1;
    }
    EXPECT_GE(profiles, 20u);  // the MK sections, the totalizer, the three Walchem controllers, generic
    EXPECT_GE(other, 2u);      // the schema and the Walchem maps file
}

TEST(ProfileHeaders, ModelsTakeTheirIdAsNameAndLowerCaseAliases) {
    const std::string text = doc(R"([{"id": "ABC-1", "aliases": ["X-One", "y"]},
                                     {"id": "def", "name": ""},
                                     {"id": "ghi", "name": "Ghi 3000"}])");
    const auto h = mb::scan_profile_headers(text, "t.json");
    ASSERT_TRUE(h.errors.empty()) << messages(h.errors)[0];
    ASSERT_EQ(h.models.size(), 3u);
    EXPECT_EQ(h.models[0].id, "abc-1");
    EXPECT_EQ(h.models[0].name, "abc-1");  // no name: the parser takes the id, lower case
    EXPECT_EQ(h.models[0].aliases, (std::vector<std::string>{"x-one", "y"}));
    EXPECT_EQ(h.models[1].name, "");  // a name given, even empty, is the model's
    EXPECT_EQ(h.models[2].name, "Ghi 3000");
    EXPECT_EQ(h.transports, (std::vector<std::string>{"rtu", "tcp"}));
    EXPECT_FALSE(h.modular);
    expect_same(h, mb::parse_profiles(text, "t.json"), "three models");
}

// JSON allows a key twice, and the scan took the last "id" or "aliases" as the parser did; the parser now
// refuses a profile that gives a key twice in one object, and so does the scan in the objects it reads (the
// root, "line", each model), in the same words at the same pointer: a device the listing named would fail to
// load, or be another. A repeat elsewhere is the load's to find, as any fault inside the document.
TEST(ProfileHeaders, AKeyGivenTwiceIsRefusedAsTheParserRefusesIt) {
    const std::vector<std::string> twice{
        doc(R"([{"id": "gone"}, {"id": "one", "id": "two"}])"),
        doc(R"([{"id": "a", "aliases": ["x"], "aliases": ["y"]}])"),
        doc(R"([{"id": "a"}])", R"( "vendor": "W",)"),
        R"({"format": "mbscope-profile/1", "family": "F", "vendor": "V", "line": {"transports": ["rtu"],
            "transports": ["tcp"]}, "models": [{"id": "a"}]})",
        R"({"format": "mbscope-profile/1", "format": "other", "models": [{"id": "a"}]})",
    };
    const std::vector<std::string> expected{
        "/models/1: key \"id\" is given twice: which one counts is not defined",
        "/models/0: key \"aliases\" is given twice: which one counts is not defined",
        ": key \"vendor\" is given twice: which one counts is not defined",
        "/line: key \"transports\" is given twice: which one counts is not defined",
        ": key \"format\" is given twice: which one counts is not defined",
    };
    for (std::size_t i = 0; i < twice.size(); ++i) {
        const auto h = mb::scan_profile_headers(twice[i], "t.json");
        const auto full = mb::parse_profiles(twice[i], "t.json");
        EXPECT_EQ(messages(h.errors), std::vector<std::string>{expected[i]}) << twice[i];
        EXPECT_EQ(messages(full.errors), messages(h.errors)) << twice[i];
        EXPECT_TRUE(h.models.empty()) << twice[i];
        EXPECT_TRUE(h.is_profile) << twice[i];
        for (const auto& e : h.errors)
            EXPECT_EQ(e.file, "t.json");
    }
    const std::string inner =
        doc(R"([{"id": "a"}])", R"( "notes": [{"text": "a"}, {"text": "b", "text": "c"}],)");
    const auto h = mb::scan_profile_headers(inner, "t.json");
    EXPECT_TRUE(h.errors.empty());
    ASSERT_EQ(h.models.size(), 1u);
    EXPECT_EQ(
        messages(mb::parse_profiles(inner, "t.json").errors),
        std::vector<std::string>{"/notes/1: key \"text\" is given twice: which one counts is not defined"});
    // JSON of another kind is no profile, repeats or not: passed over as before.
    const auto other = R"({"$schema": "x", "$schema": "y", "format": "mbscope-walchem-maps/1"})";
    EXPECT_TRUE(mb::scan_profile_headers(other, "s.json").errors.empty());
    EXPECT_TRUE(mb::parse_profiles(other, "s.json").errors.empty());
    EXPECT_FALSE(mb::parse_profiles(other, "s.json").is_profile);
}

// Fields named like the ones read, elsewhere in the document, are not taken for them.
TEST(ProfileHeaders, OnlyTheRootsFieldsAreRead) {
    const std::string text = doc(R"([{"id": "one", "notes": [{"id": "not-a-model", "name": "x"}],
                                      "overrides": {"models": [{"id": "nor-this"}], "aliases": ["z"]}}])",
                                 R"( "simulation": {"vendor": "no", "line": {"transports": ["ascii"]}},)");
    const auto h = mb::scan_profile_headers(text, "t.json");
    ASSERT_EQ(h.models.size(), 1u);
    EXPECT_EQ(h.models[0].id, "one");
    EXPECT_EQ(h.models[0].name, "one");
    EXPECT_TRUE(h.models[0].aliases.empty());
    EXPECT_EQ(h.vendor, "V");
    EXPECT_EQ(h.transports, (std::vector<std::string>{"rtu", "tcp"}));
}

// What the scan finds wrong, the parser finds wrong too, in the same words; the rest waits for the load.
TEST(ProfileHeaders, DocumentFaultsAreSaidAsTheParserSaysThem) {
    const std::vector<std::string> faulty{
        "{\"format\": \"mbscope-profile/1\", \"models\": [",  // cut short
        "[1, 2]",
        R"({"format": 5, "models": [{"id": "a"}]})",
        R"({"format": "mbscope-profile/9", "models": [{"id": "a"}]})",
        doc("[]"),
        doc(R"({"id": "a"})"),
        R"({"format": "mbscope-profile/1", "family": "F", "vendor": "V"})",
        R"({"format": "mbscope-profile/1", "models": [{"id": "a"}], "n": 1e999})",
    };
    for (const auto& text : faulty) {
        const auto h = mb::scan_profile_headers(text, "f.json");
        const auto full = mb::parse_profiles(text, "f.json");
        ASSERT_EQ(h.errors.size(), 1u) << text;
        EXPECT_EQ(h.errors[0].file, "f.json");
        const auto said = messages(full.errors);
        EXPECT_NE(std::find(said.begin(), said.end(), messages(h.errors)[0]), said.end())
            << messages(h.errors)[0] << " is not among the parser's errors of " << text;
        EXPECT_EQ(h.is_profile, full.is_profile) << text;
        EXPECT_TRUE(h.models.empty()) << text;
    }
    // JSON of another kind is no profile and no fault.
    const auto maps =
        mb::scan_profile_headers(R"({"format": "mbscope-walchem-maps/1", "maps": {}})", "m.json");
    EXPECT_FALSE(maps.is_profile);
    EXPECT_TRUE(maps.errors.empty());
    // A fault inside a model is the load's to find: the scan lists the model.
    const auto inner = mb::scan_profile_headers(doc(R"([{"id": "a", "exclude": 7}])"), "i.json");
    EXPECT_TRUE(inner.errors.empty());
    ASSERT_EQ(inner.models.size(), 1u);
}

// The store lists a directory read by headers as one read in full, and resolves a profile when loaded:
// a file broken inside is listed, and its faults are said by the load.
TEST(ProfileHeaders, AStoreReadByHeadersListsWhatAFullReadLists) {
    using mb::storage::ProfileDirectory;
    using mb::storage::ProfileReading;
    const std::string bundled = std::string(MBSCOPE_SOURCE_DIR) + "/profiles";
    const mb::storage::ProfileStore full({bundled});
    const mb::storage::ProfileStore headers(
        std::vector<ProfileDirectory>{{bundled, ProfileReading::headers}});
    EXPECT_TRUE(full.errors().empty());
    EXPECT_TRUE(headers.errors().empty());
    ASSERT_EQ(full.entries().size(), headers.entries().size());
    for (std::size_t i = 0; i < full.entries().size(); ++i) {
        const auto &a = full.entries()[i], &b = headers.entries()[i];
        EXPECT_EQ(a.id, b.id);
        EXPECT_EQ(a.name, b.name);
        EXPECT_EQ(a.aliases, b.aliases);
        EXPECT_EQ(a.vendor, b.vendor);
        EXPECT_EQ(a.family, b.family);
        EXPECT_EQ(a.file, b.file);
        EXPECT_EQ(a.transports, b.transports);
        EXPECT_EQ(a.modular, b.modular);
        EXPECT_TRUE(a.points.has_value());
        EXPECT_FALSE(b.points.has_value());
    }
    const auto walchem = headers.load("walchem-w900");
    ASSERT_TRUE(walchem.has_value());
    EXPECT_TRUE(walchem->modular);

    const fs::path dir = fs::temp_directory_path() / ("mbscope-headers-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    std::ofstream(dir / "broken.json") << doc(R"([{"id": "Broken-One", "exclude": 7}])");
    const mb::storage::ProfileStore lazy(
        std::vector<ProfileDirectory>{{dir.string(), ProfileReading::headers}});
    const mb::storage::ProfileStore eager({dir.string()});
    EXPECT_TRUE(lazy.errors().empty());
    EXPECT_FALSE(eager.errors().empty());
    ASSERT_NE(lazy.find("broken-one"), nullptr);
    const auto loaded = lazy.load("broken-one");
    ASSERT_FALSE(loaded.has_value());
    EXPECT_EQ(messages(loaded.error()), messages(eager.errors()));
    fs::remove_all(dir);
}

}  // namespace test_modbus_profile_headers_test
