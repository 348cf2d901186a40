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

// A profile or maps file, read whole. What is not a regular file is said to be so and not opened: a FIFO's
// open waits for a writer (a profile directory holding one hung every command), a device's read may not end.
std::optional<std::string> read_profile_text(const std::string& path, std::string& error) {
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (!ec && !fs::is_regular_file(status)) {
        error = fs::is_directory(status) ? "is a directory, not a file" : "not a regular file";
        return std::nullopt;
    }
    return read_text_file(path, error);  // one that is not there says so when opened
}

std::optional<std::string> read_text(const fs::path& path) {
    std::string error;
    return read_profile_text(path.string(), error);
}

IncludeFn sibling_reader(const fs::path& file) {
    return [dir = file.parent_path()](const std::string& name) { return read_text(dir / name); };
}

}  // namespace

LoadedProfiles load_profile_file(const std::string& path, const ProfileConfig& config, IncludeCache* cache) {
    std::string error;
    auto text = read_profile_text(path, error);
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

DirectoryNames::Taken DirectoryNames::take(const std::string& file, const std::string& id,
                                           const std::vector<std::string>& aliases) {
    Taken out;
    if (const auto it = names_.find(id); it != names_.end()) {
        const Owner& o = it->second;
        if (!o.alias) {
            out.id_taken = true;
            out.problems.push_back("device id \"" + id + "\" is defined twice in " + directory_ +
                                   " (first in " + o.file + "): the profile search keeps the first");
            return out;
        }
        // The id is found before any alias: the earlier model loses the name, not this one.
        out.problems.push_back("device id \"" + id + "\" is also an alias of \"" + o.id + "\" in " + o.file +
                               ": the profile search finds the id by it, not \"" + o.id + "\"");
        it->second = {file, id, false};
    } else {
        names_.emplace(id, Owner{file, id, false});
    }
    for (const auto& alias : aliases) {
        const auto [it, fresh] = names_.try_emplace(alias, Owner{file, id, true});
        const Owner& o = it->second;
        if (fresh || o.id == id) continue;  // the model's own id, or an alias it lists twice: one device
        if (o.alias)
            out.problems.push_back("alias \"" + alias + "\" of \"" + id + "\" is also an alias of \"" + o.id +
                                   "\" in " + o.file + ": the profile search finds \"" + o.id + "\" by it");
        else
            out.problems.push_back("alias \"" + alias + "\" of \"" + id + "\" is also a device id, in " +
                                   o.file + ": the profile search finds that device by it, not \"" + id +
                                   "\"");
    }
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
            // Every *.json but a directory (which is descended into): one that is no regular file is
            // reported when read, not passed over without a word.
            if (std::error_code type; it->path().extension() == ".json" && !it->is_directory(type))
                files.push_back(it->path());
        std::sort(files.begin(), files.end());
        DirectoryNames names(dir);
        const auto add = [&](const fs::path& file, ProfileEntry e) {
            if (e.id.empty()) return;
            auto taken = names.take(file.string(), e.id, e.aliases);
            for (auto& problem : taken.problems)
                errors_.push_back({file.string(), "", std::move(problem)});
            if (taken.id_taken) return;
            // Shadowed by an earlier directory's device of the same id (a user's file replaces a bundled
            // one), by id only: find() would match an alias too, even this directory's own, and an alias
            // equal to another device's id made that device disappear.
            if (std::any_of(entries_.begin(), entries_.end(), [&](const auto& x) { return x.id == e.id; }))
                return;
            for (const auto& alias : e.aliases)
                aliases_.try_emplace(alias, e.id);  // an earlier directory's alias keeps its name
            entries_.push_back(std::move(e));
        };
        for (const auto& file : files) {
            if (directory.reading == ProfileReading::headers) {
                std::string error;
                auto text = read_profile_text(file.string(), error);
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
    const auto by_id = [this](const std::string& id) -> const ProfileEntry* {
        for (const auto& e : entries_)
            if (e.id == id) return &e;
        return nullptr;
    };
    const std::string key = lower(std::string(id_or_alias));
    if (const ProfileEntry* e = by_id(key)) return e;  // an exact id is never hidden by another's alias
    const auto it = aliases_.find(key);
    return it == aliases_.end() ? nullptr : by_id(it->second);
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
