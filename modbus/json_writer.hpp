#pragma once
// A streaming JSON writer for record streams (mbscope decode --jsonl): values are appended to a text buffer
// as they come, with no document in between. nlohmann::json remains the project's JSON library (every
// parse, every document, every summary); this exists because building an nlohmann object for each of a
// million frames and dumping it cost nine times the analysis itself (bench/README.md). Tests check that
// every record it writes parses with nlohmann::json into the document nlohmann's own builder makes.
//
// Output rules, as nlohmann::json::dump() with error_handler_t::replace: strings are escaped (", \, control
// characters) and bytes that are not valid UTF-8 become U+FFFD; a double is written in the shortest form
// that reads back to the same value, with ".0" when it is integral; NaN and infinities are null.

#include <cassert>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace mbscope::modbus {

// Printable ASCII with no quote and no backslash: a JSON string of it is the text between quotes.
constexpr bool json_plain(std::string_view text) noexcept {
    for (char c : text) {
        const auto u = static_cast<unsigned char>(c);
        if (u < 0x20 || u >= 0x80 || c == '"' || c == '\\') return false;
    }
    return true;
}

// A key written in the program: checked when the program is compiled (it needs no escaping), so writing it
// is a copy. Keys known only at run time go through JsonWriter::dynamic_key().
struct JsonKey {
    std::string_view name;
    template <std::size_t N>
    consteval JsonKey(const char (&text)[N]) : name(text, N - 1) {  // NOLINT: literals convert
        if (!json_plain(name)) throw "a JsonKey must need no escaping";
    }
};

class JsonWriter {
  public:
    JsonWriter() = default;
    JsonWriter(const JsonWriter&) = delete;
    JsonWriter& operator=(const JsonWriter&) = delete;

    // What has been written since the last clear().
    std::string_view text() const noexcept { return {buffer_.get(), size_}; }
    std::size_t size() const noexcept { return size_; }
    void clear() noexcept {
        size_ = 0;
        first_ = true;
        after_key_ = false;
    }
    // Text that is already JSON (a document dumped by nlohmann::json), as the next value.
    void raw(std::string_view json) {
        separate();
        append(json.data(), json.size());
    }

    void begin_object() { open('{'); }
    void end_object() { close('}'); }
    void begin_array() { open('['); }
    void end_array() { close(']'); }
    // A key of the object being written; the value follows with one of the calls below.
    void key(JsonKey k) { plain_key(k.name); }
    // A key made by the program at run time from names that need no escaping ("sub_request[0].file_number").
    void plain_key(std::string_view name) {
        assert(json_plain(name));
        size_ = static_cast<std::size_t>(put_key(reserve(name.size() + 4), name) - buffer_.get());
        after_key_ = true;
    }
    void dynamic_key(std::string_view name);

    void value(std::string_view text);
    // A string its owner knows needs no escaping (printable ASCII, no quote, no backslash): copied as it is.
    void plain_value(std::string_view text) {
        assert(json_plain(text));  // debug builds hold the owner to its word
        separate();
        quoted(text);
    }
    void value(const char* text) { value(std::string_view(text)); }
    void value(bool b);
    void value(double d);
    void value(float f) { value(static_cast<double>(f)); }
    void value(std::uint64_t n);
    void value(std::int64_t n);
    void value(std::uint32_t n) { value(static_cast<std::uint64_t>(n)); }
    void value(std::uint16_t n) { value(static_cast<std::uint64_t>(n)); }
    void value(std::uint8_t n) { value(static_cast<std::uint64_t>(n)); }
    void value(int n) { value(static_cast<std::int64_t>(n)); }
    void null();
    // [1,2,3]: register values, the commonest array of a record stream, written through one cursor.
    void value(std::span<const std::uint16_t> words);
    // "11 03 00 60": bytes as the hex_bytes() string, without making the string first.
    void hex_value(std::span<const std::uint8_t> bytes);

    // The end of one record of a JSON-lines stream: a newline, and the next value starts a new record.
    void end_line() {
        put('\n');
        first_ = true;
        after_key_ = false;
    }

    template <class T>
    void member(JsonKey name, const T& v) {
        key(name);
        value(v);
    }
    // The hot members of a record stream, key and value written through one cursor; inline, so that the
    // key's length is a constant where the key is a literal.
    void member(JsonKey name, std::uint64_t n) {
        char* p = put_key(reserve(name.name.size() + 4 + 20), name.name);
        size_ = static_cast<std::size_t>(std::to_chars(p, p + 20, n).ptr - buffer_.get());
    }
    void member(JsonKey name, std::uint32_t n) { member(name, static_cast<std::uint64_t>(n)); }
    void member(JsonKey name, std::uint16_t n) { member(name, static_cast<std::uint64_t>(n)); }
    void member(JsonKey name, std::uint8_t n) { member(name, static_cast<std::uint64_t>(n)); }
    void member(JsonKey name, bool b) {
        char* p = put_key(reserve(name.name.size() + 4 + 5), name.name);
        if (b) {
            std::memcpy(p, "true", 4);
            p += 4;
        } else {
            std::memcpy(p, "false", 5);
            p += 5;
        }
        size_ = static_cast<std::size_t>(p - buffer_.get());
    }
    // A member whose text its owner knows needs no escaping (see plain_value).
    void plain_member(JsonKey name, std::string_view text) {
        assert(json_plain(text));
        char* p = put_key(reserve(name.name.size() + text.size() + 6), name.name);
        size_ = static_cast<std::size_t>(put_quoted(p, text) - buffer_.get());
    }

  private:
    // Room for n more characters; the buffer grows by doubling and is kept across clear().
    char* reserve(std::size_t n) {
        if (capacity_ - size_ < n) grow(n);
        return buffer_.get() + size_;
    }
    void grow(std::size_t n);
    void append(const char* p, std::size_t n) {
        std::memcpy(reserve(n), p, n);
        size_ += n;
    }
    void put(char c) {
        *reserve(1) = c;
        ++size_;
    }
    // `,"key":` (no comma at the start of an object) at p, which has room for it; returns the end. The
    // writer's state is read once and the text written through a local cursor: a store through a char*
    // may alias any member, so writing through put() made the compiler reload them after every character.
    char* put_key(char* p, std::string_view name) {
        if (!first_) *p++ = ',';
        first_ = false;
        *p++ = '"';
        std::memcpy(p, name.data(), name.size());
        p += name.size();
        *p++ = '"';
        *p++ = ':';
        return p;
    }
    void separate() {
        if (after_key_) {
            after_key_ = false;
            return;
        }
        if (!first_) put(',');
        first_ = false;
    }
    void open(char c) {
        separate();
        put(c);
        first_ = true;
    }
    void close(char c) {
        put(c);
        first_ = false;
    }
    // text between quotes, as it is (json_plain text), at p, which has room for it; returns the end
    static char* put_quoted(char* p, std::string_view text) {
        *p++ = '"';
        std::memcpy(p, text.data(), text.size());
        p += text.size();
        *p++ = '"';
        return p;
    }
    void quoted(std::string_view text) {
        size_ = static_cast<std::size_t>(put_quoted(reserve(text.size() + 2), text) - buffer_.get());
    }
    void escaped(std::string_view text);

    std::unique_ptr<char[]> buffer_;
    std::size_t size_ = 0, capacity_ = 0;
    bool first_ = true;       // nothing written yet in the innermost object or array (or at top level)
    bool after_key_ = false;  // a key was written: its value needs no comma
};

}  // namespace mbscope::modbus
