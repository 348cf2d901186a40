// mbscope profile: list, show, validate, look up and decode with device profiles.
#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "cli/commands.hpp"
#include "cli/json_text.hpp"
#include "cli/profile_json.hpp"
#include "modbus/addressing.hpp"
#include "modbus/describe.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/storage/text_file.hpp"

namespace mbscope::cli {
namespace {

using namespace mbscope::modbus;
using storage::ProfileStore;

struct ProfileOptions {
    std::vector<std::string> dirs;
    std::vector<std::string> config;
    std::string config_file;
    bool json = false;
    std::string id;
    std::string table;
    std::string address;
    std::vector<std::string> words;
    std::vector<std::string> files;
    std::string word_order;
};

// At most `bytes` bytes of `s`, cut before a UTF-8 sequence that would not fit whole: cut by bytes, a
// name or vendor ending in "ç" or "ã" printed half a character.
std::string cut_utf8(const std::string& s, std::size_t bytes) {
    if (s.size() <= bytes) return s;
    std::size_t n = bytes;
    while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80)  // s[n] continues a sequence
        --n;
    return s.substr(0, n);
}

void print_errors(const std::vector<ProfileError>& errors) {
    for (const auto& e : errors)
        std::cerr << "mbscope profile: " << to_string(e) << '\n';
}

std::optional<ProfileConfig> parse_config(const ProfileOptions& o) {
    ProfileConfig config;
    if (!o.config_file.empty()) {
        std::string error;
        const auto text = storage::read_text_file(o.config_file, error);
        if (!text) {
            std::cerr << "mbscope profile: " << o.config_file << ": " << error << '\n';
            return std::nullopt;
        }
        nlohmann::json j;
        try {
            j = nlohmann::json::parse(*text);
        } catch (const nlohmann::json::parse_error& e) {  // says where: line and column
            std::cerr << "mbscope profile: " << o.config_file << ": " << e.what() << '\n';
            return std::nullopt;
        }
        if (!j.is_object()) {
            std::cerr << "mbscope profile: " << o.config_file
                      << ": must be a JSON object {\"CHANNEL\": \"MAP\"}\n";
            return std::nullopt;
        }
        for (const auto& [channel, map] : j.items()) {
            if (!map.is_string()) {
                std::cerr << "mbscope profile: " << o.config_file << ": channel '" << channel
                          << "': the map must be a string\n";
                return std::nullopt;
            }
            config[channel] = map.get<std::string>();
        }
    }
    const auto given = parse_config_options(o.config, "profile");
    if (!given) return std::nullopt;
    for (const auto& [channel, map] : *given)
        config[channel] = map;
    return config;
}

std::optional<Profile> load(const ProfileOptions& o) {
    const auto store = open_profile_store(o.dirs, "profile");
    if (!store) return std::nullopt;
    auto config = parse_config(o);
    if (!config || !config_is_for_a_modular_device(*store, {o.id}, *config, "profile")) return std::nullopt;
    auto p = store->load(o.id, *config);
    if (!p) {
        print_errors(p.error());
        return std::nullopt;
    }
    return std::move(p.value());
}

int run_list(const ProfileOptions& o) {
    // A --profile-dir that is not a directory stops the listing as it stops every other command: listed
    // anyway, the count said "from 2 directories" of the one read.
    if (!extra_profile_dirs_exist(o.dirs, "profile")) return exit_failure;
    ProfileStore store(profile_directories(o.dirs));
    if (o.json) {
        auto a = nlohmann::json::array();
        for (const auto& e : store.entries())
            a.push_back({{"id", e.id},
                         {"name", e.name},
                         {"aliases", e.aliases},
                         {"vendor", e.vendor},
                         {"family", e.family},
                         {"file", e.file},
                         {"transports", e.transports},
                         {"points",
                          {{"coils", e.points->coils},
                           {"discrete_inputs", e.points->discrete_inputs},
                           {"input_registers", e.points->input_registers},
                           {"holding_registers", e.points->holding_registers}}}});
        std::cout << json_text(a) << '\n';
    } else {
        std::printf("%-22s %-14s %-11s %6s %6s  %s\n", "id", "vendor", "transports", "coils", "regs",
                    "aliases");
        for (const auto& e : store.entries()) {
            std::string t, aliases;
            for (const auto& x : e.transports)
                t += (t.empty() ? "" : ",") + x;
            for (const auto& x : e.aliases)
                aliases += (aliases.empty() ? "" : ", ") + x;
            std::printf("%-22s %-14s %-11s %6zu %6zu  %s\n", e.id.c_str(), cut_utf8(e.vendor, 14).c_str(),
                        t.c_str(), e.points->coils, e.points->holding_registers, aliases.c_str());
        }
        std::printf("%zu profiles from %zu directories\n", store.entries().size(),
                    store.directories().size());
    }
    print_errors(store.errors());
    return store.errors().empty() ? exit_ok : exit_findings;
}

std::string range_of(const Point& p) {
    if (!p.range_text.empty()) return p.range_text;
    if (p.min || p.max)
        return (p.min ? std::to_string(*p.min) : "") + ".." + (p.max ? std::to_string(*p.max) : "");
    return "";
}

int run_show(const ProfileOptions& o) {
    auto p = load(o);
    if (!p) return exit_failure;
    if (o.json) {
        std::cout << json_text(profile_to_json(*p)) << '\n';
        return exit_ok;
    }
    std::cout << p->id << " — " << p->vendor << " " << p->name << "  (" << p->file << ")\n";
    if (!p->title.empty()) std::cout << "  " << p->title << '\n';
    std::cout << "  source: " << p->source << '\n';
    std::string t;
    for (const auto& x : p->line.transports)
        t += (t.empty() ? "" : ", ") + x;
    std::cout << "  transports: " << t << "; unit ids " << p->line.unit_min << ".." << p->line.unit_max
              << '\n';
    std::string fcs;
    for (auto fc : p->functions.supported)
        fcs += (fcs.empty() ? "" : " ") + std::to_string(fc);
    std::cout << "  functions: " << fcs << "; max quantity";
    for (const auto& [fc, q] : p->functions.max_quantity)
        std::cout << " FC" << fc << "=" << q;
    std::cout << "; address check: "
              << (p->functions.address_check == AddressCheck::First ? "first address only" : "every address")
              << '\n';
    for (const auto& [ch, map] : p->configuration)
        std::cout << "  config " << ch << " = " << map << '\n';
    for (Table table :
         {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters}) {
        if (!p->implements(table)) continue;
        std::cout << '\n' << to_string(table);
        if (p->same_as[static_cast<int>(table)]) {
            std::cout << ": same map as " << to_string(*p->same_as[static_cast<int>(table)]) << '\n';
            continue;
        }
        std::cout << " (" << p->point_count(table) << " points)\n";
        std::printf("  %5s %-3s %-10s %-44s %s\n", "addr", "acc", "encoding", "name", "range / values");
        for (const auto& pt : p->table(table)) {
            std::string name = pt.name_en.empty() ? pt.name : pt.name_en;
            if (name.size() > 44) name = cut_utf8(name, 43) + "…";
            std::string enc(to_string(pt.encoding.type));
            if (pt.encoding.decimals) enc += "/" + std::to_string(pt.encoding.decimals);
            if (pt.encoding.words == 2) enc += " " + std::string(to_string(pt.encoding.word_order));
            std::string range = range_of(pt);
            if (pt.fixed_value) range += " reads " + hex16(*pt.fixed_value);
            if (!pt.unit.empty()) range += " [" + pt.unit + "]";
            if (pt.reconstructed) range += " (reconstructed)";
            if (pt.reserved) range += " (reserved)";
            std::printf("  %5u %-3s %-10s %-44s %s\n", pt.address, std::string(to_string(pt.access)).c_str(),
                        enc.c_str(), name.c_str(), range.c_str());
        }
    }
    if (!p->notes.empty()) {
        std::cout << "\nnotes:\n";
        for (const auto& n : p->notes)
            std::cout << "  - " << (n.kind.empty() ? "" : "[" + n.kind + "] ") << n.text
                      << (n.source.empty() ? "" : " (" + n.source + ")") << '\n';
    }
    return exit_ok;
}

// A file to validate, and the directory it was found in (empty: named).
struct ToValidate {
    std::string path;
    std::string directory;
};

// What validating one file (or listing one directory) found: a line of the text output, an entry of the JSON.
struct Validated {
    std::string file;
    // "ok", "errors", "not_a_profile", "skipped", "no_json_files"; "unreadable", "not_listed" (exit 2)
    std::string status;
    std::vector<std::string> notes;  // the text output's lines, each after "FILE: "
    std::vector<std::string> errors;
    nlohmann::json profiles = nlohmann::json::array();
};

// Each file named, and for a directory every .json file under it, in name order (`mbscope profile validate
// profiles/` in a CI job). A directory without a .json file is reported, not passed.
std::vector<ToValidate> files_to_validate(const std::vector<std::string>& named,
                                          std::vector<Validated>& out) {
    std::vector<ToValidate> files;
    for (const auto& f : named) {
        std::error_code ec;
        if (!std::filesystem::is_directory(f, ec)) {
            files.push_back({f, {}});
            continue;
        }
        std::vector<std::string> found;
        const auto skip = std::filesystem::directory_options::skip_permission_denied;
        for (std::filesystem::recursive_directory_iterator it(f, skip, ec), end; !ec && it != end;
             it.increment(ec))
            // A *.json that is no regular file (a FIFO) is listed, to be reported as one, not passed over.
            if (std::error_code type; it->path().extension() == ".json" && !it->is_directory(type))
                found.push_back(it->path().string());
        if (ec)
            out.push_back({f, "not_listed", {"cannot list: " + ec.message()}, {}, nlohmann::json::array()});
        else if (found.empty())
            out.push_back(
                {f, "no_json_files", {"no .json file in this directory"}, {}, nlohmann::json::array()});
        std::sort(found.begin(), found.end());
        for (auto& path : found)
            files.push_back({std::move(path), f});
    }
    return files;
}

int run_validate(const ProfileOptions& o) {
    std::vector<Validated> results;
    const auto files = files_to_validate(o.files, results);
    std::size_t documents = 0;  // profile documents among the files, valid or not
    // The ids and aliases each directory's models take: the profile search refuses one name for two devices
    // of a directory (ProfileStore), and so must a check of that directory, in the same words.
    std::map<std::string, storage::DirectoryNames> names;
    for (const auto& [f, directory] : files) {
        const bool found = !directory.empty();
        Validated v{f, "ok", {}, {}, nlohmann::json::array()};
        // A file that is not there or cannot be read is input the run could not read (exit 2, as frame and
        // decode), not a profile found invalid (1); the others are still validated. What is not a regular
        // file is not opened: a FIFO's open waits for a writer, and validate waited for ever.
        std::error_code ec;
        const auto type = std::filesystem::status(f, ec);
        std::string unreadable;
        if (ec)
            unreadable = "cannot read: " + ec.message();
        else if (!std::filesystem::is_regular_file(type))
            unreadable = "not a regular file";
        else if (std::ifstream probe(f, std::ios::binary); !probe)
            unreadable = std::string("cannot read: ") + std::strerror(errno);
        if (!unreadable.empty()) {
            v.status = "unreadable";
            v.notes.push_back(unreadable);
            v.errors.push_back(v.notes.back());
            results.push_back(std::move(v));
            continue;
        }
        auto loaded = storage::load_profile_file(f, parse_config(o).value_or(ProfileConfig{}));
        if (!loaded.is_profile && loaded.errors.empty()) {
            // Named, it was meant as a profile; found beside profiles (a JSON schema, a note), it is passed
            // over as the profile search passes over it.
            v.status = found ? "skipped" : "not_a_profile";
            v.notes.push_back(std::string("not a profile document (no \"format\": \"mbscope-profile/1\")") +
                              (found ? ", skipped" : ""));
            results.push_back(std::move(v));
            continue;
        }
        ++documents;
        if (!loaded.errors.empty()) {
            if (!o.json) print_errors(loaded.errors);
            v.status = "errors";
            v.notes.push_back(std::to_string(loaded.errors.size()) + " error(s)");
            for (const auto& e : loaded.errors)
                v.errors.push_back(to_string(e));
            results.push_back(std::move(v));
            continue;
        }
        std::vector<ProfileError> clashes;
        if (found) {
            auto& here = names.try_emplace(directory, directory).first->second;
            for (const auto& p : loaded.profiles)
                for (auto& problem : here.take(f, p.id, p.aliases).problems)
                    clashes.push_back({f, "", std::move(problem)});
        }
        if (!clashes.empty()) {
            if (!o.json) print_errors(clashes);
            v.status = "errors";
            v.notes.push_back(std::to_string(clashes.size()) + " error(s)");
            for (const auto& e : clashes)
                v.errors.push_back(to_string(e));
            results.push_back(std::move(v));
            continue;
        }
        for (const auto& p : loaded.profiles) {
            const auto coils = p.point_count(Table::Coils);
            const auto holding = p.point_count(Table::HoldingRegisters);
            v.notes.push_back(p.id + " ok (" + std::to_string(coils) + " coils, " + std::to_string(holding) +
                              " holding registers)");
            v.profiles.push_back({{"id", p.id}, {"coils", coils}, {"holding_registers", holding}});
        }
        results.push_back(std::move(v));
    }
    const bool any_failed = std::any_of(results.begin(), results.end(), [](const Validated& v) {
        return v.status != "ok" && v.status != "skipped";
    });
    const bool unread = std::any_of(results.begin(), results.end(), [](const Validated& v) {
        return v.status == "unreadable" || v.status == "not_listed";
    });
    const int rc = unread ? exit_failure : any_failed || documents == 0 ? exit_findings : exit_ok;
    if (o.json) {
        auto list = nlohmann::json::array();
        for (const auto& v : results) {
            nlohmann::json e{{"file", v.file}, {"status", v.status}};
            if (!v.profiles.empty()) e["profiles"] = v.profiles;
            if (!v.errors.empty()) e["errors"] = v.errors;
            list.push_back(std::move(e));
        }
        std::cout << json_text(
                         nlohmann::json{{"files", list}, {"documents", documents}, {"valid", rc == exit_ok}})
                  << '\n';
        return rc;
    }
    for (const auto& v : results)
        for (const auto& note : v.notes)
            std::cout << v.file << ": " << note << '\n';
    if (documents == 0 && !any_failed) std::cout << "no profile document among the files\n";
    return rc;
}

std::optional<Table> table_arg(const std::string& t) {
    auto table = parse_table(t);
    if (!table)
        std::cerr << "mbscope profile: unknown table '" << t << "' (coils, discrete, input, holding)\n";
    return table;
}

std::optional<std::uint16_t> address_arg(const std::string& text) {
    try {
        std::size_t used = 0;
        long v = std::stol(text, &used, 0);
        if (used == text.size() && v >= 0 && v <= 65535) return static_cast<std::uint16_t>(v);
    } catch (...) {
    }
    std::cerr << "mbscope profile: not an address 0..65535: '" << text << "'\n";
    return std::nullopt;
}

int run_lookup(const ProfileOptions& o) {
    auto table = table_arg(o.table);
    auto address = address_arg(o.address);
    if (!table || !address) return exit_failure;
    auto p = load(o);
    if (!p) return exit_failure;
    const Point* pt = p->find(*table, *address);
    // Manuals and HMIs print reference numbers (Walchem's 40001 ...): a number with no point at that protocol
    // address that reads as a reference of the table asked is looked up as the reference, and the output says
    // so. A protocol address in the map stays what it is.
    const auto reference = modbus::parse_reference(o.address);
    const bool of_table = reference && reference->table == *table;
    const std::uint16_t by_reference = of_table ? modbus::to_protocol_address(*reference).value : 0;
    bool read_as_reference = false;
    if (!pt && of_table) {
        pt = p->find(*table, by_reference);
        read_as_reference = pt != nullptr;
    }
    if (!pt) {
        if (o.json) {
            std::cout << json_text(nlohmann::json{{"found", false}}, -1) << '\n';
        } else {
            std::cout << p->id << " " << to_string(*table) << " " << *address << ": not in the device map";
            if (of_table)
                std::cout << " (nor the reference " << o.address << ", protocol address " << by_reference
                          << ")";
            std::cout << '\n';
        }
        return exit_findings;
    }
    if (o.json) {
        auto j = modbus::point_to_json(*pt);
        if (read_as_reference) j["read_as_reference"] = o.address;
        std::cout << json_text(j) << '\n';
        return exit_ok;
    }
    std::cout << p->id << " " << to_string(*table) << " " << pt->address;
    if (read_as_reference)
        std::cout << " (read as the reference " << o.address << ": no point at protocol address " << *address
                  << ")";
    std::cout << (pt->address != (read_as_reference ? by_reference : *address) ? " (second register of)" : "")
              << '\n'
              << "  name      " << pt->name << '\n';
    if (!pt->name_en.empty()) std::cout << "  english   " << pt->name_en << '\n';
    std::cout << "  access    " << to_string(pt->access) << '\n'
              << "  encoding  " << to_string(pt->encoding.type) << '\n';
    if (auto r = range_of(*pt); !r.empty()) std::cout << "  range     " << r << '\n';
    for (const auto& v : pt->encoding.values)
        std::cout << "    " << v.value << " = " << v.text
                  << (v.forbidden ? " (not allowed: refused when written)" : "") << '\n';
    if (!pt->unit.empty()) std::cout << "  unit      " << pt->unit << '\n';
    std::cout << "  source    " << pt->source << '\n';
    // A row the manual does not print, made up from its neighbours: said before anything is taken from it.
    if (pt->reconstructed)
        std::cout << "  reconstructed, not printed in the manual"
                  << (pt->reconstructed_why.empty() ? "" : ": " + pt->reconstructed_why) << '\n';
    for (const auto& n : pt->notes)
        std::cout << "  note      " << n << '\n';
    return exit_ok;
}

int run_decode(const ProfileOptions& o) {
    auto table = table_arg(o.table);
    auto start = address_arg(o.address);
    if (!table || !start) return exit_failure;
    std::vector<std::uint16_t> words;
    for (const auto& w : o.words) {
        try {
            std::size_t used = 0;
            unsigned long v = std::stoul(w, &used, 16);
            if (used != w.size() || v > 0xFFFF) throw std::out_of_range(w);
            words.push_back(static_cast<std::uint16_t>(v));
        } catch (...) {
            std::cerr << "mbscope profile: not a 16-bit hex word: '" << w << "'\n";
            return exit_failure;
        }
    }
    if (std::size_t{*start} + words.size() > 0x10000) {
        std::cerr << "mbscope profile: " << words.size() << " words from address " << *start
                  << " run past the last address, 65535\n";
        return exit_failure;
    }
    auto p = load(o);
    if (!p) return exit_failure;
    if (!o.word_order.empty())
        if (auto why = modbus::set_word_order(*p, *modbus::parse_word_order(o.word_order))) {
            // A manual that fixes the order leaves nothing to choose: the values are read in it and a note
            // says the option was not applied, as `decode --profile` does (analyzer/README.md). An order the
            // device cannot be set to, where its manual lists the ones it can, is a wrong argument.
            if (!p->word_orders.empty()) {
                std::cerr << "mbscope profile: --word-order " << o.word_order << ": " << *why << '\n';
                return exit_failure;
            }
            std::cerr << "mbscope profile: note: --word-order " << o.word_order << " is not applied to "
                      << p->id << ": " << *why << '\n';
        }
    auto values = decode_registers(*p, *table, *start, words);
    // As in lookup: a start that reads as a reference of the table, where no word of the block is a point at
    // the protocol address and some is at the reference's, is read as the reference, and said so.
    const auto any_point = [](const auto& decoded) {
        return std::any_of(decoded.begin(), decoded.end(), [](const auto& v) { return v.point != nullptr; });
    };
    std::optional<std::string> read_as_reference;
    if (const auto reference = modbus::parse_reference(o.address);
        reference && reference->table == *table && !p->open_address_space && !any_point(values)) {
        const std::uint16_t from = modbus::to_protocol_address(*reference).value;
        auto by_reference = std::size_t{from} + words.size() <= 0x10000  // as above: no wrap to register 0
                                ? decode_registers(*p, *table, from, words)
                                : decltype(values){};
        if (any_point(by_reference)) {
            values = std::move(by_reference);
            read_as_reference = o.address;
        }
    }
    if (o.json) {
        auto a = nlohmann::json::array();
        for (const auto& v : values)
            a.push_back(modbus::named_value_to_json(v));
        std::cout << json_text(a) << '\n';
    } else {
        if (read_as_reference)
            std::cout << "  read as the reference " << *read_as_reference << ": no point at protocol address "
                      << *start << " on\n";
        for (const auto& v : values) {
            std::string name =
                v.point ? (v.point->name_en.empty() ? v.point->name : v.point->name_en) : "(not in map)";
            std::printf("  %5u  %-44s %s%s%s\n", v.address, name.c_str(), v.text.c_str(),
                        v.point && !v.point->unit.empty() && v.number ? (" " + v.point->unit).c_str() : "",
                        v.partial ? "  (partial: other half or scale outside the block)" : "");
        }
    }
    bool unknown = false;
    for (const auto& v : values)
        unknown |= v.point == nullptr && !p->open_address_space;
    return unknown ? exit_findings : exit_ok;
}

}  // namespace

void register_profile(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<ProfileOptions>();
    auto* cmd = app.add_subcommand("profile", "Device profiles: list, show, validate, look up, decode");
    cmd->require_subcommand(1);
    cmd->add_option("--profile-dir", o->dirs,
                    "Extra directory of profile files, searched first (repeatable)");
    cmd->footer(
        "Profiles are searched in --profile-dir, then $MBSCOPE_PROFILE_PATH (colon-separated), then the\n"
        "installed profiles; the first directory that defines an id wins. A --profile-dir that is not a\n"
        "directory is an error; a file that cannot be read is warned about when a profile is loaded.\n"
        "Ids and aliases are matched case-insensitively.\n"
        "Exit codes, as for every command: 0 ok; 1 faults found: a profile file with errors (or no profile\n"
        "among the files validated), a point or word not in the device map; 2 the run could not complete:\n"
        "an id or alias no directory defines, an argument that is not a table, address or hex word, a bad\n"
        "--config or --word-order, a --profile-dir that is not a directory, a file to validate that cannot "
        "be\n"
        "read or is not a regular file.");
    auto common = [&](CLI::App* sub) {
        sub->add_flag("--json", o->json, "Machine-readable output");
        sub->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
        sub->add_option("--config-file", o->config_file, "Modular devices: JSON object {channel: map}");
    };
    auto* list = cmd->add_subcommand("list", "Every known profile: id, vendor, transports, point counts");
    list->add_flag("--json", o->json, "Machine-readable output");
    list->callback([o, &exit_code] { exit_code = run_list(*o); });
    auto* show = cmd->add_subcommand("show", "The resolved map of one device, table by table");
    show->add_option("id", o->id, "Device id or alias (e.g. ty-2090, walchem-w900, cth2265i)")->required();
    common(show);
    show->callback([o, &exit_code] { exit_code = run_show(*o); });
    auto* validate =
        cmd->add_subcommand("validate", "Check profile files, reporting every error with its JSON pointer");
    validate
        ->add_option("files", o->files, "Profile files, or directories of them (every .json file under it)")
        ->required();
    common(validate);
    validate->callback([o, &exit_code] { exit_code = run_validate(*o); });
    auto* lookup =
        cmd->add_subcommand("lookup", "What a point is: ID TABLE ADDRESS (0-based protocol address)");
    lookup->add_option("id", o->id)->required();
    lookup->add_option("table", o->table, "coils, discrete, input or holding")->required();
    lookup->add_option("address", o->address)->required();
    common(lookup);
    lookup->callback([o, &exit_code] { exit_code = run_lookup(*o); });
    auto* decode = cmd->add_subcommand("decode", "What raw register values mean: ID TABLE START HEXWORDS...");
    decode->add_option("id", o->id)->required();
    decode->add_option("table", o->table)->required();
    decode->add_option("start", o->address)->required();
    decode->add_option("words", o->words, "Register values in hex, e.g. 022B 0000 0064")->required();
    decode
        ->add_option("--word-order", o->word_order,
                     "The order the device is set to send 32-bit values in, where its manual makes it a "
                     "setting (Walchem's inverse format: abcd)")
        ->check(CLI::IsMember({"abcd", "badc", "cdab", "dcba"}));
    common(decode);
    decode->callback([o, &exit_code] { exit_code = run_decode(*o); });
}

}  // namespace mbscope::cli
