#include "modbus/frame_text.hpp"

#include <algorithm>
#include <sstream>

#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/hex.hpp"

namespace mbscope::modbus {

bool DecodedFrame::clean() const {
    return frame && pdu && frame->checksum_ok && frame->findings.empty() && pdu->violations.empty();
}

bool DecodedFrame::broken() const {
    const auto error = [](FindingCode code) { return info(code).severity == Severity::Error; };
    return (frame &&
            (!frame->checksum_ok || std::any_of(frame->findings.begin(), frame->findings.end(), error))) ||
           (pdu && std::any_of(pdu->violations.begin(), pdu->violations.end(), error));
}

namespace {

bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r';
}

// Characters a terminal acts on instead of showing: C0 and C1 controls (U+009B is an 8-bit CSI that some
// terminals take as ESC [), DEL, the line and paragraph separators, and the bidirectional overrides and
// isolates that make a line show in another order than it reads.
bool acts_on_terminal(char32_t c) noexcept {
    return c < 0x20 || (c >= 0x7F && c <= 0x9F) || c == 0x2028 || c == 0x2029 ||
           (c >= 0x202A && c <= 0x202E) || (c >= 0x2066 && c <= 0x2069);
}

// The length of the next piece of text printable() keeps as it is (a whole character), or 0 when its next
// byte is escaped.
std::size_t kept_length(std::string_view text, std::size_t i) noexcept {
    const Utf8Char c = utf8_at(text, i);
    return c.length == 0 || acts_on_terminal(c.code) ? 0 : c.length;
}

}  // namespace

Utf8Char utf8_at(std::string_view text, std::size_t i) noexcept {
    const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
    const unsigned char lead = byte(i);
    if (lead < 0x80) return {lead, 1};
    std::size_t length = 0;
    unsigned char low = 0x80, high = 0xBF;  // the range of the second byte
    if (lead >= 0xC2 && lead <= 0xDF) {
        length = 2;
    } else if (lead >= 0xE0 && lead <= 0xEF) {
        length = 3;
        if (lead == 0xE0) low = 0xA0;
        if (lead == 0xED) high = 0x9F;
    } else if (lead >= 0xF0 && lead <= 0xF4) {
        length = 4;
        if (lead == 0xF0) low = 0x90;
        if (lead == 0xF4) high = 0x8F;
    } else {
        return {};
    }
    if (i + length > text.size()) return {};
    char32_t code = lead & (0x7F >> length);
    for (std::size_t k = 1; k < length; ++k) {
        const unsigned char b = byte(i + k);
        if (b < (k == 1 ? low : 0x80) || b > (k == 1 ? high : 0xBF)) return {};
        code = (code << 6) | (b & 0x3F);
    }
    return {code, length};
}

std::string quote_excerpt(std::string_view text) {
    constexpr std::size_t most = 40;
    std::string s = printable(text.substr(0, most));
    if (text.size() > most) s += "...";
    return "'" + s + "'";
}

std::optional<std::string> first_unprintable(std::string_view text) {
    for (std::size_t i = 0; i < text.size();) {
        if (const std::size_t n = kept_length(text, i)) {
            i += n;
            continue;
        }
        const Utf8Char c = utf8_at(text, i);
        return printable(text.substr(i, std::max<std::size_t>(c.length, 1)));
    }
    return std::nullopt;
}

std::string printable(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (std::size_t i = 0; i < text.size();) {
        if (const std::size_t n = kept_length(text, i)) {
            out.append(text.substr(i, n));
            i += n;
            continue;
        }
        // Escaped byte by byte: a control character of one byte, each byte of a C1 control or bidirectional
        // override, and each byte that is not well-formed UTF-8 (Latin-1 text from a device, garbage).
        const Utf8Char whole = utf8_at(text, i);
        const std::size_t length = std::max<std::size_t>(whole.length, 1);
        for (const char c : text.substr(i, length)) {
            const auto u = static_cast<unsigned char>(c);
            if (c == '\r') {
                out += "\\r";
            } else if (c == '\n') {
                out += "\\n";
            } else if (c == '\t') {
                out += "\\t";
            } else {
                static constexpr char digits[] = "0123456789ABCDEF";
                out += "\\x";
                out += digits[u >> 4];
                out += digits[u & 0x0F];
            }
        }
        i += length;
    }
    return out;
}

std::optional<std::vector<std::uint8_t>> parse_hex(std::span<const std::string> tokens, std::string& error) {
    std::vector<std::uint8_t> bytes;
    for (const auto& token : tokens) {
        // A group is a run of hex digits between separators: its digits pair up within it, never with the
        // next group's ("11 3 0 6b" is not 11 30 6B).
        std::size_t group = 0;  // where the current group starts in the token
        int high = -1;          // the first digit of a byte, until its second comes
        const auto end_group = [&](std::size_t at) {
            if (high < 0) return true;
            const auto digits = token.substr(group, at - group);
            error = "odd number of hex digits in " + quote_excerpt(digits) + ": a byte is two digits" +
                    (digits.size() == 1 ? " (0" + digits + ")" : std::string()) +
                    (digits.size() != token.size() ? " in " + quote_excerpt(token) : "");
            return false;
        };
        for (std::size_t i = 0; i < token.size(); ++i) {
            const char c = token[i];
            if (c == '0' && i + 1 < token.size() && (token[i + 1] == 'x' || token[i + 1] == 'X')) {
                if (!end_group(i)) return std::nullopt;
                // A prefix of nothing ("01 0X") was dropped without a word, its line read a byte short.
                if (i + 2 >= token.size() || hex_digit(token[i + 2]) < 0) {
                    error = "no hex digits after " + quote_excerpt(token.substr(i, 2)) + " in " +
                            quote_excerpt(token);
                    return std::nullopt;
                }
                ++i;  // a 0x prefix
                group = i + 1;
                continue;
            }
            if (c == ' ' || c == ',' || c == ':' || c == '-' || c == '\t') {
                if (!end_group(i)) return std::nullopt;
                group = i + 1;
                continue;
            }
            const int v = hex_digit(c);
            if (v < 0) {
                error = "not a hex digit: " + quote_excerpt(std::string_view(&c, 1)) + " in " +
                        quote_excerpt(token);
                return std::nullopt;
            }
            if (high < 0) {
                high = v;
            } else {
                bytes.push_back(static_cast<std::uint8_t>(high << 4 | v));
                high = -1;
            }
        }
        if (!end_group(token.size())) return std::nullopt;
    }
    return bytes;
}

std::optional<std::vector<std::uint8_t>> wire_from_tokens(Framing framing,
                                                          std::span<const std::string> tokens,
                                                          std::string& error) {
    if (framing == Framing::Ascii && !tokens.empty() && !tokens[0].empty() && tokens[0][0] == ':') {
        std::string joined;
        for (const auto& t : tokens)
            joined += t;
        std::vector<std::uint8_t> text;
        text.reserve(joined.size() + 2);
        // CR and LF written out as a shell passes them ('...\r\n', or '\r' alone), each taken as itself.
        for (std::size_t i = 0; i < joined.size(); ++i) {
            const bool escape = joined[i] == '\\' && i + 1 < joined.size();
            if (escape && (joined[i + 1] == 'r' || joined[i + 1] == 'n')) {
                text.push_back(joined[i + 1] == 'r' ? '\r' : '\n');
                ++i;
            } else {
                text.push_back(static_cast<std::uint8_t>(joined[i]));
            }
        }
        // The end a frame typed as text lacks is added: CR LF, or LF after a CR already there (the shell's
        // $(cat frame.txt) strips the LF only; CR LF added after it made a frame nobody gave, "\r\r\n").
        if (!text.empty() && text.back() == '\r') {
            text.push_back('\n');
        } else if (text.size() < 2 || text[text.size() - 2] != '\r' || text.back() != '\n') {
            text.push_back('\r');
            text.push_back('\n');
        }
        return text;
    }
    return parse_hex(tokens, error);
}

std::vector<FrameLine> parse_frames_text(std::string_view text) {
    std::vector<FrameLine> lines;
    std::size_t number = 0;
    for (std::size_t begin = 0; begin < text.size();) {
        std::size_t end = text.find('\n', begin);
        if (end == std::string_view::npos) end = text.size();
        std::string_view line = text.substr(begin, end - begin);
        begin = end + 1;
        ++number;
        FrameLine out;
        out.number = number;
        if (const auto hash = line.find('#'); hash != std::string_view::npos) {
            std::string_view comment = line.substr(hash + 1);
            while (!comment.empty() && is_blank(comment.front()))
                comment.remove_prefix(1);
            while (!comment.empty() && is_blank(comment.back()))
                comment.remove_suffix(1);
            out.comment = std::string(comment);
            line = line.substr(0, hash);
        }
        std::vector<std::string> words;
        for (std::size_t i = 0; i < line.size();) {
            while (i < line.size() && is_blank(line[i]))
                ++i;
            std::size_t j = i;
            while (j < line.size() && !is_blank(line[j]))
                ++j;
            if (j > i) words.emplace_back(line.substr(i, j - i));
            i = j;
        }
        if (words.empty()) continue;
        const std::string& kind = words.front();
        if (kind == "rtu") {
            out.framing = Framing::Rtu;
        } else if (kind == "ascii") {
            out.framing = Framing::Ascii;
        } else if (kind == "tcp") {
            out.framing = Framing::Tcp;
        } else {
            out.error = "unknown framing " + quote_excerpt(kind) + " (rtu, ascii or tcp)";
            lines.push_back(std::move(out));
            continue;
        }
        const std::span<const std::string> tokens(words.data() + 1, words.size() - 1);
        if (tokens.empty()) {
            out.error = "no frame bytes after '" + kind + "'";
        } else if (auto wire = wire_from_tokens(out.framing, tokens, out.error); wire) {
            out.wire = std::move(*wire);
            if (out.wire.empty()) out.error = "no frame bytes after '" + kind + "'";
        }
        lines.push_back(std::move(out));
    }
    return lines;
}

namespace {

std::string describe_error(const DecodeError& e) {
    return std::string(to_string(e.code)) + " (at byte " + std::to_string(e.offset) + ")";
}

// How badly a PDU read one way fits its bytes, for choosing between the two readings when both break a rule:
// a byte count that disagrees with the bytes present says the bytes are not that kind of PDU at all (a
// master's FC3 request for 252 registers read as a reply whose byte count of 0 is followed by three more
// bytes), while a quantity above the maximum or an invalid coil value is a rule the sender broke. Then the
// number of rules broken.
std::size_t misfit(const Pdu& pdu) noexcept {
    return (pdu.violations.contains(FindingCode::PduByteCountMismatch) ? 100 : 0) + pdu.violations.size();
}

void choose_pdu(DecodedFrame& d, Direction direction) {
    const auto pdu_bytes = d.frame->pdu();
    if (direction != Direction::Unknown) {
        auto r = decode_pdu(pdu_bytes, direction);
        if (r)
            d.pdu = std::move(r.value());
        else
            d.error = "PDU: " + describe_error(r.error());
        return;
    }
    auto request = decode_request(pdu_bytes);
    auto response = decode_response(pdu_bytes);
    const bool req_clean = request && request->violations.empty();
    const bool rsp_clean = response && response->violations.empty();
    if (req_clean && rsp_clean) {
        d.pdu = std::move(request.value());
        d.direction_note = encode_pdu(*d.pdu) == encode_pdu(response.value())
                               ? "request, or its echo response (identical bytes)"
                               : "request (also well-formed as a response)";
    } else if (req_clean || (request && !rsp_clean && (!response || misfit(*request) <= misfit(*response)))) {
        d.pdu = std::move(request.value());
        d.direction_note = "request";
    } else if (response) {
        d.pdu = std::move(response.value());
        d.direction_note = "response";
    } else if (request) {
        d.pdu = std::move(request.value());
        d.direction_note = "request";
    } else {
        d.error = "PDU: " + describe_error(request.error());
    }
}

}  // namespace

DecodedFrame decode_frame(Framing framing, std::vector<std::uint8_t> wire, Direction direction) {
    DecodedFrame d;
    d.framing = framing;
    d.wire = std::move(wire);
    Result<Frame> frame = decode_adu(framing, d.wire);
    if (!frame) {
        d.error = std::string(to_string(framing)) + " ADU: " + describe_error(frame.error());
        return d;
    }
    d.frame = std::move(frame.value());
    choose_pdu(d, direction);
    if (d.pdu && direction != Direction::Unknown) d.direction_note = std::string(to_string(direction));
    return d;
}

namespace {

std::string value_text(const nlohmann::json& v) {
    if (v.is_string()) return v.get<std::string>();
    return v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void findings_of(const DecodedFrame& d, std::vector<FindingCode>& out) {
    if (d.frame)
        for (auto c : d.frame->findings)
            out.push_back(c);
    if (d.pdu)
        for (auto c : d.pdu->violations)
            out.push_back(c);
}

}  // namespace

std::string render_text(const DecodedFrame& d) {
    std::ostringstream os;
    const std::string shown =
        d.framing == Framing::Ascii
            ? printable(std::string_view(reinterpret_cast<const char*>(d.wire.data()), d.wire.size()))
            : hex_bytes(d.wire);
    os << to_string(d.framing) << "  " << shown << "  (" << d.wire.size() << " bytes)";
    if (!d.source.empty()) os << "  [" << printable(d.source) << "]";
    os << '\n';
    std::vector<Field> fields;
    if (d.frame) fields = describe_framing(*d.frame);
    std::vector<Field> pdu_fields;
    if (d.pdu) pdu_fields = describe_pdu(*d.pdu);
    // unit/MBAP first, then PDU fields, checksum last
    std::vector<Field> ordered;
    for (auto& f : fields)
        if (f.name != "crc" && f.name != "lrc") ordered.push_back(f);
    if (!d.direction_note.empty()) ordered.insert(ordered.begin(), Field{"direction", d.direction_note, ""});
    for (auto& f : pdu_fields)
        ordered.push_back(f);
    for (auto& f : fields)
        if (f.name == "crc" || f.name == "lrc") ordered.push_back(f);
    std::size_t width = 0;
    for (const auto& f : ordered)
        width = std::max(width, f.name.size());
    for (const auto& f : ordered) {
        const std::string v = printable(value_text(f.value));
        const std::string meaning = printable(f.meaning);
        os << "  " << f.name << std::string(width - f.name.size() + 2, ' ') << v;
        if (!meaning.empty() && meaning != v)
            os << std::string(v.size() < 12 ? 12 - v.size() : 1, ' ') << meaning;
        os << '\n';
    }
    std::vector<FindingCode> codes;
    findings_of(d, codes);
    for (auto c : codes) {
        const auto& fi = info(c);
        os << "  ! " << fi.name << " (" << to_string(fi.severity) << "): " << fi.summary << "  [" << fi.rule
           << "]\n";
    }
    if (!d.error.empty()) os << "  ! cannot decode: " << printable(d.error) << '\n';
    return os.str();
}

nlohmann::json render_json(const DecodedFrame& d) {
    nlohmann::json j;
    j["framing"] = std::string(to_string(d.framing));
    j["wire"] = d.framing == Framing::Ascii ? std::string(d.wire.begin(), d.wire.end()) : hex_bytes(d.wire);
    j["length"] = d.wire.size();
    if (!d.source.empty()) j["source"] = d.source;
    // "direction" is one word a program can compare ("request", "response"); what reading the bytes both
    // ways found ("request, or its echo response (identical bytes)") is a note beside it.
    if (d.pdu) {
        const std::string direction(to_string(d.pdu->direction));
        j["direction"] = direction;
        if (!d.direction_note.empty() && d.direction_note != direction)
            j["direction_note"] = d.direction_note;
    } else if (!d.direction_note.empty()) {
        j["direction"] = d.direction_note;
    }
    if (d.frame) {
        j["checksum_ok"] = d.frame->checksum_ok;
        for (const auto& f : describe_framing(*d.frame)) {
            nlohmann::json field{{"name", f.name}, {"value", f.value}};
            if (!f.meaning.empty()) field["meaning"] = f.meaning;
            j["framing_fields"].push_back(field);
        }
    }
    if (d.pdu) {
        j["function_raw"] = d.pdu->function_raw;
        j["function_code"] = d.pdu->function_code();
        j["exception"] = d.pdu->is_exception();
        for (const auto& f : describe_pdu(*d.pdu)) {
            nlohmann::json field{{"name", f.name}, {"value", f.value}};
            if (!f.meaning.empty()) field["meaning"] = f.meaning;
            j["fields"].push_back(field);
        }
    }
    std::vector<FindingCode> codes;
    findings_of(d, codes);
    j["findings"] = nlohmann::json::array();
    for (auto c : codes) {
        const auto& fi = info(c);
        j["findings"].push_back({{"code", std::string(fi.name)},
                                 {"severity", std::string(to_string(fi.severity))},
                                 {"summary", std::string(fi.summary)},
                                 {"rule", std::string(fi.rule)}});
    }
    if (!d.error.empty()) j["error"] = d.error;
    return j;
}

}  // namespace mbscope::modbus
