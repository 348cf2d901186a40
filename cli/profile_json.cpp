#include "cli/profile_json.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "modbus/frame_text.hpp"  // printable(), quote_excerpt()
#include "modbus/storage/profile_store.hpp"

namespace mbscope::cli {

using namespace mbscope::modbus;
using json = nlohmann::json;

json profile_to_json(const Profile& p) {
    json j{{"id", p.id},         {"name", p.name},   {"aliases", p.aliases}, {"family", p.family},
           {"vendor", p.vendor}, {"title", p.title}, {"file", p.file},       {"source", p.source}};
    j["line"] = {{"transports", p.line.transports},
                 {"baud_rates", p.line.baud_rates},
                 {"parity", p.line.parity},
                 {"data_bits", p.line.data_bits},
                 {"stop_bits", p.line.stop_bits},
                 {"unit_id",
                  {{"min", p.line.unit_min}, {"max", p.line.unit_max}, {"disabled", p.line.unit_disabled}}}};
    j["functions"] = {
        {"supported", p.functions.supported},
        {"max_quantity", p.functions.max_quantity},
        {"broadcast", p.functions.broadcast},
        {"diagnostics", p.functions.diagnostics},
        {"address_check", p.functions.address_check == AddressCheck::First ? "first" : "every"}};
    if (!p.configuration.empty()) j["configuration"] = p.configuration;
    for (Table t : {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters}) {
        if (!p.implements(t)) continue;
        const std::string name(to_string(t));
        if (auto s = p.same_as[static_cast<int>(t)]) {
            j["tables"][name] = {{"same_as", std::string(to_string(*s))}};
            continue;
        }
        j["tables"][name] = json::array();
        for (const auto& pt : p.table(t))
            j["tables"][name].push_back(modbus::point_to_json(pt));
    }
    for (const auto& n : p.notes)
        j["notes"].push_back({{"text", n.text}, {"source", n.source}, {"kind", n.kind}});
    return j;
}

std::vector<std::string> profile_directories(const std::vector<std::string>& extra) {
    namespace fs = std::filesystem;
    std::vector<std::string> dirs = extra;
    if (const char* env = std::getenv("MBSCOPE_PROFILE_PATH"))
        for (auto& d : storage::split_path_list(env))
            dirs.push_back(d);
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    const fs::path installed = exe.parent_path().parent_path() / "share" / "mbscope" / "profiles";
    if (!ec && fs::is_directory(installed, ec))
        dirs.push_back(installed.string());
    else
        dirs.push_back(MBSCOPE_SOURCE_PROFILES);
    return dirs;
}

bool extra_profile_dirs_exist(const std::vector<std::string>& extra, const char* command) {
    for (const auto& dir : extra) {
        std::error_code ec;
        if (!std::filesystem::is_directory(dir, ec)) {
            std::cerr << "mbscope " << command << ": --profile-dir " << modbus::quote_excerpt(dir)
                      << ": not a directory\n";
            return false;
        }
    }
    return true;
}

std::optional<storage::ProfileStore> open_profile_store(const std::vector<std::string>& extra,
                                                        const char* command) {
    if (!extra_profile_dirs_exist(extra, command)) return std::nullopt;
    // The bundled profiles (the last directory) are read only as far as a listing needs, and resolved when
    // named: resolving all of them took most of each command's start-up. A user's directories are read in
    // full, so a broken file of theirs is said at once.
    std::vector<storage::ProfileDirectory> dirs;
    for (auto& path : profile_directories(extra))
        dirs.push_back({std::move(path), storage::ProfileReading::full});
    dirs.back().reading = storage::ProfileReading::headers;
    storage::ProfileStore store(std::move(dirs));
    const auto& errors = store.errors();
    for (std::size_t i = 0; i < errors.size();) {
        std::size_t j = i + 1;
        while (j < errors.size() && errors[j].file == errors[i].file)
            ++j;
        std::cerr << "mbscope " << command << ": warning: " << modbus::to_string(errors[i]);
        if (j - i > 1)
            std::cerr << " (and " << j - i - 1 << " more; mbscope profile validate "
                      << modbus::printable(errors[i].file) << " lists them)";
        std::cerr << '\n';
        i = j;
    }
    return store;
}

bool config_is_for_a_modular_device(const storage::ProfileStore& store, const std::vector<std::string>& ids,
                                    const ProfileConfig& config, const char* command) {
    if (config.empty()) return true;
    std::string known;
    for (const auto& id : ids) {
        const auto* e = store.find(id);
        if (!e) return true;  // the load names the unknown id
        if (e->modular) return true;
        known += (known.empty() ? "" : ", ") + e->id;
    }
    std::cerr << "mbscope " << command << ": --config " << modbus::quote_excerpt(config.begin()->first)
              << ": " << known << " has no modular channels to configure\n";
    return false;
}

std::optional<modbus::ProfileConfig> parse_config_options(const std::vector<std::string>& options,
                                                          const char* command) {
    modbus::ProfileConfig config;
    for (const auto& kv : options) {
        const auto eq = kv.find('=');
        if (eq == std::string::npos) {
            std::cerr << "mbscope " << command << ": --config takes CHANNEL=MAP, not '" << kv << "'\n";
            return std::nullopt;
        }
        config[kv.substr(0, eq)] = kv.substr(eq + 1);
    }
    return config;
}

std::optional<modbus::Profile> load_profile_for(const std::string& id, const std::vector<std::string>& dirs,
                                                const std::vector<std::string>& config_options,
                                                const char* command) {
    const auto config = parse_config_options(config_options, command);
    if (!config) return std::nullopt;
    const auto store = open_profile_store(dirs, command);
    if (!store || !config_is_for_a_modular_device(*store, {id}, *config, command)) return std::nullopt;
    auto profile = store->load(id, *config);
    if (!profile) {
        for (const auto& e : profile.error())
            std::cerr << "mbscope " << command << ": " << modbus::to_string(e) << '\n';
        return std::nullopt;
    }
    return std::move(profile).value();
}

}  // namespace mbscope::cli
