#pragma once
// One CSV row per transaction (--csv), for spreadsheets and scripts: RFC 4180 (comma separated, CRLF line
// ends, a field with a comma, a quote or a line break in double quotes, quotes doubled), a header row first.
//
// Columns: time (ISO 8601 UTC, empty for untimed dumps), source, transport (tcp, udp, serial,
// exported-pdu), framing (tcp, rtu, ascii), link, unit_id, transaction_id (Modbus/TCP only), function,
// function_name, address and quantity (what the request names), status (ok, exception, timeout, unanswered,
// broadcast, malformed, bad_checksum, and late or late_exception for a reply after its request's timeout,
// which has a "timeout" row of its own), exception_code, latency_ms, values, registers32, findings.
// values: with a profile "name=value unit" separated by "; "; without one the registers or bits read or
// written, separated by spaces. registers32 (--word-order): "address u32=N f32=X" separated by "; ".

#include <ostream>
#include <string>
#include <string_view>

#include "analyzer/records.hpp"

namespace mbscope::analyzer {

// A field as RFC 4180 writes it: quoted only when it has to be.
std::string csv_field(std::string_view text);

class CsvSink : public Sink {
  public:
    explicit CsvSink(std::ostream& out);
    void transaction(const TransactionRecord& t) override;
    void end(const Summary&) override { out_.flush(); }
    void flush() override { out_.flush(); }

  private:
    std::ostream& out_;
};

}  // namespace mbscope::analyzer
