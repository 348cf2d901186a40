#include "analyzer/json_lines.hpp"

#include "analyzer/sinks.hpp"

#include "modbus/describe.hpp"
#include "modbus/profile_json.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;

namespace {

// Names this program gives (enumerations, function names, record types) go through out.plain_member: no
// escaping. Link, source and device names come from the input and are checked once, when they are made.
void text_member(JsonWriter& out, JsonKey key, const SharedText& text) {
    if (text.json_plain()) return out.plain_member(key, text.view());
    out.key(key);
    out.value(text.view());
}

}  // namespace

void write_frame(const FrameRecord& f, JsonWriter& out) {
    const bool tcp = f.frame.framing == Framing::Tcp;
    const auto pdu_bytes = f.frame.pdu();
    out.begin_object();
    out.member("checksum_ok", f.frame.checksum_ok);
    out.plain_member("direction", to_string(f.direction));
    if (!f.pdu) out.member("error", std::string_view(f.error));
    if (f.pdu)
        out.member("exception", f.pdu->is_exception());
    else if (!pdu_bytes.empty())  // the function byte is known even when the rest is not
        out.member("exception", (pdu_bytes[0] & 0x80) != 0);
    if (f.pdu) {
        out.key("fields");
        write_pdu_fields(*f.pdu, out);
    }
    out.member("frame", f.index);
    out.plain_member("framing", to_string(f.frame.framing));
    if (f.pdu) {
        out.member("function", f.pdu->function_code());
        if (auto n = function_name(f.pdu->function_code())) out.plain_member("function_name", *n);
        out.member("function_raw", f.pdu->function_raw);
    } else if (!pdu_bytes.empty()) {
        out.member("function", static_cast<std::uint8_t>(pdu_bytes[0] & 0x7F));
        out.member("function_raw", pdu_bytes[0]);
    }
    text_member(out, "link", f.link);
    out.member("packet", f.packet);
    if (tcp) out.member("protocol_id", f.frame.protocol_id());
    out.key("raw");
    out.hex_value(f.frame.adu());
    text_member(out, "source", f.source);
    if (tcp) out.member("transaction_id", f.frame.transaction_id());
    out.plain_member("transport", to_string(f.carrier));
    out.member("ts", seconds(f.time));
    out.plain_member("type", "frame");
    out.member("unit_id", f.frame.unit_id());
    out.end_object();
}

void write_transaction(const TransactionRecord& t, JsonWriter& out) {
    const FrameRecord& q = t.request;
    const FrameRecord* r = t.response ? &*t.response : nullptr;
    out.begin_object();
    if (t.answered_by_other_unit) out.member("answered_by_other_unit", true);
    if (!r && t.broadcast) out.member("broadcast", true);
    if (t.client_aborted) out.member("client_aborted", true);
    if (t.discarded) out.member("discarded", true);  // the keys in order, as the JSON output has them
    if (const auto code = r ? exception_code_of(*r) : std::nullopt) out.member("exception_code", *code);
    if (!t.findings.empty()) {
        out.key("findings");
        out.begin_array();
        for (auto c : t.findings)
            out.value(to_string(c));
        out.end_array();
    }
    if (q.pdu)
        out.member("function", q.pdu->function_code());
    else if (!q.frame.pdu().empty())  // a malformed request still asked for its function
        out.member("function", static_cast<std::uint8_t>(q.frame.pdu()[0] & 0x7F));
    if (r && t.late_past) out.member("late", true);
    if (r && t.latency)
        out.member("latency_ms", std::chrono::duration<double, std::milli>(*t.latency).count());
    text_member(out, "link", q.link);
    if (t.profile) out.member("profile", std::string_view(t.profile->id));
    if (t.word_order) {
        out.key("registers32");
        out.begin_array();
        // JSON has no NaN or infinity: such an f32 is null, and f32_text ("nan", "inf", "-inf", or the
        // number as the text output writes it) tells which, as a profile value's text does.
        for (const auto& reg : t.registers32) {
            out.begin_object();
            out.member("address", reg.address);
            out.member("f32", reg.f32);
            out.plain_member("f32_text", float_text(reg.f32));
            out.member("u32", reg.u32);
            out.end_object();
        }
        out.end_array();
    }
    if (t.reply_not_captured) out.member("reply_not_captured", true);
    if (t.reply_damaged) out.member("reply_damaged", true);
    out.member("request_frame", q.index);
    if (r) out.member("response_frame", r->index);
    text_member(out, "source", q.source);
    if (!r && !t.broadcast) out.member("timeout", t.timed_out);
    if (q.frame.framing == Framing::Tcp) out.member("transaction_id", q.frame.transaction_id());
    out.plain_member("transport", to_string(q.carrier));
    out.member("ts", seconds(q.time));
    out.plain_member("type", "transaction");
    out.member("unit_id", q.frame.unit_id());
    if (!t.values.empty()) {
        out.key("values");
        out.begin_array();
        for (const auto& v : t.values)
            write_named_value(v, out);
        out.end_array();
    }
    if (t.word_order) out.plain_member("word_order", to_string(*t.word_order));
    out.end_object();
}

void write_finding(const FindingRecord& f, JsonWriter& out) {
    const auto& i = info(f.code);
    out.begin_object();
    out.member("code", i.name);
    if (!f.device.empty()) text_member(out, "device", f.device);
    if (!f.frames.empty()) {
        out.key("frames");
        out.begin_array();
        for (auto n : f.frames)
            out.value(n);
        out.end_array();
    }
    text_member(out, "link", f.link);
    out.member("message", std::string_view(f.message));
    out.member("packet", f.packet);
    out.member("rule", i.rule);
    out.plain_member("severity", to_string(i.severity));
    text_member(out, "source", f.source);
    out.member("ts", seconds(f.time));
    out.plain_member("type", "finding");
    out.end_object();
}

void write_unparsed(const UnparsedRecord& u, JsonWriter& out) {
    out.begin_object();
    out.plain_member("direction", to_string(u.direction));
    out.member("length", u.length);
    text_member(out, "link", u.link);
    out.member("offset", u.offset);
    out.member("packet", u.packet);
    out.plain_member("reason", to_string(u.reason));
    text_member(out, "source", u.source);
    out.member("ts", seconds(u.time));
    out.plain_member("type", "unparsed");
    out.end_object();
}

}  // namespace mbscope::analyzer
