#include "modbus/profile.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <type_traits>

#include "modbus/function_code.hpp"

namespace mbscope::modbus {

std::string_view to_string(Access a) noexcept {
    switch (a) {
        case Access::Read:
            return "r";
        case Access::Write:
            return "w";
        case Access::ReadWrite:
            return "rw";
    }
    return "?";
}

std::optional<int> LineRules::data_bits_for(Framing framing) const {
    if (framing == Framing::Tcp) return std::nullopt;
    const auto it = data_bits.find(framing == Framing::Ascii ? "ascii" : "rtu");
    if (it == data_bits.end()) return std::nullopt;
    return it->second;
}

const std::vector<int>* LineRules::stop_bits_allowed(Framing framing, Parity parity) const {
    if (framing == Framing::Tcp) return nullptr;
    const std::string base = framing == Framing::Ascii ? "ascii" : "rtu";
    // The most specific key the manual gives: "ascii_no_parity" before "ascii".
    for (const std::string& key : {base + (parity == Parity::None ? "_no_parity" : "_parity"), base})
        if (const auto it = stop_bits.find(key); it != stop_bits.end()) return &it->second;
    return nullptr;
}

std::optional<int> LineRules::stop_bits_for(Framing framing, Parity parity) const {
    const auto* allowed = stop_bits_allowed(framing, parity);
    if (!allowed || allowed->size() != 1) return std::nullopt;
    return allowed->front();
}

SerialLine LineRules::character_for(Framing framing, SerialLine line) const {
    line.data_bits =
        static_cast<std::uint8_t>(data_bits_for(framing).value_or(framing == Framing::Ascii ? 7 : 8));
    if (const auto stop = stop_bits_for(framing, line.parity))
        line.stop_bits = static_cast<std::uint8_t>(*stop);
    return line;
}

namespace {
template <typename List>
std::string listed(const List& items) {
    std::string out;
    for (const auto& item : items) {
        if (!out.empty()) out += ", ";
        if constexpr (std::is_same_v<std::decay_t<decltype(item)>, std::string>)
            out += item;
        else
            out += std::to_string(item);
    }
    return out;
}
}  // namespace

std::vector<std::string> line_departures(const LineRules& rules, Framing framing, const SerialLine* line) {
    std::vector<std::string> out;
    const std::string transport(to_string(framing));
    if (!rules.transports.empty() &&
        std::find(rules.transports.begin(), rules.transports.end(), transport) == rules.transports.end())
        out.push_back("the manual lists no " + transport + " transport (" + listed(rules.transports) + ")");
    if (!line || framing == Framing::Tcp) return out;
    if (!rules.baud_rates.empty() &&
        std::find(rules.baud_rates.begin(), rules.baud_rates.end(), line->baud) == rules.baud_rates.end())
        out.push_back(std::to_string(line->baud) + " baud is not among the manual's (" +
                      listed(rules.baud_rates) + ")");
    const std::string parity(to_string(line->parity));
    if (!rules.parity.empty() &&
        std::find(rules.parity.begin(), rules.parity.end(), parity) == rules.parity.end())
        out.push_back("parity " + parity + " is not among the manual's (" + listed(rules.parity) + ")");
    if (const auto data = rules.data_bits_for(framing); data && *data != line->data_bits)
        out.push_back(std::to_string(line->data_bits) + " data bits where the manual fixes " +
                      std::to_string(*data) + " for " + transport);
    if (const auto* stop = rules.stop_bits_allowed(framing, line->parity);
        stop && std::find(stop->begin(), stop->end(), line->stop_bits) == stop->end())
        out.push_back(std::to_string(line->stop_bits) + " stop bits where the manual allows " +
                      listed(*stop) + " for " + transport +
                      (line->parity == Parity::None ? " without parity" : " with parity"));
    return out;
}

const Point* Profile::address_register() const noexcept {
    for (const Point& p : table(Table::HoldingRegisters))
        if (p.mirrors == LineSetting::UnitId && p.access != Access::Read && p.encoding.words == 1 &&
            !p.fixed_value)
            return &p;
    return nullptr;
}

namespace {
constexpr std::pair<std::string_view, EncodingType> encoding_names[] = {
    {"u16", EncodingType::U16},
    {"s16", EncodingType::S16},
    {"fixed", EncodingType::Fixed},
    {"scaled", EncodingType::Scaled},
    {"enum", EncodingType::Enum},
    {"ascii_char", EncodingType::AsciiChar},
    {"digits4_high", EncodingType::Digits4High},
    {"digits4_low", EncodingType::Digits4Low},
    {"u32", EncodingType::U32},
    {"s32", EncodingType::S32},
    {"f32", EncodingType::F32},
    {"u32_low", EncodingType::U32Low},
    {"u32_high", EncodingType::U32High},
    {"bytes2", EncodingType::Bytes2},
    {"bits", EncodingType::Bits},
    {"status", EncodingType::Status},
    {"bool", EncodingType::Bool},
    {"formula", EncodingType::Formula},
};
constexpr std::pair<std::string_view, WordOrder> word_orders[] = {{"abcd", WordOrder::Abcd},
                                                                  {"badc", WordOrder::Badc},
                                                                  {"cdab", WordOrder::Cdab},
                                                                  {"dcba", WordOrder::Dcba}};
}  // namespace

std::string_view to_string(EncodingType t) noexcept {
    for (const auto& [n, v] : encoding_names)
        if (v == t) return n;
    return "?";
}
std::optional<EncodingType> parse_encoding_type(std::string_view name) noexcept {
    for (const auto& [n, v] : encoding_names)
        if (n == name) return v;
    return std::nullopt;
}
std::string_view to_string(WordOrder w) noexcept {
    for (const auto& [n, v] : word_orders)
        if (v == w) return n;
    return "?";
}
std::optional<WordOrder> parse_word_order(std::string_view name) noexcept {
    for (const auto& [n, v] : word_orders)
        if (n == name) return v;
    return std::nullopt;
}

bool FunctionRules::supports(std::uint8_t fc) const {
    return std::find(supported.begin(), supported.end(), fc) != supported.end();
}

bool FunctionRules::allows_broadcast(std::uint8_t fc) const {
    return std::find(broadcast.begin(), broadcast.end(), fc) != broadcast.end();
}

int FunctionRules::max_for(std::uint8_t fc, bool write_part) const {
    const std::string key = std::to_string(fc) + (write_part ? "w" : "");
    if (auto it = max_quantity.find(key); it != max_quantity.end()) return it->second;
    switch (fc) {
        case 1:
        case 2:
            return max_read_bits;
        case 3:
        case 4:
            return max_read_registers;
        case 15:
            return max_write_bits;
        case 16:
            return max_write_registers;
        case 23:
            return write_part ? max_rw_write_registers : max_rw_read_registers;
        default:
            return 0;
    }
}

Table Profile::resolve(Table t) const noexcept {
    const auto& s = same_as[static_cast<int>(t)];
    return s ? *s : t;
}

namespace {
std::uint16_t swap_bytes(std::uint16_t w) noexcept {
    return static_cast<std::uint16_t>((w << 8) | (w >> 8));
}
}  // namespace

std::uint32_t join_words(std::uint16_t first, std::uint16_t second, WordOrder order) noexcept {
    // first/second are the registers at address and address+1; ABCD = big-endian, first register high.
    switch (order) {
        case WordOrder::Abcd:
            return (std::uint32_t{first} << 16) | second;
        case WordOrder::Cdab:
            return (std::uint32_t{second} << 16) | first;
        case WordOrder::Badc:
            return (std::uint32_t{swap_bytes(first)} << 16) | swap_bytes(second);
        case WordOrder::Dcba:
            return (std::uint32_t{swap_bytes(second)} << 16) | swap_bytes(first);
    }
    return 0;
}

std::string_view to_string(LineSetting s) noexcept {
    switch (s) {
        case LineSetting::UnitId:
            return "unit_id";
        case LineSetting::Framing:
            return "framing";
        case LineSetting::Baud:
            return "baud";
        case LineSetting::Parity:
            return "parity";
    }
    return "?";
}

std::optional<LineSetting> parse_line_setting(std::string_view text) noexcept {
    for (const auto s : {LineSetting::UnitId, LineSetting::Framing, LineSetting::Baud, LineSetting::Parity})
        if (to_string(s) == text) return s;
    return std::nullopt;
}

std::optional<std::uint16_t> mirrored_value(const Point& p, const LineState& line) {
    if (!p.mirrors) return std::nullopt;
    std::string wanted;
    switch (*p.mirrors) {
        case LineSetting::UnitId:
            return line.unit;
        case LineSetting::Framing:
            if (!line.framing || *line.framing == Framing::Tcp) return std::nullopt;
            wanted = to_string(*line.framing);
            break;
        case LineSetting::Baud:
            if (!line.baud) return std::nullopt;
            wanted = std::to_string(*line.baud);
            break;
        case LineSetting::Parity:
            if (!line.parity) return std::nullopt;
            wanted = to_string(*line.parity);
            break;
    }
    for (const auto& v : p.encoding.values)
        if (v.means == wanted && v.value >= 0 && v.value <= 0xFFFF)
            return static_cast<std::uint16_t>(v.value);
    return std::nullopt;
}

const EnumValue* mirrored_meaning(const Point& p, std::uint16_t code) {
    if (!p.mirrors) return nullptr;
    const auto v = std::find_if(p.encoding.values.begin(), p.encoding.values.end(),
                                [&](const EnumValue& e) { return e.value == code; });
    return v == p.encoding.values.end() || v->means.empty() ? nullptr : &*v;
}

void take_meaning(LineState& state, LineSetting setting, const std::string& means) {
    switch (setting) {
        case LineSetting::Framing:
            if (means == "rtu") state.framing = Framing::Rtu;
            if (means == "ascii") state.framing = Framing::Ascii;
            break;
        case LineSetting::Baud: {
            std::uint32_t baud = 0;
            const auto [end, ec] = std::from_chars(means.data(), means.data() + means.size(), baud);
            if (ec == std::errc{} && end == means.data() + means.size() && baud > 0) state.baud = baud;
            break;
        }
        case LineSetting::Parity:
            state.parity = parse_parity(means);
            break;
        case LineSetting::UnitId:
            break;
    }
}

LineState held_line_settings(const Profile& profile,
                             const std::function<std::uint16_t(std::uint16_t)>& read) {
    LineState held;
    for (const Point& p : profile.table(Table::HoldingRegisters)) {
        if (!p.mirrors || *p.mirrors == LineSetting::UnitId || p.encoding.words != 1) continue;
        if (const EnumValue* v = mirrored_meaning(p, read(p.address)))
            take_meaning(held, *p.mirrors, v->means);
    }
    return held;
}

std::optional<RawLimits> raw_limits(const Encoding& e) noexcept {
    if (e.type == EncodingType::F32) return std::nullopt;
    if (e.type == EncodingType::Bool) return RawLimits{0, 1};
    const bool is_signed = e.type == EncodingType::S16 || e.type == EncodingType::S32 || e.is_signed;
    if (e.words == 2) return is_signed ? RawLimits{INT32_MIN, INT32_MAX} : RawLimits{0, UINT32_MAX};
    return is_signed ? RawLimits{INT16_MIN, INT16_MAX} : RawLimits{0, UINT16_MAX};
}

std::array<std::uint16_t, 2> split_words(std::uint32_t value, WordOrder order) noexcept {
    const auto high = static_cast<std::uint16_t>(value >> 16), low = static_cast<std::uint16_t>(value);
    switch (order) {
        case WordOrder::Abcd:
            return {high, low};
        case WordOrder::Cdab:
            return {low, high};
        case WordOrder::Badc:
            return {swap_bytes(high), swap_bytes(low)};
        case WordOrder::Dcba:
            return {swap_bytes(low), swap_bytes(high)};
    }
    return {high, low};
}

const Point* Profile::find(Table t, std::uint16_t address) const noexcept {
    const auto& pts = table(t);
    auto it = std::lower_bound(pts.begin(), pts.end(), address,
                               [](const Point& p, std::uint16_t a) { return p.address < a; });
    if (it != pts.end() && it->address == address) return &*it;
    if (it != pts.begin()) {  // the second register of a 32-bit point
        const Point& prev = *(it - 1);
        if (prev.encoding.words == 2 && prev.address + 1 == address) return &prev;
    }
    return nullptr;
}

std::optional<std::string> set_word_order(Profile& profile, WordOrder order) {
    std::vector<Point*> wide;
    // 32-bit values listed as a low and a high register (CTH2265I): their order is fixed.
    bool halves = false;
    for (auto& table : profile.points)
        for (auto& p : table) {
            if (p.encoding.words == 2) wide.push_back(&p);
            halves |= p.encoding.type == EncodingType::U32Low || p.encoding.type == EncodingType::U32High;
        }
    // The generic profile maps nothing: its registers are read two at a time in the order given, as a
    // device's without a profile (the analyzer does). A map of 16-bit values has nothing to read in it:
    // said, not dropped without a word.
    if (wide.empty() && !halves)
        return profile.open_address_space
                   ? std::nullopt
                   : std::optional<std::string>(profile.id + "'s map holds no 32-bit value");
    const auto& orders = profile.word_orders;
    if (std::find(orders.begin(), orders.end(), order) == orders.end()) {
        std::string why = profile.id + "'s manual gives ";
        if (orders.empty()) return why + "its 32-bit values one order, which its map holds";
        for (std::size_t i = 0; i < orders.size(); ++i)
            why += (i ? i + 1 == orders.size() ? " or " : ", " : "") + std::string(to_string(orders[i]));
        return why + " (the device's setting), not " + std::string(to_string(order));
    }
    for (Point* p : wide)
        if (p->encoding.word_order == orders.front()) p->encoding.word_order = order;
    return std::nullopt;
}

std::string float_text(float f) {
    if (std::isnan(f)) return "nan";
    if (std::isinf(f)) return f < 0 ? "-inf" : "inf";
    char buf[32];
    auto [end, ec] = std::to_chars(buf, buf + sizeof buf, f);
    return ec == std::errc() ? std::string(buf, end) : std::string("?");
}

namespace {

std::string format_number(double v, int decimals) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

// A formula's value in full, to the microunit (the CTH's 19.999756 mA for 65535), without an exponent below
// 10^15 (65535000, not 6.5535e+07), trailing zeros dropped; one the arithmetic leaves undefined (a division
// by zero) said as such, never "-nan".
std::string formula_text(double v) {
    if (std::isnan(v)) return "undefined (the formula divides by zero)";
    if (std::isinf(v)) return std::string(v < 0 ? "-" : "") + "infinite (the formula divides by zero)";
    if (v == 0) v = 0;  // not "-0"
    char buf[64];
    if (std::fabs(v) >= 1e15) {
        std::snprintf(buf, sizeof buf, "%.6e", v);
        return buf;
    }
    std::snprintf(buf, sizeof buf, "%.6f", v);
    std::string text = buf;
    text.erase(text.find_last_not_of('0') + 1);
    if (text.back() == '.') text.pop_back();
    return text == "-0" ? "0" : text;
}

bool in_block(std::uint16_t address, std::uint16_t start, const std::vector<std::uint16_t>& words) {
    return address >= start && address - start < static_cast<int>(words.size());
}

// The registers a block is decoded with: its own words, then those known from elsewhere, each in its table.
struct Known {
    const Profile& profile;
    Table table;  // the block's
    std::uint16_t start;
    const std::vector<std::uint16_t>& words;
    const RegisterContext& context;

    // Register `address` of table `t`, from the block when it is the block's table (or the same map).
    std::optional<std::uint16_t> at(Table t, std::uint16_t address) const {
        const Table resolved = profile.resolve(t);
        if (resolved == profile.resolve(table) && in_block(address, start, words))
            return words[address - start];
        if (resolved != Table::HoldingRegisters && resolved != Table::InputRegisters) return std::nullopt;
        const auto& seen = resolved == Table::InputRegisters ? context.input : context.holding;
        if (auto it = seen.find(address); it != seen.end()) return it->second;
        return std::nullopt;
    }
    std::optional<std::uint16_t> at(std::uint16_t address) const { return at(table, address); }
    std::optional<std::uint16_t> at(const PointRef& ref) const { return at(ref.table, ref.address); }
};

// The decimals of a value: the encoding's own, or those another register gives (`decimals_from`).
struct Decimals {
    std::optional<int> places;
    std::string why_not;  // when there are none: " (unscaled: ...)"
};
Decimals decimals_of(const Encoding& e, const Known& known) {
    const Profile& profile = known.profile;
    if (!e.decimals_unknown.empty()) return {std::nullopt, " (unscaled: " + e.decimals_unknown + ")"};
    if (const auto& field = e.decimals_from_byte) {
        // One byte of the register is this value's decimal point, the other another value's, and the manual
        // does not say which: known when both hold the same. (Shown as a plain number, 100000 was taken for
        // a set-point of 100000 where the device meant 1000.00.)
        const auto d = known.at(*field);
        const std::string reg = "register " + std::to_string(field->address);
        if (!d) return {std::nullopt, " (unscaled: decimal point unknown, " + reg + " not seen)"};
        const int high = *d >> 8, low = *d & 0xFF;
        if (high != low)
            return {std::nullopt, " (unscaled: " + reg + " holds the decimal points " + std::to_string(high) +
                                      " and " + std::to_string(low) +
                                      ", one a byte, and the manual does not say which is this value's)"};
        if (high > 9)
            return {std::nullopt, " (unscaled: " + reg + " holds " + std::to_string(high) +
                                      " in each byte, no number of places)"};
        return {high, {}};
    }
    const PointRef* decimals_from = e.decimals_from ? &*e.decimals_from : nullptr;
    if (const auto& choice = e.decimals_selected) {
        // The register that gives the decimals is the one the selector's value names; with the selector not
        // known, so is the decimal point not.
        const auto selected = known.at(choice->selector);
        if (!selected)
            return {std::nullopt, " (unscaled: decimal point unknown, register " +
                                      std::to_string(choice->selector.address) +
                                      " that selects it not seen)"};
        for (const auto& [value, ref] : choice->by_value)
            if (value == *selected) decimals_from = &ref;
        if (!decimals_from)
            return {std::nullopt, " (unscaled: register " + std::to_string(choice->selector.address) +
                                      " holds " + std::to_string(*selected) +
                                      ", which selects no decimal point register)"};
    }
    if (!decimals_from) return {e.decimals, {}};
    const auto d = known.at(*decimals_from);
    if (!d) return {std::nullopt, " (unscaled: decimal point unknown)"};
    // What that register may hold: 0 to 9, and within its own enumeration and range (MK's PT.DEC of a
    // totalization, 0 to 7: 000:1358). Another value is no number of places, and is said to be.
    const Point* from = profile.find(decimals_from->table, decimals_from->address);
    bool valid = *d <= 9;
    if (from && !from->encoding.values.empty())
        valid &= std::any_of(from->encoding.values.begin(), from->encoding.values.end(),
                             [&](const EnumValue& v) { return v.value == *d; });
    if (from && from->max) valid &= *d <= *from->max;
    if (!valid)
        return {std::nullopt, " (unscaled: its decimal point register " +
                                  std::to_string(decimals_from->address) + " holds " + std::to_string(*d) +
                                  ", no number of places)"};
    return {*d, {}};
}

// What one 8-bit field holds: its enumeration's meaning, its bits' names, its character, else its number.
std::string byte_field_text(const Encoding& e, const ByteField& field, std::uint8_t b) {
    std::string text = std::to_string(b);
    if (field.ascii && b >= 0x20 && b < 0x7F) return text + " '" + static_cast<char>(b) + "'";
    std::string meanings;
    for (const auto& ev : e.values)
        if (ev.value == b)
            meanings += (meanings.empty() ? "" : " or ") + (ev.text_en.empty() ? ev.text : ev.text_en);
    for (const auto& bit : e.bits)
        if (bit.bit < 8 && ((b >> bit.bit) & 1u))
            meanings += (meanings.empty() ? "" : ", ") + (bit.name_en.empty() ? bit.name : bit.name_en);
    return meanings.empty() ? text : text + " (" + meanings + ")";
}

// "alarm 1 or 2: 3 (HI), alarm 2 or 1: 4 (SHI)": each byte of a register of two 8-bit fields, under the
// manual's name for it, or as the high and the low byte where the manual does not say which is which.
std::string byte_fields_text(const Encoding& e, std::uint16_t w) {
    std::string text;
    for (int i = 0; i < 2; ++i) {
        const ByteField& f = e.bytes[static_cast<std::size_t>(i)];
        const bool named = !f.name.empty() && f.name != "?";
        text += (i ? ", " : "") + (named ? f.name : std::string(i == 0 ? "high byte" : "low byte")) + ": " +
                byte_field_text(e, f, static_cast<std::uint8_t>(i == 0 ? w >> 8 : w & 0xFF));
    }
    return text;
}

// The number two registers hold as a 32-bit value of the encoding's type and word order: decoding a read
// and judging a write take it the same way.
double value_32(const Encoding& e, std::uint16_t first, std::uint16_t second) {
    const std::uint32_t u = join_words(first, second, e.word_order);
    if (e.type == EncodingType::S32) return static_cast<std::int32_t>(u);
    if (e.type == EncodingType::F32) {
        float f;
        std::memcpy(&f, &u, sizeof f);
        return f;
    }
    return u;
}

// A value no encoding put into words is shown as its number, a float as the shortest text that reads back
// as it (three decimals made 0.000123 "0.000", a measurement not told from zero, and 1.2345679 "1.235"). A
// partial one has no number: its text says what the word is, and a reader of the JSON must not take one
// half of a float, or a value not yet scaled, for the value.
NamedValue with_text(NamedValue v) {
    if (v.text.empty() && v.number && v.point && v.point->encoding.type == EncodingType::F32)
        v.text = float_text(static_cast<float>(*v.number));
    if (v.text.empty() && v.number)
        v.text = format_number(*v.number, std::floor(*v.number) == *v.number ? 0 : 3);
    if (v.partial) v.number.reset();
    return v;
}
}  // namespace

std::vector<NamedValue> decode_registers(const Profile& profile, Table table, std::uint16_t start,
                                         const std::vector<std::uint16_t>& words,
                                         const RegisterContext& context) {
    const Known known{profile, table, start, words, context};
    std::vector<NamedValue> out;
    // Words past address 65535 (a reply to a read that ran past the end) are named by nothing here.
    const std::size_t in_space = count_within_address_space(start, words.size());
    for (std::size_t i = 0; i < in_space; ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        NamedValue v;
        v.address = address;
        v.point = profile.find(table, address);
        const std::uint16_t w = words[i];
        v.raw = {w};
        if (!v.point) {
            v.number = w;
            v.text = std::to_string(w);
            out.push_back(std::move(v));
            continue;
        }
        const Point& p = *v.point;
        const Encoding& e = p.encoding;
        const auto whole_32 = [&](std::uint16_t first, std::uint16_t second) {
            v.raw = {first, second};
            v.number = value_32(e, first, second);
        };
        // The other half known from an earlier reply, not from this block: said, since it may have changed.
        const auto earlier = [&](std::uint16_t other) {
            if (!in_block(other, start, words)) v.other_half_earlier = other;
        };
        if (e.words == 2 && p.address != address) {
            // A second half. Taken with its first when the block holds that (it then starts before this
            // word); a block that starts here (a read from the middle of a value, a write of one register)
            // still shows it: whole when the first half is known from elsewhere, else alone.
            if (address != start) continue;
            if (auto first = known.at(p.address)) {
                whole_32(*first, w);
                earlier(p.address);
            } else {
                v.partial = true;
                v.text = std::to_string(w) + " (second half only)";
            }
            out.push_back(with_text(std::move(v)));
            continue;
        }
        switch (e.type) {
            case EncodingType::U16:
                v.number = w;
                break;
            case EncodingType::S16:
                v.number = static_cast<std::int16_t>(w);
                break;
            case EncodingType::Fixed:
                v.number = (e.is_signed ? static_cast<std::int16_t>(w) : w) / std::pow(10.0, e.decimals);
                v.text = format_number(*v.number, e.decimals);
                break;
            case EncodingType::Scaled: {
                const double raw = e.is_signed ? static_cast<std::int16_t>(w) : w;
                const auto decimals = decimals_of(e, known);
                v.partial = !decimals.places;  // shown unscaled, and said to be
                v.number = raw / std::pow(10.0, decimals.places.value_or(0));
                v.text = format_number(*v.number, decimals.places.value_or(0)) + decimals.why_not;
                break;
            }
            case EncodingType::Enum:
            case EncodingType::Status: {
                v.number = w;
                v.text = std::to_string(w);
                // A manual may give a value two meanings (by the device's type or mode, as Walchem's alarm
                // bits): every one is shown, not whichever was listed last.
                std::string meanings;
                for (const auto& ev : e.values)
                    if (ev.value == w)
                        meanings += (meanings.empty() ? "" : " or ") +
                                    (ev.text_en.empty() ? ev.text : ev.text + " (" + ev.text_en + ")");
                if (!meanings.empty()) v.text = meanings;
                break;
            }
            case EncodingType::AsciiChar:
                v.number = w;
                v.text = (w >= 0x20 && w < 0x7F) ? std::string("'") + static_cast<char>(w) + "'"
                                                 : std::to_string(w);
                break;
            case EncodingType::Digits4High:
            case EncodingType::Digits4Low:
            case EncodingType::U32Low:
            case EncodingType::U32High: {
                const bool high_first =
                    e.type == EncodingType::Digits4High || e.type == EncodingType::U32High;
                auto other = e.pair ? known.at(*e.pair) : std::nullopt;
                const bool digits = e.type == EncodingType::Digits4High || e.type == EncodingType::Digits4Low;
                if (!other) {
                    v.partial = true;
                    v.text = std::to_string(w) + " (one half only)";
                    break;
                }
                const std::uint16_t hi = high_first ? w : *other, lo = high_first ? *other : w;
                // The registers in address order, as for 32-bit values: CTH2265I's low word comes first
                // (003:600), MK's first four digits do (000:1243). Both halves list the pair so.
                const std::vector<std::uint16_t> in_address_order =
                    *e.pair > address ? std::vector<std::uint16_t>{w, *other}
                                      : std::vector<std::uint16_t>{*other, w};
                if (digits && (hi > 9999 || lo > 9999)) {
                    // Four digits a register ("4 primeiros / 4 últimos dígitos", 000:1243): a half above 9999
                    // is no digits, and read as such made a total that never was (10000 0 as 100000000).
                    v.raw = in_address_order;
                    earlier(*e.pair);
                    v.text = std::to_string(hi) + " " + std::to_string(lo) +
                             " (not digits: each half holds four, 0 to 9999)";
                    break;
                }
                const double whole =
                    digits ? hi * 10000.0 + lo : static_cast<double>((std::uint32_t{hi} << 16) | lo);
                v.raw = in_address_order;
                earlier(*e.pair);
                // A total whose decimal point another register gives (MK 3.13, 3.22: PT.DEC of the
                // totalization, 000:1243): shown unscaled, and said to be, while that register is unknown.
                const auto decimals = decimals_of(e, known);
                v.number = whole / std::pow(10.0, decimals.places.value_or(0));
                v.text = format_number(*v.number, decimals.places.value_or(0)) + decimals.why_not;
                v.partial = !decimals.places;
                break;
            }
            case EncodingType::U32:
            case EncodingType::S32:
            case EncodingType::F32: {
                auto second =
                    address == 0xFFFF ? std::nullopt : known.at(static_cast<std::uint16_t>(address + 1));
                if (!second) {
                    v.partial = true;
                    v.text = std::to_string(w) + " (first half only)";
                    break;
                }
                whole_32(w, *second);
                earlier(static_cast<std::uint16_t>(address + 1));
                break;
            }
            case EncodingType::Bits: {
                // Bits the manual names by their names; one it does not name (Walchem packs its fields in
                // the low byte, 002:440-443) by its number: said "none", a field with bit 8 set read as
                // "no alarm".
                v.number = w;
                std::string names;
                std::uint16_t named = 0;
                for (const auto& b : e.bits)
                    if (b.bit < 16) {
                        named |= static_cast<std::uint16_t>(1u << b.bit);
                        if ((w >> b.bit) & 1u)
                            names += (names.empty() ? "" : ", ") + (b.name_en.empty() ? b.name : b.name_en);
                    }
                for (int bit = 0; bit < 16; ++bit)
                    if ((w & ~named) >> bit & 1u)
                        names += (names.empty() ? "" : ", ") +
                                 ("bit " + std::to_string(bit) + " (not in the map)");
                v.text = names.empty() ? "none" : names;
                break;
            }
            case EncodingType::Bool:
                v.number = w ? 1 : 0;
                break;
            case EncodingType::Bytes2:
                // Two fields, each named and shown on its own: the number is the register's.
                v.number = w;
                v.text = byte_fields_text(e, w);
                break;
            case EncodingType::Formula:
                v.number = evaluate(e.formula, e.is_signed ? static_cast<std::int16_t>(w) : w);
                v.text = formula_text(*v.number);
                break;
        }
        out.push_back(with_text(std::move(v)));
    }
    return out;
}

std::uint8_t exception_for(const Profile& profile, const char* condition,
                           std::uint8_t specification_default) {
    auto it = profile.functions.exceptions.find(condition);
    if (it != profile.functions.exceptions.end() && it->second) return static_cast<std::uint8_t>(*it->second);
    return specification_default;
}

namespace {

// Is this point writable at all? nullopt: yes; otherwise why not.
std::optional<WriteRejection> check_writable(const Profile& profile, const Point* p, std::uint16_t address) {
    if (!p || p->reserved)
        return WriteRejection{exception_for(profile, "bad_address", 2), address, "address not in the map"};
    if (p->access == Access::Read)
        return WriteRejection{exception_for(profile, "write_read_only", 2), address, "read-only point"};
    return std::nullopt;
}

std::string format_limit(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

std::optional<WriteRejection> check_range(const Profile& profile, const Point& p, std::uint16_t address,
                                          double v, const std::string& shown) {
    const auto bad = [&](const std::string& why) {
        return WriteRejection{exception_for(profile, "bad_value", 3), address, "value " + shown + " " + why};
    };
    if (p.min && v < static_cast<double>(*p.min))
        return bad("below minimum " + format_limit(static_cast<double>(*p.min)));
    if (p.max && v > static_cast<double>(*p.max))
        return bad("above maximum " + format_limit(static_cast<double>(*p.max)));
    return std::nullopt;
}

// A 16-bit value written to a one-register point (or one half of a 32-bit point, which is not range-checked).
std::optional<WriteRejection> check_word(const Profile& profile, const Point& p, std::uint16_t address,
                                         std::uint16_t value) {
    const Encoding& e = p.encoding;
    if (e.words == 2) return std::nullopt;
    const bool is_signed = e.type == EncodingType::S16 || e.is_signed;
    const std::int64_t v = is_signed ? static_cast<std::int16_t>(value) : value;
    if (e.type == EncodingType::Enum && !e.values.empty()) {
        const auto it = std::find_if(e.values.begin(), e.values.end(),
                                     [&](const EnumValue& ev) { return ev.value == v; });
        if (it == e.values.end())
            return WriteRejection{exception_for(profile, "bad_value", 3), address,
                                  "value " + std::to_string(v) + " not among the enumeration's values"};
        if (it->forbidden)
            return WriteRejection{
                exception_for(profile, "bad_value", 3), address,
                "value " + std::to_string(v) + " is one the manual does not allow (\"" + it->text + "\")"};
    }
    // Two 8-bit fields whose values the map lists apply them to each byte (CTH2265I's alarm types, 0 to 4 in
    // each, 003:621): a byte outside them is a value out of range (003:574: exception 03).
    if (e.type == EncodingType::Bytes2 && !e.values.empty())
        for (const bool high : {true, false}) {
            const int byte = high ? value >> 8 : value & 0xFF;
            bool listed = false;
            for (const auto& ev : e.values)
                listed |= ev.value == byte;
            if (!listed)
                return WriteRejection{exception_for(profile, "bad_value", 3), address,
                                      std::string(high ? "high" : "low") + " byte " + std::to_string(byte) +
                                          " not among the values each byte takes"};
        }
    // A boolean in a register is its least significant bit (Walchem, 002:424-429): 0 or 1, nothing else.
    if (e.type == EncodingType::Bool && value > 1)
        return WriteRejection{exception_for(profile, "bad_value", 3), address,
                              "value " + std::to_string(value) + " is no boolean (0 or 1)"};
    if (e.type == EncodingType::AsciiChar && !e.allowed.empty() &&
        (value > 0x7F || e.allowed.find(static_cast<char>(value)) == std::string::npos))
        return WriteRejection{exception_for(profile, "bad_value", 3), address,
                              "character " + std::to_string(value) + " not among the allowed ones"};
    return check_range(profile, p, address, static_cast<double>(v), std::to_string(v));
}

}  // namespace

std::optional<std::uint8_t> check_read(const Profile& profile, Table t, std::uint16_t start,
                                       std::uint32_t quantity) {
    const auto bad = exception_for(profile, "bad_address", 0x02);
    if (start + quantity > 65536u) return bad;
    if (profile.open_address_space) return std::nullopt;
    if (!profile.implements(t) && !profile.implements(profile.resolve(t))) return bad;
    const std::uint32_t checked = profile.functions.address_check == AddressCheck::First ? 1 : quantity;
    for (std::uint32_t i = 0; i < checked; ++i)
        if (!profile.find(t, static_cast<std::uint16_t>(start + i))) return bad;
    return std::nullopt;
}

std::optional<WriteRejection> check_writes(
    const Profile& profile, Table table, std::uint16_t start, const std::vector<std::uint16_t>& values,
    const std::function<std::optional<std::uint16_t>(std::uint16_t)>& held) {
    if (profile.open_address_space || values.empty()) return std::nullopt;
    const std::size_t checked_addresses =
        profile.functions.address_check == AddressCheck::First ? 1 : values.size();
    for (std::size_t i = 0; i < checked_addresses; ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        if (auto r = check_writable(profile, profile.find(table, address), address)) return r;
    }
    for (std::size_t i = 0; i < values.size(); ++i) {
        const auto address = static_cast<std::uint16_t>(start + i);
        const Point* p = profile.find(table, address);
        if (!p || p->reserved || p->access == Access::Read)
            continue;  // unchecked addresses (first-only devices)
        const Encoding& e = p->encoding;
        if (e.words == 2) {
            const bool whole = p->address == address && i + 1 < values.size();
            std::uint16_t first = values[i], second = whole ? values[i + 1] : 0;
            if (!whole) {  // a lone half: with the other half the device holds, when it is known
                const bool is_first = p->address == address;
                const auto other =
                    held ? held(static_cast<std::uint16_t>(is_first ? address + 1 : address - 1))
                         : std::nullopt;
                if (!other) continue;
                first = is_first ? values[i] : *other;
                second = is_first ? *other : values[i];
            }
            const double v = value_32(e, first, second);
            if (!std::isfinite(v))  // a float's NaN or infinity
                return WriteRejection{exception_for(profile, "bad_value", 3), address,
                                      "value is not a finite number"};
            // A float in full: six digits made 90.0000076 "90", "above maximum 90".
            const std::string shown = e.type == EncodingType::F32
                                          ? float_text(static_cast<float>(v))
                                          : std::to_string(static_cast<std::int64_t>(v));
            if (auto r = check_range(profile, *p, address, v, shown)) return r;
            if (whole) ++i;
            continue;
        }
        if (auto r = check_word(profile, *p, address, values[i])) return r;
    }
    return std::nullopt;
}

std::optional<std::uint8_t> check_write(const Profile& profile, Table table, std::uint16_t address,
                                        std::uint16_t value) {
    if (auto r = check_writes(profile, table, address, {value})) return r->exception_code;
    return std::nullopt;
}

}  // namespace mbscope::modbus
