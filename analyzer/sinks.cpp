#include "analyzer/sinks.hpp"

#include <algorithm>
#include <cstdio>

#include "analyzer/json_lines.hpp"
#include "analyzer/timestamps.hpp"
#include "analyzer/word_order.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/profile_json.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;
using json = nlohmann::json;

// Whole seconds and their fraction converted apart: nanoseconds since 1970 (1.7e18) are past a double's
// 53 bits, and converting them whole made .012999 print as .0129988.
double seconds(Timestamp t) {
    const auto whole = std::chrono::duration_cast<std::chrono::seconds>(t);  // toward zero: -0.5 s is 0 - 0.5
    return static_cast<double>(whole.count()) + std::chrono::duration<double>(t - whole).count();
}

namespace {

// Text from the input as a terminal may be given it: links, devices and serial lines are named after files
// and interfaces, and messages quote them, so a file named with ESC sequences would drive the reader's
// terminal (errors escape them the same way). Plain ASCII, nearly every name, is written as it is.
struct Shown {
    std::string_view text;
};
std::ostream& operator<<(std::ostream& out, Shown s) {
    const bool plain = std::all_of(s.text.begin(), s.text.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u >= 0x20 && u < 0x7F;
    });
    return plain ? out << s.text : out << printable(s.text);
}

std::string pdu_brief(const FrameRecord& f) {
    if (!f.pdu) {
        if (const auto code = exception_code_of(f)) {  // "83 06 00": the code is there all the same
            const auto name = exception_name(*code);
            return "FC" + std::to_string(f.frame.pdu()[0] & 0x7F) + " exception " + std::to_string(*code) +
                   (name ? " " + std::string(*name) : "") + ", undecodable PDU (" + f.error + ")";
        }
        return "undecodable PDU (" + f.error + ")";
    }
    const Pdu& p = *f.pdu;
    std::string s = "FC" + std::to_string(p.function_code());
    if (p.is_exception()) {
        const auto code = std::get<ExceptionResponse>(p.body).exception_code;
        const auto name = exception_name(code);
        return s + " exception " + std::to_string(code) + (name ? " " + std::string(*name) : "");
    }
    if (const auto* r = std::get_if<ReadRequest>(&p.body))
        return s + " read " + std::to_string(r->starting_address) + "+" + std::to_string(r->quantity);
    if (const auto* w = std::get_if<WriteSingle>(&p.body))
        return s + " write " + std::to_string(w->address) + " = " + std::to_string(w->value);
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&p.body))
        return s + " write " + std::to_string(w->starting_address) + "+" + std::to_string(w->quantity);
    if (const auto* w = std::get_if<WriteMultipleCoilsRequest>(&p.body))
        return s + " write coils " + std::to_string(w->starting_address) + "+" + std::to_string(w->quantity);
    if (const auto* r = std::get_if<ReadRegistersResponse>(&p.body)) {
        std::string v = s + " [";
        for (std::size_t i = 0; i < r->values.size() && i < 8; ++i)
            v += (i ? ", " : "") + std::to_string(r->values[i]);
        return v + (r->values.size() > 8 ? ", …]" : "]");
    }
    if (const auto* b = std::get_if<ReadBitsResponse>(&p.body)) return s + " bits " + hex_bytes(b->values);
    if (auto name = function_name(p.function_code())) return s + " " + std::string(*name);
    return s;
}

json direction_json(Direction d) {
    return std::string(to_string(d));
}

}  // namespace

std::string TextSink::time_of(Timestamp t) {
    if (t.count() == 0) return "       (untimed)";
    return time_of_day_text(t);
}

void TextSink::transaction(const TransactionRecord& t) {
    if (summary_only_) return;
    out_ << time_of(t.request.time) << "  " << Shown{t.request.link.view()} << "  unit "
         << int(t.request.frame.unit_id());
    if (t.request.frame.framing == Framing::Tcp)
        out_ << "  tid " << t.request.frame.transaction_id();
    else
        out_ << "  " << to_string(t.request.frame.framing);
    out_ << "  " << pdu_brief(t.request);
    if (t.response) {
        out_ << "  -> " << pdu_brief(*t.response)
             << (t.latency ? "  " + milliseconds_text(*t.latency) : std::string());
        if (!t.response->frame.checksum_ok)
            out_ << "  bad " << (t.response->frame.framing == Framing::Ascii ? "LRC" : "CRC")
                 << ", a master discards it";
        // Paired all the same, as most masters take it (rtu.gap_inside_frame says what SL §2.5.1.1 wants).
        else if (t.response->frame.findings.contains(FindingCode::RtuGapInsideFrame))
            out_ << "  silence inside " << (t.response->frame.gap_at_t3_5 ? "at or above t3.5" : "above t1.5")
                 << ", a strict master discards it";
        if (t.late_past) {
            const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(*t.late_past).count();
            if (!t.late_moved_on)
                out_ << "  late, past the " << waited << " ms timeout";
            else if (t.request.time.count())
                out_ << "  late, the master moved on after " << waited << " ms";
            else
                out_ << "  late, the master had moved on";
        }
    } else
        out_ << "  -> "
             << (t.broadcast                ? "broadcast, no response expected"
                 : t.reply_not_captured     ? "answered, the reply not captured whole"
                 : t.reply_damaged          ? "answered, the reply damaged: it formed no frame"
                 : t.discarded              ? (t.request.frame.checksum_ok
                                                   ? "no response: the request had a silence inside, discarded"
                                                   : "no response: the request's checksum failed, discarded")
                 : t.client_aborted         ? "no response: the client reset the connection first"
                 : t.answered_by_other_unit ? "no response from the unit asked, only another unit replied"
                 : t.timed_out              ? "no response"
                                            : "no response before the capture ended");
    out_ << '\n';
    for (const auto& v : t.values) {
        out_ << "                   " << v.address << "  ";
        if (v.point)
            out_ << Shown{v.point->name_en.empty() ? v.point->name : v.point->name_en};
        else
            out_ << "(not in the map)";
        out_ << " = " << v.text;
        if (v.point && !v.point->unit.empty() && v.number)
            out_ << ' ' << v.point->unit;  // not after a raw half
        if (v.partial) out_ << "  (partial)";
        if (v.other_half_earlier)
            out_ << "  (register " << *v.other_half_earlier << " from an earlier reply)";
        out_ << '\n';
    }
    for (const auto& r : t.registers32)
        out_ << "                   " << r.address << "  " << to_string(*t.word_order) << "  u32 " << r.u32
             << "  f32 " << float_text(r.f32) << '\n';
}

void TextSink::finding(const FindingRecord& f) {
    if (summary_only_) return;
    const auto& i = info(f.code);
    out_ << time_of(f.time) << "  ! " << i.name << " (" << to_string(i.severity) << ") "
         << Shown{f.link.view()};
    // A gateway or a multi-drop line has several devices on one link: the line says which one the finding is
    // about (as its JSON record's `device` does), unless the message names it already.
    if (const std::string_view device = f.device.view();
        !device.empty() && f.message.find(device) == std::string::npos)
        if (const auto unit = device.rfind(" unit "); unit != std::string_view::npos)
            out_ << Shown{device.substr(unit)};
    out_ << ": " << Shown{f.message};
    if (!f.frames.empty()) {
        out_ << " [frame";
        for (auto n : f.frames)
            out_ << ' ' << n;
        out_ << ']';
    }
    out_ << '\n';
}

void TextSink::unparsed(const UnparsedRecord&) {}  // reported through its finding

void TextSink::end(const Summary& s) {
    out_ << "\nsummary: " << s.packets << " packets, " << s.frames << " frames, " << s.transactions
         << " transactions, " << s.unparsed_bytes << " unparsed bytes";
    if (s.damaged_broadcasts)
        out_ << ", " << s.damaged_broadcasts << " damaged frames to unit 0 (bad CRC/LRC: no broadcast)";
    if (s.damaged_to_unseen_units)
        out_ << ", " << s.damaged_to_unseen_units
             << " damaged frames to units not seen on their line (bad CRC/LRC: no device's)";
    out_ << '\n';
    for (const auto& [device, d] : s.devices) {
        out_ << "  " << Shown{device} << ": " << d.requests << " requests, " << d.responses << " responses, "
             << d.exceptions << " exceptions, " << d.timeouts << " timeouts";
        if (d.late_responses) out_ << " (" << d.late_responses << " answered late)";
        if (d.unanswered_at_end) out_ << ", " << d.unanswered_at_end << " unanswered at the end";
        if (d.answered_by_other_unit)
            out_ << ", " << d.answered_by_other_unit << " of these unanswered while another unit replied";
        if (d.replies_not_captured)
            out_ << ", " << d.replies_not_captured << " answered with replies not captured whole";
        if (d.damaged_replies)
            out_ << ", " << d.damaged_replies << " answered with damaged replies that formed no frame";
        if (d.damaged_unanswered)
            out_ << ", " << d.damaged_unanswered
                 << " damaged requests discarded (no reply, as the rules want)";
        if (d.client_aborted)
            out_ << ", " << d.client_aborted << " given up by the client (it reset the connection)";
        if (d.checksum_errors) out_ << ", " << d.checksum_errors << " frames with a bad CRC/LRC";
        if (d.latency.count())
            out_ << "; latency min " << milliseconds_text(d.latency.min()) << " / median "
                 << milliseconds_text(d.latency.quantile(0.5)) << " / p99 "
                 << milliseconds_text(d.latency.quantile(0.99)) << " / max "
                 << milliseconds_text(d.latency.max());
        out_ << "\n    functions:";
        for (const auto& [fc, n] : d.functions)
            out_ << " FC" << fc << "×" << n;
        out_ << '\n';
        if (!d.exception_codes.empty()) {
            out_ << "    exceptions:";
            const char* separator = " ";
            for (const auto& [code, n] : d.exception_codes) {
                const auto name = exception_name(static_cast<std::uint8_t>(code));
                out_ << separator << code << ' ' << (name ? *name : "undefined") << "×" << n;
                separator = ", ";
            }
            out_ << '\n';
        }
        if (!d.findings.empty()) {
            out_ << "    findings:";
            for (const auto& [code, n] : d.findings)
                out_ << ' ' << code << "×" << n;
            out_ << '\n';
        }
    }
    for (const auto& [line, read] : s.serial_lines) {
        out_ << "  " << Shown{line} << ": read as ";
        for (std::size_t i = 0; i < read.framings.size(); ++i)
            out_ << (i ? ", then " : "") << (read.framings[i] == Framing::Ascii ? "ASCII" : "RTU")
                 << (i == 0 && read.told ? " (told from its first bytes)" : "");
        out_ << '\n';
    }
    if (!s.findings.empty()) {
        out_ << "  findings:";
        for (const auto& [code, n] : s.findings)
            out_ << ' ' << code << "×" << n;
        out_ << '\n';
    }
    for (const auto& e : s.input_errors)
        out_ << "  input error: " << Shown{e} << '\n';
    if (s.input_errors_unlisted)
        out_ << "  input errors: " << s.input_errors_unlisted << " more, not listed\n";
    for (const auto& e : s.input_notes)
        out_ << "  input note: " << Shown{e} << '\n';
    if (s.input_notes_unlisted) out_ << "  input notes: " << s.input_notes_unlisted << " more, not listed\n";
    if (s.ip_datagrams_incomplete)
        out_ << "  not decoded: " << s.ip_datagrams_incomplete << " IP datagrams missing fragments ("
             << s.ip_fragments_incomplete << " fragments captured)\n";
    if (s.ip_fragments_invalid)
        out_ << "  not decoded: " << s.ip_fragments_invalid
             << " IP fragments reaching past the largest datagram (65,535 bytes)\n";
    if (s.packets_malformed)
        out_ << "  not decoded: " << s.packets_malformed
             << " packets whose link, IP or TCP/UDP header is damaged or cut short\n";
    if (s.packets_cut)
        out_
            << "  cut short: " << s.packets_cut
            << " TCP segments cut to the capture's snapshot length, their missing bytes stream gaps (capture "
               "with a larger snapshot length: tcpdump -s 0)\n";
    if (s.modbus_security_packets)
        out_ << "  not decoded: " << s.modbus_security_packets
             << " packets on TCP port 802, Modbus/TCP Security: TLS, encrypted\n";
    for (const auto& [where, n] : s.modbus_like_ports)
        out_ << "  hint: " << n << (where.first ? " UDP" : " TCP") << " packets on port " << where.second
             << " hold Modbus/TCP ADUs; decode them with " << (where.first ? "--udp-port " : "--tcp-port ")
             << where.second << '\n';
    for (const auto& [where, n] : s.rtu_like_ports)
        out_ << "  hint: " << n << (where.first ? " UDP" : " TCP") << " packets on port " << where.second
             << " hold RTU frames with valid CRCs, not Modbus/TCP"
             // A UDP port decoded tells RTU datagrams from MBAP ones by their CRC.
             << (where.first
                     ? "; decode them with --udp-port "
                     : ": looks like RTU over TCP (a serial gateway); decode them with --rtu-over-tcp ")
             << where.second << '\n';
    for (const auto& [port, n] : s.rtu_over_tcp_connections)
        out_ << "  hint: " << n << (n == 1 ? " TCP connection" : " TCP connections") << " to port " << port
             << " carried RTU frames, not Modbus/TCP: looks like RTU over TCP (a serial gateway), "
                "not decoded; decode them with --rtu-over-tcp "
             << port << '\n';
}

// ---------------------------------------------------------------- JSON

nlohmann::ordered_json frame_to_json(const FrameRecord& f) {
    json j{{"type", "frame"},
           {"ts", seconds(f.time)},
           {"source", f.source},
           {"link", f.link},
           {"frame", f.index},
           {"packet", f.packet},
           {"direction", direction_json(f.direction)},
           {"transport", std::string(to_string(f.carrier))},
           {"framing", std::string(to_string(f.frame.framing))},
           {"unit_id", f.frame.unit_id()},
           {"raw", hex_bytes(f.frame.adu())},
           {"checksum_ok", f.frame.checksum_ok}};
    if (f.frame.framing == Framing::Tcp) {
        j["transaction_id"] = f.frame.transaction_id();
        j["protocol_id"] = f.frame.protocol_id();
    }
    nlohmann::ordered_json fields = nlohmann::ordered_json::object();
    if (f.pdu) {
        j["function_raw"] = f.pdu->function_raw;
        j["function"] = f.pdu->function_code();
        if (auto n = function_name(f.pdu->function_code())) j["function_name"] = std::string(*n);
        j["exception"] = f.pdu->is_exception();
        for (const auto& field : describe_pdu(*f.pdu))
            if (field.name != "function_code") fields[field.name] = field.value;
        j["fields"] = nullptr;  // its place among the record's keys, sorted as every record's are
    } else {
        j["error"] = f.error;
        if (!f.frame.pdu().empty()) {  // the function byte is known even when the rest is not
            j["function_raw"] = f.frame.pdu()[0];
            j["function"] = f.frame.pdu()[0] & 0x7F;
            j["exception"] = (f.frame.pdu()[0] & 0x80) != 0;
        }
    }
    nlohmann::ordered_json out = j;
    if (f.pdu) out["fields"] = std::move(fields);
    return out;
}

JsonSink::~JsonSink() {
    pass_on();
}

void JsonSink::pass_on() {
    const auto text = writer_.text();
    out_.write(text.data(), static_cast<std::streamsize>(text.size()));
    writer_.clear();
}

void JsonSink::flush() {
    if (!lines_) return;
    pass_on();
    out_.flush();
}

void JsonSink::line_written() {
    writer_.end_line();
    if (writer_.size() >= (1u << 16)) pass_on();
}

void JsonSink::emit(nlohmann::ordered_json j) {
    // Strings from a capture (a log line quoted in an input error, FC43 identification objects) need not be
    // UTF-8: invalid bytes become U+FFFD instead of an exception that would end the run.
    if (lines_) {
        writer_.raw(j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
        line_written();
    } else {
        document_.push_back(std::move(j));
    }
}

void JsonSink::frame(const FrameRecord& f) {
    if (summary_only_) return;
    if (!lines_) return emit(frame_to_json(f));
    write_frame(f, writer_);
    line_written();
}

void JsonSink::transaction(const TransactionRecord& t) {
    if (summary_only_) return;
    if (!lines_) return emit(transaction_to_json(t));
    write_transaction(t, writer_);
    line_written();
}

void JsonSink::finding(const FindingRecord& f) {
    if (summary_only_) return;
    if (!lines_) return emit(finding_to_json(f));
    write_finding(f, writer_);
    line_written();
}

void JsonSink::unparsed(const UnparsedRecord& u) {
    if (summary_only_) return;
    if (!lines_) return emit(unparsed_to_json(u));
    write_unparsed(u, writer_);
    line_written();
}

json transaction_to_json(const TransactionRecord& t) {
    json j{
        {"type", "transaction"},  {"ts", seconds(t.request.time)},    {"source", t.request.source},
        {"link", t.request.link}, {"request_frame", t.request.index}, {"unit_id", t.request.frame.unit_id()}};
    j["transport"] = std::string(to_string(t.request.carrier));
    if (t.request.pdu)
        j["function"] = t.request.pdu->function_code();
    else if (!t.request.frame.pdu().empty())  // a malformed request still asked for its function
        j["function"] = t.request.frame.pdu()[0] & 0x7F;
    if (t.request.frame.framing == Framing::Tcp) j["transaction_id"] = t.request.frame.transaction_id();
    if (t.response) {
        j["response_frame"] = t.response->index;
        if (t.latency) j["latency_ms"] = std::chrono::duration<double, std::milli>(*t.latency).count();
        if (t.late_past) j["late"] = true;
        if (const auto code = exception_code_of(*t.response)) j["exception_code"] = *code;
    } else if (t.broadcast) {
        j["broadcast"] = true;
    } else {
        j["timeout"] = t.timed_out;
        if (t.reply_not_captured) j["reply_not_captured"] = true;
        if (t.reply_damaged) j["reply_damaged"] = true;
        if (t.discarded) j["discarded"] = true;
        if (t.client_aborted) j["client_aborted"] = true;
        if (t.answered_by_other_unit) j["answered_by_other_unit"] = true;
    }
    if (!t.findings.empty()) {
        for (auto c : t.findings)
            j["findings"].push_back(std::string(to_string(c)));
    }
    if (t.profile) j["profile"] = t.profile->id;
    for (const auto& v : t.values)
        j["values"].push_back(named_value_to_json(v));
    if (t.word_order) {
        j["word_order"] = std::string(to_string(*t.word_order));
        j["registers32"] = json::array();
        for (const auto& r : t.registers32)  // a NaN or infinite f32 is null: f32_text tells which
            j["registers32"].push_back(
                {{"address", r.address}, {"u32", r.u32}, {"f32", r.f32}, {"f32_text", float_text(r.f32)}});
    }
    return j;
}

json finding_to_json(const FindingRecord& f) {
    const auto& i = info(f.code);
    json j{{"type", "finding"},           {"ts", seconds(f.time)},
           {"source", f.source},          {"link", f.link},
           {"code", std::string(i.name)}, {"severity", std::string(to_string(i.severity))},
           {"message", f.message},        {"rule", std::string(i.rule)},
           {"packet", f.packet}};
    if (!f.device.empty()) j["device"] = f.device;
    if (!f.frames.empty()) j["frames"] = f.frames;
    return j;
}

json unparsed_to_json(const UnparsedRecord& u) {
    return json{{"type", "unparsed"},
                {"ts", seconds(u.time)},
                {"source", u.source},
                {"link", u.link},
                {"direction", direction_json(u.direction)},
                {"offset", u.offset},
                {"length", u.length},
                {"reason", std::string(to_string(u.reason))},
                {"packet", u.packet}};
}

json summary_to_json(const Summary& s) {
    json j{{"type", "summary"},
           {"schema_version", jsonl_schema_version},
           {"packets", s.packets},
           {"frames", s.frames},
           {"transactions", s.transactions},
           {"unparsed_bytes", s.unparsed_bytes},
           {"damaged_broadcasts", s.damaged_broadcasts},
           {"damaged_to_unseen_units", s.damaged_to_unseen_units},
           {"errors", s.errors},
           {"findings", s.findings}};
    json devices = json::object();
    for (const auto& [name, d] : s.devices) {
        json dev{{"requests", d.requests},
                 {"responses", d.responses},
                 {"exceptions", d.exceptions},
                 {"timeouts", d.timeouts},
                 {"unanswered_at_end", d.unanswered_at_end}};
        if (d.late_responses) dev["late_responses"] = d.late_responses;
        if (d.replies_not_captured) dev["replies_not_captured"] = d.replies_not_captured;
        if (d.damaged_replies) dev["damaged_replies"] = d.damaged_replies;
        if (d.damaged_unanswered) dev["damaged_unanswered"] = d.damaged_unanswered;
        if (d.client_aborted) dev["client_aborted"] = d.client_aborted;
        if (d.answered_by_other_unit) dev["answered_by_other_unit"] = d.answered_by_other_unit;
        if (d.checksum_errors) dev["checksum_errors"] = d.checksum_errors;
        if (!d.findings.empty()) dev["findings"] = d.findings;
        json fcs = json::object();
        for (const auto& [fc, n] : d.functions)
            fcs[std::to_string(fc)] = n;
        dev["functions"] = fcs;
        if (!d.exception_codes.empty()) {
            json codes = json::object();
            for (const auto& [code, n] : d.exception_codes)
                codes[std::to_string(code)] = n;
            dev["exception_codes"] = codes;
        }
        if (d.latency.count()) {
            auto m = [](Timestamp t) { return std::chrono::duration<double, std::milli>(t).count(); };
            dev["latency_ms"] = {{"min", m(d.latency.min())},
                                 {"median", m(d.latency.quantile(0.5))},
                                 {"p99", m(d.latency.quantile(0.99))},
                                 {"max", m(d.latency.max())}};
        }
        devices[name] = dev;
    }
    j["devices"] = devices;
    if (!s.input_errors.empty()) j["input_errors"] = s.input_errors;
    if (s.input_errors_unlisted) j["input_errors_unlisted"] = s.input_errors_unlisted;
    if (!s.input_notes.empty()) j["input_notes"] = s.input_notes;
    if (s.input_notes_unlisted) j["input_notes_unlisted"] = s.input_notes_unlisted;
    if (s.ip_datagrams_incomplete || s.ip_fragments_invalid)
        j["ip_fragments_not_decoded"] = {{"datagrams_incomplete", s.ip_datagrams_incomplete},
                                         {"fragments_incomplete", s.ip_fragments_incomplete},
                                         {"fragments_invalid", s.ip_fragments_invalid}};
    if (s.packets_malformed) j["packets_malformed"] = s.packets_malformed;
    if (s.packets_cut) j["packets_cut"] = s.packets_cut;
    if (s.modbus_security_packets) j["modbus_security_packets"] = s.modbus_security_packets;
    if (!s.serial_lines.empty()) {
        json lines = json::object();
        for (const auto& [line, read] : s.serial_lines) {
            json framings = json::array();
            for (const Framing f : read.framings)
                framings.push_back(std::string(to_string(f)));
            lines[line] = {{"framings", framings}, {"told_from_bytes", read.told}};
        }
        j["serial_lines"] = lines;
    }
    // Ports not decoded, by (udp?, port): packets of Modbus/TCP ADUs, or of RTU frames.
    const auto like_ports = [&j](const char* key,
                                 const std::map<std::pair<bool, std::uint16_t>, std::uint64_t>& tally) {
        if (tally.empty()) return;
        json ports = json::array();
        for (const auto& [where, n] : tally)
            ports.push_back(
                {{"transport", where.first ? "udp" : "tcp"}, {"port", where.second}, {"packets", n}});
        j[key] = ports;
    };
    like_ports("modbus_like_ports", s.modbus_like_ports);
    like_ports("rtu_like_ports", s.rtu_like_ports);
    if (!s.rtu_over_tcp_connections.empty()) {
        json ports = json::array();
        for (const auto& [port, n] : s.rtu_over_tcp_connections)
            ports.push_back({{"port", port}, {"connections", n}});
        j["rtu_over_tcp_connections"] = ports;
    }
    return j;
}

void TeeSink::frame(const FrameRecord& f) {
    for (auto* s : sinks_)
        s->frame(f);
}
bool TeeSink::wants_transactions() const {
    return std::any_of(sinks_.begin(), sinks_.end(), [](const Sink* s) { return s->wants_transactions(); });
}

void TeeSink::transaction(const TransactionRecord& t) {
    for (auto* s : sinks_)
        s->transaction(t);
}
void TeeSink::finding(const FindingRecord& f) {
    for (auto* s : sinks_)
        s->finding(f);
}
void TeeSink::unparsed(const UnparsedRecord& u) {
    for (auto* s : sinks_)
        s->unparsed(u);
}
void TeeSink::end(const Summary& summary) {
    for (auto* s : sinks_)
        s->end(summary);
}
void TeeSink::flush() {
    for (auto* s : sinks_)
        s->flush();
}

void JsonSink::end(const Summary& s) {
    emit(summary_to_json(s));
    pass_on();
    if (!lines_) out_ << document_.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
    out_.flush();
}

}  // namespace mbscope::analyzer
