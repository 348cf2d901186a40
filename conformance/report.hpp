#pragma once
// The four faces of a certification report: text for a person, JSON for machines (schema in
// conformance/README.md), JUnit XML for CI systems (one testcase per rule), and a single self-contained
// HTML page a firmware team can attach to a release.

#include <nlohmann/json.hpp>
#include <ostream>

#include "conformance/runner.hpp"

namespace mbscope::conformance {

void write_text(std::ostream& out, const Report& report, bool verbose);
nlohmann::json to_json(const Report& report);
// The restore ledger (Session::restore), as the JSON of every command that writes lists it: `mbscope check`,
// `mbscope fuzz` and `mbscope replay`.
nlohmann::json to_json(const std::vector<Touched>& ledger);
void write_junit(std::ostream& out, const Report& report);
void write_html(std::ostream& out, const Report& report);

}  // namespace mbscope::conformance
