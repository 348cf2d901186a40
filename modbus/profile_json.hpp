#pragma once
// JSON views of profile points and named values, shared by `mbscope profile` and the analyzer's sinks.

#include <nlohmann/json.hpp>

#include "modbus/profile.hpp"

namespace mbscope::modbus {

nlohmann::json point_to_json(const Point& p);
nlohmann::json named_value_to_json(const NamedValue& v);

}  // namespace mbscope::modbus
