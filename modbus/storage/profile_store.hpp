#pragma once
// Finds and loads profile files from directories (the installed profiles, the source tree's profiles/, a
// user's --profile-dir or $MBSCOPE_PROFILE_PATH). This is the only place that reads profile files from disk;
// the codec parses text (modbus/profile_loader.hpp). Directories are searched in order: a device id found in
// an earlier directory shadows the same id in a later one, so a user's file replaces a bundled one. A name
// is looked up as an id first: an alias never hides a device's id, whichever directory either comes from.
// Of two aliases alike in different directories, the earlier directory's answers.

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "modbus/profile_loader.hpp"

namespace mbscope::modbus::storage {

// How much of a directory's files a store reads when it opens.
enum class ProfileReading {
    full,     // every profile resolved: its errors reported and its points counted at once
    headers,  // what each file says of itself (modbus/profile_headers.hpp); a profile is resolved, and its
              // errors found, when it is loaded. For the bundled profiles, which the tests resolve.
};

struct ProfileDirectory {
    std::string path;
    ProfileReading reading = ProfileReading::full;
};

struct PointCounts {
    std::size_t coils = 0, discrete_inputs = 0, input_registers = 0, holding_registers = 0;
};

struct ProfileEntry {
    std::string id;  // lower case
    std::string name;
    std::vector<std::string> aliases;
    std::string vendor;
    std::string family;
    std::string file;
    std::vector<std::string> transports;
    bool modular = false;               // a configuration (--config) chooses its channels' maps
    std::optional<PointCounts> points;  // read in full: the points of its default configuration
};

class ProfileStore {
  public:
    // Loads every *.json below each directory (recursively). Files of another kind (schemas, shared map
    // files) are skipped; broken profile files, and a *.json that is no regular file (a FIFO, never opened),
    // are reported in errors() and the rest still load.
    explicit ProfileStore(std::vector<std::string> directories);
    explicit ProfileStore(std::vector<ProfileDirectory> directories);

    const std::vector<ProfileEntry>& entries() const noexcept { return entries_; }
    const std::vector<ProfileError>& errors() const noexcept { return errors_; }
    const std::vector<std::string>& directories() const noexcept { return directories_; }

    // Case-insensitive id or alias (an id before any alias); nullptr when unknown.
    const ProfileEntry* find(std::string_view id_or_alias) const;
    // The resolved profile, with a configuration for modular devices; errors name file and JSON pointer.
    Result<Profile, std::vector<ProfileError>> load(std::string_view id_or_alias,
                                                    const ProfileConfig& config = {}) const;

  private:
    std::vector<std::string> directories_;
    std::vector<ProfileEntry> entries_;
    std::vector<ProfileError> errors_;
    std::map<std::string, std::string> aliases_;  // alias → the id of the first entry that has it
    // The maps files read while listing, for load() too (shared: a copy of the store may share it).
    std::shared_ptr<IncludeCache> includes_ = std::make_shared<IncludeCache>();
};

// The device ids and aliases one directory's models take, and the file that gave each. The profile search
// finds one device per name in a directory: an id given twice, or a name that is one model's id and another
// model's alias, or two models' aliases, is an error naming both files (`mbscope profile validate` and the
// store say the same).
class DirectoryNames {
  public:
    explicit DirectoryNames(std::string directory) : directory_(std::move(directory)) {}

    struct Taken {
        bool id_taken = false;              // another file of the directory defines the id: passed over
        std::vector<std::string> problems;  // each a message for an error of `file`
    };
    // Takes a model's names (lower case), the first taker of a name keeping it.
    Taken take(const std::string& file, const std::string& id, const std::vector<std::string>& aliases);

  private:
    struct Owner {
        std::string file;
        std::string id;  // the model's
        bool alias = false;
    };
    std::string directory_;
    std::map<std::string, Owner> names_;
};

// Loads a single file (for `mbscope profile validate`): every profile it defines, every error it has.
// `cache`: maps files already read for other files (a directory's controllers share theirs).
LoadedProfiles load_profile_file(const std::string& path, const ProfileConfig& config = {},
                                 IncludeCache* cache = nullptr);

// Directories from a colon-separated list such as $MBSCOPE_PROFILE_PATH.
std::vector<std::string> split_path_list(const std::string& list);

}  // namespace mbscope::modbus::storage
