#pragma once
// JSON views of profile points and named values, shared by `mbscope profile` and the analyzer's sinks.

#include <nlohmann/json.hpp>

#include "modbus/profile.hpp"

namespace mbscope::modbus {

nlohmann::json point_to_json(const Point& p);
nlohmann::json named_value_to_json(const NamedValue& v);
class JsonWriter;
void write_named_value(const NamedValue& v, JsonWriter& out);  // the same object, written to a stream

}  // namespace mbscope::modbus
