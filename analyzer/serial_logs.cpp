#include "analyzer/serial_logs.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <set>
#include <utility>

#include "modbus/describe.hpp"    // hex_bytes()
#include "modbus/frame_text.hpp"  // quote_excerpt()
#include "modbus/hex.hpp"
#include "modbus/storage/text_file.hpp"

namespace mbscope::analyzer {

using modbus::Direction;
using modbus::Timestamp;

std::optional<Direction> direction_word(std::string_view word) {
    std::string t(word);
    for (auto& c : t)
        c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (t == ">" || t == "M" || t == "TX" || t == "REQ" || t == "MASTER") return Direction::Request;
    if (t == "<" || t == "S" || t == "RX" || t == "RSP" || t == "SLAVE") return Direction::Response;
    return std::nullopt;
}

namespace {

std::string_view trim_right(std::string_view s) {
    while (!s.empty() && (s.back() == '\r' || s.back() == '\n' || s.back() == ' ' || s.back() == '\t'))
        s.remove_suffix(1);
    return s;
}

bool is_hex(char c) {
    return modbus::hex_digit(c) >= 0;
}

std::uint8_t hex_pair(char hi, char lo) {  // both checked with is_hex
    return static_cast<std::uint8_t>(modbus::hex_digit(hi) * 16 + modbus::hex_digit(lo));
}

std::optional<int> digits(std::string_view s, std::size_t& pos, std::size_t count) {
    if (pos + count > s.size()) return std::nullopt;
    int v = 0;
    for (std::size_t i = 0; i < count; ++i) {
        const char c = s[pos + i];
        if (c < '0' || c > '9') return std::nullopt;
        v = v * 10 + (c - '0');
    }
    pos += count;
    return v;
}

bool expect(std::string_view s, std::size_t& pos, char c) {
    if (pos < s.size() && s[pos] == c) {
        ++pos;
        return true;
    }
    return false;
}

struct CalendarTime {
    std::chrono::sys_seconds seconds;
    std::string_view fraction;  // digits after '.', empty when there is none
};

// "YYYY<sep>MM<sep>DD HH:MM:SS[.DIGITS]" at s[pos]; on success pos moves past it.
std::optional<CalendarTime> parse_calendar(std::string_view s, std::size_t& pos, char sep) {
    std::size_t p = pos;
    const auto y = digits(s, p, 4);
    if (!y || !expect(s, p, sep)) return std::nullopt;
    const auto mo = digits(s, p, 2);
    if (!mo || !expect(s, p, sep)) return std::nullopt;
    const auto d = digits(s, p, 2);
    if (!d || !expect(s, p, ' ')) return std::nullopt;
    const auto h = digits(s, p, 2);
    if (!h || !expect(s, p, ':')) return std::nullopt;
    const auto mi = digits(s, p, 2);
    if (!mi || !expect(s, p, ':')) return std::nullopt;
    const auto sec = digits(s, p, 2);
    if (!sec) return std::nullopt;
    const std::chrono::year_month_day ymd{std::chrono::year{*y},
                                          std::chrono::month{static_cast<unsigned>(*mo)},
                                          std::chrono::day{static_cast<unsigned>(*d)}};
    // Timestamps are nanoseconds since 1970 in 64 bits: years past 2261 (or before 1970, which no logger
    // writes) would overflow, so such a line is malformed rather than a time.
    if (!ymd.ok() || *y < 1970 || *y > 2261 || *h > 23 || *mi > 59 || *sec > 60) return std::nullopt;
    CalendarTime t{std::chrono::sys_days{ymd} + std::chrono::hours(*h) + std::chrono::minutes(*mi) +
                       std::chrono::seconds(*sec),
                   {}};
    if (expect(s, p, '.')) {
        const std::size_t begin = p;
        while (p < s.size() && std::isdigit(static_cast<unsigned char>(s[p])))
            ++p;
        if (p == begin || p - begin > 9) return std::nullopt;
        t.fraction = s.substr(begin, p - begin);
    }
    pos = p;
    return t;
}

// Seconds and fraction as a timestamp; nine digits hold microseconds when `nine_is_micro` (socat 1.7.4).
Timestamp to_timestamp(const CalendarTime& t, bool nine_is_micro) {
    std::string_view f = t.fraction;
    if (f.size() == 9 && nine_is_micro) f.remove_prefix(3);
    std::int64_t ns = 0;
    for (char c : f)
        ns = ns * 10 + (c - '0');
    for (std::size_t i = f.size(); i < 9; ++i)
        ns *= 10;
    return std::chrono::duration_cast<Timestamp>(t.seconds.time_since_epoch()) + Timestamp(ns);
}

std::string where(const std::string& name, std::uint64_t line) {
    return name + ":" + std::to_string(line) + ": ";
}

// ---------------------------------------------------------------- jpnevulator

// "YYYY-MM-DD HH:MM:SS.UUUUUU:[ ALIAS]"; alias is what follows ": ".
std::optional<Timestamp> jpnevulator_header(std::string_view line, std::string_view& alias) {
    std::size_t p = 0;
    const auto t = parse_calendar(line, p, '-');
    if (!t || t->fraction.size() != 6 || !expect(line, p, ':')) return std::nullopt;
    if (p < line.size() && line[p] != ' ') return std::nullopt;
    alias = p < line.size() ? line.substr(p + 1) : std::string_view{};
    return to_timestamp(*t, false);
}

// "[%08lX\t]XX XX ...[padding\tASCII]": hexadecimal ("%02X") or binary (--base 2, eight digits) bytes.
// A log pasted from a page or re-indented has spaces where jpnevulator wrote tabs: the offset is then eight
// hex digits followed by two spaces or more, and the --ascii column is told by what it is, the rendering
// of the line's bytes (a printable byte as itself, any other as '.'), not by where it stands.
bool jpnevulator_bytes(std::string_view line, std::vector<std::uint8_t>& out) {
    const auto blank = [](char c) { return c == ' ' || c == '\t'; };
    while (!line.empty() && blank(line.front()))
        line.remove_prefix(1);
    if (line.size() > 9 && std::all_of(line.begin(), line.begin() + 8, is_hex) &&
        (line[8] == '\t' || (line[8] == ' ' && line[9] == ' '))) {
        line.remove_prefix(8);  // --byte-count
        while (!line.empty() && blank(line.front()))
            line.remove_prefix(1);
    }
    if (const auto tab = line.find('\t'); tab != std::string_view::npos)
        line = line.substr(0, tab);  // --ascii
    while (!line.empty() && line.back() == ' ')
        line.remove_suffix(1);
    // The byte tokens from the start, each with where it begins; `rest` where the first other one begins.
    std::vector<std::uint8_t> got;
    std::vector<std::size_t> starts;
    std::size_t rest = line.size();
    for (std::size_t p = 0; p < line.size();) {
        if (line[p] == ' ') {
            ++p;
            continue;
        }
        std::size_t e = line.find(' ', p);
        if (e == std::string_view::npos) e = line.size();
        const auto token = line.substr(p, e - p);
        if (token.size() == 2 && is_hex(token[0]) && is_hex(token[1])) {
            got.push_back(hex_pair(token[0], token[1]));
        } else if (token.size() == 8 && token.find_first_not_of("01") == std::string_view::npos) {
            std::uint8_t b = 0;
            for (char c : token)
                b = static_cast<std::uint8_t>(b * 2 + (c - '0'));
            got.push_back(b);
        } else {
            rest = p;
            break;
        }
        starts.push_back(p);
        p = e;
    }
    // What follows the first k bytes is their --ascii column (which may itself look like bytes: "41 42 AB").
    const auto column_after = [&](std::size_t k) {
        const auto column = line.substr(starts[k]);
        if (column.size() != k) return false;
        for (std::size_t i = 0; i < k; ++i)
            if (std::isprint(got[i]) ? column[i] != static_cast<char>(got[i]) : column[i] != '.')
                return false;
        return true;
    };
    std::size_t kept = got.size();
    for (std::size_t k = 1; k < got.size(); ++k)
        if (starts[k] > 0 && line[starts[k] - 1] == ' ' && column_after(k)) {
            kept = k;
            break;
        }
    if (kept == got.size() && rest < line.size()) {
        // A token that is no byte: only the --ascii column of all the bytes before it may stand there.
        starts.push_back(rest);
        if (got.empty() || !column_after(got.size())) return false;
    }
    if (kept == 0) return false;
    out.insert(out.end(), got.begin(), got.begin() + static_cast<std::ptrdiff_t>(kept));
    return true;
}

// The direction of a tty: the user's aliases first (one named is enough when two ttys are read), then the
// direction words; an unknown tty is left to the request → response state machine.
std::optional<Direction> alias_direction(std::string_view alias, const SerialLogOptions& o) {
    if (!o.master_alias.empty()) return alias == o.master_alias ? Direction::Request : Direction::Response;
    if (!o.slave_alias.empty()) return alias == o.slave_alias ? Direction::Response : Direction::Request;
    return direction_word(alias);
}

// ---------------------------------------------------------------- socat

struct SocatHeader {
    bool left_to_right = true;
    CalendarTime time;
    std::uint64_t length = 0, from = 0, to = 0;
};

bool number_field(std::string_view s, std::size_t& p, std::string_view key, std::uint64_t& value) {
    while (p < s.size() && s[p] == ' ')
        ++p;
    if (s.substr(p, key.size()) != key) return false;
    p += key.size();
    const auto [end, ec] = std::from_chars(s.data() + p, s.data() + s.size(), value);
    if (ec != std::errc()) return false;
    p = static_cast<std::size_t>(end - s.data());
    return true;
}

// "> YYYY/MM/DD HH:MM:SS.FRACTION  length=N from=A to=B"
std::optional<SocatHeader> socat_header(std::string_view line) {
    if (line.size() < 2 || (line[0] != '>' && line[0] != '<') || line[1] != ' ') return std::nullopt;
    std::size_t p = 2;
    const auto t = parse_calendar(line, p, '/');
    if (!t) return std::nullopt;
    SocatHeader h{line[0] == '>', *t};
    if (!number_field(line, p, "length=", h.length) || !number_field(line, p, "from=", h.from) ||
        !number_field(line, p, "to=", h.to) || p != line.size())
        return std::nullopt;
    return h;
}

// "YYYY/MM/DD HH:MM:SS[.FRACTION] socat[PID] X message" (-d, -lu)
bool socat_diagnostic(std::string_view line) {
    std::size_t p = 0;
    return parse_calendar(line, p, '/') && line.substr(p).starts_with(" socat[");
}

// " xx xx ...": the hex pairs that lead the line, each after one space, all of them (socat writes 16 a line
// at most; a line holding more than its block announced is told by the caller, not cut here). socat -x -v
// pads the hex to sixteen pairs' width and puts two spaces more before its ASCII rendering, one character a
// byte, so that column ("ab" may read as a byte) stops the pairs and is never taken for bytes. Anything
// else after the pairs (" 11 03 zz", a log edited by hand) is returned as `rest` for the caller to name.
struct SocatBytes {
    std::vector<std::uint8_t> bytes;
    std::string_view rest;  // not hex pairs and not socat's ASCII column; empty when the line is socat's
};

SocatBytes socat_bytes(std::string_view line) {
    constexpr std::size_t ascii_column = 16 * 3 + 2;
    SocatBytes out;
    std::size_t p = 0;
    for (; p + 3 <= line.size() && line[p] == ' ' && is_hex(line[p + 1]) && is_hex(line[p + 2]) &&
           (p + 3 == line.size() || line[p + 3] == ' ');
         p += 3)
        out.bytes.push_back(hex_pair(line[p + 1], line[p + 2]));
    if (p == line.size()) return out;
    // trim_right took any spaces at the line's end: something follows the pairs here.
    const std::size_t text_at = line.find_first_not_of(' ', p);
    if (text_at < ascii_column || line.size() - ascii_column > out.bytes.size())
        out.rest = line.substr(text_at);
    return out;
}

}  // namespace

bool next_log_line(modbus::storage::LineReader& lines, std::string& text, const std::string& name,
                   const LogErrorCallback& error, bool& ok) {
    while (lines.next(text)) {
        if (!lines.too_long()) return true;
        error(where(name, lines.number()) + modbus::storage::too_long_line_message(lines));
        ok = false;
    }
    return false;
}

bool read_jpnevulator_log(std::istream& in, const std::string& name, const SerialLogOptions& options,
                          const ChunkCallback& chunk, const LogErrorCallback& error) {
    bool ok = true;
    SerialChunk run;
    Timestamp start{0};
    std::set<std::string, std::less<>> seen;  // the ttys the log names
    const auto flush = [&] {
        if (run.bytes.empty()) return;
        // The stamp is the run's first read: its bytes are taken back to back from there.
        if (start.count())
            run.received =
                start + options.line.character_time() * static_cast<std::int64_t>(run.bytes.size() - 1);
        chunk(run);
        run.bytes.clear();
    };
    modbus::storage::LineReader lines(in);
    for (std::string text; next_log_line(lines, text, name, error, ok);) {
        const auto number = lines.number();
        const auto line = trim_right(text);
        if (line.empty()) continue;
        std::string_view alias;
        if (const auto t = jpnevulator_header(line, alias)) {
            flush();
            start = *t;
            run.direction = alias.empty() ? Direction::Unknown
                                          : alias_direction(alias, options).value_or(Direction::Unknown);
            if (!alias.empty()) seen.emplace(alias);
            continue;
        }
        if (line.starts_with("le=")) continue;  // --control: modem line state, no data
        if (jpnevulator_bytes(line, run.bytes)) continue;
        // Several ttys without --timing-print: a line naming the tty before its bytes.
        if (line == options.master_alias || line == options.slave_alias || direction_word(line) ||
            line.starts_with("/")) {
            flush();
            run.direction = alias_direction(line, options).value_or(Direction::Unknown);
            seen.emplace(line);
            continue;
        }
        error(where(name, number) +
              "not a jpnevulator timestamp or data line: " + modbus::quote_excerpt(line));
        ok = false;
    }
    flush();
    // An alias the log never names made every tty the other side's: each request was decoded as a
    // malformed response and the devices blamed for it ("ttyUSB0" for "/dev/ttyUSB0").
    for (const auto& [option, alias] : {std::pair{"--master-alias", &options.master_alias},
                                        std::pair{"--slave-alias", &options.slave_alias}}) {
        if (alias->empty() || seen.empty() || seen.count(*alias)) continue;
        std::string named;
        for (const auto& tty : seen)
            named += (named.empty() ? "" : ", ") + modbus::quote_excerpt(tty);
        error(name + ": " + option + " " + modbus::quote_excerpt(*alias) +
              " names no tty of the log, so every tty would be taken for the other side; the log's ttys: " +
              named);
        ok = false;
    }
    return ok;
}

bool read_socat_log(std::istream& in, const std::string& name, const SerialLogOptions& options,
                    const ChunkCallback& chunk, const LogErrorCallback& error) {
    // First pass: do nine-digit fractions hold nanoseconds or socat 1.7.4's microseconds?
    bool nine_is_micro = true;
    modbus::storage::LineReader first_pass(in);
    for (std::string text; first_pass.next(text);) {
        const auto h = socat_header(trim_right(text));
        if (h && h->time.fraction.size() == 9 && !h->time.fraction.starts_with("000")) nine_is_micro = false;
    }
    in.clear();
    in.seekg(0);

    bool ok = true;
    SerialChunk block;
    std::uint64_t announced = 0;
    std::uint64_t header_line = 0;
    bool open = false, any_data = false;
    const auto close = [&] {
        if (!open) return;
        open = false;
        if (block.bytes.empty() && announced) {
            error(where(name, header_line) + "block announces " + std::to_string(announced) +
                  " bytes and the log holds none of them: its data lines are missing (a log cut or edited)");
            ok = false;
        } else if (block.bytes.size() != announced) {
            error(where(name, header_line) + "block announces " + std::to_string(announced) +
                  " bytes, the log holds " + std::to_string(block.bytes.size()));
            ok = false;
        }
        if (!block.bytes.empty()) chunk(block);
        block.bytes.clear();
    };
    modbus::storage::LineReader lines(in);
    for (std::string text; next_log_line(lines, text, name, error, ok);) {
        const auto number = lines.number();
        const auto line = trim_right(text);
        if (line.empty()) continue;
        if (const auto h = socat_header(line)) {
            close();
            if (h->length == 0 || h->to + 1 != h->from + h->length) {
                error(where(name, number) + "length=" + std::to_string(h->length) +
                      " does not span from=" + std::to_string(h->from) + " to=" + std::to_string(h->to));
                ok = false;
            }
            open = true;
            header_line = number;
            announced = h->length;
            block.received = to_timestamp(h->time, nine_is_micro);
            block.direction =
                h->left_to_right == options.socat_master_left ? Direction::Request : Direction::Response;
            continue;
        }
        // "--" ends a block. One whose bytes are missing (a header and "--" alone: a log cut or edited)
        // is named as such by close(); it is no sign of socat's text mode, which writes no "--" before
        // its first block's text.
        if (line == "--") {
            close();
            continue;
        }
        if (open && block.bytes.size() < announced) {
            auto [got, rest] = socat_bytes(line);
            if (got.empty() && !any_data) {
                error(where(name, number) +
                      "socat wrote this block as text (-v without -x): non-printable bytes are lost; "
                      "capture with socat -x -v");
                return false;
            }
            if (!got.empty()) {  // fewer than 16 when the data held a 0x0A: socat -v breaks the line after it
                any_data = true;
                // Bytes past the announced length: the header and the data disagree (a log edited or two
                // blocks run together). The announced bytes are the block, as socat counted them; the
                // rest are named here rather than dropped unseen or decoded as part of a frame.
                const std::size_t room = announced - block.bytes.size();
                if (got.size() > room) {
                    const std::span<const std::uint8_t> extra(got.data() + room, got.size() - room);
                    error(where(name, number) + "block announces " + std::to_string(announced) +
                          " bytes (line " + std::to_string(header_line) + "), this line holds " +
                          std::to_string(extra.size()) + " more, not decoded: " +
                          modbus::hex_bytes(extra.first(std::min<std::size_t>(extra.size(), 16))) +
                          (extra.size() > 16 ? " ..." : ""));
                    ok = false;
                    got.resize(room);
                }
                block.bytes.insert(block.bytes.end(), got.begin(), got.end());
                // The pairs are taken; what follows them is neither more pairs nor socat's ASCII column.
                if (!rest.empty()) {
                    error(where(name, number) +
                          "this line's hex pairs are followed by what is neither a pair nor socat -x -v's "
                          "ASCII column, not decoded: " +
                          modbus::quote_excerpt(rest));
                    ok = false;
                }
                continue;
            }
        }
        if (socat_diagnostic(line)) continue;
        error(where(name, number) + "not a socat -x line: " + modbus::quote_excerpt(line));
        ok = false;
    }
    close();
    return ok;
}

bool looks_like_jpnevulator_log(std::string_view head) {
    std::size_t begin = 0;
    while (begin < head.size()) {
        std::size_t end = head.find('\n', begin);
        if (end == std::string_view::npos) end = head.size();
        const auto line = trim_right(head.substr(begin, end - begin));
        std::string_view alias;
        if (!line.empty()) return jpnevulator_header(line, alias).has_value();
        begin = end + 1;
    }
    return false;
}

bool looks_like_socat_log(std::string_view head) {
    std::size_t begin = 0;
    bool diagnostics = false;
    while (begin < head.size()) {
        std::size_t end = head.find('\n', begin);
        if (end == std::string_view::npos) break;  // a cut line says nothing
        const auto line = trim_right(head.substr(begin, end - begin));
        if (socat_header(line)) return true;
        if (!line.empty() && !socat_diagnostic(line)) return false;
        diagnostics |= !line.empty();
        begin = end + 1;
    }
    return diagnostics;  // socat -d lines only, so far
}

}  // namespace mbscope::analyzer
