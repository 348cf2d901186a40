#pragma once
// The text of every JSON document a command prints or writes. Text the user supplies (a file name, a
// target URI, a directory listed) may hold bytes that are not UTF-8, on which nlohmann::json's dump() throws
// type_error.316 unless told to replace them: `mbscope profile list --json` aborted (exit 134) over a profile
// file named "c\xFFth.json". Every command dumps through here, so none can forget.

#include <nlohmann/json.hpp>
#include <string>

namespace mbscope::cli {

// `j` as JSON text indented by `indent` spaces (-1: on one line); bytes that are not UTF-8 become U+FFFD.
// Never throws on text.
inline std::string json_text(const nlohmann::json& j, int indent = 2) {
    return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace mbscope::cli
