#include "modbus/profile_headers.hpp"

#include <cctype>
#include <optional>
#include <set>

#include <nlohmann/json.hpp>

namespace mbscope::modbus {

namespace {

using json = nlohmann::json;

std::string lower(std::string s) {
    for (auto& c : s)  // as the document parser does
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// Where the event stream is: one entry per open object or array, with the key or index being read in it.
struct Level {
    bool object = false;
    std::string key;             // objects: the key whose value comes next
    std::size_t elements = 0;    // arrays: the values read so far
    bool models = false;         // this array is the root's "models"
    std::set<std::string> keys;  // the objects read from (the root, "line", a model): their keys so far
};

// A JSON pointer's reference token for an object key (RFC 6901), as the document parser writes it.
std::string pointer_token(const std::string& key) {
    std::string out;
    for (char c : key)
        out += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
    return out;
}

// Reads the few fields a listing needs and skips the rest of the document, which the stream still checks
// for JSON syntax. A key given twice in an object it reads from is refused, as the document parser refuses
// it (the parser refuses one anywhere in the document, which the load finds): the scan took the last "id"
// given, and a listing could name a device the load does not give. Places, as stack depths: 1 the root
// object, 2 a root field's value ("models" or "line"), 3 a model object or the line's "transports", 4 a
// model's "aliases".
class HeaderScanner final : public nlohmann::json_sax<json> {
  public:
    explicit HeaderScanner(ProfileHeaders& out) : out_(out) {}

    bool null() override { return value(nullptr); }
    bool boolean(bool) override { return value(nullptr); }
    bool number_integer(number_integer_t) override { return value(nullptr); }
    bool number_unsigned(number_unsigned_t) override { return value(nullptr); }
    bool number_float(number_float_t, const string_t&) override { return value(nullptr); }
    bool binary(binary_t&) override { return value(nullptr); }
    bool string(string_t& s) override { return value(&s); }

    bool start_object(std::size_t) override {
        if (stack_.empty()) root_is_object_ = true;
        if (in_models()) {  // a model: model_field() reads into it
            out_.models.emplace_back();
            named_.push_back(false);
        }
        value(nullptr);
        stack_.push_back({true, {}, 0, false, {}});
        return true;
    }
    bool key(string_t& k) override {
        if (const bool read_from = stack_.size() == 1 || model_field() ||
                                   (stack_.size() == 2 && stack_[0].key == "line" && stack_[1].object);
            read_from && !stack_.back().keys.insert(k).second) {
            if (stack_.size() == 1 && k == "format") format_twice_ = true;
            if (!repeat_) repeat_ = {pointer(), k};
        }
        stack_.back().key = k;
        if (stack_.size() == 1) {  // a root field given again replaces what was read of it (a profile
                                   // is refused for it, a document of another kind is not)
            if (k == "models") {
                out_.models.clear();
                named_.clear();
                models_ = std::nullopt;
            } else if (k == "line") {
                out_.transports.clear();
            } else if (k == "modular") {
                out_.modular = true;
            }
        } else if (model_field() && k == "aliases") {
            out_.models.back().aliases.clear();
        } else if (stack_.size() == 2 && stack_[0].key == "line" && stack_[1].object && k == "transports") {
            out_.transports.clear();
        }
        return true;
    }
    bool end_object() override {
        stack_.pop_back();
        return true;
    }
    bool start_array(std::size_t) override {
        const bool models = stack_.size() == 1 && stack_.back().object && stack_.back().key == "models";
        value(nullptr);
        stack_.push_back({false, {}, 0, models, {}});
        return true;
    }
    bool end_array() override {
        if (stack_.back().models) models_ = stack_.back().elements;
        stack_.pop_back();
        return true;
    }
    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
        syntax_error_ = std::string("not valid JSON: ") + e.what();
        return false;
    }

    bool root_is_object() const { return root_is_object_; }
    // The first object read from that gives a key twice: its pointer and the key.
    const std::optional<std::pair<std::string, std::string>>& repeat() const { return repeat_; }
    bool format_twice() const { return format_twice_; }
    const std::string& syntax_error() const { return syntax_error_; }
    bool format_given() const { return format_given_; }
    const std::optional<std::string>& format() const { return format_; }
    // The elements of the root's "models" when it is an array; nothing when it is absent or not an array.
    std::optional<std::size_t> models() const { return models_; }
    // Whether each model has a name of its own (a string, even an empty one); the others take their id.
    const std::vector<bool>& named() const { return named_; }

  private:
    bool in_models() const { return stack_.size() == 2 && stack_[1].models; }
    bool model_field() const { return stack_.size() == 3 && stack_[1].models && stack_[2].object; }
    // The pointer of the innermost object or array.
    std::string pointer() const {
        std::string out;
        for (std::size_t i = 0; i + 1 < stack_.size(); ++i)
            out += '/' +
                   (stack_[i].object ? pointer_token(stack_[i].key) : std::to_string(stack_[i].elements - 1));
        return out;
    }

    // A value (a scalar, or the start of an object or array) at the current place; `s` when it is a string.
    bool value(const std::string* s) {
        if (stack_.empty()) return true;
        Level& at = stack_.back();
        if (!at.object) ++at.elements;
        if (stack_.size() == 1) {
            if (at.key == "format") {
                format_given_ = true;
                format_ = s ? std::optional<std::string>(*s) : std::nullopt;
            } else if (at.key == "vendor") {
                out_.vendor = s ? *s : std::string();
            } else if (at.key == "family") {
                out_.family = s ? *s : std::string();
            } else if (at.key == "models") {
                models_ = std::nullopt;  // start_array() follows when it is an array
            }
        } else if (model_field()) {
            if (at.key == "id") out_.models.back().id = s ? lower(*s) : std::string();
            if (at.key == "name") {
                out_.models.back().name = s ? *s : std::string();
                named_.back() = s != nullptr;
            }
        } else if (s && stack_.size() == 3 && stack_[0].key == "line" && stack_[1].object &&
                   stack_[1].key == "transports" && !at.object) {
            out_.transports.push_back(*s);
        } else if (s && stack_.size() == 4 && stack_[1].models && stack_[2].object &&
                   stack_[2].key == "aliases" && !at.object) {
            out_.models.back().aliases.push_back(lower(*s));
        }
        return true;
    }

    ProfileHeaders& out_;
    std::vector<Level> stack_;
    bool root_is_object_ = false;
    bool format_given_ = false;
    std::optional<std::string> format_;
    std::optional<std::size_t> models_;
    std::vector<bool> named_;
    std::string syntax_error_;
    std::optional<std::pair<std::string, std::string>> repeat_;
    bool format_twice_ = false;
};

}  // namespace

ProfileHeaders scan_profile_headers(std::string_view text, const std::string& file) {
    ProfileHeaders out;
    HeaderScanner scan(out);
    const bool whole = json::sax_parse(text.begin(), text.end(), &scan);
    // What the document parser says of the same faults, in the same words (modbus/profile_loader.cpp).
    const auto refuse = [&](const std::string& pointer, const std::string& message, bool is_profile) {
        ProfileHeaders refused;
        refused.is_profile = is_profile;
        if (!message.empty()) refused.errors.push_back({file, pointer, message});
        return refused;
    };
    if (!whole) return refuse("", scan.syntax_error().empty() ? "not valid JSON" : scan.syntax_error(), true);
    if (!scan.root_is_object()) return refuse("", "a profile is a JSON object", true);
    const auto repeated = [&] {
        return refuse(scan.repeat()->first,
                      "key \"" + scan.repeat()->second + "\" is given twice: which one counts is not defined",
                      true);
    };
    if (scan.format_twice()) return repeated();  // which kind of document it is is undecided
    if (scan.format_given() && !scan.format()) return refuse("/format", "must be a string", false);
    if (!scan.format() || *scan.format() != profile_format) {
        if (scan.format() && scan.format()->rfind("mbscope-profile/", 0) == 0)
            return refuse("/format",
                          "unsupported format version \"" + *scan.format() + "\" (this mbscope reads " +
                              std::string(profile_format) + ")",
                          false);
        return refuse("", "", false);
    }
    if (scan.repeat()) return repeated();
    if (!scan.models() || *scan.models() == 0)
        return refuse("", "\"models\" must list at least one model (the device ids this file resolves to)",
                      true);
    for (std::size_t i = 0; i < out.models.size(); ++i)
        if (!scan.named()[i]) out.models[i].name = out.models[i].id;
    return out;
}

}  // namespace mbscope::modbus
