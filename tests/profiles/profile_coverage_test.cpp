// The bundled device profiles against the manuals they were transcribed from (../shared/seeds):
//  - every profile file loads without error, every model id resolves;
//  - the number of points per section and table equals the rows the manual lists (inventory in
//    ../shared/spec/manual-rules.md §7, recounted from the text), lost rows only as "reconstructed";
//  - every transcribed point's name (and range text) stands on the manual line it cites.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "modbus/storage/profile_store.hpp"

namespace test_profiles_profile_coverage_test {

namespace fs = std::filesystem;
namespace mb = mbscope::modbus;

namespace {

const fs::path profiles_dir = fs::path(MBSCOPE_SOURCE_DIR) / "profiles";
const fs::path seeds_dir = fs::path(MBSCOPE_SOURCE_DIR) / ".." / "shared" / "seeds";

const mb::storage::ProfileStore& store() {
    static const mb::storage::ProfileStore s({profiles_dir.string()});
    return s;
}

// All resolved models of one profile file, loaded once.
const std::vector<mb::Profile>& file_profiles(const std::string& file) {
    static std::map<std::string, std::vector<mb::Profile>> cache;
    auto it = cache.find(file);
    if (it == cache.end()) it = cache.emplace(file, mb::storage::load_profile_file(file).profiles).first;
    return it->second;
}

std::string file_with_prefix(const std::string& dir, const std::string& prefix) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(profiles_dir / dir, ec))
        if (e.path().filename().string().rfind(prefix, 0) == 0) return e.path().string();
    return {};
}

struct Union {
    std::set<std::uint16_t> listed, reconstructed, reserved;
};

Union union_of(const std::vector<mb::Profile>& models, mb::Table table) {
    Union u;
    for (const auto& p : models) {
        if (p.same_as[static_cast<int>(table)]) continue;
        for (const auto& pt : p.table(table)) {
            if (pt.reconstructed)
                u.reconstructed.insert(pt.address);
            else if (pt.reserved)
                u.reserved.insert(pt.address);
            else
                u.listed.insert(pt.address);
        }
    }
    return u;
}

// A manual's lines, read once: the tests look up a line for each of thousands of points.
const std::vector<std::string>& seed_lines(const std::string& prefix) {
    static std::map<std::string, std::vector<std::string>> cache;
    auto it = cache.find(prefix);
    if (it != cache.end()) return it->second;
    std::vector<std::string> lines;
    for (const auto& e : fs::directory_iterator(seeds_dir))
        if (e.path().filename().string().rfind(prefix + "_", 0) == 0) {
            std::ifstream in(e.path());
            for (std::string l; std::getline(in, l);)
                lines.push_back(l);
        }
    return cache[prefix] = lines;
}

// Text as compared: HTML tags, Markdown escapes and all white space removed, lower case (the manual's
// "( <i>i</i> )" and the profile's "(i)" are the same text).
std::string normal(const std::string& s) {
    std::string out;
    bool tag = false;
    for (char c : s) {
        if (c == '<') tag = true;
        if (tag) {
            if (c == '>') tag = false;
            continue;
        }
        if (c == '\\' || c == '*') continue;
        if (c == ' ' || c == '\t') continue;
        out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    return out;
}

// "000:612" → 612; "000:612-615" → 612 and 615 (the end of the span).
int line_of(const std::string& source) {
    if (source.size() < 5) return 0;
    return std::atoi(source.c_str() + 4);
}
int line_of_end(const std::string& source) {
    const int first = line_of(source);
    const auto dash = source.find('-', 4);
    if (dash == std::string::npos) return first;
    const int last = std::atoi(source.c_str() + dash + 1);
    return last >= first && last - first < 40 ? last : first;
}

}  // namespace

TEST(BundledProfiles, LoadWithoutErrors) {
    for (const auto& e : store().errors())
        ADD_FAILURE() << mb::to_string(e);
    EXPECT_FALSE(store().entries().empty());
}

struct MkSection {
    const char* prefix;
    std::size_t registers, registers_lost, coils, coils_blank, coils_lost;
};

// manual-rules.md §7.1, checked against the text: rows with a description, lost rows, blank numbered coil
// rows.
constexpr MkSection mk_sections[] = {
    {"3.08", 111, 0, 74, 5, 0},   {"3.09", 149, 1, 26, 0, 0},   {"3.10", 42, 0, 6, 0, 0},
    {"3.11", 23, 0, 10, 0, 0},    {"3.12", 95, 0, 9, 0, 0},     {"3.13", 124, 0, 84, 4, 0},
    {"3.14", 108, 0, 74, 7, 0},   {"3.15", 107, 0, 71, 5, 0},   {"3.16", 125, 54, 112, 0, 0},
    {"3.17", 123, 0, 79, 0, 0},   {"3.18", 179, 54, 135, 0, 1}, {"3.19", 151, 0, 96, 0, 0},
    {"3.20", 217, 54, 145, 0, 0}, {"3.21", 205, 0, 119, 0, 0},  {"3.22", 124, 0, 64, 5, 0},
    {"3.23", 76, 0, 64, 5, 0},
};

class MkSectionCoverage : public ::testing::TestWithParam<MkSection> {};

TEST_P(MkSectionCoverage, PointCountsMatchTheManualsRows) {
    const auto& s = GetParam();
    const auto file = file_with_prefix("mk", s.prefix);
    ASSERT_FALSE(file.empty()) << "no profile file for MK section " << s.prefix;
    const auto& models = file_profiles(file);
    ASSERT_FALSE(models.empty()) << file;
    const auto regs = union_of(models, mb::Table::HoldingRegisters);
    const auto coils = union_of(models, mb::Table::Coils);
    EXPECT_EQ(regs.listed.size(), s.registers) << file;
    EXPECT_LE(regs.reconstructed.size(), s.registers_lost) << file;
    EXPECT_EQ(coils.listed.size(), s.coils) << file;
    EXPECT_EQ(coils.reserved.size(), s.coils_blank) << file;
    EXPECT_LE(coils.reconstructed.size(), s.coils_lost) << file;
}

INSTANTIATE_TEST_SUITE_P(Manual000, MkSectionCoverage, ::testing::ValuesIn(mk_sections),
                         [](const auto& info) {
                             const std::string prefix = info.param.prefix;  // "3.08" → "Section3_08"
                             return "Section" + prefix.substr(0, 1) + "_" + prefix.substr(2);
                         });

TEST(MkCoverage, TotalsOfTheManual) {
    std::size_t regs = 0, coils = 0, blank = 0;
    for (const auto& s : mk_sections) {
        const auto file = file_with_prefix("mk", s.prefix);
        if (file.empty()) continue;
        regs += union_of(file_profiles(file), mb::Table::HoldingRegisters).listed.size();
        const auto c = union_of(file_profiles(file), mb::Table::Coils);
        coils += c.listed.size();
        blank += c.reserved.size();
    }
    EXPECT_EQ(regs, 1959u);  // manual-rules.md §7.1 Σ
    EXPECT_EQ(coils, 1168u);
    EXPECT_EQ(blank, 31u);
}

TEST(MkCoverage, EveryModelNameResolves) {
    // The 35 model names of file 000 (index 000:25-53 and the section headings).
    for (const char* id :
         {"mmk-2030",     "ty-2090",  "mmk-2030-f", "ty-2090-f",      "mmk-2032",     "dcy-2050",
          "dcy-2051",     "dcy-2058", "dcy-2059",   "mmk-2030-light", "mmk-2030-tot", "mmk-2030-tot-f",
          "dmy-2017",     "dmy-2011", "dmy-2011-f", "dmy-2035",       "dmy-2036",     "mmk-2030-tot-fcs",
          "dmy-2031-fcs", "dmy-2030", "dmy-2032"})
        EXPECT_NE(store().find(id), nullptr) << id;
}

TEST(CthCoverage, RegistersOfTheManual) {
    // manual-rules.md §7.4: 123 holding registers 3999-4121, five reserved reading 0x55AA. And one row that
    // count stops short of, the table's last (003:728, a line without a final newline): BOBINA 0 at 1000,
    // read-only, bits 0, 1, 5 and 6 alarms and 7 the display overflow, the coils 1000-1007 (CTH-COIL-01).
    auto p = store().load("cth2265i");
    ASSERT_TRUE(p.has_value());
    const auto& regs = p->table(mb::Table::HoldingRegisters);
    EXPECT_EQ(regs.size(), 123u);
    const auto& coils = p->table(mb::Table::Coils);
    ASSERT_EQ(coils.size(), 8u);
    for (std::size_t i = 0; i < coils.size(); ++i) {
        EXPECT_EQ(coils[i].address, 1000 + i);
        EXPECT_EQ(coils[i].access, mb::Access::Read) << coils[i].address;
        EXPECT_EQ(coils[i].reserved, i >= 2 && i <= 4) << coils[i].address;
    }
    EXPECT_EQ(coils[7].name_en, "display overflow (bit 7 of coil block 0)");
    int fixed = 0;
    for (const auto& pt : regs)
        fixed += pt.fixed_value == 0x55AA;
    EXPECT_EQ(fixed, 5);
}

TEST(WalchemCoverage, ControllersLoadWithTheirDefaultConfiguration) {
    for (const char* id : {"walchem-w600", "walchem-w900", "walchem-intuition9"}) {
        auto p = store().load(id);
        ASSERT_TRUE(p.has_value()) << id << ": " << mb::to_string(p.error().front());
        EXPECT_FALSE(p->configuration.empty()) << id;
        EXPECT_GT(p->point_count(mb::Table::HoldingRegisters), 100u) << id;
        EXPECT_EQ(p->functions.address_check, mb::AddressCheck::First) << id;
    }
}

// The alternative maps number the objects the configuration installs (002:762-776): with a dual sensor
// card in slot 1 and a dual analog input card in slot 3, sensors 5 and 6 are slot 3's inputs; with a single
// sensor card in slot 2 as well, they are slot 2's and slot 3's inputs become sensors 7 and 8. Each
// alternative point reads its object's own field (Point::same_value_as): the primary value (index 0),
// the status (34), the low alarm (28, a coil too), every one read-only.
TEST(WalchemCoverage, AlternativeMapsNumberTheInstalledObjectsAsTheManualsScenarios) {
    const auto w900 = [](const mb::ProfileConfig& config) {
        auto p = store().load("walchem-w900", config);
        EXPECT_TRUE(p.has_value()) << mb::to_string(p.error().front());
        return std::move(p.value());
    };
    const auto reads = [](const mb::Profile& p, std::uint16_t address) -> std::optional<std::uint16_t> {
        const mb::Point* pt = p.find(mb::Table::HoldingRegisters, address);
        if (!pt || pt->address != address) return std::nullopt;
        EXPECT_EQ(pt->access, mb::Access::Read) << address;
        return pt->same_value_as;
    };
    const auto one = w900({{"slot-1", "dual-sensor"},
                           {"slot-2", "empty"},
                           {"slot-3", "dual-analog-input"},
                           {"slot-4", "empty"}});
    EXPECT_EQ(reads(one, 9216), 1152);          // Sensor 1: Entra S 1-1, x1153
    EXPECT_EQ(reads(one, 9222), 1260);          // Sensor 4: Entra S 1-4, x1261
    EXPECT_EQ(reads(one, 9224), 2304);          // Sensor 5: Entra S 3-1, x2305
    EXPECT_EQ(reads(one, 9226), 2340);          // Sensor 6: Entra S 3-2, x2341
    EXPECT_EQ(reads(one, 9228), std::nullopt);  // no sensor 7
    EXPECT_EQ(reads(one, 9280), 1152 + 34);     // Sensor 1's status
    EXPECT_EQ(reads(one, 9284), 2304 + 34);     // Sensor 5's status
    EXPECT_EQ(reads(one, 9344), 1152 + 28);     // Sensor 1's low alarm
    EXPECT_NE(one.find(mb::Table::Coils, 9344), nullptr);
    const auto* primary = one.find(mb::Table::HoldingRegisters, 9216);
    ASSERT_NE(primary, nullptr);
    EXPECT_EQ(primary->encoding.type, mb::EncodingType::F32);
    EXPECT_EQ(primary->ref, "x9217");
    const auto two = w900({{"slot-1", "dual-sensor"},
                           {"slot-2", "single-sensor"},
                           {"slot-3", "dual-analog-input"},
                           {"slot-4", "empty"}});
    EXPECT_EQ(reads(two, 9224), 1728);  // Sensor 5: Entra S 2-1, x1729
    EXPECT_EQ(reads(two, 9226), 1764);  // Sensor 6: Entra S 2-2, x1765
    EXPECT_EQ(reads(two, 9228), 2304);  // Sensor 7: Entra S 3-1
    EXPECT_EQ(reads(two, 9230), 2340);  // Sensor 8: Entra S 3-2
    // A card no controller file names, and a slot the controller does not have, are errors.
    EXPECT_FALSE(store().load("walchem-w900", {{"slot-2", "no-such-card"}}).has_value());
    EXPECT_FALSE(store().load("walchem-w900", {{"slot-9", "empty"}}).has_value());
}

// A column is served for an object only when the object's map has its field: a digital input's "Tempo
// Total" in state mode, its "Vazão" (the map's "Vazão atual") and "Fluxo total" as a paddlewheel flowmeter
// (002:3108-3112, "Modos de controle"); a relay's state except as a pulse output, its pulse output only as
// one (002:3161).
TEST(WalchemCoverage, AlternativeMapsServeAColumnInTheModesThatHaveIt) {
    auto state = store().load("walchem-w600");
    auto paddle =
        store().load("walchem-w600", {{"di-1", "di-paddlewheel"}, {"relay-1", "pulse-proportional"}});
    ASSERT_TRUE(state.has_value() && paddle.has_value());
    const auto di1 = state->find(mb::Table::HoldingRegisters, 9648);  // x9649: Tempo Total / Fluxo total
    ASSERT_NE(di1, nullptr);
    EXPECT_EQ(di1->encoding.type, mb::EncodingType::U32);
    EXPECT_EQ(state->find(mb::Table::HoldingRegisters, 9616), nullptr);  // x9617 Vazão: not in state mode
    EXPECT_NE(state->find(mb::Table::HoldingRegisters, 9680), nullptr);  // x9681 Estado da DI
    const auto flow = paddle->find(mb::Table::HoldingRegisters, 9648);
    ASSERT_NE(flow, nullptr);
    EXPECT_EQ(flow->encoding.type, mb::EncodingType::F32);
    const auto rate = paddle->find(mb::Table::HoldingRegisters, 9616);
    ASSERT_NE(rate, nullptr);
    const mb::Point* di = paddle->find(mb::Table::HoldingRegisters, *rate->same_value_as);
    ASSERT_NE(di, nullptr);
    EXPECT_NE(di->name.find("Vazão atual"), std::string::npos) << di->name;
    EXPECT_EQ(paddle->find(mb::Table::HoldingRegisters, 9680), nullptr);  // no DI state as a flowmeter
    // A pulse output in delay-output mode names its output "Saída percentual" (002:2710).
    auto delay = store().load("walchem-w600", {{"relay-2", "pulse-delay-output"}});
    ASSERT_TRUE(delay.has_value());
    EXPECT_NE(delay->find(mb::Table::HoldingRegisters, 9794), nullptr);  // x9795 Saída de pulso 2
    EXPECT_NE(state->find(mb::Table::HoldingRegisters, 9600), nullptr);  // x9601 Estado do relé 1
    EXPECT_EQ(state->find(mb::Table::HoldingRegisters, 9792), nullptr);  // x9793 Saída de pulso 1
    EXPECT_EQ(paddle->find(mb::Table::HoldingRegisters, 9600), nullptr);
    EXPECT_NE(paddle->find(mb::Table::HoldingRegisters, 9792), nullptr);
}

// Every map a channel may take loads, on every controller: a configuration naming it gave an error nobody
// saw before (the PID gain's range 0.001-1000 on a pulse output, pulse-pid, refused as "not an integer").
// Each map is taken once per controller, by a channel that allows it, several channels at a time, with the
// channels that share its addresses (exclusive_groups) set to none.
TEST(WalchemCoverage, EveryMapAChannelMayTakeLoads) {
    for (const char* file : {"walchem-w600.json", "walchem-w900.json", "walchem-intuition9.json"}) {
        std::ifstream in(profiles_dir / "walchem" / file);
        ASSERT_TRUE(in) << file;
        const auto device = nlohmann::json::parse(in);
        const std::string id = device["models"][0]["id"];
        std::set<std::string> uncovered;
        for (const auto& ch : device["modular"]["channels"])
            for (const auto& m : ch["maps"])
                if (m != "none") uncovered.insert(m.get<std::string>());
        std::map<std::string, std::vector<std::string>> partners;
        for (const auto& group : device["modular"]["exclusive_groups"])
            for (const auto& a : group)
                for (const auto& b : group)
                    if (a != b) partners[a.get<std::string>()].push_back(b.get<std::string>());
        int rounds = 0;
        while (!uncovered.empty() && ++rounds <= 40) {
            mb::ProfileConfig config;
            for (const auto& ch : device["modular"]["channels"]) {
                const std::string channel = ch["id"];
                if (config.count(channel)) continue;  // set to none as another's partner
                for (const auto& m : ch["maps"]) {
                    if (!uncovered.count(m.get<std::string>())) continue;
                    config[channel] = m.get<std::string>();
                    uncovered.erase(m.get<std::string>());
                    for (const auto& other : partners[channel])
                        config[other] = "none";
                    break;
                }
            }
            std::string named;
            for (const auto& [channel, map] : config)
                named += " " + channel + "=" + map;
            const auto p = store().load(id, config);
            ASSERT_TRUE(p.has_value()) << id << named << ": " << mb::to_string(p.error().front());
            for (const auto& [channel, map] : config) {
                if (map != "none") {
                    EXPECT_EQ(p->configuration.at(channel), map) << id << " " << channel;
                }
            }
        }
        EXPECT_TRUE(uncovered.empty()) << id << ": " << uncovered.size() << " maps no channel took";
    }
}

TEST(WalchemCoverage, TypeMapsMatchTheManualsFieldCounts) {
    // manual-rules.md §7.3: 53 type-specific maps, 821 defined fields, 402 read-only and 419 read/write.
    std::ifstream in(profiles_dir / "walchem" / "type-maps.json");
    ASSERT_TRUE(in) << "profiles/walchem/type-maps.json";
    auto j = nlohmann::json::parse(in);
    std::size_t fields = 0, ro = 0, rw = 0;
    std::map<std::string, std::size_t> by_type;
    for (auto it = j["maps"].begin(); it != j["maps"].end(); ++it) {
        if (it->value("alternative", false)) continue;
        for (const auto& f : (*it)["fields"]) {
            ++fields;
            (f["access"] == "r" ? ro : rw)++;
        }
    }
    EXPECT_EQ(fields, 821u);
    EXPECT_EQ(ro, 402u);
    EXPECT_EQ(rw, 419u);
}

TEST(BundledProfiles, EveryPointStandsOnTheLineItCites) {
    // Field-by-field check of every transcribed point against the manual: the cited line holds the point's
    // name and, where the profile quotes it, its range text. Reconstructed points cite no row of their own.
    std::size_t checked = 0;
    std::vector<std::string> mismatches;
    std::set<std::string> files;
    for (const auto& e : store().entries())
        files.insert(e.file);
    for (const auto& file : files) {
        for (const auto& p : file_profiles(file)) {
            for (auto table : {mb::Table::Coils, mb::Table::HoldingRegisters}) {
                if (p.same_as[static_cast<int>(table)]) continue;
                for (const auto& pt : p.table(table)) {
                    if (pt.reconstructed || pt.source.size() < 5 || pt.source[3] != ':') continue;
                    const std::string prefix = pt.source.substr(0, 3);
                    const auto dash = pt.source.find_first_of("-,; ", 4);
                    const int line = std::atoi(
                        pt.source.substr(4, dash == std::string::npos ? std::string::npos : dash - 4)
                            .c_str());
                    const auto& lines = seed_lines(prefix);
                    ASSERT_FALSE(lines.empty()) << "seed " << prefix << " not found in " << seeds_dir;
                    if (line < 1 || line > static_cast<int>(lines.size())) {
                        mismatches.push_back(file + ": " + pt.source + " is not a line of the manual");
                        continue;
                    }
                    const std::string text = normal(lines[static_cast<std::size_t>(line - 1)]);
                    std::string name = pt.name;
                    if (auto colon = name.find(": ");
                        colon != std::string::npos && p.family.find("walchem") != std::string::npos)
                        name = name.substr(colon + 2);  // modular maps prefix the channel id
                    ++checked;
                    if (text.find(normal(name)) == std::string::npos)
                        mismatches.push_back(file + " " + p.id + " " + std::string(mb::to_string(table)) +
                                             " " + std::to_string(pt.address) + ": name \"" + pt.name +
                                             "\" not on " + pt.source);
                    else if (!pt.range_text.empty() && prefix != "002") {
                        // a model override's range text stands on the footnote it cites
                        const std::string where = pt.range_source.empty() ? pt.source : pt.range_source;
                        std::string lines_text;
                        for (int l = line_of(where);
                             l > 0 && l <= line_of_end(where) && l <= static_cast<int>(lines.size()); ++l)
                            lines_text += normal(lines[static_cast<std::size_t>(l - 1)]);
                        if (lines_text.find(normal(pt.range_text)) == std::string::npos)
                            mismatches.push_back(file + " " + p.id + " " + std::string(mb::to_string(table)) +
                                                 " " + std::to_string(pt.address) + ": range \"" +
                                                 pt.range_text + "\" not on " + where);
                    }
                }
            }
        }
    }
    EXPECT_GT(checked, 3000u);
    for (std::size_t i = 0; i < std::min<std::size_t>(mismatches.size(), 40); ++i)
        ADD_FAILURE() << mismatches[i];
    EXPECT_TRUE(mismatches.empty()) << mismatches.size() << " points do not match their cited line";
}

// Field by field against the cited line, for every transcribed point: what the line says about access and
// encoding must be what the profile says.
//  - MK (000): "Somente leitura" → read-only (unless conditional); a range with a decimal point (0.0 a 25.0)
//  → fixed with that
//    many decimals; a negative lower bound → signed.
//  - CTH2265I (003): the Função column "Leitura" → read-only, "Leitura / Escrita" → read/write.
//  - Walchem (002): "Leitura" → read-only, "Leitura/ Gravação" → read/write; "Flutuante de 32 bits" → f32,
//    "Inteiro de 32 bits" → a 32-bit integer.
TEST(BundledProfiles, AccessAndEncodingAgreeWithTheCitedLine) {
    std::size_t checked = 0;
    std::vector<std::string> mismatches;
    std::set<std::string> files;
    for (const auto& e : store().entries())
        files.insert(e.file);
    for (const auto& file : files) {
        const auto& models = file_profiles(file);
        if (models.empty()) continue;
        const auto& p = models.front();
        for (auto table : {mb::Table::Coils, mb::Table::HoldingRegisters}) {
            if (p.same_as[static_cast<int>(table)]) continue;
            for (const auto& pt : p.table(table)) {
                if (pt.reconstructed || pt.source.size() < 5 || pt.source[3] != ':') continue;
                const std::string prefix = pt.source.substr(0, 3);
                const auto& lines = seed_lines(prefix);
                const int n = line_of(pt.source);
                if (n < 1 || n > static_cast<int>(lines.size())) continue;
                const std::string& raw = lines[static_cast<std::size_t>(n - 1)];
                auto bad = [&](const std::string& what) {
                    mismatches.push_back(file + " " + std::string(mb::to_string(table)) + " " +
                                         std::to_string(pt.address) + ": " + what + " (" + pt.source + ")");
                };
                ++checked;
                using A = mb::Access;
                using E = mb::EncodingType;
                if (prefix == "000" && table == mb::Table::HoldingRegisters) {
                    // "Somente leitura para modo …" / "… se …" is conditional (MK-RO-02): read/write with a
                    // note
                    const auto ro = raw.find("Somente leitura");
                    const bool conditional =
                        ro != std::string::npos &&
                        (raw.compare(ro + 15, 5, " para") == 0 || raw.compare(ro + 15, 4, " se ") == 0);
                    if (ro != std::string::npos && !conditional && pt.access != A::Read)
                        bad("line says read-only");
                    // "0.0 a 25.0": the number of decimals after the point in the range text
                    const auto& rt = pt.range_text;
                    const auto dot = rt.find('.');
                    if (dot != std::string::npos && dot > 0 &&
                        std::isdigit(static_cast<unsigned char>(rt[dot - 1])) && dot + 1 < rt.size() &&
                        std::isdigit(static_cast<unsigned char>(rt[dot + 1]))) {
                        int decimals = 0;
                        for (std::size_t k = dot + 1;
                             k < rt.size() && std::isdigit(static_cast<unsigned char>(rt[k])); ++k)
                            ++decimals;
                        const bool fixed = pt.encoding.type == E::Fixed ||
                                           pt.encoding.type == E::Digits4High ||
                                           pt.encoding.type == E::Digits4Low;
                        if (!fixed || pt.encoding.decimals != decimals)
                            bad("range \"" + rt + "\" has " + std::to_string(decimals) + " fixed decimals");
                    }
                    if (!rt.empty() && rt[0] == '-' && pt.min && *pt.min >= 0)
                        bad("range \"" + rt + "\" is signed");
                }
                if (prefix == "003") {
                    const bool rw = raw.find("Leitura / Escrita") != std::string::npos;
                    if (rw != (pt.access == A::ReadWrite))
                        bad(rw ? "line says read/write" : "line says read-only");
                }
                if (prefix == "002") {
                    const bool rw = raw.find("Grava") != std::string::npos;
                    if (raw.find("Leitura") != std::string::npos && rw != (pt.access != A::Read))
                        bad(rw ? "line says read/write" : "line says read-only");
                    if (raw.find("Flutuante de 32 bits") != std::string::npos && pt.encoding.type != E::F32)
                        bad("line says float32");
                    if (raw.find("Inteiro de 32 bits") != std::string::npos && pt.encoding.type != E::S32 &&
                        pt.encoding.type != E::U32)
                        bad("line says 32-bit integer");
                }
            }
        }
    }
    EXPECT_GT(checked, 4000u);
    for (std::size_t i = 0; i < std::min<std::size_t>(mismatches.size(), 30); ++i)
        ADD_FAILURE() << mismatches[i];
    EXPECT_TRUE(mismatches.empty()) << mismatches.size() << " points disagree with their line";
}

}  // namespace test_profiles_profile_coverage_test
