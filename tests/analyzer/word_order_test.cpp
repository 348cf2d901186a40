// --word-order: FC3/FC4 replies of devices without a profile read two registers at a time as u32 and
// float32. Expected values are written by hand: 1.5f is 0x3FC00000 and 123456789 is 0x075BCD15 (IEEE 754,
// and the byte positions each order names).
#include <gtest/gtest.h>

#include <sstream>

#include "analyzer/sinks.hpp"
#include "analyzer/word_order.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_packets.hpp"

namespace test_analyzer_word_order_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

namespace {

struct Case {
    const char* source;
    mb::WordOrder order;
    std::vector<std::uint16_t> registers;  // 1.5f then 123456789, as the device sends them
};

const Case cases[] = {
    {"abcd: big-endian, first register high", mb::WordOrder::Abcd, {0x3FC0, 0x0000, 0x075B, 0xCD15}},
    {"cdab: registers swapped", mb::WordOrder::Cdab, {0x0000, 0x3FC0, 0xCD15, 0x075B}},
    {"badc: bytes swapped in each register", mb::WordOrder::Badc, {0xC03F, 0x0000, 0x5B07, 0x15CD}},
    {"dcba: little-endian", mb::WordOrder::Dcba, {0x0000, 0xC03F, 0x15CD, 0x5B07}},
};

std::vector<std::uint8_t> read_request(std::uint16_t start, std::uint16_t quantity) {
    return mb::encode_tcp(
        1, 17,
        mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, start, quantity)));
}
std::vector<std::uint8_t> read_response(const std::vector<std::uint16_t>& values) {
    return mb::encode_tcp(
        1, 17,
        mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, values)));
}

std::vector<std::uint8_t> exchange(const std::vector<std::uint16_t>& values) {
    mbscope::test::Conversation c;
    c.send(true, read_request(96, static_cast<std::uint16_t>(values.size())), 1s);
    c.send(false, read_response(values), 1s + 2ms);
    return c.file();
}

}  // namespace

TEST(WordOrder, EveryOrderReadsTheSameValues) {
    for (const auto& c : cases) {
        SCOPED_TRACE(c.source);
        const auto r = an::registers32(96, c.registers, c.order);
        ASSERT_EQ(r.size(), 2u);
        EXPECT_EQ(r[0].address, 96);
        EXPECT_EQ(r[0].u32, 0x3FC00000u);
        EXPECT_EQ(r[0].f32, 1.5f);
        EXPECT_EQ(r[1].address, 98);
        EXPECT_EQ(r[1].u32, 123456789u);
    }
}

TEST(WordOrder, AnOddLastRegisterIsLeftOut) {
    const std::vector<std::uint16_t> three = {0x3FC0, 0x0000, 0x1234};
    EXPECT_EQ(an::registers32(0, three, mb::WordOrder::Abcd).size(), 1u);
}

// A pair whose second register would be past 65535 (a reply to a read that ran past the end) is left out,
// not labelled with an address wrapped round to the start.
TEST(WordOrder, NoPairCrossesTheLastAddress) {
    const std::vector<std::uint16_t> four = {0x3FC0, 0x0000, 0x1234, 0x5678};
    const auto r = an::registers32(65532, four, mb::WordOrder::Abcd);
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r[1].address, 65534);
    EXPECT_EQ(an::registers32(65533, four, mb::WordOrder::Abcd).size(), 1u);
    EXPECT_TRUE(an::registers32(65535, four, mb::WordOrder::Abcd).empty());
}

TEST(WordOrder, FloatText) {
    EXPECT_EQ(an::float_text(1.5f), "1.5");
    EXPECT_EQ(an::float_text(0.1f), "0.1");
    EXPECT_EQ(an::float_text(std::bit_cast<float>(0x7FC00000u)), "nan");
    EXPECT_EQ(an::float_text(std::bit_cast<float>(0xFF800000u)), "-inf");
}

TEST(WordOrder, TransactionsCarryThePairsInTextAndJson) {
    an::AnalyzerOptions o;
    o.word_order = mb::WordOrder::Cdab;
    auto d = mbscope::test::decode_pcap(exchange(cases[1].registers), o);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    const auto& t = d->sink.transactions[0];
    ASSERT_EQ(t.registers32.size(), 2u);
    EXPECT_EQ(t.registers32[0].f32, 1.5f);
    EXPECT_EQ(t.registers32[1].u32, 123456789u);

    std::ostringstream text;
    an::TextSink(text).transaction(t);
    EXPECT_NE(text.str().find("96  cdab  u32 1069547520  f32 1.5\n"), std::string::npos) << text.str();
    EXPECT_NE(text.str().find("98  cdab  u32 123456789  f32 "), std::string::npos) << text.str();

    std::ostringstream lines;
    an::JsonSink(lines, true).transaction(t);
    const auto j = nlohmann::json::parse(lines.str());
    EXPECT_EQ(j["word_order"], "cdab");
    ASSERT_EQ(j["registers32"].size(), 2u);
    EXPECT_EQ(j["registers32"][0]["address"], 96);
    EXPECT_EQ(j["registers32"][0]["u32"], 1069547520u);
    EXPECT_EQ(j["registers32"][0]["f32"], 1.5);
    EXPECT_EQ(j["transport"], "tcp");
}

// JSON has no NaN or infinity: f32 is null for each, and f32_text says which (it was null alone, so a NaN,
// +inf and -inf read alike), in the document and in JSON lines the same.
TEST(WordOrder, NonFiniteFloatsAreToldApartInJson) {
    an::AnalyzerOptions o;
    o.word_order = mb::WordOrder::Abcd;
    auto d = mbscope::test::decode_pcap(
        exchange({0x7FC0, 0x0000, 0xFF80, 0x0000, 0x7F80, 0x0000, 0x3FC0, 0x0000}), o);
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    for (const bool lines : {true, false}) {
        SCOPED_TRACE(lines ? "json lines" : "json");
        std::ostringstream out;
        {
            an::JsonSink sink(out, lines);
            sink.transaction(d->sink.transactions[0]);
            sink.end(an::Summary{});
        }
        const auto text = out.str();
        auto j = nlohmann::json::parse(lines ? text.substr(0, text.find('\n')) : text);
        if (!lines) j = j.at(0);
        const auto& r = j.at("registers32");
        ASSERT_EQ(r.size(), 4u);
        EXPECT_TRUE(r[0]["f32"].is_null());
        EXPECT_EQ(r[0]["f32_text"], "nan");
        EXPECT_TRUE(r[1]["f32"].is_null());
        EXPECT_EQ(r[1]["f32_text"], "-inf");
        EXPECT_TRUE(r[2]["f32"].is_null());
        EXPECT_EQ(r[2]["f32_text"], "inf");
        EXPECT_EQ(r[3]["f32"], 1.5);
        EXPECT_EQ(r[3]["f32_text"], "1.5");
    }
}

TEST(WordOrder, NothingIsAddedWithoutTheOption) {
    auto d = mbscope::test::decode_pcap(exchange(cases[0].registers));
    ASSERT_EQ(d->sink.transactions.size(), 1u);
    EXPECT_FALSE(d->sink.transactions[0].word_order);
    EXPECT_TRUE(d->sink.transactions[0].registers32.empty());
}

}  // namespace test_analyzer_word_order_test
