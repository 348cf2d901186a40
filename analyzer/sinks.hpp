#pragma once
// Output formats, each a Sink over the same records: text for people, JSON lines / one JSON document for
// machines (schema in analyzer/README.md), and the summary alone (the fast path).

#include <nlohmann/json.hpp>
#include <ostream>
#include <vector>

#include "analyzer/records.hpp"
#include "modbus/json_writer.hpp"

namespace mbscope::analyzer {

inline constexpr int jsonl_schema_version = 1;

class TextSink : public Sink {
  public:
    explicit TextSink(std::ostream& out, bool summary_only = false)
        : out_(out), summary_only_(summary_only) {}
    void transaction(const TransactionRecord& t) override;
    void finding(const FindingRecord& f) override;
    void unparsed(const UnparsedRecord& u) override;
    void end(const Summary& s) override;
    void flush() override { out_.flush(); }
    bool wants_transactions() const override { return !summary_only_; }

  private:
    std::string time_of(modbus::Timestamp t);
    std::ostream& out_;
    bool summary_only_;
};

class JsonSink : public Sink {
  public:
    // lines: one object per line as records come (JSONL); otherwise one document written at the end.
    // Lines are written by json_lines.hpp's streaming writer into a buffer passed on to `out` in 64 KiB
    // pieces; the document is built with nlohmann::json. summary_only: the summary record alone (--summary).
    JsonSink(std::ostream& out, bool lines, bool summary_only = false)
        : out_(out), lines_(lines), summary_only_(summary_only) {}
    ~JsonSink() override;
    void frame(const FrameRecord& f) override;
    void transaction(const TransactionRecord& t) override;
    void finding(const FindingRecord& f) override;
    void unparsed(const UnparsedRecord& u) override;
    void end(const Summary& s) override;
    // JSON lines taken so far, to `out` and flushed (a document is written whole, at the end).
    void flush() override;
    bool wants_transactions() const override { return !summary_only_; }

  private:
    void emit(nlohmann::ordered_json j);
    void line_written();
    void pass_on();  // the lines in the buffer, to `out`
    std::ostream& out_;
    bool lines_;
    bool summary_only_;
    modbus::JsonWriter writer_;
    nlohmann::ordered_json document_ = nlohmann::ordered_json::array();
};

// One pass, several outputs (--csv FILE beside the text or JSON on standard output).
class TeeSink : public Sink {
  public:
    explicit TeeSink(std::vector<Sink*> sinks) : sinks_(std::move(sinks)) {}
    void frame(const FrameRecord& f) override;
    void transaction(const TransactionRecord& t) override;
    void finding(const FindingRecord& f) override;
    void unparsed(const UnparsedRecord& u) override;
    void end(const Summary& s) override;
    void flush() override;
    bool wants_transactions() const override;

  private:
    std::vector<Sink*> sinks_;
};

nlohmann::json summary_to_json(const Summary& s);
// Each record as an nlohmann document (--json, and the reference the JSON lines are tested against). A
// frame's `fields` keep the specification's order (starting address before quantity), as the JSON lines
// do: a sorted object put quantity first. Its other keys are sorted, as every record's are.
nlohmann::ordered_json frame_to_json(const FrameRecord& f);
nlohmann::json transaction_to_json(const TransactionRecord& t);
nlohmann::json finding_to_json(const FindingRecord& f);
nlohmann::json unparsed_to_json(const UnparsedRecord& u);
double seconds(modbus::Timestamp t);

}  // namespace mbscope::analyzer
