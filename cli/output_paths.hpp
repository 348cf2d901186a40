#pragma once
// Output paths checked before a long run: `mbscope check` writes its reports at the end of a certification
// that takes minutes on a bench slave and tens of minutes on a real controller, `mbscope fuzz` its
// reproducers whenever a finding comes. A mistyped directory must stop the command at once, not cost the run.

#include <optional>
#include <string>

namespace mbscope::cli {

// Why a file could not be written at `path` (its directory is missing or not writable, the path is a
// directory or a read-only file); nullopt when it can. Nothing is created or changed.
std::optional<std::string> cannot_write_file(const std::string& path);

// Creates `dir` with its parents when missing; why files could not be made in it, or nullopt.
std::optional<std::string> cannot_use_directory(const std::string& dir);

}  // namespace mbscope::cli
