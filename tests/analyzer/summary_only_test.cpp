// A sink that takes no transaction records (--summary) lets the analyzer skip making them. Everything the
// summary and the findings say must stay the same: each capture is decoded by a sink that takes every
// record and by one that takes none, and the two are compared finding by finding and count by count.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "analyzer/analyzer.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_summary_only_test {

using namespace std::chrono_literals;
namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::Collect;

namespace {

struct SummaryOnly : Collect {
    bool wants_transactions() const override { return false; }
    void transaction(const an::TransactionRecord&) override { ADD_FAILURE() << "a transaction was made"; }
};

std::shared_ptr<an::Semantics> fixture_semantics() {
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/tests/fixtures/profiles"});
    auto p = store.load("test-device");
    EXPECT_TRUE(p.has_value());
    auto s = std::make_shared<an::Semantics>();
    s->add({}, std::make_shared<const mb::Profile>(std::move(p.value())));
    return s;
}

// Decodes `file` (a path, or the bytes when `bytes` is not empty) into `sink`; the summary.
an::Summary decode(an::Sink& sink, const std::string& path, const std::vector<std::uint8_t>& bytes,
                   std::shared_ptr<an::Semantics> semantics) {
    an::AnalyzerOptions o;
    o.semantics = std::move(semantics);
    an::Analyzer a(o, sink);
    std::string error;
    auto source = bytes.empty() ? an::CaptureSource::open_file(path, error)
                                : an::CaptureSource::open_memory(bytes, error);
    EXPECT_TRUE(source) << error;
    if (source) a.read_capture(*source);
    a.finish();
    return a.summary();
}

void expect_same(const std::string& what, const std::string& path,
                 const std::vector<std::uint8_t>& bytes = {},
                 std::shared_ptr<an::Semantics> semantics = nullptr) {
    SCOPED_TRACE(what);
    Collect all;
    SummaryOnly summary_only;
    const auto a = decode(all, path, bytes, semantics);
    const auto b = decode(summary_only, path, bytes, semantics);
    EXPECT_EQ(a.packets, b.packets);
    EXPECT_EQ(a.frames, b.frames);
    EXPECT_EQ(a.transactions, b.transactions);
    // A late reply's record pairs a request counted with its timeout already.
    EXPECT_EQ(std::count_if(all.transactions.begin(), all.transactions.end(),
                            [](const an::TransactionRecord& t) { return !t.late_past; }),
              static_cast<std::ptrdiff_t>(a.transactions));
    EXPECT_EQ(a.unparsed_bytes, b.unparsed_bytes);
    EXPECT_EQ(a.findings, b.findings);
    EXPECT_EQ(a.errors, b.errors);
    EXPECT_EQ(a.input_errors, b.input_errors);
    ASSERT_EQ(a.devices.size(), b.devices.size());
    for (const auto& [name, d] : a.devices) {
        ASSERT_TRUE(b.devices.count(name)) << name;
        const auto& e = b.devices.at(name);
        EXPECT_EQ(d.requests, e.requests) << name;
        EXPECT_EQ(d.responses, e.responses) << name;
        EXPECT_EQ(d.exceptions, e.exceptions) << name;
        EXPECT_EQ(d.exception_codes, e.exception_codes) << name;
        EXPECT_EQ(d.timeouts, e.timeouts) << name;
        EXPECT_EQ(d.unanswered_at_end, e.unanswered_at_end) << name;
        EXPECT_EQ(d.late_responses, e.late_responses) << name;
        EXPECT_EQ(d.checksum_errors, e.checksum_errors) << name;
        EXPECT_EQ(d.functions, e.functions) << name;
        EXPECT_EQ(d.latency.count(), e.latency.count()) << name;
        EXPECT_EQ(d.latency.min(), e.latency.min()) << name;
        EXPECT_EQ(d.latency.max(), e.latency.max()) << name;
        EXPECT_EQ(d.latency.quantile(0.5), e.latency.quantile(0.5)) << name;
    }
    ASSERT_EQ(all.findings.size(), summary_only.findings.size());
    for (std::size_t i = 0; i < all.findings.size(); ++i) {
        const auto &f = all.findings[i], &g = summary_only.findings[i];
        EXPECT_EQ(f.code, g.code) << i;
        EXPECT_EQ(f.message, g.message) << i;
        EXPECT_EQ(f.frames, g.frames) << i;
        EXPECT_EQ(f.packet, g.packet) << i;
        EXPECT_EQ(f.time, g.time) << i;
        EXPECT_EQ(f.device, g.device) << i;
    }
    EXPECT_EQ(all.frames.size(), summary_only.frames.size());
    EXPECT_EQ(all.unparsed_records.size(), summary_only.unparsed_records.size());
}

}  // namespace

// Every pairing finding, and the profile's findings about responses, in one conversation.
TEST(SummaryOnly, FindingsAboutPairsAreTheSame) {
    mbscope::test::Conversation c;
    mb::Timestamp t = 1s;
    std::uint16_t tid = 0;
    const auto exchange = [&](const mb::Pdu& q, mb::Pdu a, std::uint8_t unit = 1,
                              std::uint8_t answer_unit = 1, bool answered = true) {
        ++tid;
        c.send(true, mb::encode_tcp(tid, unit, mb::encode_pdu(q)), t += 1ms);
        a.direction = mb::Direction::Response;
        if (answered) c.send(false, mb::encode_tcp(tid, answer_unit, mb::encode_pdu(a)), t += 2ms);
    };
    const auto read = mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2);
    const std::vector<std::uint16_t> both{2, 1234}, one{2};
    exchange(read, mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, both));
    exchange(read, mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, one));  // size
    exchange(read, mb::make_exception(3, 2));  // exception the map says cannot be
    exchange(read, mb::make_exception(4, 2));  // function mismatch
    exchange(read, mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, both), 1,
             2);                                                                             // unit mismatch
    exchange(mb::make_write_single_register(23, 5), mb::make_write_single_register(23, 6));  // echo
    exchange(mb::make_write_single_register(23, 251), mb::make_exception(6, 3));  // out of the range
    exchange(read, mb::make_exception(3, 2), 1, 1, false);                        // no response
    c.send(false, mb::encode_tcp(999, 1, mb::encode_pdu([] {
                                     auto a = mb::make_exception(3, 4);
                                     a.direction = mb::Direction::Response;
                                     return a;
                                 }())),
           t += 5s);  // unsolicited, and the one before has timed out
    exchange(read, mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, both), 1, 1,
             false);  // unanswered at the end
    const auto file = c.file();
    expect_same("without a profile", "", file);
    expect_same("with the fixture profile", "", file, fixture_semantics());
    // the conversation does show what it is meant to
    Collect all;
    decode(all, "", file, fixture_semantics());
    for (auto code : {mb::FindingCode::PairResponseSizeMismatch, mb::FindingCode::PairExceptionResponse,
                      mb::FindingCode::PairFunctionMismatch, mb::FindingCode::PairUnitMismatch,
                      mb::FindingCode::PairEchoMismatch, mb::FindingCode::PairNoResponse,
                      mb::FindingCode::PairUnsolicitedResponse, mb::FindingCode::PairNoResponseAtEnd,
                      mb::FindingCode::ProfileExceptionUnexpected})
        EXPECT_GE(all.count(code), 1) << mb::to_string(code);
}

// What a device's registers were read holding decides whether a later write changes anything (MK-CFG-01:
// a write of the line settings they already hold is no note): remembered without transaction records too.
TEST(SummaryOnly, RegistersReadBeforeAreRememberedToo) {
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    auto p = store.load("mmk-2030");
    ASSERT_TRUE(p.has_value());
    auto mk = std::make_shared<an::Semantics>();
    mk->add({}, std::make_shared<const mb::Profile>(std::move(p.value())));
    mbscope::test::Conversation c;
    mb::Timestamp t = 1s;
    std::uint16_t tid = 0;
    const auto exchange = [&](const mb::Pdu& q, mb::Pdu a) {
        ++tid;
        c.send(true, mb::encode_tcp(tid, 1, mb::encode_pdu(q)), t += 1ms);
        a.direction = mb::Direction::Response;
        c.send(false, mb::encode_tcp(tid, 1, mb::encode_pdu(a)), t += 2ms);
    };
    const std::vector<std::uint16_t> held{1, 5, 0}, ascii{0, 5, 0};  // PROT, BAUD, PARID
    exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 8, 3),
             mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, held));
    const auto ack = mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleRegisters, 8, 3);
    exchange(mb::make_write_multiple_registers(8, held), ack);   // what they hold: no note
    exchange(mb::make_write_multiple_registers(8, ascii), ack);  // PROT := 0: the note
    const auto file = c.file();
    expect_same("mmk-2030", "", file, mk);
    Collect all;
    decode(all, "", file, mk);
    EXPECT_EQ(all.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
}

// The bundled captures and the public ones in ../shared/captures, read from their files (read ahead).
TEST(SummaryOnly, RealCapturesGiveTheSameSummary) {
    std::vector<std::string> files;
    for (const auto* dir : {"/captures", "/../shared/captures"}) {
        const std::filesystem::path root = std::string(MBSCOPE_SOURCE_DIR) + dir;
        if (!std::filesystem::exists(root)) continue;
        for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
            const auto ext = e.path().extension();
            if (e.is_regular_file() && (ext == ".pcap" || ext == ".pcapng"))
                files.push_back(e.path().string());
        }
    }
    ASSERT_GE(files.size(), 2u);
    for (const auto& f : files)
        expect_same(f, f);
}

namespace {
// `mbscope decode ARGS`: its exit code and standard output.
std::pair<int, std::string> run_decode(const std::string& args) {
    return mbscope::test::run_command(std::string(MBSCOPE_BINARY) + " decode --no-progress " + args);
}
}  // namespace

// --summary with --json or --jsonl: the summary record alone, the one the whole output ends with. It was
// ignored there, every record written.
TEST(SummaryOnly, WithJsonItIsTheSummaryRecordAlone) {
    const std::string capture = std::string(MBSCOPE_SOURCE_DIR) + "/captures/suricata-modbus.pcap";
    const auto [all_code, all] = run_decode("--jsonl " + capture);
    const auto [lines_code, lines] = run_decode("--summary --jsonl " + capture);
    EXPECT_EQ(lines_code, all_code);
    ASSERT_FALSE(all.empty());
    const auto last = all.substr(all.rfind('\n', all.size() - 2) + 1);
    EXPECT_EQ(lines, last);
    EXPECT_EQ(nlohmann::json::parse(lines)["type"], "summary");

    const auto [document_code, document] = run_decode("--summary --json " + capture);
    EXPECT_EQ(document_code, all_code);
    const auto records = nlohmann::json::parse(document);
    ASSERT_TRUE(records.is_array());
    ASSERT_EQ(records.size(), 1u);
    EXPECT_EQ(records[0], nlohmann::json::parse(last));
}

}  // namespace test_analyzer_summary_only_test
