#include "cli/frame_text.hpp"

#include <cctype>
#include <sstream>

#include "modbus/adu.hpp"
#include "modbus/describe.hpp"

namespace mbscope::cli {

using namespace mbscope::modbus;

bool DecodedFrame::clean() const {
    return frame && pdu && frame->checksum_ok && frame->findings.empty() && pdu->violations.empty();
}

std::optional<std::vector<std::uint8_t>> parse_hex(const std::vector<std::string>& tokens,
                                                   std::string& error) {
    std::string digits;
    for (const auto& token : tokens) {
        std::string t = token;
        for (std::size_t pos = 0; (pos = t.find("0x")) != std::string::npos;)
            t.erase(pos, 2);
        for (std::size_t pos = 0; (pos = t.find("0X")) != std::string::npos;)
            t.erase(pos, 2);
        for (char c : t) {
            if (c == ' ' || c == ',' || c == ':' || c == '-' || c == '\t') continue;
            if (!std::isxdigit(static_cast<unsigned char>(c))) {
                error = std::string("not a hex digit: '") + c + "' in '" + token + "'";
                return std::nullopt;
            }
            digits.push_back(c);
        }
    }
    if (digits.size() % 2 != 0) {
        error = "odd number of hex digits (" + std::to_string(digits.size()) + ")";
        return std::nullopt;
    }
    std::vector<std::uint8_t> bytes;
    for (std::size_t i = 0; i < digits.size(); i += 2)
        bytes.push_back(static_cast<std::uint8_t>(std::stoi(digits.substr(i, 2), nullptr, 16)));
    return bytes;
}

namespace {

std::string describe_error(const DecodeError& e) {
    return std::string(to_string(e.code)) + " (at byte " + std::to_string(e.offset) + ")";
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
    } else if (req_clean || (request && !rsp_clean && !response)) {
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
    const std::string wire =
        d.framing == Framing::Ascii ? std::string(d.wire.begin(), d.wire.end()) : hex_bytes(d.wire);
    std::string shown = wire;
    if (d.framing == Framing::Ascii) {
        shown.clear();
        for (char c : wire)
            shown += c == '\r' ? "\\r" : c == '\n' ? "\\n" : std::string(1, c);
    }
    os << to_string(d.framing) << "  " << shown << "  (" << d.wire.size() << " bytes)";
    if (!d.source.empty()) os << "  [" << d.source << "]";
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
        std::string v = value_text(f.value);
        os << "  " << f.name << std::string(width - f.name.size() + 2, ' ') << v;
        if (!f.meaning.empty() && f.meaning != v)
            os << std::string(v.size() < 12 ? 12 - v.size() : 1, ' ') << f.meaning;
        os << '\n';
    }
    std::vector<FindingCode> codes;
    findings_of(d, codes);
    for (auto c : codes) {
        const auto& fi = info(c);
        os << "  ! " << fi.name << " (" << to_string(fi.severity) << "): " << fi.summary << "  [" << fi.rule
           << "]\n";
    }
    if (!d.error.empty()) os << "  ! cannot decode: " << d.error << '\n';
    return os.str();
}

nlohmann::json render_json(const DecodedFrame& d) {
    nlohmann::json j;
    j["framing"] = std::string(to_string(d.framing));
    j["wire"] = d.framing == Framing::Ascii ? std::string(d.wire.begin(), d.wire.end()) : hex_bytes(d.wire);
    j["length"] = d.wire.size();
    if (!d.source.empty()) j["source"] = d.source;
    if (!d.direction_note.empty()) j["direction"] = d.direction_note;
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

}  // namespace mbscope::cli
