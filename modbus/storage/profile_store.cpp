#include "modbus/storage/profile_store.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <sstream>

#include "modbus/storage/text_file.hpp"

namespace mbscope::modbus::storage {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
    for (auto& c : s)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::optional<std::string> read_text(const fs::path& path) {
    std::string error;
    return read_text_file(path.string(), error);
}

IncludeFn sibling_reader(const fs::path& file) {
    return [dir = file.parent_path()](const std::string& name) { return read_text(dir / name); };
}

}  // namespace

LoadedProfiles load_profile_file(const std::string& path, const ProfileConfig& config, IncludeCache* cache) {
    std::string error;
    auto text = read_text_file(path, error);
    if (!text) {
        LoadedProfiles out;
        out.errors.push_back({path, "", error});
        return out;
    }
    return parse_profiles(*text, path, sibling_reader(path), config, cache);
}

std::vector<std::string> split_path_list(const std::string& list) {
    std::vector<std::string> out;
    std::stringstream ss(list);
    for (std::string item; std::getline(ss, item, ':');)
        if (!item.empty()) out.push_back(item);
    return out;
}

ProfileStore::ProfileStore(std::vector<std::string> directories) : directories_(std::move(directories)) {
    for (const auto& dir : directories_) {
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) {
            errors_.push_back({dir, "", "not a directory"});
            continue;
        }
        std::vector<fs::path> files;
        for (auto it = fs::recursive_directory_iterator(dir, ec);
             !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
            if (it->is_regular_file() && it->path().extension() == ".json") files.push_back(it->path());
        std::sort(files.begin(), files.end());
        std::vector<std::string> ids_here;
        for (const auto& file : files) {
            auto loaded = load_profile_file(file.string(), {}, includes_.get());
            errors_.insert(errors_.end(), loaded.errors.begin(), loaded.errors.end());
            for (const auto& p : loaded.profiles) {
                if (p.id.empty()) continue;
                if (std::find(ids_here.begin(), ids_here.end(), p.id) != ids_here.end()) {
                    errors_.push_back(
                        {file.string(), "", "device id \"" + p.id + "\" is defined twice in " + dir});
                    continue;
                }
                ids_here.push_back(p.id);
                if (find(p.id)) continue;  // shadowed by an earlier directory
                ProfileEntry e{
                    p.id,      p.name, p.aliases, p.vendor, p.family, file.string(), p.line.transports,
                    p.modular, 0,      0,         0,        0};
                e.coils = p.table(Table::Coils).size();
                e.discrete_inputs = p.table(Table::DiscreteInputs).size();
                e.input_registers = p.table(Table::InputRegisters).size();
                e.holding_registers = p.table(Table::HoldingRegisters).size();
                entries_.push_back(std::move(e));
            }
        }
    }
    std::sort(entries_.begin(), entries_.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
}

const ProfileEntry* ProfileStore::find(std::string_view id_or_alias) const {
    const std::string key = lower(std::string(id_or_alias));
    for (const auto& e : entries_)
        if (e.id == key) return &e;
    for (const auto& e : entries_)
        if (std::find(e.aliases.begin(), e.aliases.end(), key) != e.aliases.end()) return &e;
    return nullptr;
}

Result<Profile, std::vector<ProfileError>> ProfileStore::load(std::string_view id_or_alias,
                                                              const ProfileConfig& config) const {
    const ProfileEntry* e = find(id_or_alias);
    if (!e) {
        std::string known;
        for (const auto& x : entries_)
            known += (known.empty() ? "" : ", ") + x.id;
        return std::vector<ProfileError>{
            {"", "", "no profile \"" + std::string(id_or_alias) + "\" (known: " + known + ")"}};
    }
    auto loaded = load_profile_file(e->file, config, includes_.get());
    if (!loaded.errors.empty()) return loaded.errors;
    for (auto& p : loaded.profiles)
        if (p.id == e->id) return std::move(p);
    return std::vector<ProfileError>{{e->file, "", "profile \"" + e->id + "\" vanished from its file"}};
}

}  // namespace mbscope::modbus::storage
