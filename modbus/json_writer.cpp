#include "modbus/json_writer.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>

namespace mbscope::modbus {

namespace {

// Length of the valid UTF-8 sequence at the start of `s` (RFC 3629: no overlong forms, no surrogates,
// nothing above U+10FFFF), 0 when it is not one.
std::size_t utf8_sequence(std::string_view s) {
    const auto b = [&s](std::size_t i) { return static_cast<unsigned char>(s[i]); };
    const unsigned char c = b(0);
    const auto cont = [&](std::size_t i) { return i < s.size() && (b(i) & 0xC0) == 0x80; };
    if (c >= 0xC2 && c <= 0xDF) return cont(1) ? 2 : 0;
    if (c >= 0xE0 && c <= 0xEF) {
        if (!cont(1) || !cont(2)) return 0;
        if (c == 0xE0 && b(1) < 0xA0) return 0;   // overlong
        if (c == 0xED && b(1) >= 0xA0) return 0;  // UTF-16 surrogate
        return 3;
    }
    if (c >= 0xF0 && c <= 0xF4) {
        if (!cont(1) || !cont(2) || !cont(3)) return 0;
        if (c == 0xF0 && b(1) < 0x90) return 0;   // overlong
        if (c == 0xF4 && b(1) >= 0x90) return 0;  // above U+10FFFF
        return 4;
    }
    return 0;
}

// Bytes an invalid sequence at the start of `s` spans: its lead byte and the continuation bytes that were
// still possible after it (the "maximal subpart" of Unicode 3.9), which become one U+FFFD, as in
// nlohmann::json's replace handler; at least 1.
std::size_t invalid_sequence(std::string_view s) {
    const auto c = static_cast<unsigned char>(s[0]);
    std::size_t need = 0;
    unsigned char low = 0x80, high = 0xBF;  // the range of the second byte
    if (c >= 0xC2 && c <= 0xDF) need = 1;
    if (c >= 0xE0 && c <= 0xEF) need = 2;
    if (c >= 0xF0 && c <= 0xF4) need = 3;
    if (c == 0xE0) low = 0xA0;
    if (c == 0xED) high = 0x9F;
    if (c == 0xF0) low = 0x90;
    if (c == 0xF4) high = 0x8F;
    std::size_t n = 1;
    while (n <= need && n < s.size()) {
        const auto b = static_cast<unsigned char>(s[n]);
        if (n == 1 ? (b < low || b > high) : (b & 0xC0) != 0x80) break;
        ++n;
    }
    return n;
}

}  // namespace

void JsonWriter::grow(std::size_t n) {
    std::size_t capacity = std::max<std::size_t>(capacity_ * 2, 4096);
    while (capacity - size_ < n)
        capacity *= 2;
    auto bigger = std::make_unique_for_overwrite<char[]>(capacity);
    if (size_) std::memcpy(bigger.get(), buffer_.get(), size_);
    buffer_ = std::move(bigger);
    capacity_ = capacity;
}

void JsonWriter::dynamic_key(std::string_view name) {
    separate();
    escaped(name);
    put(':');
    after_key_ = true;
}

void JsonWriter::value(std::string_view text) {
    separate();
    escaped(text);
}

void JsonWriter::value(bool b) {
    separate();
    if (b)
        append("true", 4);
    else
        append("false", 5);
}

void JsonWriter::null() {
    separate();
    append("null", 4);
}

void JsonWriter::value(std::uint64_t n) {
    separate();
    char* p = reserve(24);
    size_ = static_cast<std::size_t>(std::to_chars(p, p + 24, n).ptr - buffer_.get());
}

void JsonWriter::value(std::int64_t n) {
    separate();
    char* p = reserve(24);
    size_ = static_cast<std::size_t>(std::to_chars(p, p + 24, n).ptr - buffer_.get());
}

void JsonWriter::value(std::span<const std::uint16_t> words) {
    separate();
    char* p = reserve(2 + words.size() * 6);  // "65535," each
    *p++ = '[';
    for (std::size_t i = 0; i < words.size(); ++i) {
        if (i) *p++ = ',';
        p = std::to_chars(p, p + 5, words[i]).ptr;
    }
    *p++ = ']';
    size_ = static_cast<std::size_t>(p - buffer_.get());
    first_ = false;
}

void JsonWriter::value(double d) {
    if (!std::isfinite(d)) return null();
    separate();
    char buf[400];
    // Plain decimals where people read them (times, latencies): 1700000000.25, not 1.70000000025e+09.
    const double magnitude = std::fabs(d);
    const auto r = (magnitude == 0 || (magnitude >= 1e-5 && magnitude < 1e15))
                       ? std::to_chars(buf, buf + sizeof buf, d, std::chars_format::fixed)
                       : std::to_chars(buf, buf + sizeof buf, d);
    const auto n = static_cast<std::size_t>(r.ptr - buf);
    append(buf, n);
    bool integral = true;  // written without a point or an exponent: add ".0", as nlohmann does
    for (std::size_t i = 0; i < n; ++i)
        integral &= buf[i] != '.' && buf[i] != 'e';
    if (integral) append(".0", 2);
}

void JsonWriter::hex_value(std::span<const std::uint8_t> bytes) {
    // Every byte's two digits and a space, so that each byte is one 4-byte copy (the next byte's copy
    // overwrites the fourth): a table of 1 KiB.
    static constexpr auto table = [] {
        constexpr char digits[] = "0123456789ABCDEF";
        std::array<std::array<char, 4>, 256> t{};
        for (std::size_t b = 0; b < 256; ++b)
            t[b] = {digits[b >> 4], digits[b & 0xF], ' ', ' '};
        return t;
    }();
    separate();
    const std::size_t n = 2 + (bytes.empty() ? 0 : bytes.size() * 3 - 1);
    char* p = reserve(n + 2);  // room for the last copy's two spare characters
    size_ += n;
    *p++ = '"';
    for (const std::uint8_t b : bytes) {
        std::memcpy(p, table[b].data(), 4);
        p += 3;
    }
    p[bytes.empty() ? 0 : -1] = '"';
}

void JsonWriter::escaped(std::string_view s) {
    static constexpr char digits[] = "0123456789abcdef";
    if (json_plain(s)) return quoted(s);  // the common case: nothing to escape or check
    put('"');
    std::size_t plain = 0;  // start of the run of characters copied as they are
    const auto flush = [&](std::size_t i) { append(s.data() + plain, i - plain); };
    for (std::size_t i = 0; i < s.size();) {
        const auto c = static_cast<unsigned char>(s[i]);
        if (c >= 0x20 && c != '"' && c != '\\' && c < 0x80) {
            ++i;
            continue;
        }
        if (c >= 0x80) {
            if (const std::size_t n = utf8_sequence(s.substr(i))) {
                i += n;
                continue;
            }
            flush(i);
            append("\xEF\xBF\xBD", 3);  // U+FFFD REPLACEMENT CHARACTER, as nlohmann's replace handler
            i += invalid_sequence(s.substr(i));
            plain = i;
            continue;
        }
        flush(i);
        switch (c) {
            case '"':
                append("\\\"", 2);
                break;
            case '\\':
                append("\\\\", 2);
                break;
            case '\b':
                append("\\b", 2);
                break;
            case '\f':
                append("\\f", 2);
                break;
            case '\n':
                append("\\n", 2);
                break;
            case '\r':
                append("\\r", 2);
                break;
            case '\t':
                append("\\t", 2);
                break;
            default:
                append("\\u00", 4);
                put(digits[c >> 4]);
                put(digits[c & 0xF]);
        }
        plain = ++i;
    }
    flush(s.size());
    put('"');
}

}  // namespace mbscope::modbus
