// The JSON lines of `mbscope decode --jsonl` are written by a streaming writer (modbus/json_writer.hpp,
// analyzer/json_lines.hpp) for speed; the documents of --json are built with nlohmann::json. Here every
// record the streaming writer writes must parse, with nlohmann::json, into exactly the document nlohmann's
// own builder makes of the same record: over every PDU of the fuzz corpus (both directions, every function
// code the decoder knows, broken ones), the bundled captures, a device profile's named values, 32-bit word
// order views, and strings that need escaping or are not UTF-8.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "analyzer/analyzer.hpp"
#include "analyzer/json_lines.hpp"
#include "analyzer/sinks.hpp"
#include "modbus/adu.hpp"
#include "modbus/json_writer.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_json_lines_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using json = nlohmann::json;
using namespace std::chrono_literals;
using namespace std::string_literals;

namespace {

std::vector<std::uint8_t> read_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// One record through the streaming writer, parsed back.
template <class Record>
json streamed(const Record& r, void (*write)(const Record&, mb::JsonWriter&)) {
    mb::JsonWriter w;
    write(r, w);
    w.end_line();
    const std::string text(w.text());
    EXPECT_EQ(text.back(), '\n');
    EXPECT_EQ(text.find('\n'), text.size() - 1) << "one record, one line: " << text;
    return json::parse(text);  // throws, failing the test, if it is not JSON
}

// What --json and the JSON lines before the streaming writer wrote: the document dumped the way JsonSink
// dumps (invalid UTF-8 replaced, NaN as null), read back.
json as_written(const json& document) {
    return json::parse(document.dump(-1, ' ', false, json::error_handler_t::replace));
}

// Every record compared as it comes.
struct Compare : an::Sink {
    int frames = 0, transactions = 0, findings = 0, unparsed_records = 0, late = 0;
    void frame(const an::FrameRecord& f) override {
        ++frames;
        EXPECT_EQ(streamed(f, an::write_frame), as_written(an::frame_to_json(f))) << "frame " << f.index;
    }
    void transaction(const an::TransactionRecord& t) override {
        ++transactions;
        const json written = streamed(t, an::write_transaction);
        EXPECT_EQ(written, as_written(an::transaction_to_json(t)))
            << "transaction of frame " << t.request.index;
        if (written.contains("late")) {
            ++late;
            EXPECT_EQ(written["late"], true);
            EXPECT_TRUE(written.contains("latency_ms"));
        }
    }
    void finding(const an::FindingRecord& f) override {
        ++findings;
        EXPECT_EQ(streamed(f, an::write_finding), as_written(an::finding_to_json(f))) << f.message;
    }
    void unparsed(const an::UnparsedRecord& u) override {
        ++unparsed_records;
        EXPECT_EQ(streamed(u, an::write_unparsed), as_written(an::unparsed_to_json(u)));
    }
};

an::FrameRecord frame_of_pdu(std::span<const std::uint8_t> pdu, mb::Direction direction) {
    an::FrameRecord r;
    r.index = 7;
    r.packet = 9;
    r.time = 1'700'000'000'123'456'789ns;
    r.source = "corpus";
    r.link = "10.0.0.1:40000 -> 10.0.0.2:502";
    r.device = "10.0.0.2:502 unit 1";
    r.direction = direction;
    auto frame = mb::decode_tcp(mb::encode_tcp(0x1234, 1, {pdu.begin(), pdu.end()}));
    EXPECT_TRUE(frame.has_value());
    r.frame = frame.value();
    auto decoded = mb::decode_pdu(r.frame.pdu(), direction);
    if (decoded)
        r.pdu = std::move(decoded.value());
    else
        r.error = "truncated at PDU byte 3";
    return r;
}

}  // namespace

TEST(JsonLines, EveryPduOfTheFuzzCorpusInBothDirectionsWritesWhatNlohmannBuilds) {
    const auto dir = std::filesystem::path(MBSCOPE_SOURCE_DIR) / "corpus" / "pdu";
    int pdus = 0, decoded = 0, undecodable = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const auto bytes = read_file(entry.path());
        if (bytes.size() < 2 || bytes.size() > 254) continue;
        const std::span<const std::uint8_t> pdu(bytes.data() + 1, bytes.size() - 1);
        for (auto direction : {mb::Direction::Request, mb::Direction::Response}) {
            const auto r = frame_of_pdu(pdu, direction);
            ++pdus;
            (r.pdu ? decoded : undecodable)++;
            EXPECT_EQ(streamed(r, an::write_frame), as_written(an::frame_to_json(r))) << entry.path();
        }
    }
    EXPECT_GT(decoded, 300);     // the corpus holds every function code the decoder knows
    EXPECT_GT(undecodable, 50);  // and PDUs it cannot decode (the "error" form of a frame)
    EXPECT_GT(pdus, 600);
}

TEST(JsonLines, BundledCapturesWriteWhatNlohmannBuilds) {
    int files = 0;
    Compare total;
    for (const auto& entry :
         std::filesystem::directory_iterator(std::filesystem::path(MBSCOPE_SOURCE_DIR) / "captures")) {
        if (entry.path().extension() != ".pcap") continue;
        ++files;
        Compare sink;
        an::Analyzer a({}, sink);
        EXPECT_TRUE(a.read_capture(entry.path().string()));
        a.finish();
        EXPECT_GT(sink.frames, 0) << entry.path();
        total.frames += sink.frames;
        total.transactions += sink.transactions;
        total.findings += sink.findings;
    }
    EXPECT_GE(files, 2);
    EXPECT_GT(total.transactions, 10);
    EXPECT_GT(total.findings, 0);  // the public captures hold exceptions and unanswered requests
}

TEST(JsonLines, DamagedStreamsTimeoutsAndUnparsedBytesWriteWhatNlohmannBuilds) {
    mbscope::test::Conversation c;
    const auto read = mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 2));
    c.send(true, mb::encode_tcp(1, 1, read), 1s);
    c.send(false, mbscope::test::bytes({0, 1, 0, 0, 0, 7, 1, 3, 4, 0, 1, 0, 2}), 1s + 2ms);
    c.send(true, mbscope::test::bytes({0xDE, 0xAD, 0xBE, 0xEF, 0, 2, 0, 0, 0, 6, 1, 3, 0, 0, 0, 2}), 2s);
    c.send(true, mb::encode_tcp(3, 1, read), 3s);                                   // never answered
    c.send(false, mbscope::test::bytes({0, 9, 0, 0, 0, 3, 1, 0x83, 2}), 3s + 1ms);  // unsolicited id
    c.send(true, mb::encode_tcp(4, 0, mb::encode_pdu(mb::make_write_single_register(5, 0xFFFF))), 9s);
    c.send(true, mb::encode_tcp(5, 1, read), 20s);
    c.send(false, mbscope::test::bytes({0, 5, 0, 0, 0, 7, 1, 3, 4, 0, 1, 0, 2}), 24s);  // past its timeout
    Compare sink;
    an::Analyzer a({}, sink);
    std::string error;
    auto capture = an::CaptureSource::open_memory(c.file(), error);
    ASSERT_TRUE(capture) << error;
    a.read_capture(*capture);
    a.finish();
    EXPECT_GE(sink.frames, 5);
    EXPECT_GE(sink.transactions, 2);
    EXPECT_GE(sink.findings, 2);
    EXPECT_GE(sink.unparsed_records, 1);
    EXPECT_EQ(sink.late, 1);
}

TEST(JsonLines, NamedValuesAndWordOrderViewsWriteWhatNlohmannBuilds) {
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/tests/fixtures/profiles"});
    auto profile = store.load("test-device");
    ASSERT_TRUE(profile.has_value());
    mbscope::test::Conversation c;
    int tid = 0;
    const auto exchange = [&](const mb::Pdu& q, const std::vector<std::uint8_t>& answer) {
        ++tid;
        c.send(true, mb::encode_tcp(static_cast<std::uint16_t>(tid), 1, mb::encode_pdu(q)), tid * 1s);
        c.send(false, mb::encode_tcp(static_cast<std::uint16_t>(tid), 1, answer), tid * 1s + 3ms);
    };
    exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2), {3, 4, 0, 2, 0x04, 0xD2});
    exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 16, 4),
             {3, 8, 0, 0, 0, 2, 0x04, 0xD2, 0x7F, 0xC0});
    exchange(mb::make_write_single_register(23, 300), {6, 0, 23, 1, 0x2C});

    Compare with_profile;
    an::AnalyzerOptions o;
    o.semantics = std::make_shared<an::Semantics>();
    o.semantics->add({}, std::make_shared<const mb::Profile>(std::move(profile.value())));
    an::Analyzer a(o, with_profile);
    std::string error;
    auto capture = an::CaptureSource::open_memory(c.file(), error);
    ASSERT_TRUE(capture) << error;
    a.read_capture(*capture);
    a.finish();
    EXPECT_EQ(with_profile.transactions, 3);

    Compare words;
    an::AnalyzerOptions w;
    w.word_order = mb::WordOrder::Cdab;
    an::Analyzer b(w, words);
    capture = an::CaptureSource::open_memory(c.file(), error);
    ASSERT_TRUE(capture) << error;
    b.read_capture(*capture);
    b.finish();
    EXPECT_EQ(words.transactions, 3);
}

TEST(JsonLines, StringsAreEscapedAndBytesThatAreNotUtf8BecomeReplacementCharacters) {
    const std::string samples[] = {
        "plain",
        "quote \" backslash \\ slash /",
        "controls \x01\x1F\b\f\n\r\t and a NUL \0 inside"s,  // the NUL is part of the string
        "Vazão instantânea m³/h",                            // UTF-8 from the manuals
        "emoji \xF0\x9F\x98\x80 ok",                         // four bytes
        "bad \xFF\xFE lone \x80 continuation",
        "truncated \xE2\x82",
        "cut short \xE2\x82 then more \xF0\x9F\x98 and \xF4\x8F",
        "overlong \xC0\xAF and \xE0\x80\xAF",
        "surrogate \xED\xA0\x80",
        "above U+10FFFF \xF4\x90\x80\x80",
    };
    for (const auto& s : samples) {
        mb::JsonWriter w;
        w.begin_object();
        w.dynamic_key(s);
        w.value(s);
        w.end_object();
        const std::string text(w.text());
        const json expected = json::parse(json{{s, s}}.dump(-1, ' ', false, json::error_handler_t::replace));
        EXPECT_EQ(json::parse(text), expected) << text;
    }
}

TEST(JsonLines, NumbersReadBackToTheSameValue) {
    const double doubles[] = {0.0,
                              -0.0,
                              1.0,
                              0.1,
                              1700000000.0019999,
                              1700000000.25,
                              1e-300,
                              1e300,
                              -2.5e-7,
                              123456789012345678.0,
                              3.4028234663852886e38,
                              5e-324,
                              1e15,
                              0.001};
    for (double d : doubles) {
        mb::JsonWriter w;
        w.value(d);
        const json back = json::parse(std::string(w.text()));
        ASSERT_TRUE(back.is_number_float()) << w.text();  // a double stays a double, 1.0 included
        EXPECT_EQ(back.get<double>(), d) << w.text();
    }
    for (double d : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
        mb::JsonWriter w;
        w.value(d);
        EXPECT_EQ(w.text(), "null");  // as nlohmann::json writes them
    }
    mb::JsonWriter w;
    w.begin_array();
    w.value(std::uint64_t{18446744073709551615u});
    w.value(std::int64_t{-9223372036854775807 - 1});
    w.value(std::uint8_t{255});
    w.value(true);
    w.null();
    w.hex_value(std::vector<std::uint8_t>{});
    w.hex_value(std::vector<std::uint8_t>{0x00, 0xAB, 0xFF});
    w.begin_object();
    w.end_object();
    w.begin_array();
    w.end_array();
    w.end_array();
    EXPECT_EQ(w.text(), "[18446744073709551615,-9223372036854775808,255,true,null,\"\",\"00 AB FF\",{},[]]");
}

// A time is written to the microsecond as the capture gave it: nanoseconds since 1970 converted to a double
// whole lost their last digits (.012999 printed as .0129988), in --json and in the JSON lines alike.
TEST(JsonLines, TimesKeepTheirDigits) {
    for (const auto& [time, text] :
         {std::pair{1'700'000'000'012'999'000ns, "1700000000.012999"},
          std::pair{1'700'000'000'000'001'000ns, "1700000000.000001"},
          std::pair{1'700'000'000'500'000'000ns, "1700000000.5"}, std::pair{12'345'678ns, "0.012345678"},
          std::pair{-12'999'000ns, "-0.012999"},
          std::pair{-1'700'000'000'012'999'000ns, "-1700000000.012999"}}) {
        const mb::Timestamp t(time);
        EXPECT_EQ(json(an::seconds(t)).dump(), text);
        mb::JsonWriter w;
        w.value(an::seconds(t));
        EXPECT_EQ(w.text(), text);
    }
}

}  // namespace test_analyzer_json_lines_test
