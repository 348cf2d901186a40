// --csv: one RFC 4180 row per transaction. The output is parsed back by a reader written here (quoted
// fields, doubled quotes, CRLF) and every column checked against values written by hand.
#include "analyzer/csv_sink.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "analyzer/sinks.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_csv_sink_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

namespace {

using Row = std::map<std::string, std::string>;

// RFC 4180 §2: records end in CRLF, fields in double quotes may hold commas, CRLF and doubled quotes.
std::vector<std::vector<std::string>> parse_csv(const std::string& text) {
    std::vector<std::vector<std::string>> records(1);
    std::string field;
    bool quoted = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (quoted) {
            if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
                field += '"';
                ++i;
            } else if (c == '"') {
                quoted = false;
            } else {
                field += c;
            }
        } else if (c == '"') {
            quoted = true;
        } else if (c == ',') {
            records.back().push_back(field);
            field.clear();
        } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
            records.back().push_back(field);
            field.clear();
            records.emplace_back();
            ++i;
        } else {
            field += c;
        }
    }
    if (records.back().empty()) records.pop_back();  // the text ends with CRLF
    return records;
}

// Rows keyed by the header's column names; every row must have as many fields as the header.
std::vector<Row> rows_of(const std::string& text) {
    const auto records = parse_csv(text);
    EXPECT_FALSE(records.empty());
    std::vector<Row> rows;
    for (std::size_t r = 1; r < records.size(); ++r) {
        EXPECT_EQ(records[r].size(), records[0].size()) << "row " << r;
        Row row;
        for (std::size_t i = 0; i < records[0].size() && i < records[r].size(); ++i)
            row[records[0][i]] = records[r][i];
        rows.push_back(row);
    }
    return rows;
}

std::vector<std::uint8_t> adu(std::uint16_t tid, const mb::Pdu& pdu) {
    return mb::encode_tcp(tid, 1, mb::encode_pdu(pdu));
}

// `mbscope decode ARGS`: its exit code and standard output.
std::pair<int, std::string> decode(const std::string& args) {
    return mbscope::test::run_command(std::string(MBSCOPE_BINARY) + " decode " + args);
}

mb::Pdu response(mb::Pdu p) {
    p.direction = mb::Direction::Response;
    return p;
}

// The CSV of a conversation decoded, with `beside` taking the records too (as --csv FILE sits beside the
// text output).
std::string csv_of(const mbscope::test::Conversation& c, an::Sink* beside = nullptr) {
    std::ostringstream out;
    {
        an::CsvSink csv(out);
        an::TeeSink both(beside ? std::vector<an::Sink*>{beside, &csv} : std::vector<an::Sink*>{&csv});
        an::Analyzer analyzer({}, both);
        std::string error;
        const auto file = c.file();
        auto capture = an::CaptureSource::open_memory(file, error);
        EXPECT_TRUE(capture) << error;
        if (capture) analyzer.read_capture(*capture);
        analyzer.finish();
    }
    return out.str();
}

}  // namespace

TEST(CsvSink, FieldsAreQuotedOnlyWhenTheyMustBe) {
    EXPECT_EQ(an::csv_field("plain text"), "plain text");
    EXPECT_EQ(an::csv_field("a,b"), "\"a,b\"");
    EXPECT_EQ(an::csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    EXPECT_EQ(an::csv_field("two\r\nlines"), "\"two\r\nlines\"");
    EXPECT_EQ(an::csv_field(""), "");
    // Not UTF-8, and control characters (a file name may hold them): written as the text output writes
    // them, so that the file decodes as UTF-8; well-formed UTF-8 and tabs stay.
    EXPECT_EQ(an::csv_field("we,ird\xFF\x01.txt"), "\"we,ird\\xFF\\x01.txt\"");
    EXPECT_EQ(an::csv_field("caf\xC3\xA9\tok"), "caf\xC3\xA9\tok");
    EXPECT_EQ(an::csv_field("\xC2\x9B\x7F"), "\\xC2\\x9B\\x7F");
}

TEST(CsvSink, RawValuesStatusesAndLatency) {
    mbscope::test::Conversation c;
    const bool coils[] = {true, false, true};
    const std::uint16_t registers[] = {555, 0, 100};
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadCoils, 10, 3)), 1s);
    c.send(false, adu(1, response(mb::make_read_bits_response(mb::FunctionCode::ReadCoils, coils))),
           1s + 2500us);
    c.send(true, adu(2, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 3)), 2s);
    c.send(
        false,
        adu(2, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, registers))),
        2s + 1ms);
    c.send(true, adu(3, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 40, 1)), 3s);
    c.send(false, adu(3, mb::make_exception(3, 2)), 3s + 1ms);
    c.send(true, adu(4, mb::make_write_single_register(7, 1234)), 4s);  // never answered
    mbscope::test::Collect kept;
    const auto text = csv_of(c, &kept);
    EXPECT_EQ(kept.transactions.size(), 4u);
    EXPECT_EQ(
        text.substr(0, text.find("\r\n")),
        "time,source,transport,framing,link,unit_id,transaction_id,function,function_name,address,quantity,"
        "status,exception_code,latency_ms,values,registers32,findings");
    const auto rows = rows_of(text);
    ASSERT_EQ(rows.size(), 4u);
    EXPECT_EQ(rows[0].at("time"), "1970-01-01T00:00:01.000000Z");
    EXPECT_EQ(rows[0].at("transport"), "tcp");
    EXPECT_EQ(rows[0].at("framing"), "tcp");
    EXPECT_EQ(rows[0].at("link"), "10.0.0.1:40000 -> 10.0.0.2:502");
    EXPECT_EQ(rows[0].at("unit_id"), "1");
    EXPECT_EQ(rows[0].at("transaction_id"), "1");
    EXPECT_EQ(rows[0].at("function"), "1");
    EXPECT_EQ(rows[0].at("function_name"), "Read Coils");
    EXPECT_EQ(rows[0].at("address"), "10");
    EXPECT_EQ(rows[0].at("quantity"), "3");
    EXPECT_EQ(rows[0].at("status"), "ok");
    EXPECT_EQ(rows[0].at("latency_ms"), "2.500");
    EXPECT_EQ(rows[0].at("values"), "1 0 1");
    EXPECT_EQ(rows[1].at("values"), "555 0 100");
    EXPECT_EQ(rows[1].at("time"), "1970-01-01T00:00:02.000000Z");
    EXPECT_EQ(rows[2].at("status"), "exception");
    EXPECT_EQ(rows[2].at("exception_code"), "2");
    EXPECT_EQ(rows[2].at("values"), "");
    EXPECT_EQ(rows[2].at("findings"), "pair.exception_response");
    EXPECT_EQ(rows[3].at("status"), "unanswered");
    EXPECT_EQ(rows[3].at("function"), "6");
    EXPECT_EQ(rows[3].at("address"), "7");
    EXPECT_EQ(rows[3].at("quantity"), "1");
    EXPECT_EQ(rows[3].at("values"), "1234");
    EXPECT_EQ(rows[3].at("latency_ms"), "");
}

// A normal reply to a request that does not decode (an FC3 request with a byte too many): its row said "ok",
// as if the exchange were clean; it is "malformed_request", with the request's finding.
TEST(CsvSink, ANormalReplyToARequestThatDoesNotDecodeIsNotOk) {
    mbscope::test::Conversation c;
    const std::uint16_t registers[] = {7};
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 1)), 1s);
    c.send(
        false,
        adu(1, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, registers))),
        1s + 1ms);
    c.send(true, mb::encode_tcp(2, 1, std::vector<std::uint8_t>{0x03, 0x00, 0x60, 0x00, 0x01, 0xFF}), 2s);
    c.send(
        false,
        adu(2, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, registers))),
        2s + 1ms);
    const auto rows = rows_of(csv_of(c));
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows[0].at("status"), "ok");
    EXPECT_EQ(rows[1].at("status"), "malformed_request");
    EXPECT_NE(rows[1].at("findings").find("pdu.malformed"), std::string::npos) << rows[1].at("findings");
}

// A reply that does not answer its request as asked (two registers for three, a write echoed with another
// value): its row said "ok" beside the finding; it is "mismatch".
TEST(CsvSink, AReplyThatDoesNotAnswerItsRequestIsAMismatch) {
    mbscope::test::Conversation c;
    const std::uint16_t two[] = {1, 2};
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 107, 3)), 1s);
    c.send(false,
           adu(1, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, two))),
           1s + 1ms);
    c.send(true, mb::encode_tcp(2, 1, std::vector<std::uint8_t>{0x06, 0x00, 0x01, 0x00, 0x03}), 2s);
    c.send(false, mb::encode_tcp(2, 1, std::vector<std::uint8_t>{0x06, 0x00, 0x01, 0x00, 0x05}), 2s + 1ms);
    c.send(true, adu(3, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 107, 2)), 3s);
    c.send(false,
           adu(3, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, two))),
           3s + 1ms);
    const auto rows = rows_of(csv_of(c));
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[0].at("status"), "mismatch");
    EXPECT_NE(rows[0].at("findings").find("pair.response_size_mismatch"), std::string::npos)
        << rows[0].at("findings");
    EXPECT_EQ(rows[1].at("status"), "mismatch");
    EXPECT_NE(rows[1].at("findings").find("pair.echo_mismatch"), std::string::npos) << rows[1].at("findings");
    EXPECT_EQ(rows[2].at("status"), "ok");
}

// A reply after its request's timeout: the request's row says "timeout", and the reply has a row of its own
// with its values and latency.
TEST(CsvSink, ALateReplyHasARowOfItsOwn) {
    mbscope::test::Conversation c;
    const std::uint16_t registers[] = {7, 8};
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 2)), 1s);
    c.send(true, adu(2, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 40, 1)), 4500ms);
    c.send(
        false,
        adu(1, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, registers))),
        5s);
    c.send(false, adu(2, mb::make_exception(3, 2)), 9s);
    const auto rows = rows_of(csv_of(c));
    ASSERT_EQ(rows.size(), 4u);
    EXPECT_EQ(rows[0].at("status"), "timeout");
    EXPECT_EQ(rows[0].at("transaction_id"), "1");
    EXPECT_EQ(rows[1].at("status"), "late");
    EXPECT_EQ(rows[1].at("transaction_id"), "1");
    EXPECT_EQ(rows[1].at("values"), "7 8");
    EXPECT_EQ(rows[1].at("latency_ms"), "4000.000");
    EXPECT_EQ(rows[1].at("findings"), "pair.late_response");
    EXPECT_EQ(rows[2].at("status"), "timeout");
    EXPECT_EQ(rows[3].at("status"), "late_exception");
    EXPECT_EQ(rows[3].at("exception_code"), "2");
    EXPECT_EQ(rows[3].at("findings"), "pair.late_response pair.exception_response");
}

TEST(CsvSink, NamedValuesWithAProfileAndAQuotedSourceName) {
    // tests/fixtures/profiles/test-device.json: 17 decimal places, 18 flow in m3/h scaled by 17, 23 filter
    // with one decimal in s.
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/tests/fixtures/profiles"});
    auto profile = store.load("test-device");
    ASSERT_TRUE(profile.has_value());
    an::AnalyzerOptions o;
    o.semantics = std::make_shared<an::Semantics>();
    o.semantics->add({}, std::make_shared<const mb::Profile>(std::move(profile.value())));
    const std::uint16_t values[] = {2, 1234};
    mbscope::test::Conversation c;
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2)), 1s);
    c.send(false,
           adu(1, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, values))),
           1s + 1ms);
    c.send(true, adu(2, mb::make_write_single_register(23, 250)), 2s);
    c.send(false, adu(2, response(mb::make_write_single_register(23, 250))), 2s + 1ms);
    const std::string path = ::testing::TempDir() + "site \"A\", line 2.pcap";
    const auto file = c.file();
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
    std::ostringstream out;
    {
        an::CsvSink csv(out);
        an::Analyzer analyzer(o, csv);
        EXPECT_TRUE(analyzer.read_capture(path));
        analyzer.finish();
    }
    std::remove(path.c_str());
    EXPECT_NE(out.str().find("\"" + ::testing::TempDir() + "site \"\"A\"\", line 2.pcap\""),
              std::string::npos);
    const auto rows = rows_of(out.str());
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows[0].at("source"), path);
    EXPECT_EQ(rows[0].at("values"), "decimal places=2; flow=12.34 m3/h");
    EXPECT_EQ(rows[1].at("values"), "filter=25.0 s");
}

TEST(CsvSink, DecodeWritesCsvToStandardOutput) {
    const auto [exit_code, out] =
        decode("--csv - " + std::string(MBSCOPE_SOURCE_DIR) + "/captures/suricata-modbus.pcap");
    EXPECT_EQ(exit_code, 1 /* the capture has error findings */) << out;
    const auto rows = rows_of(out);
    ASSERT_EQ(rows.size(), 18u);  // analyzer/README.md: 18 transactions in this capture
    EXPECT_EQ(rows[0].at("link"), "10.0.0.57:2578 -> 10.0.0.3:502");
    EXPECT_EQ(rows[0].at("status"), "exception");
    EXPECT_EQ(rows[0].at("exception_code"), "11");
    EXPECT_EQ(out.find("summary"), std::string::npos);  // nothing but CSV on standard output
}

// A serial reply whose CRC fails: the analyzer decodes and pairs it (the device did answer), but a master
// discards it (serial line §2.5.1.2). Its row said status ok with an empty findings column.
TEST(CsvSink, AReplyWithABadCrcIsNotOk) {
    const std::string path = testing::TempDir() + "csv_bad_crc.txt";
    {
        std::ofstream f(path);
        f << "0.000 > 01 03 00 00 00 03 05 cb\n"           // read 3 registers from 0
          << "0.050 < 01 03 06 02 2b 00 00 00 64 05 7b\n"  // the reply with a bit of its CRC flipped
          << "1.000 > 01 03 00 00 00 03 05 cb\n"
          << "1.050 < 01 03 06 02 2b 00 00 00 64 05 7a\n";
    }
    const auto [exit_code, out] = decode("--format text --csv - " + path);
    EXPECT_EQ(exit_code, 1 /* a CRC mismatch is an error finding */) << out;
    const auto rows = rows_of(out);
    ASSERT_EQ(rows.size(), 2u) << out;
    EXPECT_EQ(rows[0].at("status"), "bad_checksum");
    EXPECT_EQ(rows[0].at("findings"), "rtu.crc_mismatch");
    EXPECT_EQ(rows[1].at("status"), "ok");
    EXPECT_EQ(rows[1].at("findings"), "");
    // Nor are its registers read as 32-bit values (--word-order): they are not what the device holds.
    const auto [words_exit, words] = decode("--format text --word-order abcd --csv - " + path);
    const auto word_rows = rows_of(words);
    ASSERT_EQ(word_rows.size(), 2u) << words;
    EXPECT_EQ(word_rows[0].at("registers32"), "");
    EXPECT_NE(word_rows[1].at("registers32"), "");
    std::remove(path.c_str());
}

// What the device's manual says a request or its reply breaks (profile.*), and a broadcast that only reads
// (pair.broadcast_read), were reported as findings but left out of the transaction's: an acknowledged write
// of 100 to the MK's slave address, which its manual bounds at 0..99 (000:500), was a row "ok" with no
// findings, and so was its JSON transaction record. CRCs by hand (MK manual's frames, 000:396-405 shape).
TEST(CsvSink, TheManualsFindingsAreTheTransactionsToo) {
    const std::string path = testing::TempDir() + "csv_profile_findings.txt";
    {
        std::ofstream f(path);
        f << "1.000 > 11 06 00 07 00 64 3B 70\n"   // ENDER := 100
          << "1.020 < 11 06 00 07 00 64 3B 70\n"   // acknowledged
          << "3.000 > 00 03 0F A0 00 02 C6 EC\n";  // a broadcast read of 4000, which no MK has
    }
    const auto [exit_code, out] = decode("--profile mmk-2030 --csv - " + path);
    EXPECT_EQ(exit_code, 1) << out;
    const auto rows = rows_of(out);
    ASSERT_EQ(rows.size(), 2u) << out;
    EXPECT_EQ(rows[0].at("status"), "ok");
    EXPECT_NE(rows[0].at("findings").find("profile.value_out_of_range"), std::string::npos) << out;
    EXPECT_EQ(rows[1].at("status"), "broadcast");
    EXPECT_EQ(rows[1].at("findings"), "profile.address_unknown pair.broadcast_read");
    const auto [json_exit, jsonl] = decode("--profile mmk-2030 --jsonl " + path);
    EXPECT_EQ(json_exit, 1);
    std::vector<nlohmann::json> transactions;
    std::istringstream lines(jsonl);
    for (std::string line; std::getline(lines, line);)
        if (auto j = nlohmann::json::parse(line, nullptr, false);
            !j.is_discarded() && j["type"] == "transaction")
            transactions.push_back(j);
    ASSERT_EQ(transactions.size(), 2u) << jsonl;
    EXPECT_NE(transactions[0]["findings"].dump().find("profile.value_out_of_range"), std::string::npos);
    EXPECT_EQ(transactions[1]["findings"],
              nlohmann::json::array({"profile.address_unknown", "pair.broadcast_read"}));
    std::remove(path.c_str());
}

// Two MKs on one line; the master asks unit 12 for its decimal places and unit 17 answers [3, 3] with a
// CRC that holds. That reply was counted as unit 12's and its values remembered as unit 12's settings, so
// unit 12's process values read later were scaled 100 and 1000 times off, with nothing said. A slave answers
// only frames with its own address (SL §2.2; MK-MS-02, 000:285): the reply is no answer from unit 12 (a
// master discards it) and the request keeps waiting. Where unit 12 then answers, its own reply is paired
// (it was "unsolicited"); where it does not, the request times out, said to have drawn only the other
// unit's reply, and nothing of that reply is named or remembered. CRCs computed by pymodbus.
TEST(CsvSink, ASerialReplyFromAnotherUnitIsNotTheAskedUnitsAnswer) {
    const std::string path = testing::TempDir() + "csv_other_unit.txt";
    {
        std::ofstream f(path);
        f << "1.000 > 11 03 00 11 00 02 96 9E\n"      // unit 17: decimal places of both channels
          << "1.020 < 11 03 04 00 01 00 02 3B F3\n"   // 1 and 2
          << "3.000 > 0C 03 00 11 00 02 95 13\n"      // unit 12: the same
          << "3.020 < 11 03 04 00 03 00 03 5B F3\n"   // unit 17 answers: 3 and 3; unit 12 never does
          << "5.000 > 0C 03 00 00 00 02 C5 16\n"      // unit 12: its process values
          << "5.020 < 0C 03 04 04 D2 16 2E 09 86\n"   // 1234, 5678
          << "6.000 > 0C 03 00 11 00 02 95 13\n"      // unit 12: decimal places again
          << "6.020 < 11 03 04 00 03 00 03 5B F3\n"   // unit 17 answers again
          << "6.040 < 0C 03 04 00 02 00 01 46 F3\n"   // and unit 12 does: 2 and 1
          << "7.000 > 0C 03 00 00 00 02 C5 16\n"      // unit 12: its process values
          << "7.020 < 0C 03 04 04 D2 16 2E 09 86\n";  // 1234, 5678
    }
    const auto [exit_code, out] = decode("--profile mmk-2030 --csv - " + path);
    EXPECT_EQ(exit_code, 1) << out;
    const auto rows = rows_of(out);
    ASSERT_EQ(rows.size(), 5u) << out;
    EXPECT_EQ(rows[1].at("unit_id"), "12");
    EXPECT_EQ(rows[1].at("status"), "timeout");
    EXPECT_EQ(rows[1].at("values"), "");
    EXPECT_EQ(rows[1].at("findings"), "pair.unit_mismatch pair.no_response");
    // Not 1.234 and 5.678: unit 12's decimal places were not read yet.
    EXPECT_NE(rows[2].at("values").find("decimal point unknown"), std::string::npos) << rows[2].at("values");
    // Its own reply after the other unit's answers its request, and names its values.
    EXPECT_EQ(rows[3].at("status"), "ok");
    EXPECT_NE(rows[3].at("values").find("decimal places channel 1=duas casas decimais"), std::string::npos)
        << rows[3].at("values");
    EXPECT_EQ(rows[3].at("findings"), "");
    EXPECT_NE(rows[4].at("values").find("channel 1 process value=12.34"), std::string::npos)
        << rows[4].at("values");
    EXPECT_NE(rows[4].at("values").find("channel 2 process value=567.8"), std::string::npos)
        << rows[4].at("values");
    const auto [json_exit, jsonl] = decode("--profile mmk-2030 --jsonl " + path);
    EXPECT_EQ(json_exit, 1);
    nlohmann::json summary;
    std::vector<nlohmann::json> transactions;
    std::istringstream lines(jsonl);
    for (std::string line; std::getline(lines, line);) {
        auto j = nlohmann::json::parse(line, nullptr, false);
        if (!j.is_discarded() && j["type"] == "summary") summary = j;
        if (!j.is_discarded() && j["type"] == "transaction") transactions.push_back(j);
    }
    ASSERT_EQ(transactions.size(), 5u);
    EXPECT_EQ(transactions[1]["answered_by_other_unit"], true);
    EXPECT_EQ(transactions[1]["timeout"], true);
    EXPECT_FALSE(transactions[3].contains("answered_by_other_unit"));
    const auto& twelve = summary["devices"]["serial " + path + " unit 12"];
    EXPECT_EQ(twelve["requests"], 4);
    EXPECT_EQ(twelve["responses"], 3);
    EXPECT_EQ(twelve["timeouts"], 1);
    EXPECT_EQ(twelve["answered_by_other_unit"], 1);
    EXPECT_FALSE(summary["findings"].contains("pair.unsolicited_response")) << summary.dump();
    EXPECT_EQ(summary["devices"]["serial " + path + " unit 17"]["findings"]["pair.unit_mismatch"], 2);
    std::remove(path.c_str());

    // A request that timed out with only another unit's reply, then answered late by its own: a timeout
    // answered late, its late row after its timeout row, as for any late reply.
    const std::string late = testing::TempDir() + "csv_other_unit_late.txt";
    {
        std::ofstream f(late);
        f << "1.000 > 0C 03 00 11 00 02 95 13\n"     // unit 12: decimal places
          << "1.020 < 11 03 04 00 03 00 03 5B F3\n"  // unit 17 answers
          << "2.500 < 0C 03 04 00 02 00 01 46 F3\n"  // unit 12, 1.5 s later
          << "3.000 > 0C 03 00 11 00 02 95 13\n"
          << "3.020 < 0C 03 04 00 02 00 01 46 F3\n";
    }
    const auto [late_exit, late_out] = decode("--csv - " + late);
    const auto late_rows = rows_of(late_out);
    ASSERT_EQ(late_rows.size(), 3u) << late_out;
    EXPECT_EQ(late_rows[0].at("status"), "timeout");
    EXPECT_EQ(late_rows[1].at("status"), "late");
    EXPECT_EQ(late_rows[2].at("status"), "ok");
    const auto [text_exit, text] = decode(late);
    EXPECT_NE(text.find("1 timeouts (1 answered late), 1 of these unanswered while another unit replied"),
              std::string::npos)
        << text;
    std::remove(late.c_str());
}

// Findings reported as a frame is seen, before its transaction is made, are the transaction's too: a reply
// whose transaction id is not its request's (the only one outstanding), and a broadcast write that changes
// a device's line settings (MK BAUD, as a unicast one's record carries it). Both rows were clean.
TEST(CsvSink, FindingsReportedBeforeTheTransactionAreItsOwn) {
    mbscope::test::Conversation c;
    const std::uint16_t registers[] = {555};
    c.send(true, adu(1, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 1)), 1s);
    c.send(
        false,
        adu(2, response(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, registers))),
        1s + 1ms);
    auto rows = rows_of(csv_of(c));
    ASSERT_EQ(rows.size(), 1u);
    EXPECT_EQ(rows[0].at("findings"), "pair.transaction_id_mismatch");

    const std::string path = testing::TempDir() + "csv_broadcast_baud.txt";
    {
        std::ofstream f(path);
        f << "1.000 > 11 03 00 60 00 03 07 45\n"  // unit 17 answers: it is on the line
          << "1.020 < 11 03 06 02 2B 00 00 00 64 C8 BA\n"
          << "2.000 > 00 06 00 09 00 04 59 DA\n";  // broadcast BAUD := 4 (CRC by pymodbus)
    }
    const auto [exit_code, out] = decode("--profile mmk-2030 --csv - " + path);
    rows = rows_of(out);
    ASSERT_EQ(rows.size(), 2u) << out;
    EXPECT_EQ(rows[1].at("status"), "broadcast");
    EXPECT_EQ(rows[1].at("findings"), "profile.line_settings_changed") << out;
    std::remove(path.c_str());
}

}  // namespace test_analyzer_csv_sink_test
