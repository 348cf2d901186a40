#include "modbus/profile_loader.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>

#include "modbus/frame.hpp"          // max_frame_bytes
#include "modbus/frame_text.hpp"     // printable(), first_unprintable()
#include "modbus/function_code.hpp"  // max_pdu_length

namespace mbscope::modbus {

std::string to_string(const ProfileError& e) {
    std::string where = e.file;
    if (!e.pointer.empty()) where += (where.empty() ? "" : ": ") + e.pointer;
    return where.empty() ? e.message : where + ": " + e.message;
}

namespace {

using json = nlohmann::json;

std::string lower(std::string s) {
    for (auto& c : s)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// A JSON pointer's reference token for an object key (RFC 6901: '~' as ~0, '/' as ~1), as nlohmann's
// json_pointer writes it.
std::string pointer_token(const std::string& key) {
    if (key.find_first_of("~/") == std::string::npos) return key;  // nothing to escape: most keys
    return (json::json_pointer() / key).to_string().substr(1);
}

// The start of a text quoted in a message, cut between UTF-8 characters: an "expr" that does not parse may
// be 200 kB, and the message says at which character it fails.
std::string excerpt(const std::string& text, std::size_t bytes = 40) {
    if (text.size() <= bytes) return text;
    std::size_t n = bytes;
    while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80)  // text[n] continues a character
        --n;
    return text.substr(0, n) + "…";
}

// A JSON integer as a 64-bit signed one; nullopt for any other value, and for an unsigned one past
// INT64_MAX, which get<std::int64_t>() would wrap to a negative number.
std::optional<std::int64_t> as_int64(const json& j) {
    if (!j.is_number_integer()) return std::nullopt;
    if (j.is_number_unsigned() && j.get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX))
        return std::nullopt;
    return j.get<std::int64_t>();
}

// Reads fields with type checks; every problem is recorded with its JSON pointer, reading goes on.
class Reader {
  public:
    Reader(std::string file, std::vector<ProfileError>& errors) : file_(std::move(file)), errors_(errors) {}

    // Messages quote the document's text (an unknown name): escaped, as the pointer, for the terminal.
    void error(const std::string& pointer, const std::string& message) {
        errors_.push_back({file_, printable(pointer), printable(message)});
    }
    // A fault found in a resolved model: the models it holds for, then the message. Every model of a file
    // resolves the same base tables, so one fault of the document is one error naming the models it
    // affects ("a, b: ..."), not one per model.
    void model_error(const std::string& pointer, const std::string& model, const std::string& message) {
        auto [it, fresh] = by_model_.try_emplace({pointer, message}, errors_.size(), std::string());
        it->second.second += (fresh ? "" : ", ") + model;
        const std::string text = it->second.second + ": " + message;
        if (fresh)
            errors_.push_back({file_, printable(pointer), printable(text)});
        else
            errors_[it->second.first].message = printable(text);
    }

    const json* child(const json& j, const std::string& key) {
        if (!j.is_object()) return nullptr;
        auto it = j.find(key);
        return it == j.end() ? nullptr : &*it;
    }
    std::optional<std::string> string(const json& j, const std::string& key, const std::string& ptr,
                                      bool required) {
        const json* c = child(j, key);
        if (!c) {
            if (required) error(ptr, "missing required field \"" + key + "\"");
            return std::nullopt;
        }
        if (!c->is_string()) {
            error(ptr + "/" + key, "must be a string");
            return std::nullopt;
        }
        return c->get<std::string>();
    }
    std::optional<std::int64_t> integer(const json& j, const std::string& key, const std::string& ptr,
                                        bool required, std::int64_t lo = INT64_MIN,
                                        std::int64_t hi = INT64_MAX) {
        const json* c = child(j, key);
        if (!c || c->is_null()) {
            if (required) error(ptr, "missing required field \"" + key + "\"");
            return std::nullopt;
        }
        if (!c->is_number_integer()) {
            error(ptr + "/" + key, "must be an integer");
            return std::nullopt;
        }
        const auto v = as_int64(*c).value_or(INT64_MIN);  // past INT64_MAX: out of any range
        if (!as_int64(*c) || v < lo || v > hi) {
            error(ptr + "/" + key, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
            return std::nullopt;
        }
        return v;
    }
    std::string source_of(const json& j) {
        const json* c = child(j, "source");
        if (!c) return {};
        if (c->is_string()) return c->get<std::string>();
        if (c->is_object()) {
            std::string s;
            for (const char* k : {"lines", "manual", "section"})
                if (c->contains(k) && (*c)[k].is_string()) return (*c)[k].get<std::string>();
            return s;
        }
        return {};
    }

  private:
    std::string file_;
    std::vector<ProfileError>& errors_;
    // (pointer, message) → index of its error and the models named so far
    std::map<std::pair<std::string, std::string>, std::pair<std::size_t, std::string>> by_model_;
};

std::optional<Table> table_named(const std::string& name) {
    if (name == "coils") return Table::Coils;
    if (name == "discrete_inputs") return Table::DiscreteInputs;
    if (name == "input_registers") return Table::InputRegisters;
    if (name == "holding_registers") return Table::HoldingRegisters;
    return std::nullopt;
}

std::optional<PointRef> point_ref(Reader& r, const json& j, const std::string& ptr, Table default_table) {
    if (j.is_number_integer()) {
        const auto a = j.get<std::int64_t>();
        if (a < 0 || a > 65535) {
            r.error(ptr, "must be an address from 0 to 65535");
            return std::nullopt;
        }
        return PointRef{default_table, static_cast<std::uint16_t>(a)};
    }
    if (!j.is_object()) {
        r.error(ptr, "must be {\"table\", \"address\"} or an address");
        return std::nullopt;
    }
    PointRef ref{default_table, 0};
    if (auto t = r.string(j, "table", ptr, false)) {
        auto table = table_named(*t);
        if (!table)
            r.error(ptr + "/table", "unknown table \"" + *t + "\"");
        else
            ref.table = *table;
    }
    auto a = r.integer(j, "address", ptr, true, 0, 65535);
    if (!a) return std::nullopt;
    ref.address = static_cast<std::uint16_t>(*a);
    return ref;
}

std::vector<std::string> notes_of(const json& j) {
    std::vector<std::string> out;
    auto it = j.find("notes");
    if (it == j.end() || !it->is_array()) return out;
    for (const auto& n : *it) {
        if (n.is_string())
            out.push_back(n.get<std::string>());
        else if (n.is_object() && n.contains("text") && n["text"].is_string()) {
            std::string text = n["text"].get<std::string>();
            if (n.contains("source") && n["source"].is_string())
                text += " [" + n["source"].get<std::string>() + "]";
            out.push_back(text);
        }
    }
    return out;
}

Encoding parse_encoding(Reader& r, const json& j, const std::string& ptr, Table table) {
    Encoding e;
    const auto wide = [](EncodingType t) {
        return t == EncodingType::U32 || t == EncodingType::S32 || t == EncodingType::F32;
    };
    if (j.is_string()) {  // shorthand "u16": a type that needs no other field
        auto t = parse_encoding_type(j.get<std::string>());
        if (!t) {
            r.error(ptr, "unknown encoding \"" + j.get<std::string>() + "\"");
            return e;
        }
        e.type = *t;
        e.words = wide(e.type) ? 2 : 1;  // "u32" was read as one register
        if (e.type == EncodingType::Scaled || e.type == EncodingType::Enum ||
            e.type == EncodingType::Digits4High || e.type == EncodingType::Digits4Low ||
            e.type == EncodingType::U32Low || e.type == EncodingType::U32High ||
            e.type == EncodingType::Formula)
            r.error(ptr, "\"" + std::string(to_string(e.type)) + "\" needs an object with its " +
                             (e.type == EncodingType::Scaled    ? "\"decimals_from\""
                              : e.type == EncodingType::Enum    ? "\"values\""
                              : e.type == EncodingType::Formula ? "\"expr\""
                                                                : "\"pair\""));
        return e;
    }
    if (!j.is_object()) {
        r.error(ptr, "must be an object with a \"type\"");
        return e;
    }
    auto type = r.string(j, "type", ptr, true);
    if (type) {
        auto t = parse_encoding_type(*type);
        if (!t)
            r.error(ptr + "/type", "unknown encoding type \"" + *type + "\"");
        else
            e.type = *t;
    }
    if (auto d = r.integer(j, "decimals", ptr, false, 0, 9)) e.decimals = static_cast<int>(*d);
    if (auto s = r.child(j, "signed"); s && s->is_boolean()) e.is_signed = s->get<bool>();
    if (auto d = r.child(j, "decimals_from"))
        e.decimals_from = point_ref(r, *d, ptr + "/decimals_from", table);
    if (auto d = r.child(j, "decimals_from_byte"))
        e.decimals_from_byte = point_ref(r, *d, ptr + "/decimals_from_byte", table);
    e.decimals_unknown = r.string(j, "decimals_unknown", ptr, false).value_or("");
    if (auto d = r.child(j, "decimals_selected_by")) {
        const std::string p = ptr + "/decimals_selected_by";
        DecimalsChoice choice;
        const auto selector = point_ref(r, *d, p, table);
        const json* choices = d->is_object() ? r.child(*d, "choices") : nullptr;
        if (!choices || !choices->is_array() || choices->empty())
            r.error(p, "needs \"choices\": [{\"value\", \"address\"}, ...]");
        else
            for (std::size_t i = 0; i < choices->size(); ++i) {
                const std::string cp = p + "/choices/" + std::to_string(i);
                const auto value = r.integer((*choices)[i], "value", cp, true);
                const auto ref = point_ref(r, (*choices)[i], cp, table);
                if (value && ref) choice.by_value.emplace_back(*value, *ref);
            }
        if (selector && !choice.by_value.empty()) {
            choice.selector = *selector;
            e.decimals_selected = std::move(choice);
        }
        if (e.decimals_from) r.error(p, "give \"decimals_from\" or \"decimals_selected_by\", not both");
    }
    if (e.type == EncodingType::Scaled && !e.decimals_from && !e.decimals_selected)
        r.error(ptr, "\"scaled\" needs \"decimals_from\" or \"decimals_selected_by\"");
    if (auto v = r.child(j, "values")) {
        if (!v->is_array())
            r.error(ptr + "/values", "must be an array");
        else
            for (std::size_t i = 0; i < v->size(); ++i) {
                const auto& item = (*v)[i];
                const std::string p = ptr + "/values/" + std::to_string(i);
                EnumValue ev;
                if (auto val = r.integer(item, "value", p, true)) ev.value = *val;
                ev.text = r.string(item, "text", p, false).value_or("");
                ev.text_en = r.string(item, "text_en", p, false).value_or("");
                ev.means = r.string(item, "means", p, false).value_or("");
                if (auto f = r.child(item, "forbidden"); f && f->is_boolean()) ev.forbidden = f->get<bool>();
                e.values.push_back(std::move(ev));
            }
    }
    if (e.type == EncodingType::Enum && e.values.empty()) r.error(ptr, "\"enum\" needs \"values\"");
    e.allowed = r.string(j, "allowed", ptr, false).value_or("");
    if (auto p = r.integer(j, "pair", ptr, false, 0, 65535)) e.pair = static_cast<std::uint16_t>(*p);
    const bool paired = e.type == EncodingType::Digits4High || e.type == EncodingType::Digits4Low ||
                        e.type == EncodingType::U32Low || e.type == EncodingType::U32High;
    if (paired && !e.pair) r.error(ptr, "\"" + std::string(to_string(e.type)) + "\" needs \"pair\"");
    if (auto w = r.string(j, "word_order", ptr, false)) {
        auto order = parse_word_order(*w);
        if (!order)
            r.error(ptr + "/word_order", "must be abcd, badc, cdab or dcba");
        else
            e.word_order = *order;
    }
    e.words = static_cast<int>(r.integer(j, "words", ptr, false, 1, 2).value_or(wide(e.type) ? 2 : 1));
    if (wide(e.type) && e.words != 2) r.error(ptr + "/words", "a 32-bit value takes two registers");
    if (auto b = r.child(j, "bits"); b && b->is_array()) {
        for (std::size_t i = 0; i < b->size(); ++i) {
            const auto& item = (*b)[i];
            const std::string p = ptr + "/bits/" + std::to_string(i);
            BitName bn;
            if (auto bit = r.integer(item, "bit", p, true, 0, 15)) bn.bit = static_cast<std::uint8_t>(*bit);
            bn.name = r.string(item, "name", p, false).value_or("");
            bn.name_en = r.string(item, "name_en", p, false).value_or("");
            e.bits.push_back(std::move(bn));
        }
    }
    e.expr = r.string(j, "expr", ptr, false).value_or("");
    if (e.type == EncodingType::Formula) {
        if (e.expr.empty()) {
            r.error(ptr, "\"formula\" needs \"expr\"");
        } else if (auto f = parse_formula(e.expr); !f) {
            r.error(ptr + "/expr", "\"" + excerpt(e.expr) + "\": " + f.error());
        } else {
            e.formula = std::move(f).value();
        }
    }
    if (e.type == EncodingType::Bytes2)
        for (int i = 0; i < 2; ++i) {
            const char* half = i == 0 ? "high" : "low";
            const auto field = r.child(j, half);
            if (!field) continue;
            const std::string p = ptr + "/" + half;
            e.bytes[i].name = r.string(*field, "name", p, false).value_or("");
            if (auto a = r.child(*field, "ascii"); a && a->is_boolean()) e.bytes[i].ascii = a->get<bool>();
        }
    // A value the register cannot carry (70000 or -3 on a u16) is a text no reply can show and a write
    // that would go out cut to 16 bits. Bytes2's values are each byte's; a bit is 0 or 1.
    if (const json* v = r.child(j, "values"); v && v->is_array() && !e.values.empty()) {
        std::optional<RawLimits> limits = raw_limits(e);
        std::string holder =
            "its " + std::string(to_string(e.type)) + " register" + (e.words == 2 ? "s" : "");
        if (is_bit_table(table)) {
            limits = RawLimits{0, 1};
            holder = "a bit";
        } else if (e.type == EncodingType::Bytes2) {
            limits = RawLimits{0, 255};
            holder = "a byte";
        }
        for (std::size_t i = 0; limits && i < v->size(); ++i) {
            const json* value = r.child((*v)[i], "value");
            const auto x = value ? as_int64(*value) : std::nullopt;
            if (x && (*x < limits->min || *x > limits->max))
                r.error(ptr + "/values/" + std::to_string(i) + "/value",
                        std::to_string(*x) + " is not a value " + holder + " can carry (" +
                            std::to_string(limits->min) + " to " + std::to_string(limits->max) + ")");
        }
    }
    return e;
}

std::optional<Access> parse_access(const std::string& a) {
    if (a == "r") return Access::Read;
    if (a == "w") return Access::Write;
    if (a == "rw") return Access::ReadWrite;
    return std::nullopt;
}

void apply_range(Reader& r, const json& j, const std::string& ptr, Point& p) {
    if (auto rg = r.child(j, "range"); rg && !rg->is_null()) {
        if (!rg->is_object())
            r.error(ptr + "/range", "must be {\"min\", \"max\"}");
        else {
            // A float's range is in engineering units, and may have decimals (Walchem's PID gain, 0.001 -
            // 1000, 002:2630); ranges are held as integers, so it is widened to the integers around it (no
            // value the manual allows is refused) and the range text keeps the exact one.
            const auto widened = [&](const char* key, bool lower) -> std::optional<std::int64_t> {
                const auto it = rg->find(key);
                if (p.encoding.type != EncodingType::F32 || it == rg->end() || !it->is_number_float() ||
                    !std::isfinite(it->get<double>()) || std::abs(it->get<double>()) > 1e15)
                    return std::nullopt;
                const double v = it->get<double>();
                return static_cast<std::int64_t>(lower ? std::floor(v) : std::ceil(v));
            };
            if (auto mn = widened("min", true))
                p.min = *mn;
            else if (auto m = r.integer(*rg, "min", ptr + "/range", false))
                p.min = *m;
            if (auto mx = widened("max", false))
                p.max = *mx;
            else if (auto m = r.integer(*rg, "max", ptr + "/range", false))
                p.max = *m;
            if (p.min && p.max && *p.min > *p.max) r.error(ptr + "/range", "min is above max");
        }
    }
    if (auto rf = r.child(j, "range_from"); rf && rf->is_object()) {
        if (auto mn = r.child(*rf, "min")) p.min_from = point_ref(r, *mn, ptr + "/range_from/min", p.table);
        if (auto mx = r.child(*rf, "max")) p.max_from = point_ref(r, *mx, ptr + "/range_from/max", p.table);
    }
    if (auto t = r.string(j, "range_text", ptr, false)) p.range_text = *t;
    // "conditional_access": {"text", "source", "read_only_when": {"table", "address", "values": [..]}}
    if (auto ca = r.child(j, "conditional_access"); ca && ca->is_object())
        if (auto when = r.child(*ca, "read_only_when")) {
            const std::string wptr = ptr + "/conditional_access/read_only_when";
            auto ref = point_ref(r, *when, wptr, p.table);
            const auto values = when->is_object() ? when->find("values") : when->end();
            if (!when->is_object() || values == when->end() || !values->is_array() || values->empty()) {
                r.error(wptr,
                        "needs \"values\": a non-empty array of the values that make the point read-only");
            } else if (ref) {
                Point::ReadOnlyWhen c{*ref, {}};
                for (const auto& v : *values)
                    if (!v.is_number_integer() || v.get<std::int64_t>() < 0 || v.get<std::int64_t>() > 65535)
                        r.error(wptr + "/values", "each value must be an integer 0 to 65535");
                    else
                        c.values.push_back(static_cast<std::uint16_t>(v.get<int>()));
                p.read_only_when = std::move(c);
            }
        }
}

struct RawPoint {
    Point point;
    std::vector<std::string> models;  // restricted to these model ids (lower case); empty = all
    std::string ptr;                  // where the document describes it, for the errors found on a model
};

std::optional<RawPoint> parse_point(Reader& r, const json& j, const std::string& ptr, Table table) {
    if (!j.is_object()) {
        r.error(ptr, "a point must be an object");
        return std::nullopt;
    }
    RawPoint rp;
    rp.ptr = ptr;
    Point& p = rp.point;
    p.table = table;
    auto address = r.integer(j, "address", ptr, true, 0, 65535);
    if (!address) return std::nullopt;
    p.address = static_cast<std::uint16_t>(*address);
    p.name = r.string(j, "name", ptr, true).value_or("");
    p.name_en = r.string(j, "name_en", ptr, false).value_or("");
    p.mnemonic = r.string(j, "mnemonic", ptr, false).value_or("");
    if (auto a = r.string(j, "access", ptr, true)) {
        auto access = parse_access(*a);
        if (!access)
            r.error(ptr + "/access", "must be r, w or rw");
        else
            p.access = *access;
    }
    if (auto e = r.child(j, "encoding"))
        p.encoding = parse_encoding(r, *e, ptr + "/encoding", table);
    else if (is_bit_table(table))
        p.encoding.type = EncodingType::Bool;
    // Addresses end at 65535: a value's second register cannot be past it (it would wrap round to 0).
    if (p.encoding.words == 2 && p.address == 0xFFFF)
        r.error(ptr + "/address", "a two-register value at 65535 has no second register");
    apply_range(r, j, ptr, p);
    p.unit = r.string(j, "unit", ptr, false).value_or("");
    if (auto f = r.integer(j, "fixed_value", ptr, false, 0, 65535))
        p.fixed_value = static_cast<std::uint16_t>(*f);
    if (auto res = r.child(j, "reserved"); res && res->is_boolean()) p.reserved = res->get<bool>();
    if (const auto* m = r.child(j, "momentary")) {
        if (m->is_boolean())
            p.momentary = m->get<bool>();
        else
            r.error(ptr + "/momentary", "must be true or false");
    }
    if (const auto* rec = r.child(j, "reconstructed")) {
        p.reconstructed = true;
        if (rec->is_object()) {
            p.reconstructed_why = r.string(*rec, "reason", ptr + "/reconstructed", false).value_or("");
            if (auto from = r.string(*rec, "from", ptr + "/reconstructed", false))
                p.reconstructed_why += (p.reconstructed_why.empty() ? "from " : " (from ") + *from +
                                       (p.reconstructed_why.empty() ? "" : ")");
        }
    }
    p.source = r.source_of(j);
    if (p.source.empty()) r.error(ptr, "missing \"source\" (the manual line it comes from)");
    p.notes = notes_of(j);
    p.ref = r.string(j, "ref", ptr, false).value_or("");
    if (auto m = r.string(j, "mirrors", ptr, false)) {
        p.mirrors = parse_line_setting(*m);
        if (!p.mirrors) {
            r.error(ptr + "/mirrors", "must be unit_id, framing, baud or parity");
        } else if (*p.mirrors != LineSetting::UnitId) {
            // The codes are the map's: each says which setting it stands for.
            const auto& values = p.encoding.values;
            if (p.encoding.type != EncodingType::Enum ||
                std::any_of(values.begin(), values.end(), [](const EnumValue& v) { return v.means.empty(); }))
                r.error(ptr + "/mirrors", "a mirrored " + *m +
                                              " needs an \"enum\" encoding whose every value says what it "
                                              "\"means\"");
        }
    }
    if (auto m = r.child(j, "models"); m && m->is_array())
        for (const auto& id : *m)
            if (id.is_string()) rp.models.push_back(lower(id.get<std::string>()));
    return rp;
}

struct TableSpec {
    std::vector<RawPoint> points;
    std::optional<Table> same_as;
    bool present = false;
};

using Tables = std::array<TableSpec, 5>;
constexpr Table all_tables[] = {Table::Coils, Table::DiscreteInputs, Table::InputRegisters,
                                Table::HoldingRegisters};
int idx(Table t) {
    return static_cast<int>(t);
}

// `modular`: the coils and holding registers are filled from the maps file (resolve_model), so a table
// may serve their map without the document listing them.
void parse_tables(Reader& r, const json& j, Tables& tables, bool modular) {
    const json* t = r.child(j, "tables");
    if (!t) return;
    if (!t->is_object()) {
        r.error("/tables", "must be an object");
        return;
    }
    for (auto it = t->begin(); it != t->end(); ++it) {
        const std::string ptr = "/tables/" + it.key();
        auto table = table_named(it.key());
        if (!table) {
            r.error(ptr, "unknown table (coils, discrete_inputs, input_registers, holding_registers)");
            continue;
        }
        TableSpec& spec = tables[idx(*table)];
        spec.present = true;
        if (it->is_object() && it->contains("from")) {  // filled by the modular maps (Walchem)
            if (r.string(*it, "from", ptr, true).value_or("") != "modular")
                r.error(ptr + "/from", "the only source of a table's points is \"modular\"");
            continue;
        }
        if (it->is_object()) {
            auto same = r.string(*it, "same_as", ptr, true);
            if (same) {
                spec.same_as = table_named(*same);
                if (!spec.same_as) r.error(ptr + "/same_as", "unknown table \"" + *same + "\"");
            }
            continue;
        }
        if (!it->is_array()) {
            r.error(ptr, "must be a list of points or {\"same_as\": table}");
            continue;
        }
        spec.points.reserve(it->size());
        for (std::size_t i = 0; i < it->size(); ++i)
            if (auto p = parse_point(r, (*it)[i], ptr + "/" + std::to_string(i), *table))
                spec.points.push_back(std::move(*p));
        // duplicates are an error: two rows cannot describe one address
        std::vector<std::uint16_t> seen;
        for (const auto& p : spec.points)
            seen.push_back(p.point.address);
        std::sort(seen.begin(), seen.end());
        for (std::size_t i = 1; i < seen.size(); ++i)
            if (seen[i] == seen[i - 1])
                r.error(ptr, "address " + std::to_string(seen[i]) + " is described more than once");
    }
    // A table serves the map of another of its kind, which lists its points: FC2 answers from the coils'
    // map, FC4 from the holding registers'. A register table serving bits, a table serving itself or one that
    // serves a third table's map resolve to nothing the device has (Profile::resolve follows one step).
    for (Table t : all_tables) {
        TableSpec& spec = tables[idx(t)];
        if (!spec.same_as) continue;
        const Table target = *spec.same_as;
        const std::string ptr = "/tables/" + std::string(to_string(t)) + "/same_as";
        const std::string name(to_string(target));
        std::string why;
        if (target == t)
            why = "a table cannot serve its own map";
        else if (is_bit_table(t) != is_bit_table(target))
            why = "\"" + name + "\" is not a " + (is_bit_table(t) ? "bit" : "register") +
                  " table: coils and discrete_inputs serve each other's map, holding_registers and "
                  "input_registers each other's";
        else if (tables[idx(target)].same_as)
            why = "\"" + name + "\" serves another table's map itself: name the table that lists the points";
        else if (!tables[idx(target)].present &&
                 !(modular && (target == Table::Coils || target == Table::HoldingRegisters)))
            why = "\"" + name + "\" is not among this profile's tables";
        if (why.empty()) continue;
        r.error(ptr, why);
    }
    for (Table t : all_tables) {  // after all are judged: a cycle is reported on each of its tables
        TableSpec& spec = tables[idx(t)];
        if (spec.same_as && (*spec.same_as == t || is_bit_table(t) != is_bit_table(*spec.same_as) ||
                             tables[idx(*spec.same_as)].same_as))
            spec.same_as.reset();
    }
}

// The longer of the request and the normal reply of function `fc` at `quantity` (AP §6): the device must
// take one and send the other.
std::size_t longest_pdu(int fc, bool write_part, int quantity) noexcept {
    const auto q = static_cast<std::size_t>(quantity);
    switch (fc) {
        case 1:
        case 2:
            return 2 + (q + 7) / 8;  // reply: function, byte count, bits
        case 15:
            return 6 + (q + 7) / 8;  // request: function, address, quantity, byte count, bits
        case 16:
            return 6 + 2 * q;
        case 23:
            return write_part ? 10 + 2 * q : 2 + 2 * q;
        default:
            return 2 + 2 * q;  // FC3, FC4: reply
    }
}

LineRules parse_line(Reader& r, const json& j) {
    LineRules l;
    const json* line = r.child(j, "line");
    if (!line) {
        r.error("", "missing required field \"line\"");
        return l;
    }
    if (auto t = r.child(*line, "transports"); t && t->is_array())
        for (const auto& x : *t)
            if (x.is_string()) {
                const auto s = x.get<std::string>();
                if (s != "rtu" && s != "ascii" && s != "tcp")
                    r.error("/line/transports", "unknown transport \"" + s + "\"");
                l.transports.push_back(s);
            }
    if (l.transports.empty()) r.error("/line", "\"transports\" must list rtu, ascii and/or tcp");
    // Anything else in these lists was dropped without a word (a baud rate written "9600", a parity "E").
    if (auto b = r.child(*line, "baud_rates"); b && b->is_array())
        for (std::size_t i = 0; i < b->size(); ++i) {
            const auto& x = (*b)[i];
            if (x.is_number_integer() && x.get<std::int64_t>() >= 50 && x.get<std::int64_t>() <= 10'000'000)
                l.baud_rates.push_back(x.get<std::uint32_t>());
            else
                r.error("/line/baud_rates/" + std::to_string(i), "must be a baud rate from 50 to 10000000");
        }
    if (auto p = r.child(*line, "parity"); p && p->is_array())
        for (std::size_t i = 0; i < p->size(); ++i) {
            const auto& x = (*p)[i];
            if (x.is_string() && (x == "none" || x == "even" || x == "odd"))
                l.parity.push_back(x.get<std::string>());
            else
                r.error("/line/parity/" + std::to_string(i), "must be \"none\", \"even\" or \"odd\"");
        }
    if (auto u = r.child(*line, "unit_id"); u && u->is_object()) {
        l.unit_min = static_cast<int>(r.integer(*u, "min", "/line/unit_id", false, 0, 255).value_or(1));
        l.unit_max = static_cast<int>(r.integer(*u, "max", "/line/unit_id", false, 0, 255).value_or(247));
        if (l.unit_min > l.unit_max) r.error("/line/unit_id", "min is above max");
        if (auto d = r.child(*u, "disabled"); d && d->is_array())
            for (std::size_t i = 0; i < d->size(); ++i) {
                // Read as int, 4294967296 was unit 0; a unit id is one byte.
                const auto unit = as_int64((*d)[i]);
                if (unit && *unit >= 0 && *unit <= 255)
                    l.unit_disabled.push_back(static_cast<int>(*unit));
                else
                    r.error("/line/unit_id/disabled/" + std::to_string(i), "must be a unit id from 0 to 255");
            }
        else if (d)
            r.error("/line/unit_id/disabled", "must be a list of unit ids");
        if (auto a = r.child(*u, "any_nonzero_answered"); a && a->is_boolean())
            l.any_unit_answered = a->get<bool>();
    }
    l.tcp_port = static_cast<int>(r.integer(*line, "tcp_port", "/line", false, 1, 65535).value_or(502));
    // Held as int: a larger time would wrap (2^32 + 5 ms was 5 ms), so it is refused.
    constexpr std::int64_t most_ms = std::numeric_limits<int>::max();
    if (auto m = r.integer(*line, "min_poll_interval_ms", "/line", false, 0, most_ms))
        l.min_poll_interval_ms = static_cast<int>(*m);
    if (auto m = r.integer(*line, "response_timeout_ms", "/line", false, 0, most_ms))
        l.response_timeout_ms = static_cast<int>(*m);
    l.ascii_inter_char_timeout_ms = static_cast<int>(
        r.integer(*line, "ascii_inter_char_timeout_ms", "/line", false, 0, most_ms).value_or(1000));
    // 256 at most: the longest Modbus/TCP ADU a stack here reads (MBAP length 257, frame.hpp), as Walchem
    // states; a PDU must hold at least a function code and a byte of data.
    l.pdu_max_bytes = static_cast<std::size_t>(
        r.integer(*line, "pdu_max_bytes", "/line", false, 2, static_cast<std::int64_t>(max_frame_bytes - 7))
            .value_or(static_cast<std::int64_t>(max_pdu_length)));
    if (auto d = r.child(*line, "data_bits"); d && !d->is_object()) {
        r.error("/line/data_bits", "must be an object: {\"rtu\": 8, \"ascii\": 7}");
    } else if (d) {
        for (const auto& [key, x] : d->items()) {
            if (key != "rtu" && key != "ascii")
                r.error("/line/data_bits/" + key, "unknown framing (rtu or ascii)");
            else if (!x.is_number_integer() || x.get<std::int64_t>() < 5 || x.get<std::int64_t>() > 8)
                r.error("/line/data_bits/" + key, "must be 5 to 8 data bits");
            else
                l.data_bits[key] = x.get<int>();
        }
    }
    if (auto s = r.child(*line, "stop_bits")) {
        const json empty = json::object();
        static constexpr std::string_view keys[] = {"rtu",   "rtu_parity",   "rtu_no_parity",
                                                    "ascii", "ascii_parity", "ascii_no_parity"};
        if (!s->is_object()) r.error("/line/stop_bits", "must be an object: {\"rtu\": [1], ...}");
        for (const auto& [key, x] : s->is_object() ? s->items() : empty.items()) {
            if (std::find(std::begin(keys), std::end(keys), key) == std::end(keys)) {
                r.error("/line/stop_bits/" + key,
                        "unknown key (rtu, ascii, each also _parity or _no_parity)");
                continue;
            }
            std::vector<int> allowed;
            for (const auto& b : x.is_array() ? x : empty)
                if (b.is_number_integer() && (b.get<std::int64_t>() == 1 || b.get<std::int64_t>() == 2))
                    allowed.push_back(b.get<int>());
            if (!x.is_array() || allowed.empty() || allowed.size() != x.size())
                r.error("/line/stop_bits/" + key, "must be a list of 1 and/or 2");
            else
                l.stop_bits[key] = std::move(allowed);
        }
    }
    return l;
}

FunctionRules parse_functions(Reader& r, const json& j, std::size_t pdu_max_bytes) {
    FunctionRules f;
    const json* fn = r.child(j, "functions");
    if (!fn) {
        r.error("", "missing required field \"functions\"");
        return f;
    }
    auto codes = [&](const char* key, auto& out, std::int64_t lo, std::int64_t hi) {
        if (auto c = r.child(*fn, key)) {
            if (!c->is_array()) {
                r.error(std::string("/functions/") + key, "must be a list of numbers");
                return;
            }
            // Read as int first, 4294967299 was function 3: the range is checked on the whole number.
            for (std::size_t i = 0; i < c->size(); ++i) {
                const auto x = as_int64((*c)[i]);
                if (!x || *x < lo || *x > hi)
                    r.error(std::string("/functions/") + key + "/" + std::to_string(i),
                            "must be a number from " + std::to_string(lo) + " to " + std::to_string(hi));
                else if (std::find(out.begin(), out.end(), *x) != out.end())
                    r.error(std::string("/functions/") + key, std::to_string(*x) + " is listed twice");
                else
                    out.push_back(static_cast<typename std::decay_t<decltype(out)>::value_type>(*x));
            }
        }
    };
    // Function codes are 1 to 127 (AP §4.1: 0 is not valid, 128-255 are the exception responses).
    codes("supported", f.supported, 1, 127);
    if (f.supported.empty()) r.error("/functions", "\"supported\" must list the function codes");
    codes("broadcast", f.broadcast, 1, 127);
    codes("diagnostics", f.diagnostics, 0, 65535);
    if (auto m = r.child(*fn, "max_quantity"); m && m->is_object())
        for (auto it = m->begin(); it != m->end(); ++it) {
            const std::string where = "/functions/max_quantity/" + it.key();
            // The key is a function with a quantity ("3"), or "23w" for FC23's write part. A limit past the
            // specification's is kept when a manual prints it (Walchem's FC16 125, noted as a contradiction),
            // but not past what the one-byte byte count can describe: 127 registers or 2040 bits. The slave
            // serving 200 registers wrapped the byte count to 144 in a 403-byte reply.
            const std::string& key = it.key();
            const bool write_part = !key.empty() && key.back() == 'w';
            const std::string digits = write_part ? key.substr(0, key.size() - 1) : key;
            const bool numeric = !digits.empty() && digits.size() <= 3 &&
                                 digits.find_first_not_of("0123456789") == std::string::npos;
            const int fc = numeric ? std::atoi(digits.c_str()) : 0;  // three digits at most: no overflow
            const int specification = numeric && fc <= 127 && (!write_part || fc == 23)
                                          ? FunctionRules{}.max_for(static_cast<std::uint8_t>(fc), write_part)
                                          : 0;
            const int capacity = fc == 1 || fc == 2 || fc == 15 ? 255 * 8 : 255 / 2;
            if (specification == 0)
                r.error(where,
                        "not a function with a quantity (1, 2, 3, 4, 15, 16, 23, or 23w for FC23's write)");
            else if (!it->is_number_integer() || it->get<std::int64_t>() < 1)
                r.error(where, "must be a positive integer");
            else if (it->get<std::int64_t>() > capacity)
                r.error(where,
                        "above " + std::to_string(capacity) +
                            ", the most a one-byte byte count can describe (the specification allows " +
                            std::to_string(specification) + ")");
            else if (const std::size_t pdu = longest_pdu(fc, write_part, it->get<int>()); pdu > pdu_max_bytes)
                r.error(where, "a request or reply of " + std::to_string(it->get<int>()) +
                                   " needs a PDU of " + std::to_string(pdu) + " bytes, more than the " +
                                   std::to_string(pdu_max_bytes) +
                                   " the device takes (line.pdu_max_bytes; AP §4.1: 253)");
            else
                f.max_quantity[key] = it->get<int>();
        }
    if (auto a = r.string(*fn, "address_check", "/functions", false)) {
        if (*a == "first")
            f.address_check = AddressCheck::First;
        else if (*a != "every")
            r.error("/functions/address_check", "must be \"every\" or \"first\"");
    }
    if (auto e = r.child(*fn, "exceptions"); e && e->is_object())
        for (auto it = e->begin(); it != e->end(); ++it) {
            // An exception code is the one byte of an exception response (AP §7): 1 to 255. Read as int,
            // 4294967299 was code 3, and 0 or 300 went out as a byte the manual never gave.
            const std::string where = "/functions/exceptions/" + pointer_token(it.key());
            const bool wrapped = it->is_object() && it->contains("code");
            const json& code = wrapped ? (*it)["code"] : *it;
            const std::string code_at = wrapped ? where + "/code" : where;
            if (code.is_null()) {
                f.exceptions[it.key()] = std::nullopt;
            } else if (const auto c = as_int64(code); c && *c >= 1 && *c <= 255) {
                f.exceptions[it.key()] = static_cast<int>(*c);
            } else if (code.is_number_integer()) {
                r.error(code_at, "must be an exception code from 1 to 255");
            } else {
                r.error(code_at, wrapped ? "must be an exception code or null (the manual is silent)"
                                         : "must be an exception code, null or {\"code\", ...}");
            }
            if (const json* implied = r.child(*it, "implied"); implied) {
                if (!implied->is_boolean())
                    r.error("/functions/exceptions/" + it.key() + "/implied", "must be true or false");
                else if (implied->get<bool>())
                    f.implied_exceptions.insert(it.key());
            }
        }
    return f;
}

// Addresses as written in "exclude" and an override's "addresses": each an address or an inclusive
// [first, last]. Read as int, 4294967299 was address 3: anything but addresses 0 to 65535 is an error.
void check_range(Reader& r, const json& x, const std::string& p) {
    const auto address = [](const json& j) {
        const auto a = as_int64(j);
        return a && *a >= 0 && *a <= 65535 ? a : std::nullopt;
    };
    if (x.is_array() && x.size() == 2) {
        const auto first = address(x[0]), last = address(x[1]);
        if (!first) r.error(p + "/0", "must be an address from 0 to 65535");
        if (!last) r.error(p + "/1", "must be an address from 0 to 65535");
        if (first && last && *first > *last) r.error(p, "first is above last");
    } else if (!address(x)) {
        r.error(p, x.is_array() ? "a range is [first, last]" : "must be an address from 0 to 65535");
    }
}

void check_ranges(Reader& r, const json& ranges, const std::string& ptr) {
    if (!ranges.is_array()) {
        r.error(ptr, "must be a list of addresses and [first, last] ranges");
        return;
    }
    for (std::size_t i = 0; i < ranges.size(); ++i)
        check_range(r, ranges[i], ptr + "/" + std::to_string(i));
}

bool in_ranges(const json& ranges, std::uint16_t address) {
    if (!ranges.is_array()) return false;
    for (const auto& r : ranges) {
        if (as_int64(r) == std::int64_t{address}) return true;
        if (r.is_array() && r.size() == 2 && as_int64(r[0]) && as_int64(r[1]) && address >= *as_int64(r[0]) &&
            address <= *as_int64(r[1]))
            return true;
    }
    return false;
}

// `encoded_by`: address → the override that gave the point its encoding, for the errors found after.
void apply_override(Reader& r, const json& o, const std::string& ptr, std::vector<Point>& points, Table table,
                    std::map<std::uint16_t, std::string>& encoded_by) {
    json ranges = json::array();
    if (o.contains("addresses")) {
        check_ranges(r, o["addresses"], ptr + "/addresses");
        if (o["addresses"].is_array()) ranges = o["addresses"];
    }
    if (o.contains("address")) {
        check_range(r, o["address"], ptr + "/address");
        ranges.push_back(o["address"]);
    }
    if (ranges.empty()) r.error(ptr, "an override needs \"address\" or \"addresses\"");
    int matched = 0;
    for (auto& p : points) {
        if (!in_ranges(ranges, p.address)) continue;
        ++matched;
        if (o.contains("range") || o.contains("range_text") || o.contains("range_from")) {
            if (o.contains("range")) p.min.reset(), p.max.reset();
            apply_range(r, o, ptr, p);
            if (o.contains("range_text")) p.range_source = r.source_of(o);
        }
        if (o.contains("encoding")) {
            p.encoding = parse_encoding(r, o["encoding"], ptr + "/encoding", table);
            encoded_by[p.address] = ptr + "/encoding";
            // As parse_point refuses it: the second register would wrap round to register 0.
            if (p.encoding.words == 2 && p.address == 0xFFFF)
                r.error(ptr + "/encoding", "a two-register value at 65535 has no second register");
        }
        if (auto a = r.string(o, "access", ptr, false)) {
            if (auto access = parse_access(*a))
                p.access = *access;
            else
                r.error(ptr + "/access", "must be r, w or rw");
        }
        if (auto u = r.string(o, "unit", ptr, false)) p.unit = *u;
        for (auto& n : notes_of(o))
            p.notes.push_back(n);
        if (auto s = r.string(o, "source", ptr, false)) p.notes.push_back("model override [" + *s + "]");
    }
    if (matched == 0) r.error(ptr, "override matches no point of the table");
}

struct ModularMaps {
    json maps;  // map id → map
    json status_codes;
    json alarm_bits;
    json alternative;  // alternative map id → map (Walchem 5.3.9)
    // The status codes as an encoding's "values", which every status field gets (complete_field): built
    // once, they are a hundred codes and the alternative maps hold a status point per object.
    json status_values;
};

struct MapField {
    RawPoint point;  // address = index inside the 36-address block
    bool coil = false;
};

// A maps file's status code key as the register value it stands for.
std::optional<std::uint16_t> status_code(const std::string& key) {
    unsigned value = 0;
    const auto [end, ec] = std::from_chars(key.data(), key.data() + key.size(), value);
    if (ec != std::errc{} || end != key.data() + key.size() || key.empty() || value > 0xFFFF)
        return std::nullopt;
    return static_cast<std::uint16_t>(value);
}

// The status codes (checked: every key is a register value) as an encoding's "values" list.
json status_values(const json& status_codes) {
    json values = json::array();
    for (auto it = status_codes.begin(); it != status_codes.end(); ++it) {
        json v = it->is_object() ? *it : json{{"text", *it}};
        v["value"] = status_code(it.key()).value_or(0);  // every key was checked when the file was read
        values.push_back(std::move(v));
    }
    return values;
}

// A maps file's field as a point's JSON: its printed value as the range text, the alarm bit names and the
// status codes it refers to filled in.
void complete_field(json& f, const ModularMaps& maps) {
    if (f.contains("value_text") && !f.contains("range_text")) f["range_text"] = f["value_text"];
    if (auto e = f.find("encoding");
        e != f.end() && e->is_object() && e->contains("bits_ref") && (*e)["bits_ref"].is_string()) {
        const auto ref = (*e)["bits_ref"].get<std::string>();
        if (maps.alarm_bits.contains(ref)) (*e)["bits"] = maps.alarm_bits[ref];
    }
    if (auto e = f.find("encoding"); e != f.end() && e->is_object() && (*e)["type"] == "status" &&
                                     maps.status_codes.is_object() && !e->contains("values"))
        (*e)["values"] = maps.status_values;
}

// The fields of one type map as points at their index; status codes and alarm bit names filled in.
std::vector<MapField> parse_map_fields(Reader& r, const json& map, const std::string& map_id, int block,
                                       const ModularMaps& maps, const std::string& model_id) {
    std::vector<MapField> out;
    const json* fields = r.child(map, "fields");
    if (!fields || !fields->is_array()) return out;
    for (std::size_t k = 0; k < fields->size(); ++k) {
        json f = (*fields)[k];
        const std::string fptr = "maps/" + map_id + "/fields/" + std::to_string(k);
        auto index = r.integer(f, "index", fptr, true, 0, block - 1);
        if (!index) continue;
        // A field of some models only (Walchem's "†": "O campo só está disponível para controladores W900",
        // 002:908): another model has no such point, its channel nor the alternative maps' reading of it.
        // A model answers an address it lacks as any other it does not have.
        if (auto only = f.find("only"); only != f.end()) {
            if (!only->is_array() || only->empty() ||
                !std::all_of(only->begin(), only->end(), [](const json& x) { return x.is_string(); })) {
                r.error(fptr + "/only", "needs a non-empty list of model ids");
                continue;
            }
            if (std::none_of(only->begin(), only->end(),
                             [&](const json& x) { return lower(x.get<std::string>()) == model_id; }))
                continue;
            f.erase("only");
        }
        f["address"] = *index;
        complete_field(f, maps);
        auto rp = parse_point(r, f, fptr, Table::HoldingRegisters);
        if (!rp) continue;
        out.push_back(
            {std::move(*rp), f.contains("coil") && f["coil"].is_boolean() && f["coil"].get<bool>()});
    }
    return out;
}

// A modular map's field placed as a holding register and, when it is coil-accessible, as a coil that views
// the register at its address (profile.coils_view_registers).
void place_field(RawPoint rp, bool coil, Tables& tables, Profile& profile) {
    if (coil) {
        profile.coils_view_registers = true;
        // Copied without the register's encoding, which a coil does not keep (a status field's lists about a
        // hundred codes).
        Encoding encoding = std::move(rp.point.encoding);
        RawPoint view = rp;
        rp.point.encoding = std::move(encoding);
        view.point.table = Table::Coils;
        view.point.encoding = Encoding{};
        view.point.encoding.type = EncodingType::Bool;
        tables[idx(Table::Coils)].points.push_back(std::move(view));
    }
    tables[idx(Table::HoldingRegisters)].points.push_back(std::move(rp));
}

// A channel the configuration gives a map: what the alternative maps number and read.
struct PlacedChannel {
    std::string id;
    std::string kind;
    std::string map_id;
    std::uint16_t start = 0;
    const std::vector<MapField>* fields = nullptr;
};

// The field of an object's map an alternative map's column reads: the column's own name, or what its
// "from_field" gives for the map ("pulse-manual" exactly, else the longest "prefix-*", else "*"); nullopt
// when that is null (the column is not served in that map).
std::optional<std::string> column_field(const json& column, const std::string& map_id) {
    const std::string name = column.contains("name") && column["name"].is_string()
                                 ? column["name"].get<std::string>()
                                 : std::string();
    const auto from = column.find("from_field");
    if (from == column.end() || !from->is_object()) return name;
    const json* chosen = nullptr;
    std::size_t best = 0;
    for (auto it = from->begin(); it != from->end(); ++it) {
        const std::string& key = it.key();
        if (key == map_id) {
            chosen = &*it;
            break;
        }
        if (!key.empty() && key.back() == '*' &&
            map_id.compare(0, key.size() - 1, key, 0, key.size() - 1) == 0 &&
            (!chosen || key.size() > best)) {
            chosen = &*it;
            best = key.size();
        }
    }
    if (!chosen) return name;
    if (chosen->is_string()) return chosen->get<std::string>();
    return std::nullopt;
}

// The alternative maps (Walchem 5.3.9, 002:750-776): the same field of objects of one kind at consecutive
// addresses, the objects numbered in the order of the channels the configuration gives a map. Each point
// reads what its object's own field holds (Point::same_value_as); a column whose field the object's map
// lacks is not served for it. Where the manual prints an address twice (Sensor 32's x9278 inside Sensor
// 31's float), the first point keeps it.
void expand_alternative(Reader& r, const json& modular, const ModularMaps& maps,
                        const std::vector<PlacedChannel>& placed, Tables& tables, Profile& profile) {
    const json* ids = r.child(modular, "alternative_maps");
    if (!ids || !ids->is_array()) return;
    std::vector<bool> occupied(65536, false);
    for (const auto& rp : tables[idx(Table::HoldingRegisters)].points)
        for (int w = 0; w < rp.point.encoding.words && rp.point.address + w <= 0xFFFF; ++w)
            occupied[rp.point.address + static_cast<std::size_t>(w)] = true;
    for (std::size_t i = 0; i < ids->size(); ++i) {
        const std::string ptr = "/modular/alternative_maps/" + std::to_string(i);
        const json& id = (*ids)[i];
        if (!id.is_string() || !maps.alternative.is_object() ||
            !maps.alternative.contains(id.get<std::string>())) {
            r.error(ptr, "alternative map " + id.dump() + " is not defined in the maps file");
            continue;
        }
        const json& alt = maps.alternative[id.get<std::string>()];
        const std::string aptr = "alternative_maps/" + id.get<std::string>();
        const auto kind = r.string(alt, "kind", aptr, true).value_or("");
        const json* columns = r.child(alt, "columns");
        const json* rows = r.child(alt, "rows");
        if (!columns || !columns->is_array() || !rows || !rows->is_array()) {
            r.error(aptr, "an alternative map needs \"columns\" and \"rows\" lists");
            continue;
        }
        std::vector<const PlacedChannel*> objects;
        for (const auto& ch : placed)
            if (ch.kind == kind) objects.push_back(&ch);
        for (std::size_t k = 0; k < rows->size() && k < objects.size(); ++k) {
            const json& row = (*rows)[k];
            const PlacedChannel& object = *objects[k];
            const std::string rptr = aptr + "/rows/" + std::to_string(k);
            const json* addresses = r.child(row, "addresses");
            if (!addresses || !addresses->is_array() || addresses->size() != columns->size()) {
                r.error(rptr, "a row needs one address per column");
                continue;
            }
            const std::string object_name = r.string(row, "object", rptr, true).value_or("");
            for (std::size_t c = 0; c < columns->size(); ++c) {
                const json& column = (*columns)[c];
                const auto field_name = column_field(column, object.map_id);
                if (!field_name) continue;
                const auto field =
                    std::find_if(object.fields->begin(), object.fields->end(),
                                 [&](const MapField& f) { return f.point.point.name == *field_name; });
                if (field == object.fields->end()) continue;
                json pj = column;
                pj.erase("from_field");
                pj["address"] = (*addresses)[c];
                pj["name"] = object_name + " (" + object.id + "): " + column.value("name", "");
                if (column.contains("name_en") && column["name_en"].is_string())
                    pj["name_en"] =
                        object_name + " (" + object.id + ") " + column["name_en"].get<std::string>();
                if (const json* refs = r.child(row, "refs");
                    refs && refs->is_array() && c < refs->size() && (*refs)[c].is_string())
                    pj["ref"] = (*refs)[c];
                complete_field(pj, maps);
                auto rp =
                    parse_point(r, pj, rptr + "/addresses/" + std::to_string(c), Table::HoldingRegisters);
                if (!rp) continue;
                Point& p = rp->point;
                if (p.encoding.words != field->point.point.encoding.words) continue;  // no such value to read
                if (p.address + p.encoding.words - 1 > 0xFFFF) continue;
                bool taken = false;
                for (int w = 0; w < p.encoding.words; ++w)
                    taken = taken || occupied[p.address + static_cast<std::size_t>(w)];
                if (taken) continue;
                for (int w = 0; w < p.encoding.words; ++w)
                    occupied[p.address + static_cast<std::size_t>(w)] = true;
                p.access = Access::Read;  // 002:3061-3064 and every other alternative map: "Leitura"
                p.same_value_as = static_cast<std::uint16_t>(object.start + field->point.point.address);
                p.notes.push_back("alternative map " + alt.value("heading", std::string()) + ", " +
                                  object_name + " [" + row.value("source", std::string()) + "]: reads " +
                                  object.id + "'s \"" + *field_name + "\" (holding register " +
                                  std::to_string(*p.same_value_as) + ")");
                // Coil access where the column's cell says so (5.3.9's bold "Est Alarme" columns) and the
                // object's own field has it.
                const bool column_coil =
                    column.contains("coil") && column["coil"].is_boolean() && column["coil"].get<bool>();
                place_field(std::move(*rp), column_coil && field->coil, tables, profile);
            }
        }
    }
}

// A configuration's "slot-N" keys resolved (walchem/README.md, "Configuration"): every channel of slot N
// becomes none, then the card's channels get the card's maps; the channel keys are applied after them, so
// a channel named on its own takes the map it names.
ProfileConfig resolve_slots(Reader& r, const json& modular, const ProfileConfig& given) {
    ProfileConfig out;
    const json* cards = r.child(modular, "cards");
    const json* channels = r.child(modular, "channels");
    for (const auto& [key, card_id] : given) {
        if (key.rfind("slot-", 0) != 0) continue;
        const std::string slot = key.substr(5);
        const bool number =
            !slot.empty() && slot.size() <= 2 &&
            std::all_of(slot.begin(), slot.end(), [](char c) { return c >= '0' && c <= '9'; });
        const json* card = nullptr;
        if (cards && cards->is_array())
            for (const auto& c : *cards)
                if (c.is_object() && c.value("id", std::string()) == card_id) card = &c;
        if (!number || !card) {
            r.error("/modular",
                    std::string(number ? "unknown card \"" + card_id + "\" for " : "no such slot: ") + "\"" +
                        key + "\"");
            continue;
        }
        bool any = false;
        if (channels && channels->is_array())
            for (const auto& ch : *channels)
                if (ch.is_object() && ch.contains("slot") && ch["slot"].is_number_integer() &&
                    std::to_string(ch["slot"].get<long long>()) == slot) {
                    out[ch.value("id", std::string())] = "none";
                    any = true;
                }
        if (!any) r.error("/modular", "\"" + key + "\": this controller has no channel in slot " + slot);
        if (const auto fills = card->find("channels"); fills != card->end() && fills->is_object())
            for (auto it = fills->begin(); it != fills->end(); ++it) {
                std::string id = it.key();
                if (const auto at = id.find("{slot}"); at != std::string::npos) id.replace(at, 6, slot);
                if (it->is_string()) out[id] = it->get<std::string>();
            }
    }
    for (const auto& [key, map] : given)
        if (key.rfind("slot-", 0) != 0) out[key] = map;
    return out;
}

void expand_modular(Reader& r, const json& modular, const ModularMaps& maps, const std::string& model_id,
                    const ProfileConfig& given, Tables& tables, Profile& profile) {
    const ProfileConfig config = resolve_slots(r, modular, given);
    std::map<std::string, std::vector<MapField>> templates;
    std::vector<PlacedChannel> placed;
    const int block =
        static_cast<int>(r.integer(modular, "block_size", "/modular", false, 1, 1000).value_or(36));
    const json* channels = r.child(modular, "channels");
    if (!channels || !channels->is_array()) {
        r.error("/modular", "missing \"channels\" list");
        return;
    }
    const json* defaults = r.child(modular, "default_config");
    std::vector<std::string> known_channels;
    std::map<std::int64_t, std::string> owner;  // address → the channel whose map placed a point there
    for (std::size_t i = 0; i < channels->size(); ++i) {
        const json& ch = (*channels)[i];
        const std::string ptr = "/modular/channels/" + std::to_string(i);
        auto id = r.string(ch, "id", ptr, true);
        auto start = r.integer(ch, "start", ptr, true, 0, 65535);
        if (!id || !start) continue;
        if (auto m = r.child(ch, "models"); m && m->is_array()) {
            bool listed = false;
            for (const auto& x : *m)
                listed |= x.is_string() && lower(x.get<std::string>()) == model_id;
            if (!listed) continue;
        }
        known_channels.push_back(*id);
        std::string map_id;
        if (auto c = config.find(*id); c != config.end())
            map_id = c->second;
        else if (defaults && defaults->contains(*id) && (*defaults)[*id].is_string())
            map_id = (*defaults)[*id].get<std::string>();
        else
            map_id = r.string(ch, "default_map", ptr, false).value_or("");
        if (map_id.empty() || map_id == "none") continue;
        if (auto allowed = r.child(ch, "maps"); allowed && allowed->is_array() && !allowed->empty()) {
            bool ok = false;
            for (const auto& x : *allowed)
                ok |= x.is_string() && x.get<std::string>() == map_id;
            if (!ok) {
                r.error(ptr, "channel \"" + *id + "\" cannot take map \"" + map_id + "\"");
                continue;
            }
        }
        if (!maps.maps.is_object() || !maps.maps.contains(map_id)) {
            r.error(ptr, "map \"" + map_id + "\" is not defined in the maps file");
            continue;
        }
        profile.configuration[*id] = map_id;
        const json& map = maps.maps[map_id];
        if (auto only = map.find("only"); only != map.end() && only->is_array() && !only->empty()) {
            bool ok = false;
            for (const auto& x : *only)
                ok |= x.is_string() && lower(x.get<std::string>()) == model_id;
            if (!ok) r.error(ptr, "map \"" + map_id + "\" does not exist on " + model_id);
        }
        // Each type map is parsed once (at index addresses) and then placed at every channel that uses it.
        auto parsed = templates.find(map_id);
        if (parsed == templates.end())
            parsed = templates.emplace(map_id, parse_map_fields(r, map, map_id, block, maps, model_id)).first;
        // Channels of different cards may share addresses (Walchem's sensor and analog output 1-1 both
        // start at 1152): a configuration that gives both a map would put two points on one register.
        std::string collision;
        for (const MapField& field : parsed->second)
            for (int w = 0; w < field.point.point.encoding.words && collision.empty(); ++w) {
                const std::int64_t a = *start + field.point.point.address + w;
                if (const auto it = owner.find(a); it != owner.end())
                    collision = "channel \"" + *id + "\" (map \"" + map_id + "\") and channel \"" +
                                it->second + "\" both hold register " + std::to_string(a) +
                                ": the configuration gives a map to only one of them (slot-N=CARD sets the "
                                "slot's other channels to none)";
            }
        if (!collision.empty()) {
            r.error(ptr, collision);
            continue;
        }
        for (const MapField& field : parsed->second)
            for (int w = 0; w < field.point.point.encoding.words; ++w)
                owner.emplace(*start + field.point.point.address + w, *id);
        placed.push_back({*id, r.string(ch, "kind", ptr, false).value_or(""), map_id,
                          static_cast<std::uint16_t>(*start), &parsed->second});
        for (const MapField& field : parsed->second) {
            RawPoint rp = field.point;
            // Placed past 65535 the point would wrap round to a low address another point may hold.
            const std::int64_t last = *start + rp.point.address + (rp.point.encoding.words == 2 ? 1 : 0);
            if (last > 0xFFFF) {
                r.error(ptr + "/start", "channel \"" + *id + "\" at " + std::to_string(*start) + " puts \"" +
                                            rp.point.name + "\" at " + std::to_string(last) +
                                            ", past the last address 65535");
                continue;
            }
            rp.point.address = static_cast<std::uint16_t>(*start + rp.point.address);
            rp.point.name = *id + ": " + rp.point.name;
            if (!rp.point.name_en.empty()) rp.point.name_en = *id + " " + rp.point.name_en;
            place_field(std::move(rp), field.coil, tables, profile);
        }
    }
    for (const auto& [channel, map] : config)
        if (std::find(known_channels.begin(), known_channels.end(), channel) == known_channels.end())
            r.error("/modular", "configuration names unknown channel \"" + channel + "\"");
    expand_alternative(r, modular, maps, placed, tables, profile);
    (void)block;
}

std::optional<double> number(Reader& r, const json& j, const std::string& key, const std::string& ptr,
                             bool required) {
    const json* c = r.child(j, key);
    if (!c) {
        if (required) r.error(ptr, "missing required field \"" + key + "\"");
        return std::nullopt;
    }
    if (!c->is_number()) {
        r.error(ptr + "/" + key, "must be a number");
        return std::nullopt;
    }
    return c->get<double>();
}

// "simulation": {"source": ..., "signals": [{"id", "model": "walk"|"integrate"|"alarm"|"constant", "point",
// ...}]}
Simulation parse_simulation(Reader& r, const json& doc) {
    Simulation sim;
    const json* j = r.child(doc, "simulation");
    if (!j) return sim;
    if (!j->is_object()) {
        r.error("/simulation", "must be an object");
        return sim;
    }
    sim.source = r.source_of(*j);
    const json* signals = r.child(*j, "signals");
    if (!signals || !signals->is_array()) {
        r.error("/simulation", "\"signals\" must be an array");
        return sim;
    }
    for (std::size_t i = 0; i < signals->size(); ++i) {
        const json& x = (*signals)[i];
        const std::string ptr = "/simulation/signals/" + std::to_string(i);
        SimulationSignal s;
        s.id = r.string(x, "id", ptr, true).value_or("");
        const auto model = r.string(x, "model", ptr, true).value_or("");
        // No "point": a hidden signal (it moves and others follow it; a client cannot read it).
        if (const json* point = r.child(x, "point")) {
            auto ref = point_ref(r, *point, ptr + "/point", Table::HoldingRegisters);
            if (!ref) continue;
            s.point = *ref;
        } else {
            s.hidden = true;
        }
        if (model == "walk") {
            s.model = SimulationSignal::Model::Walk;
            s.start = number(r, x, "start", ptr, true).value_or(0);
            s.min = number(r, x, "min", ptr, true).value_or(0);
            s.max = number(r, x, "max", ptr, true).value_or(0);
            s.step = number(r, x, "step", ptr, true).value_or(0);
            if (s.min > s.start || s.start > s.max) r.error(ptr, "needs min <= start <= max");
        } else if (model == "integrate") {
            s.model = SimulationSignal::Model::Integrate;
            s.of = r.string(x, "of", ptr, true).value_or("");
            s.per_second = number(r, x, "per_second", ptr, true).value_or(0);
            s.start = number(r, x, "start", ptr, false).value_or(0);
            s.max = number(r, x, "max", ptr, true).value_or(0);
            if (s.max <= 0) r.error(ptr + "/max", "must be positive (the value a total wraps at)");
        } else if (model == "alarm") {
            s.model = SimulationSignal::Model::Alarm;
            s.of = r.string(x, "of", ptr, true).value_or("");
            const auto direction = r.string(x, "direction", ptr, true).value_or("high");
            if (direction != "high" && direction != "low")
                r.error(ptr + "/direction", "must be \"high\" or \"low\"");
            s.high = direction == "high";
            if (const json* sp = r.child(x, "setpoint"))
                s.setpoint = point_ref(r, *sp, ptr + "/setpoint", Table::HoldingRegisters);
            else
                r.error(ptr, "missing required field \"setpoint\"");
            if (const json* h = r.child(x, "hysteresis"))
                s.hysteresis = point_ref(r, *h, ptr + "/hysteresis", Table::HoldingRegisters);
            if (s.hidden) r.error(ptr, "missing required field \"point\" (an alarm is an output)");
        } else if (model == "constant") {
            s.model = SimulationSignal::Model::Constant;
            s.start = s.min = s.max = number(r, x, "value", ptr, true).value_or(0);
            if (s.hidden)
                r.error(ptr, "missing required field \"point\" (a constant is a value the map shows)");
        } else {
            r.error(ptr + "/model", "unknown model \"" + model + "\" (walk, integrate, alarm, constant)");
            continue;
        }
        // Modular devices: {"CHANNEL": "MAP"}, the configuration the signal's addresses belong to.
        if (const json* c = r.child(x, "configuration"); c && !c->is_object())
            r.error(ptr + "/configuration", "must be an object of CHANNEL: MAP");
        else if (c)
            for (auto it = c->begin(); it != c->end(); ++it) {
                if (it->is_string())
                    s.configuration[it.key()] = it->get<std::string>();
                else
                    r.error(ptr + "/configuration/" + it.key(), "must be a map id");
            }
        for (const auto& earlier : sim.signals)
            if (earlier.id == s.id) r.error(ptr + "/id", "\"" + s.id + "\" is already used");
        if (!s.of.empty() && std::none_of(sim.signals.begin(), sim.signals.end(),
                                          [&](const SimulationSignal& e) { return e.id == s.of; }))
            r.error(ptr + "/of", "\"" + s.of + "\" names no earlier signal");
        sim.signals.push_back(std::move(s));
    }
    return sim;
}

// A model keeps the signals whose points it has (a model without a register has no process there) in the
// configuration they name, and drops those that follow a dropped signal.
bool configured_for(const SimulationSignal& s, const Profile& p) {
    return std::all_of(s.configuration.begin(), s.configuration.end(), [&](const auto& c) {
        const auto it = p.configuration.find(c.first);
        return it != p.configuration.end() && it->second == c.second;
    });
}

void keep_simulation_of(Profile& p) {
    std::vector<SimulationSignal> kept;
    for (const auto& s : p.simulation.signals) {
        const bool configured = configured_for(s, p);
        const bool here = (s.hidden || p.find(s.point.table, s.point.address)) &&
                          (!s.setpoint || p.find(s.setpoint->table, s.setpoint->address)) &&
                          (!s.hysteresis || p.find(s.hysteresis->table, s.hysteresis->address));
        const bool source_kept = s.of.empty() || std::any_of(kept.begin(), kept.end(),
                                                             [&](const auto& k) { return k.id == s.of; });
        if (configured && here && source_kept) kept.push_back(s);
    }
    p.simulation.signals = std::move(kept);
}

// Per table: address → the JSON pointer of what placed it there (a point's row, an override's encoding).
using Where = std::array<std::map<std::uint16_t, std::string>, 5>;

std::string where_of(const Where& w, Table t, std::uint16_t address) {
    const auto& m = w[idx(t)];
    const auto it = m.find(address);
    return it == m.end() ? std::string() : it->second;
}

// A point exactly at `address` (not the second register of a wider one).
const Point* point_at(const Profile& p, Table t, std::uint16_t address) {
    const auto& pts = p.points[idx(t)];
    const auto it = std::lower_bound(pts.begin(), pts.end(), address,
                                     [](const Point& x, std::uint16_t a) { return x.address < a; });
    return it != pts.end() && it->address == address ? &*it : nullptr;
}

// Two points on one register: a two-register value's second register listed as a point of its own. Lookups
// (Profile::find) name the register by whichever comes first, decoding splits the value, and the slave's
// writes of one clobber the other. Checked on the model, after overrides, which may widen a u16 to a u32.
void check_overlaps(Reader& r, const Profile& p, const Where& described, const Where& encoded) {
    for (Table t : all_tables)
        for (const auto& w : p.points[idx(t)]) {
            if (w.encoding.words != 2 || w.address == 0xFFFF) continue;
            const auto second = static_cast<std::uint16_t>(w.address + 1);
            const Point* other = point_at(p, t, second);
            if (!other) continue;
            const std::string table(to_string(t)), type(to_string(w.encoding.type));
            const std::string by_override = where_of(encoded, t, w.address);
            const std::string other_at = where_of(described, t, second);
            if (!by_override.empty())
                r.model_error(by_override, p.id,
                              "register " + std::to_string(second) + " is the second register of " + table +
                                  " " + std::to_string(w.address) + ", which this override makes a " + type +
                                  ", and another point (" + other_at + ")");
            else
                r.model_error(other_at.empty() ? "" : other_at + "/address", p.id,
                              "register " + std::to_string(second) + " is the second register of " + table +
                                  " " + std::to_string(w.address) + " (a " + type + ", " +
                                  where_of(described, t, w.address) +
                                  "): it cannot be another point as well");
        }
}

// The halves of a value split over two points name each other in "pair": a u32_low its u32_high, a
// digits4_high its digits4_low. The slave writes the other half at that address and decoding joins the
// two, so it must be the other half, in this table and this model.
void check_pairs(Reader& r, const Profile& p, const Where& described, const Where& encoded) {
    using T = EncodingType;
    for (Table t : all_tables)
        for (const auto& pt : p.points[idx(t)]) {
            const T type = pt.encoding.type;
            const std::optional<T> other_half = type == T::U32Low        ? T::U32High
                                                : type == T::U32High     ? T::U32Low
                                                : type == T::Digits4Low  ? T::Digits4High
                                                : type == T::Digits4High ? T::Digits4Low
                                                                         : std::optional<T>();
            if (!other_half || !pt.encoding.pair) continue;
            std::string at = where_of(encoded, t, pt.address);
            if (at.empty()) at = where_of(described, t, pt.address) + "/encoding";
            at += "/pair";
            const std::string table(to_string(t)), half(to_string(*other_half));
            const std::uint16_t pair = *pt.encoding.pair;
            const Point* other = point_at(p, t, pair);
            const std::string what =
                "a " + std::string(to_string(type)) + "'s pair is the address of its " + half + " half";
            if (pair == pt.address)
                r.model_error(at, p.id, "names the point itself: " + what);
            else if (!other)
                r.model_error(at, p.id,
                              table + " " + std::to_string(pair) + " is no point of the model: " + what);
            else if (other->encoding.type != *other_half)
                r.model_error(at, p.id,
                              table + " " + std::to_string(pair) + " is a " +
                                  std::string(to_string(other->encoding.type)) + ", not the " + half +
                                  " half: " + what);
            else if (other->encoding.pair != pt.address)
                r.model_error(at, p.id,
                              table + " " + std::to_string(pair) + " pairs with " +
                                  (other->encoding.pair ? std::to_string(*other->encoding.pair) : "nothing") +
                                  ", not with " + std::to_string(pt.address));
        }
}

std::string number_text(double v) {
    if (std::isfinite(v) && std::floor(v) == v && std::abs(v) < 1e18)
        return std::to_string(static_cast<std::int64_t>(v));
    return json(v).dump();
}

// The values a signal writes must be ones its point holds: the slave writes them cut to the register's 16
// or 32 bits (70000 on a u16 reads 4464), and a value outside the point's range is one the device would
// never show. A total wraps at its max, so its last value is the one below.
void check_signal_values(Reader& r, const json& doc, const Profile& common, const Profile& p) {
    const json* signals = r.child(doc, "simulation");
    signals = signals ? r.child(*signals, "signals") : nullptr;
    if (!signals || !signals->is_array()) return;
    using Model = SimulationSignal::Model;
    for (std::size_t i = 0; i < common.simulation.signals.size() && i < signals->size(); ++i) {
        const SimulationSignal& s = common.simulation.signals[i];
        const std::string ptr = "/simulation/signals/" + std::to_string(i);
        if (s.hidden || s.model == Model::Alarm) continue;  // an alarm writes 0 or 1
        if (std::none_of(p.simulation.signals.begin(), p.simulation.signals.end(),
                         [&](const SimulationSignal& k) { return k.id == s.id; }))
            continue;
        const Point* pt = p.find(s.point.table, s.point.address);
        if (!pt) continue;
        const std::string table(to_string(s.point.table));
        const std::string point = table + " " + std::to_string(pt->address);
        if (pt->address != s.point.address) {
            r.model_error(ptr + "/point", p.id,
                          "register " + std::to_string(s.point.address) + " is the second register of " +
                              point + ": a signal names the value's first register");
            continue;
        }
        const Encoding& e = pt->encoding;
        using T = EncodingType;
        double lo = 0, hi = 0;
        std::string holder;
        bool whole = true;  // the point's range is the signal's value's (a half's range is one register's)
        if (is_bit_table(s.point.table)) {
            hi = 1, holder = point + ", a bit,";
        } else if (e.type == T::F32) {
            hi = std::numeric_limits<float>::max(), lo = -hi, holder = point + "'s f32";
        } else if (e.pair && (e.type == T::U32Low || e.type == T::U32High)) {
            hi = UINT32_MAX, holder = "the u32 " + point + " and " + std::to_string(*e.pair) + " make",
            whole = false;
        } else if (e.pair && (e.type == T::Digits4Low || e.type == T::Digits4High)) {
            hi = 99'999'999, holder = "the 8 digits " + point + " and " + std::to_string(*e.pair) + " make",
            whole = false;
        } else if (const auto limits = raw_limits(e)) {
            lo = static_cast<double>(limits->min), hi = static_cast<double>(limits->max);
            holder = point + "'s " + std::string(to_string(e.type)) + " register" + (e.words == 2 ? "s" : "");
        } else {
            continue;
        }
        struct Written {
            const char* key;
            double value;
            std::string what;  // how the value comes to be written, when it is not the key's own
        };
        std::vector<Written> written;
        const json& x = (*signals)[i];
        if (s.model == Model::Walk)
            written = {{"start", s.start, ""}, {"min", s.min, ""}, {"max", s.max, ""}};
        else if (s.model == Model::Constant)
            written = {{"value", s.start, ""}};
        else if (s.model == Model::Integrate) {
            if (r.child(x, "start")) written.push_back({"start", s.start, ""});
            // Shown in whole counts below max (a float: up to max itself, nearly).
            const double last = e.type == T::F32 ? s.max : std::ceil(s.max) - 1;
            written.push_back(
                {"max", last,
                 last == s.max ? ""
                               : " (the last count before the total wraps at " + number_text(s.max) + ")"});
        }
        for (const auto& w : written) {
            if (!r.child(x, w.key)) continue;  // reported as missing
            const std::string value = number_text(w.value) + w.what;
            if (w.value < lo || w.value > hi)
                r.model_error(ptr + "/" + w.key, p.id,
                              value + " is more than " + holder + " can hold (" + number_text(lo) + " to " +
                                  number_text(hi) + ")");
            else if (whole && ((pt->min && w.value < static_cast<double>(*pt->min)) ||
                               (pt->max && w.value > static_cast<double>(*pt->max))))
                r.model_error(ptr + "/" + w.key, p.id,
                              value + " is outside " + point + "'s range (" +
                                  (pt->min ? number_text(static_cast<double>(*pt->min)) : "") + " to " +
                                  (pt->max ? number_text(static_cast<double>(*pt->max)) : "") + ")");
        }
    }
}

// `base`: the document's tables, shared by its models; the last model resolved (`last`) takes their points,
// the others copy them.
Profile resolve_model(Reader& r, const json& doc, const json& model, const std::string& mptr, Tables& base,
                      bool last, const Profile& common, const ModularMaps* maps,
                      const ProfileConfig& config) {
    Profile p = common;
    // An id is typed on command lines (`--profile`, `--map 3=ID`), named in reports and file names: words
    // of letters and digits joined by '-', as the schema says. "a<b&c" was accepted and served.
    const auto id_ok = [](const std::string& id) {
        const bool chars = std::all_of(id.begin(), id.end(), [](char c) {
            return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
        });
        return chars && !id.empty() && id.front() != '-' && id.back() != '-' &&
               id.find("--") == std::string::npos;
    };
    const char* id_rule = "must be letters and digits in words joined by '-' (\"mmk-2030\")";
    p.id = lower(r.string(model, "id", mptr, true).value_or(""));
    if (model.contains("id") && model["id"].is_string() && !id_ok(p.id)) r.error(mptr + "/id", id_rule);
    p.name = r.string(model, "name", mptr, false).value_or(p.id);
    if (auto a = r.child(model, "aliases"); a && a->is_array())
        for (std::size_t i = 0; i < a->size(); ++i)
            if (const auto& x = (*a)[i]; x.is_string()) {
                p.aliases.push_back(lower(x.get<std::string>()));
                if (!id_ok(p.aliases.back())) r.error(mptr + "/aliases/" + std::to_string(i), id_rule);
            }
    // A modular model adds its channels' points to the base tables: to a copy of them unless it is the last.
    Tables expanded;
    if (maps) {
        expanded = last ? std::move(base) : base;
        p.modular = true;
        if (auto modular = r.child(doc, "modular"))
            expand_modular(r, *modular, *maps, p.id, config, expanded, p);
        expanded[idx(Table::Coils)].present = expanded[idx(Table::HoldingRegisters)].present = true;
    }
    Tables& tables = maps ? expanded : base;
    const bool own = maps || last;  // the tables' points are this model's to take
    if (const json* ex = r.child(model, "exclude"); ex && !ex->is_object()) {
        r.error(mptr + "/exclude", "must be an object: {\"<table>\": [addresses and [first, last] ranges]}");
    } else if (ex) {
        for (auto it = ex->begin(); it != ex->end(); ++it)
            if (!table_named(it.key()))
                r.error(mptr + "/exclude/" + pointer_token(it.key()), "unknown table");
            else
                check_ranges(r, *it, mptr + "/exclude/" + it.key());
    }
    Where described, encoded;
    for (Table t : all_tables) {
        TableSpec& spec = tables[idx(t)];
        p.has_table[idx(t)] = spec.present;
        p.same_as[idx(t)] = spec.same_as;
        const json* exclude = nullptr;
        if (auto ex = r.child(model, "exclude");
            ex && ex->is_object() && ex->contains(std::string(to_string(t))))
            exclude = &(*ex)[std::string(to_string(t))];
        p.points[idx(t)].reserve(spec.points.size());
        for (RawPoint& rp : spec.points) {
            if (!rp.models.empty() && std::find(rp.models.begin(), rp.models.end(), p.id) == rp.models.end())
                continue;
            if (exclude && in_ranges(*exclude, rp.point.address)) continue;
            described[idx(t)].emplace(rp.point.address, rp.ptr);
            if (own)
                p.points[idx(t)].push_back(std::move(rp.point));
            else
                p.points[idx(t)].push_back(rp.point);
        }
        std::sort(p.points[idx(t)].begin(), p.points[idx(t)].end(),
                  [](const Point& a, const Point& b) { return a.address < b.address; });
    }
    if (auto ov = r.child(model, "overrides"); ov && ov->is_array())
        for (std::size_t i = 0; i < ov->size(); ++i) {
            const json& o = (*ov)[i];
            const std::string ptr = mptr + "/overrides/" + std::to_string(i);
            auto t = table_named(r.string(o, "table", ptr, true).value_or(""));
            if (!t) {
                r.error(ptr + "/table", "unknown table");
                continue;
            }
            apply_override(r, o, ptr, p.points[idx(*t)], *t, encoded[idx(*t)]);
        }
    keep_simulation_of(p);
    check_overlaps(r, p, described, encoded);
    check_pairs(r, p, described, encoded);
    check_signal_values(r, doc, common, p);
    // A range is in raw units: a limit the point's registers cannot hold would be written cut to 16 bits
    // (70000 on one register is 4464) by whoever trusts the profile, and judged against a value no reply
    // can carry. Checked here, after the overrides, which may give a point its range.
    for (Table t : all_tables)
        for (const auto& pt : p.points[idx(t)]) {
            const auto limits = raw_limits(pt.encoding);
            if (!limits) continue;
            for (const auto& [limit, which] : {std::pair{pt.min, "minimum"}, std::pair{pt.max, "maximum"}})
                if (limit && (*limit < limits->min || *limit > limits->max))
                    r.error(mptr, p.id + ": " + std::string(to_string(t)) + " " + std::to_string(pt.address) +
                                      " has the range " + which + " " + std::to_string(*limit) +
                                      ", which its " + std::string(to_string(pt.encoding.type)) +
                                      " register" + (pt.encoding.words == 2 ? "s" : "") + " cannot hold (" +
                                      std::to_string(limits->min) + " to " + std::to_string(limits->max) +
                                      ")");
        }
    // references to other points must exist in this model
    for (Table t : all_tables)
        for (const auto& pt : p.points[idx(t)]) {
            std::vector<const PointRef*> refs{
                pt.encoding.decimals_from ? &*pt.encoding.decimals_from : nullptr,
                pt.min_from ? &*pt.min_from : nullptr, pt.max_from ? &*pt.max_from : nullptr,
                pt.read_only_when ? &pt.read_only_when->when : nullptr};
            if (pt.encoding.decimals_from_byte) refs.push_back(&*pt.encoding.decimals_from_byte);
            if (const auto& choice = pt.encoding.decimals_selected) {
                refs.push_back(&choice->selector);
                for (const auto& [value, ref] : choice->by_value)
                    refs.push_back(&ref);
            }
            for (const auto* ref : refs)
                if (ref && !p.find(ref->table, ref->address) && !p.open_address_space)
                    r.error(mptr, p.id + ": " + std::string(to_string(t)) + " " + std::to_string(pt.address) +
                                      " refers to " + std::string(to_string(ref->table)) + " " +
                                      std::to_string(ref->address) + ", which this model does not have");
        }
    return p;
}

// Every string of a profile document, keys included, ends up on a terminal or in a report (names, units,
// value texts, notes): one holding a control character (an escape sequence, a carriage return that hides
// what precedes it) is an error at its JSON pointer, not something to print. Profiles nest 11 levels at most
// (the schema); a document nested deeper than max_depth is refused there rather than walked (a hostile one
// nests hundreds of thousands deep, and the walk recurses).
constexpr int max_depth = 32;
// `ptr`: the pointer of `j`, grown and cut back as the walk goes down and up (one string for the whole
// walk, not one per value: every key of a profile is visited).
void check_text(Reader& r, const json& j, std::string& ptr, int depth = 0) {
    if (depth > max_depth && (j.is_object() || j.is_array())) {
        r.error(ptr, "nested deeper than " + std::to_string(max_depth) + " levels");
        return;
    }
    const auto complain = [&r](const std::string& where, const std::string& escaped) {
        r.error(where, "holds a control character (" + escaped + "): profile text is printed as it is");
    };
    const std::size_t parent = ptr.size();
    if (j.is_string()) {
        if (const auto c = first_unprintable(j.get_ref<const std::string&>())) complain(ptr, *c);
    } else if (j.is_object()) {
        for (auto it = j.begin(); it != j.end(); ++it) {
            ptr += '/';
            ptr += pointer_token(it.key());
            if (const auto c = first_unprintable(it.key())) complain(ptr, *c);
            check_text(r, it.value(), ptr, depth + 1);
            ptr.resize(parent);
        }
    } else if (j.is_array()) {
        for (std::size_t i = 0; i < j.size(); ++i) {
            ptr += '/';
            ptr += std::to_string(i);
            check_text(r, j[i], ptr, depth + 1);
            ptr.resize(parent);
        }
    }
}

// A key that an object of the document gives twice: the object's JSON pointer, and the key.
struct RepeatedKey {
    std::string object;
    std::string key;
};

std::string repeated_key_message(const RepeatedKey& repeat) {
    return "key \"" + repeat.key + "\" is given twice: which one counts is not defined";
}

// Builds the document json::parse() builds, and notes each object that gives a key twice. JSON leaves such a
// document to the reader (RFC 8259 §4) and nlohmann keeps the last value: a point with "address": 0,
// "address": 99 loaded as 99, either of which may be the one meant. The check is the lookup that inserting
// the key does anyway.
class DocumentBuilder {
  public:
    DocumentBuilder(json& root, std::vector<RepeatedKey>& repeats) : root_(root), repeats_(repeats) {}

    bool null() { return add(nullptr); }
    bool boolean(bool v) { return add(v); }
    bool number_integer(json::number_integer_t v) { return add(v); }
    bool number_unsigned(json::number_unsigned_t v) { return add(v); }
    bool number_float(json::number_float_t v, const json::string_t&) { return add(v); }
    bool string(json::string_t& v) { return add(std::move(v)); }
    bool binary(json::binary_t& v) { return add(json(std::move(v))); }
    bool start_object(std::size_t) {
        levels_.push_back({place(json::object())});
        return true;
    }
    bool start_array(std::size_t) {
        levels_.push_back({place(json::array())});
        return true;
    }
    bool end_object() {
        levels_.pop_back();
        return true;
    }
    bool end_array() {
        levels_.pop_back();
        return true;
    }
    bool key(json::string_t& k) {
        Level& at = levels_.back();
        const auto [it, fresh] = at.value->get_ref<json::object_t&>().try_emplace(k);
        if (!fresh) repeats_.push_back({pointer(), k});  // the last value is kept, as json::parse() keeps it
        at.key = &it->first;
        at.slot = &it->second;
        return true;
    }
    bool parse_error(std::size_t, const std::string&, const json::exception& e) {
        error_ = e.what();
        return false;
    }

    // nlohmann's message, which says where: empty when the text is JSON.
    const std::string& error() const { return error_; }

  private:
    struct Level {
        json* value;                       // the object or array being read
        const std::string* key = nullptr;  // objects: the key whose value comes next (a node of the map)
        json* slot = nullptr;              // and where its value goes
    };

    bool add(json&& v) {
        place(std::move(v));
        return true;
    }
    json* place(json&& v) {
        if (levels_.empty()) {
            root_ = std::move(v);
            return &root_;
        }
        Level& at = levels_.back();
        if (at.value->is_array()) {
            auto& array = at.value->get_ref<json::array_t&>();
            array.push_back(std::move(v));
            return &array.back();
        }
        *at.slot = std::move(v);
        return at.slot;
    }
    // The pointer of the innermost object or array being read.
    std::string pointer() const {
        std::string out;
        for (std::size_t i = 0; i + 1 < levels_.size(); ++i)
            out += '/' + (levels_[i].value->is_array() ? std::to_string(levels_[i].value->size() - 1)
                                                       : pointer_token(*levels_[i].key));
        return out;
    }

    json& root_;
    std::vector<RepeatedKey>& repeats_;
    std::vector<Level> levels_;
    std::string error_;
};

// `text` as a document; nullopt with `error` set (nlohmann's message) when it is not JSON.
std::optional<json> parse_document(std::string_view text, std::vector<RepeatedKey>& repeats,
                                   std::string& error) {
    json doc;
    DocumentBuilder builder(doc, repeats);
    if (!json::sax_parse(text.begin(), text.end(), &builder)) {
        error = builder.error().empty() ? "not JSON" : builder.error();
        return std::nullopt;
    }
    return doc;
}

// What reading a maps file gave: its maps, or why the document including it cannot have them (`failure`,
// reported at the document's "/maps_file"), and the errors in the file itself, which name it.
struct IncludedMaps {
    std::optional<ModularMaps> maps;
    std::string failure;
    std::vector<ProfileError> errors;
};

IncludedMaps read_maps(const std::string& name, const std::string& text) {
    IncludedMaps out;
    try {
        std::vector<RepeatedKey> repeats;
        std::string not_json;
        auto parsed = parse_document(text, repeats, not_json);
        if (!parsed) {
            out.failure = name + " is not valid JSON: " + not_json;
            return out;
        }
        json m = std::move(*parsed);
        // Moved out, not copied: the Walchem type maps are half a megabyte of JSON.
        const auto take = [&m](const char* key) {
            auto it = m.find(key);
            return it == m.end() ? json::object() : std::move(*it);
        };
        if (!m.is_object()) {
            out.failure = name + " is not a JSON object";
            return out;
        }
        Reader maps_reader(name, out.errors);  // errors name the maps file
        if (!repeats.empty()) {  // as in a profile: which value is meant is not known, so neither is used
            for (const auto& repeat : repeats)
                maps_reader.error(repeat.object, repeated_key_message(repeat));
            out.failure = name + " gives a key twice in one object";
            return out;
        }
        std::string root;
        check_text(maps_reader, m, root);
        ModularMaps& maps = out.maps.emplace(ModularMaps{
            take("maps"), take("status_codes"), take("alarm_bits"), take("alternative_maps"), {}});
        // A status code's key is the register's value (complete_field reads it as one): a key that is no
        // number from 0 to 65535 would stand for no value, or throw.
        if (maps.status_codes.is_object())
            for (auto it = maps.status_codes.begin(); it != maps.status_codes.end();) {
                if (status_code(it.key())) {
                    ++it;
                    continue;
                }
                maps_reader.error("/status_codes/" + pointer_token(it.key()),
                                  "a status code is a register value from 0 to 65535");
                it = maps.status_codes.erase(it);
            }
        if (maps.status_codes.is_object()) maps.status_values = status_values(maps.status_codes);
    } catch (const json::exception& e) {
        out.failure = name + " is not valid JSON: " + e.what();
    }
    return out;
}

}  // namespace

struct IncludeCache::Entries {
    // The maps file `name` with this exact text, read once; later readers get the same entry (a node of a
    // std::map stays where it is while others are added).
    const IncludedMaps& read(const std::string& name, std::string text) {
        const std::lock_guard lock(mutex);
        auto& texts = by_name[name];
        auto it = texts.find(text);
        if (it == texts.end()) {
            IncludedMaps maps = read_maps(name, text);
            it = texts.emplace(std::move(text), std::move(maps)).first;
        }
        return it->second;
    }

    std::mutex mutex;
    std::map<std::string, std::map<std::string, IncludedMaps>> by_name;  // name → text → what it gave
};

IncludeCache::IncludeCache() : entries_(std::make_unique<Entries>()) {}
IncludeCache::~IncludeCache() = default;

LoadedProfiles parse_profiles(std::string_view text, const std::string& file, const IncludeFn& include,
                              const ProfileConfig& config, IncludeCache* cache) {
    LoadedProfiles out;
    Reader r(file, out.errors);
    std::vector<RepeatedKey> repeats;
    std::string not_json;  // parse_error, and out_of_range for a number too large (406)
    auto parsed = parse_document(text, repeats, not_json);
    if (!parsed) {
        r.error("", "not valid JSON: " + not_json);
        return out;
    }
    const json& doc = *parsed;
    if (!doc.is_object()) {
        r.error("", "a profile is a JSON object");
        return out;
    }
    // A key given twice is a profile's fault, each reported; JSON of another kind beside the profiles (a
    // schema) is passed over with its repeats. A "format" given twice leaves undecided which kind it is.
    const auto refuse_repeats = [&] {
        for (const auto& repeat : repeats)
            r.error(repeat.object, repeated_key_message(repeat));
        return out;
    };
    if (std::any_of(repeats.begin(), repeats.end(),
                    [](const RepeatedKey& k) { return k.object.empty() && k.key == "format"; }))
        return refuse_repeats();
    const auto format = r.string(doc, "format", "", false);
    if (!format || *format != profile_format) {
        out.is_profile = false;
        if (format && format->rfind("mbscope-profile/", 0) == 0)
            r.error("/format", "unsupported format version \"" + *format + "\" (this mbscope reads " +
                                   std::string(profile_format) + ")");
        return out;
    }
    if (!repeats.empty()) return refuse_repeats();
    std::string root;
    check_text(r, doc, root);
    Profile common;
    common.file = file;
    common.family = r.string(doc, "family", "", true).value_or("");
    common.vendor = r.string(doc, "vendor", "", true).value_or("");
    common.title = r.string(doc, "title", "", false).value_or("");
    common.source = r.source_of(doc);
    common.line = parse_line(r, doc);
    common.functions = parse_functions(r, doc, common.line.pdu_max_bytes);
    common.open_address_space = r.string(doc, "address_space", "", false).value_or("") == "open";
    if (auto n = r.child(doc, "notes"); n && n->is_array())
        for (std::size_t i = 0; i < n->size(); ++i) {
            const json& x = (*n)[i];
            if (!x.is_object()) continue;
            const std::string ptr = "/notes/" + std::to_string(i);
            common.notes.push_back({r.string(x, "text", ptr, false).value_or(""),
                                    r.string(x, "source", ptr, false).value_or(""),
                                    r.string(x, "kind", ptr, false).value_or("")});
        }
    common.simulation = parse_simulation(r, doc);
    // The 32-bit order the device sends by default and the others it can be set to (Walchem, 002:470-477).
    if (const auto* words = r.child(doc, "words"); words && words->is_object()) {
        const auto order_at = [&](const json& j, const std::string& ptr) {
            if (!j.is_string()) return r.error(ptr, "must be abcd, badc, cdab or dcba");
            if (auto o = parse_word_order(j.get<std::string>()))
                common.word_orders.push_back(*o);
            else
                r.error(ptr, "must be abcd, badc, cdab or dcba");
        };
        if (const auto* d = r.child(*words, "word_order")) order_at(*d, "/words/word_order");
        if (const auto* alt = r.child(*words, "word_order_alternatives")) {
            if (common.word_orders.empty())
                r.error("/words/word_order_alternatives", "alternatives need the default \"word_order\"");
            else if (!alt->is_array())
                r.error("/words/word_order_alternatives", "must be an array");
            else
                for (std::size_t i = 0; i < alt->size(); ++i)
                    order_at((*alt)[i], "/words/word_order_alternatives/" + std::to_string(i));
        }
    }
    Tables base;
    parse_tables(r, doc, base, r.child(doc, "modular") != nullptr);

    const ModularMaps* maps = nullptr;
    IncludedMaps uncached;  // read for this document alone, without a cache
    if (r.child(doc, "modular")) {
        auto name = r.string(doc, "maps_file", "", true);
        if (name) {
            std::optional<std::string> maps_text = include ? include(*name) : std::nullopt;
            if (!maps_text) {
                r.error("/maps_file", "cannot read \"" + *name + "\"");
            } else {
                const IncludedMaps& read = cache ? cache->entries().read(*name, std::move(*maps_text))
                                                 : (uncached = read_maps(*name, *maps_text));
                out.errors.insert(out.errors.end(), read.errors.begin(), read.errors.end());
                if (!read.failure.empty()) r.error("/maps_file", read.failure);
                if (read.maps) maps = &*read.maps;
            }
        }
    }

    const json* models = r.child(doc, "models");
    if (!models || !models->is_array() || models->empty()) {
        r.error("", "\"models\" must list at least one model (the device ids this file resolves to)");
        return out;
    }
    for (std::size_t i = 0; i < models->size(); ++i)
        out.profiles.push_back(resolve_model(r, doc, (*models)[i], "/models/" + std::to_string(i), base,
                                             i + 1 == models->size(), common, maps, config));
    // A device is found by its id, in lower case: an empty one names no device, and one that another model
    // of the file also takes ("TWO" and "two") names two; the profile store passed over both without a word.
    for (std::size_t i = 0; i < out.profiles.size(); ++i) {
        const std::string ptr = "/models/" + std::to_string(i) + "/id";
        const json& model = (*models)[i];
        if (model.is_object() && model.contains("id") && model["id"].is_string() &&
            out.profiles[i].id.empty())
            r.error(ptr, "a device id cannot be empty");
        for (std::size_t j = 0; j < i; ++j)
            if (!out.profiles[i].id.empty() && out.profiles[j].id == out.profiles[i].id) {
                r.error(ptr, "device id \"" + out.profiles[i].id + "\" is also /models/" + std::to_string(j) +
                                 "'s (ids are compared in lower case)");
                break;
            }
    }
    // A model without a signal's point drops the signal (it has no process there), but a point that no
    // model has, in the configuration the signal names and with the signal it follows, is a slip: the
    // signal would never run.
    for (std::size_t i = 0; i < common.simulation.signals.size(); ++i) {
        const SimulationSignal& s = common.simulation.signals[i];
        const std::string ptr = "/simulation/signals/" + std::to_string(i);
        const std::pair<const char*, std::optional<PointRef>> refs[] = {
            {"point", s.hidden ? std::nullopt : std::optional<PointRef>(s.point)},
            {"setpoint", s.setpoint},
            {"hysteresis", s.hysteresis}};
        for (const auto& [key, ref] : refs) {
            if (!ref) continue;
            bool configured = false, found = false;
            for (const auto& p : out.profiles)
                if (configured_for(s, p) &&
                    (s.of.empty() || std::any_of(p.simulation.signals.begin(), p.simulation.signals.end(),
                                                 [&](const SimulationSignal& k) { return k.id == s.of; }))) {
                    configured = true;
                    found = found || p.find(ref->table, ref->address) || p.open_address_space;
                }
            if (configured && !found)
                r.error(ptr + "/" + key, std::string(to_string(ref->table)) + " " +
                                             std::to_string(ref->address) +
                                             " is no point of any model: the signal would never run");
        }
    }
    return out;
}

}  // namespace mbscope::modbus
