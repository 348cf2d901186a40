#pragma once
// JSON views of resolved profiles (profile show --json, lookup, decode) and the profile search path.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "modbus/profile.hpp"
#include "modbus/profile_json.hpp"
#include "modbus/profile_loader.hpp"
#include "modbus/storage/profile_store.hpp"

namespace mbscope::cli {

nlohmann::json profile_to_json(const modbus::Profile& p);

// --profile-dir entries, then $MBSCOPE_PROFILE_PATH, then the installed profiles (next to the binary:
// ../share/mbscope/profiles), else the source tree's profiles/ (running from a build directory).
std::vector<std::string> profile_directories(const std::vector<std::string>& extra);

// False, after a message naming `command`, when one of `extra` (--profile-dir) is not a directory.
bool extra_profile_dirs_exist(const std::vector<std::string>& extra, const char* command);

// The profile store over profile_directories(extra), for a command that loads profiles by id. A --profile-dir
// that is not a directory is an error (nullopt after a message naming `command`): a mistyped one would
// otherwise fall back to the bundled profiles without a word. Files in the store that could not be read are
// warned about (the first problem of each file), since one of them may be the user's edited copy of the
// profile asked for, shadowed then by the bundled one.
std::optional<modbus::storage::ProfileStore> open_profile_store(const std::vector<std::string>& extra,
                                                                const char* command);

// --config chooses the maps of a modular device's channels. Given when none of the profiles `ids` (those
// the store knows) is modular, it would be dropped without a word: false after a message naming `command`.
bool config_is_for_a_modular_device(const modbus::storage::ProfileStore& store,
                                    const std::vector<std::string>& ids, const modbus::ProfileConfig& config,
                                    const char* command);

// --config CHANNEL=MAP options as a configuration; nullopt (after a message naming `command`) when one is
// not of that form.
std::optional<modbus::ProfileConfig> parse_config_options(const std::vector<std::string>& options,
                                                          const char* command);

// The profile `id` with its --config options, from --profile-dir entries and the usual places; nullopt
// after messages naming `command` and what is wrong.
std::optional<modbus::Profile> load_profile_for(const std::string& id, const std::vector<std::string>& dirs,
                                                const std::vector<std::string>& config_options,
                                                const char* command);

}  // namespace mbscope::cli
