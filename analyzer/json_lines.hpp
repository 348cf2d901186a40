#pragma once
// Each record of the analysis as one JSON object written straight to a stream: the JSON lines of
// `mbscope decode --jsonl`, the fast path for large captures. The objects are the ones frame_to_json(),
// transaction_to_json(), finding_to_json() and unparsed_to_json() build as nlohmann documents (sinks.hpp),
// keys in the same sorted order; tests/analyzer/json_lines_test.cpp holds the two to the same output.

#include "analyzer/records.hpp"
#include "modbus/json_writer.hpp"

namespace mbscope::analyzer {

void write_frame(const FrameRecord& f, modbus::JsonWriter& out);
void write_transaction(const TransactionRecord& t, modbus::JsonWriter& out);
void write_finding(const FindingRecord& f, modbus::JsonWriter& out);
void write_unparsed(const UnparsedRecord& u, modbus::JsonWriter& out);

}  // namespace mbscope::analyzer
