// Whether a response answers its request (modbus::reply_misfit), first on the MK manual's worked examples
// (000:330-465: every request with the response the manual prints for it), then on each way a response can
// fail to answer: the data size of a read, a write's echo, FC8's sub-functions that echo and those that
// return a value (AP §6.8.1).
#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "modbus/reply_fit.hpp"
#include "test_util.hpp"

namespace mbscope::modbus::test_modbus_reply_fit_test {
namespace {

Pdu request(const std::string& rtu_hex) {
    const auto bytes = mbscope::test::hex(rtu_hex);
    const auto frame = decode_rtu(bytes).value();
    return decode_request(frame.pdu()).value();
}

Pdu response(const std::string& rtu_hex) {
    const auto bytes = mbscope::test::hex(rtu_hex);
    const auto frame = decode_rtu(bytes).value();
    return decode_response(frame.pdu()).value();
}

Pdu response_pdu(std::initializer_list<std::uint8_t> pdu) {
    const std::vector<std::uint8_t> bytes(pdu);
    return decode_response(bytes).value();
}

TEST(ReplyFit, TheManualsExamplesAnswerTheirRequests) {
    const std::pair<const char*, const char*> pairs[] = {
        {"11 01 00 13 00 15 0E 90", "11 01 03 B2 0E 1B DA 92"},                 // 000:330, 343
        {"11 03 00 60 00 03 07 45", "11 03 06 02 2B 00 00 00 64 C8 BA"},        // 000:356, 365
        {"11 05 00 54 FF 00 CF 7A", "11 05 00 54 FF 00 CF 7A"},                 // 000:376, 385
        {"11 06 00 54 03 9E 4B D2", "11 06 00 54 03 9E 4B D2"},                 // 000:396, 405
        {"11 08 00 00 A5 37 D8 1D", "11 08 00 00 A5 37 D8 1D"},                 // 000:416, 425
        {"11 0F 00 13 00 0A 02 CD 00 7E CB", "11 0F 00 13 00 0A 26 99"},        // 000:436, 445
        {"11 10 00 60 00 02 04 00 0A 01 02 01 14", "11 10 00 60 00 02 43 46"},  // 000:456, 465
    };
    for (const auto& [q, a] : pairs)
        EXPECT_FALSE(reply_misfit(request(q), response(a)).has_value()) << q << " -> " << a;
}

TEST(ReplyFit, AReadAnswersAsManyItemsAsItAsked) {
    const auto fc3 = request("11 03 00 60 00 03 07 45");  // three registers
    const auto two = reply_misfit(fc3, response_pdu({0x03, 0x04, 0x02, 0x2B, 0x00, 0x00}));
    ASSERT_TRUE(two.has_value());
    EXPECT_EQ(two->kind, ReplyMisfit::Kind::DataSize);
    EXPECT_EQ(two->expected, "3 registers");
    EXPECT_EQ(two->expected_bytes, 6u);
    EXPECT_EQ(two->got_bytes, 4u);
    // 21 coils take 3 bytes (000:343); a fourth is one too many.
    const auto fc1 = request("11 01 00 13 00 15 0E 90");
    const auto four = reply_misfit(fc1, response_pdu({0x01, 0x04, 0xCD, 0x6B, 0x05, 0x00}));
    ASSERT_TRUE(four.has_value());
    EXPECT_EQ(four->kind, ReplyMisfit::Kind::DataSize);
    // The manual's own bits with one past the 21st set: padding, not size.
    const auto padded = reply_misfit(fc1, response_pdu({0x01, 0x03, 0xCD, 0x6B, 0x25}));
    ASSERT_TRUE(padded.has_value());
    EXPECT_EQ(padded->kind, ReplyMisfit::Kind::Padding);
}

TEST(ReplyFit, AWriteOfSeveralAcknowledgesItsStartAndQuantity) {
    const auto fc16 = request("11 10 00 60 00 02 04 00 0A 01 02 01 14");
    const auto more = reply_misfit(fc16, response_pdu({0x10, 0x00, 0x60, 0x00, 0x03}));
    ASSERT_TRUE(more.has_value());
    EXPECT_EQ(more->kind, ReplyMisfit::Kind::Echo);
    EXPECT_EQ(more->expected, "an echo of the request's starting address and quantity");
    EXPECT_TRUE(reply_misfit(fc16, response_pdu({0x10, 0x00, 0x61, 0x00, 0x02})).has_value());
    const auto fc15 = request("11 0F 00 13 00 0A 02 CD 00 7E CB");
    EXPECT_TRUE(reply_misfit(fc15, response_pdu({0x0F, 0x00, 0x13, 0x00, 0x0B})).has_value());
    // FC6's echo: the value too (000:405).
    const auto fc6 = request("11 06 00 54 03 9E 4B D2");
    EXPECT_TRUE(reply_misfit(fc6, response_pdu({0x06, 0x00, 0x54, 0x03, 0x9F})).has_value());
}

TEST(ReplyFit, Fc8EchoesWhereTheSpecificationSaysAndReturnsACounterElsewhere) {
    const std::uint8_t zero[] = {0x00, 0x00};
    // Sub-function 0x0B (bus message count) returns the count, not the request's 00 00.
    const auto count = make_diagnostics(0x0B, zero);
    EXPECT_FALSE(reply_misfit(count, response_pdu({0x08, 0x00, 0x0B, 0x00, 0x2A})).has_value());
    // ... but under its own sub-function.
    const auto other = reply_misfit(count, response_pdu({0x08, 0x00, 0x0C, 0x00, 0x2A}));
    ASSERT_TRUE(other.has_value());
    EXPECT_EQ(other->expected, "an echo of the request's sub-function");
    // Sub-function 0x0A (clear counters) echoes the request.
    const auto clear = make_diagnostics(0x0A, zero);
    EXPECT_FALSE(reply_misfit(clear, response_pdu({0x08, 0x00, 0x0A, 0x00, 0x00})).has_value());
    EXPECT_TRUE(reply_misfit(clear, response_pdu({0x08, 0x00, 0x0A, 0x00, 0x01})).has_value());
    // Sub-function 0x00 echoes its data (000:425).
    const auto echo = request("11 08 00 00 A5 37 D8 1D");
    EXPECT_TRUE(reply_misfit(echo, response_pdu({0x08, 0x00, 0x00, 0xA5, 0x38})).has_value());
}

TEST(ReplyFit, AnExceptionOrAnotherFunctionIsNotJudgedHere) {
    const auto fc3 = request("11 03 00 60 00 03 07 45");
    EXPECT_FALSE(reply_misfit(fc3, response_pdu({0x83, 0x02})).has_value());
    EXPECT_FALSE(reply_misfit(fc3, response_pdu({0x04, 0x02, 0x00, 0x01})).has_value());
}

// A reply's bytes are shaped as the request's reply by a read's byte count (the one it needs, or the count of
// the bytes after it), by a multiple write's five bytes or its address and quantity, whatever else is wrong
// with them; other functions' replies always are.
TEST(ReplyClaims, ByTheByteCountAReadNeedsOrTheWritesAddressAndQuantity) {
    const auto claims = [](const char* request_pdu, const char* reply_pdu) {
        const auto q = decode_request(mbscope::test::hex(request_pdu)).value();
        return reply_claims_to_answer(q, mbscope::test::hex(reply_pdu));
    };
    EXPECT_TRUE(claims("03 00 6B 00 02", "03 04 00 00 01"));   // short, but a reply to this read
    EXPECT_FALSE(claims("03 00 0A 00 02", "03 00 00 00 01"));  // a read of register 0 instead
    EXPECT_TRUE(claims("03 00 00 00 01", "03 03 00 00 05"));   // an odd count, but of its own bytes
    EXPECT_TRUE(claims("01 00 13 00 15", "01 03 B2 0E 1B"));
    EXPECT_FALSE(claims("01 00 13 00 15", "01 00 13 00 15"));
    EXPECT_TRUE(claims("17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF", "17 0C 00 FE"));
    EXPECT_FALSE(claims("17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF", "17 00 03 00 01"));
    EXPECT_TRUE(claims("10 00 00 00 02 04 00 01 00 02", "10 00 00 00 02 04"));
    EXPECT_FALSE(claims("10 00 00 00 02 04 00 01 00 02", "10 00 0A 00 01 02 00 07"));
    EXPECT_FALSE(claims("0F 00 13 00 0A 02 CD 01", "0F 00"));
    EXPECT_TRUE(claims("10 00 00 00 02 04 00 01 00 02", "10 00 0A 00 01"));  // a wrong echo, but an echo
    EXPECT_TRUE(claims("06 00 01 00 03", "06"));
}

}  // namespace
}  // namespace mbscope::modbus::test_modbus_reply_fit_test
