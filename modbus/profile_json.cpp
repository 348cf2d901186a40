#include "modbus/profile_json.hpp"

#include "modbus/json_writer.hpp"

namespace mbscope::modbus {

using json = nlohmann::json;

json point_to_json(const Point& p) {
    json j{{"table", std::string(to_string(p.table))},
           {"address", p.address},
           {"name", p.name},
           {"access", std::string(to_string(p.access))},
           {"source", p.source}};
    if (!p.name_en.empty()) j["name_en"] = p.name_en;
    if (!p.mnemonic.empty()) j["mnemonic"] = p.mnemonic;
    json e{{"type", std::string(to_string(p.encoding.type))}};
    if (p.encoding.decimals) e["decimals"] = p.encoding.decimals;
    if (p.encoding.is_signed) e["signed"] = true;
    if (p.encoding.words == 2) {
        e["words"] = 2;
        e["word_order"] = std::string(to_string(p.encoding.word_order));
    }
    if (const auto& field = p.encoding.decimals_from_byte)
        e["decimals_from_byte"] = {{"table", std::string(to_string(field->table))},
                                   {"address", field->address}};
    if (!p.encoding.decimals_unknown.empty()) e["decimals_unknown"] = p.encoding.decimals_unknown;
    if (const auto& choice = p.encoding.decimals_selected) {
        auto& d = e["decimals_selected_by"];
        d = {{"table", std::string(to_string(choice->selector.table))},
             {"address", choice->selector.address}};
        for (const auto& [value, ref] : choice->by_value)
            d["choices"].push_back(
                {{"value", value}, {"table", std::string(to_string(ref.table))}, {"address", ref.address}});
    }
    if (p.encoding.decimals_from)
        e["decimals_from"] = {{"table", std::string(to_string(p.encoding.decimals_from->table))},
                              {"address", p.encoding.decimals_from->address}};
    if (p.encoding.pair) e["pair"] = *p.encoding.pair;
    for (const auto& v : p.encoding.values) {
        json x{{"value", v.value}, {"text", v.text}};
        if (!v.text_en.empty()) x["text_en"] = v.text_en;
        if (!v.means.empty()) x["means"] = v.means;
        if (v.forbidden) x["forbidden"] = true;
        e["values"].push_back(x);
    }
    for (const auto& b : p.encoding.bits)
        e["bits"].push_back({{"bit", b.bit}, {"name", b.name}, {"name_en", b.name_en}});
    if (!p.encoding.allowed.empty()) e["allowed"] = p.encoding.allowed;
    if (!p.encoding.expr.empty()) e["expr"] = p.encoding.expr;
    j["encoding"] = e;
    if (p.min) j["range"]["min"] = *p.min;
    if (p.max) j["range"]["max"] = *p.max;
    if (!p.range_text.empty()) j["range_text"] = p.range_text;
    if (!p.unit.empty()) j["unit"] = p.unit;
    if (p.fixed_value) j["fixed_value"] = *p.fixed_value;
    if (p.reserved) j["reserved"] = true;
    if (p.momentary) j["momentary"] = true;
    if (p.reconstructed)
        j["reconstructed"] =
            p.reconstructed_why.empty() ? nlohmann::json(true) : nlohmann::json(p.reconstructed_why);
    if (!p.notes.empty()) j["notes"] = p.notes;
    if (!p.ref.empty()) j["ref"] = p.ref;
    if (p.mirrors) j["mirrors"] = std::string(to_string(*p.mirrors));
    if (p.same_value_as) j["same_value_as"] = *p.same_value_as;
    return j;
}

json named_value_to_json(const NamedValue& v) {
    json j{{"address", v.address}, {"raw", v.raw}, {"text", v.text}};
    if (v.number) j["value"] = *v.number;
    if (v.point) {
        j["name"] = v.point->name;
        if (!v.point->name_en.empty()) j["name_en"] = v.point->name_en;
        if (!v.point->unit.empty()) j["unit"] = v.point->unit;
    } else {
        j["in_map"] = false;
    }
    if (v.partial) j["partial"] = true;
    if (v.other_half_earlier) j["other_half_earlier"] = *v.other_half_earlier;
    return j;
}

void write_named_value(const NamedValue& v, JsonWriter& out) {  // named_value_to_json's object, keys sorted
    out.begin_object();
    out.member("address", v.address);
    if (!v.point) out.member("in_map", false);
    if (v.point) {
        out.member("name", std::string_view(v.point->name));
        if (!v.point->name_en.empty()) out.member("name_en", std::string_view(v.point->name_en));
    }
    if (v.other_half_earlier) out.member("other_half_earlier", *v.other_half_earlier);
    if (v.partial) out.member("partial", true);
    out.key("raw");
    out.begin_array();
    for (auto w : v.raw)
        out.value(w);
    out.end_array();
    out.member("text", std::string_view(v.text));
    if (v.point && !v.point->unit.empty()) out.member("unit", std::string_view(v.point->unit));
    if (v.number) out.member("value", *v.number);
    out.end_object();
}

}  // namespace mbscope::modbus
