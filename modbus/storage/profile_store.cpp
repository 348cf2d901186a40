#include "modbus/storage/profile_store.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <sstream>

#include "modbus/profile_headers.hpp"
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

namespace {

std::vector<ProfileDirectory> read_in_full(std::vector<std::string> paths) {
    std::vector<ProfileDirectory> out;
    for (auto& p : paths)
        out.push_back({std::move(p), ProfileReading::full});
    return out;
}

}  // namespace

ProfileStore::ProfileStore(std::vector<std::string> directories)
    : ProfileStore(read_in_full(std::move(directories))) {}

ProfileStore::ProfileStore(std::vector<ProfileDirectory> directories) {
    for (const auto& directory : directories) {
        const std::string& dir = directory.path;
        directories_.push_back(dir);
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
        const auto add = [&](const fs::path& file, ProfileEntry e) {
            if (e.id.empty()) return;
            if (std::find(ids_here.begin(), ids_here.end(), e.id) != ids_here.end()) {
                errors_.push_back(
                    {file.string(), "", "device id \"" + e.id + "\" is defined twice in " + dir});
                return;
            }
            ids_here.push_back(e.id);
            if (find(e.id)) return;  // shadowed by an earlier directory
            entries_.push_back(std::move(e));
        };
        for (const auto& file : files) {
            if (directory.reading == ProfileReading::headers) {
                std::string error;
                auto text = read_text_file(file.string(), error);
                if (!text) {
                    errors_.push_back({file.string(), "", error});
                    continue;
                }
                auto headers = scan_profile_headers(*text, file.string());
                errors_.insert(errors_.end(), headers.errors.begin(), headers.errors.end());
                for (auto& m : headers.models)
                    add(file,
                        {std::move(m.id), std::move(m.name), std::move(m.aliases), headers.vendor,
                         headers.family, file.string(), headers.transports, headers.modular, std::nullopt});
                continue;
            }
            auto loaded = load_profile_file(file.string(), {}, includes_.get());
            errors_.insert(errors_.end(), loaded.errors.begin(), loaded.errors.end());
            for (const auto& p : loaded.profiles)
                add(file,
                    {p.id, p.name, p.aliases, p.vendor, p.family, file.string(), p.line.transports, p.modular,
                     PointCounts{p.table(Table::Coils).size(), p.table(Table::DiscreteInputs).size(),
                                 p.table(Table::InputRegisters).size(),
                                 p.table(Table::HoldingRegisters).size()}});
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
