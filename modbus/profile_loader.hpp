#pragma once
// Loading profile documents (profiles/README.md) into resolved Profiles, one per model. Parsing is strict
// about structure and complete about errors: every problem in a file is reported, each with the file, the
// JSON pointer and what is wrong, not only the first. nlohmann's exceptions never leave this edge.

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/profile.hpp"

namespace mbscope::modbus {

struct ProfileError {
    std::string file;
    std::string pointer;  // JSON pointer, "" for the whole document
    std::string message;
};
std::string to_string(const ProfileError& e);

struct LoadedProfiles {
    std::vector<Profile> profiles;
    std::vector<ProfileError> errors;
    bool is_profile = true;  // false: the document is JSON of another kind (a shared map file, a schema)
};

// Fetches a file named relative to the document being loaded (the Walchem device files' "maps_file").
using IncludeFn = std::function<std::optional<std::string>(const std::string& name)>;

// Configuration of a modular device: channel id → map id ("none" removes the channel).
using ProfileConfig = std::map<std::string, std::string>;

inline constexpr std::string_view profile_format = "mbscope-profile/1";

// The maps files documents include, each read and checked once for all of them: the three Walchem
// controllers include the same type-maps.json, half a megabyte of JSON, and a store loads each controller
// twice (listing it, then resolving the one a command names). An entry is the file's name and exact text,
// so a changed file or one of another directory is read anew. Safe to share between threads.
class IncludeCache {
  public:
    IncludeCache();
    ~IncludeCache();
    IncludeCache(const IncludeCache&) = delete;
    IncludeCache& operator=(const IncludeCache&) = delete;

    struct Entries;  // the loader's: the maps files read so far
    Entries& entries() noexcept { return *entries_; }

  private:
    std::unique_ptr<Entries> entries_;
};

// `cache`: where the maps files the document includes are looked up and kept; none, they are read for this
// document alone.
LoadedProfiles parse_profiles(std::string_view text, const std::string& file, const IncludeFn& include = {},
                              const ProfileConfig& config = {}, IncludeCache* cache = nullptr);

}  // namespace mbscope::modbus
