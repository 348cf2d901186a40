#include "analyzer/csv_sink.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <vector>

#include "analyzer/word_order.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;

namespace {

constexpr const char* columns[] = {
    "time",           "source",     "transport",     "framing",     "link",     "unit_id",
    "transaction_id", "function",   "function_name", "address",     "quantity", "status",
    "exception_code", "latency_ms", "values",        "registers32", "findings"};

std::string iso_time(Timestamp t) {
    if (t.count() == 0) return {};  // raw dumps carry no time
    using namespace std::chrono;
    const auto us = duration_cast<microseconds>(t);
    const auto day = floor<days>(sys_time<microseconds>(us));
    const year_month_day date(day);
    const auto in_day = us - day.time_since_epoch();
    const long long u = in_day.count();
    char buf[48];
    std::snprintf(buf, sizeof buf, "%04d-%02u-%02uT%02lld:%02lld:%02lld.%06lldZ",
                  static_cast<int>(date.year()), static_cast<unsigned>(date.month()),
                  static_cast<unsigned>(date.day()), u / 3'600'000'000LL, u / 60'000'000 % 60,
                  u / 1'000'000 % 60, u % 1'000'000);
    return buf;
}

struct Extent {
    std::uint16_t address;
    std::uint16_t quantity;
};

// What the request names: the first address and how many coils or registers.
std::optional<Extent> extent_of(const Pdu& p) {
    if (const auto* r = std::get_if<ReadRequest>(&p.body)) return Extent{r->starting_address, r->quantity};
    if (const auto* w = std::get_if<WriteSingle>(&p.body)) return Extent{w->address, 1};
    if (const auto* c = std::get_if<WriteMultipleCoilsRequest>(&p.body))
        return Extent{c->starting_address, c->quantity};
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&p.body))
        return Extent{w->starting_address, w->quantity};
    if (const auto* m = std::get_if<MaskWriteRegister>(&p.body)) return Extent{m->reference_address, 1};
    if (const auto* rw = std::get_if<ReadWriteMultipleRequest>(&p.body))
        return Extent{rw->read_starting_address, rw->quantity_to_read};
    return std::nullopt;
}

template <typename T>
std::string joined(const std::vector<T>& values) {
    std::string s;
    for (const auto& v : values)
        s += (s.empty() ? "" : " ") + std::to_string(v);
    return s;
}

std::string bits(std::span<const std::uint8_t> packed, std::uint16_t quantity) {
    std::string s;
    for (std::size_t i = 0; i < quantity && i / 8 < packed.size(); ++i)
        s += std::string(i ? " " : "") + ((packed[i / 8] >> (i % 8)) & 1 ? "1" : "0");
    return s;
}

// The values a transaction read or wrote, as the device gives them (no profile).
std::string raw_values(const Pdu& request, const Pdu* response) {
    if (response) {
        if (const auto* r = std::get_if<ReadRegistersResponse>(&response->body)) return joined(r->values);
        if (const auto* b = std::get_if<ReadBitsResponse>(&response->body)) {
            const auto* read = std::get_if<ReadRequest>(&request.body);
            return bits(b->values, read ? read->quantity : static_cast<std::uint16_t>(b->values.size() * 8));
        }
    }
    if (const auto* w = std::get_if<WriteSingle>(&request.body)) {
        if (request.function_code() == 5) return w->value == 0xFF00 ? "1" : "0";  // AP §6.5: FF00 is ON
        return std::to_string(w->value);
    }
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&request.body)) return joined(w->values);
    if (const auto* c = std::get_if<WriteMultipleCoilsRequest>(&request.body))
        return bits(c->values, c->quantity);
    return {};
}

std::string named_values(const std::vector<NamedValue>& values) {
    std::string s;
    for (const auto& v : values) {
        if (!s.empty()) s += "; ";
        if (v.point)
            s += v.point->name_en.empty() ? v.point->name : v.point->name_en;
        else
            s += std::to_string(v.address);
        s += "=" + v.text;
        if (v.point && !v.point->unit.empty() && v.number) s += " " + v.point->unit;  // not after a raw half
        if (v.partial) s += " (partial)";
        if (v.other_half_earlier)
            s += " (register " + std::to_string(*v.other_half_earlier) + " from an earlier reply)";
    }
    return s;
}

// A reply paired with the request that does not answer it as asked: another function, unit or transaction
// id, a data size the request does not call for, a write not echoed. Its row said "ok" beside the finding,
// and a reader counting rows by status took the exchange for a clean one.
bool answers_another_request(const TransactionRecord& t) {
    return std::any_of(t.findings.begin(), t.findings.end(), [](FindingCode code) {
        return code == FindingCode::PairFunctionMismatch || code == FindingCode::PairUnitMismatch ||
               code == FindingCode::PairTransactionIdMismatch ||
               code == FindingCode::PairResponseSizeMismatch || code == FindingCode::PairEchoMismatch;
    });
}

std::string status_of(const TransactionRecord& t) {
    if (t.broadcast) return "broadcast";
    if (!t.response)
        return t.reply_not_captured ? "reply_not_captured"
               : t.reply_damaged    ? "reply_damaged"
               : t.discarded        ? "discarded"
               : t.client_aborted   ? "client_aborted"
               : t.timed_out        ? "timeout"
                                    : "unanswered";
    if (!t.response->pdu) return "malformed";
    // The master discards a reply whose CRC or LRC fails (serial line §2.5.1.2): decoded, but no answer.
    if (!t.response->frame.checksum_ok) return "bad_checksum";
    // After its timeout: the request has a row of its own already, "timeout".
    if (t.late_past) return t.response->pdu->is_exception() ? "late_exception" : "late";
    if (answers_another_request(t)) return "mismatch";
    if (t.response->pdu->is_exception()) return "exception";
    // A normal reply to a request that does not decode was "ok": the row passed for a clean exchange.
    return t.request.pdu ? "ok" : "malformed_request";
}

}  // namespace

namespace {
// Bytes that are not UTF-8 and control characters other than CR, LF and tab (a file name may hold both)
// written as \xNN: RFC 4180's text holds neither, and a reader decoding the file as UTF-8 stopped at them.
// CR and LF are a quoted field's own.
std::string csv_text(std::string_view raw) {
    std::string out;
    out.reserve(raw.size());
    for (std::size_t i = 0; i < raw.size();) {
        const auto c = utf8_at(raw, i);
        const bool control =
            c.length != 0 && ((c.code < 0x20 && c.code != '\r' && c.code != '\n' && c.code != '\t') ||
                              (c.code >= 0x7F && c.code <= 0x9F));
        if (c.length != 0 && !control) {
            out.append(raw.substr(i, c.length));
            i += c.length;
            continue;
        }
        const std::size_t n = c.length ? c.length : 1;
        for (std::size_t k = 0; k < n; ++k) {
            char hex[5];
            std::snprintf(hex, sizeof hex, "\\x%02X", static_cast<unsigned char>(raw[i + k]));
            out += hex;
        }
        i += n;
    }
    return out;
}
}  // namespace

std::string csv_field(std::string_view raw) {
    const std::string text = csv_text(raw);
    if (text.find_first_of(",\"\r\n") == std::string_view::npos) return text;
    std::string quoted = "\"";
    for (char c : text) {
        if (c == '"') quoted += '"';
        quoted += c;
    }
    return quoted + '"';
}

CsvSink::CsvSink(std::ostream& out) : out_(out) {
    std::string header;
    for (const char* c : columns)
        header += (header.empty() ? "" : ",") + std::string(c);
    out_ << header << "\r\n";
}

void CsvSink::transaction(const TransactionRecord& t) {
    const FrameRecord& q = t.request;
    const Pdu* response = t.response && t.response->pdu ? &*t.response->pdu : nullptr;
    std::vector<std::string> row;
    row.push_back(iso_time(q.time));
    row.push_back(q.source);
    row.push_back(std::string(to_string(q.carrier)));
    row.push_back(std::string(to_string(q.frame.framing)));
    row.push_back(q.link);
    row.push_back(std::to_string(q.frame.unit_id()));
    row.push_back(q.frame.framing == Framing::Tcp ? std::to_string(q.frame.transaction_id()) : "");
    std::optional<Extent> extent = q.pdu ? extent_of(*q.pdu) : std::nullopt;
    const std::optional<int> fc = q.pdu                   ? std::optional<int>(q.pdu->function_code())
                                  : q.frame.pdu().empty() ? std::nullopt
                                                          : std::optional<int>(q.frame.pdu()[0] & 0x7F);
    row.push_back(fc ? std::to_string(*fc) : "");
    const auto name = fc ? function_name(static_cast<std::uint8_t>(*fc)) : std::nullopt;
    row.push_back(name ? std::string(*name) : "");
    row.push_back(extent ? std::to_string(extent->address) : "");
    row.push_back(extent ? std::to_string(extent->quantity) : "");
    row.push_back(status_of(t));
    const auto exception = t.response ? exception_code_of(*t.response) : std::nullopt;
    row.push_back(exception ? std::to_string(*exception) : "");
    if (t.latency) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.3f", std::chrono::duration<double, std::milli>(*t.latency).count());
        row.push_back(buf);
    } else {
        row.push_back("");
    }
    if (!t.values.empty())
        row.push_back(named_values(t.values));
    else
        row.push_back(q.pdu && !(response && response->is_exception()) ? raw_values(*q.pdu, response) : "");
    std::string words;
    for (const auto& r : t.registers32)
        words += (words.empty() ? "" : "; ") + std::to_string(r.address) + " u32=" + std::to_string(r.u32) +
                 " f32=" + float_text(r.f32);
    row.push_back(words);
    std::string findings;
    for (auto c : t.findings)
        findings += (findings.empty() ? "" : " ") + std::string(to_string(c));
    row.push_back(findings);
    std::string line;
    for (std::size_t i = 0; i < row.size(); ++i)
        line += (i ? "," : "") + csv_field(row[i]);
    out_ << line << "\r\n";
}

}  // namespace mbscope::analyzer
