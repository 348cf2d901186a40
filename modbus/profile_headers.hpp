#pragma once
// What a profile file says about itself without being resolved: its format, vendor, family and transports,
// whether its devices are modular, and each model's id, name and aliases. A store lists a directory from
// these (modbus/storage/profile_store.hpp) and resolves only the profile a command names: resolving every
// bundled profile was most of each command's start-up (bench/README.md, "Profile loading").
//
// The scan reads the JSON as a stream of events and keeps no document, so it checks only what it reads:
// the JSON syntax, the format, and that "models" is a list with something in it (a model that is no object
// is listed by neither). Everything else is parse_profiles()'s to check when the profile is loaded. Where
// both succeed they agree (fuzz/fuzz_profile.cpp checks it).

#include <string>
#include <string_view>
#include <vector>

#include "modbus/profile_loader.hpp"

namespace mbscope::modbus {

struct ProfileHeader {
    std::string id;  // lower case, as parse_profiles() gives it; empty when the model has none
    std::string name;
    std::vector<std::string> aliases;  // lower case
};

struct ProfileHeaders {
    std::string vendor;
    std::string family;
    std::vector<std::string> transports;
    bool modular = false;  // the document has a "modular" block: a configuration chooses channels' maps
    std::vector<ProfileHeader> models;
    std::vector<ProfileError> errors;
    bool is_profile = true;  // false: JSON of another kind (a shared map file, a schema)
};

ProfileHeaders scan_profile_headers(std::string_view text, const std::string& file);

}  // namespace mbscope::modbus
