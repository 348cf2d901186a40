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

// What an echo got wrong, in words ("fits" when it is no misfit).
std::string differs(const Pdu& request, std::initializer_list<std::uint8_t> reply) {
    const auto misfit = reply_misfit(request, response_pdu(reply));
    return misfit ? misfit->differs : "fits";
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
    // What differs is said, field by field: a reader should not have to compare the frames byte by byte.
    EXPECT_EQ(more->differs, "its quantity is 3, not 2");
    EXPECT_EQ(differs(fc16, {0x10, 0x00, 0x61, 0x00, 0x01}),
              "its starting address is 97, not 96; its quantity is 1, not 2");
    const auto fc15 = request("11 0F 00 13 00 0A 02 CD 00 7E CB");
    EXPECT_EQ(differs(fc15, {0x0F, 0x00, 0x13, 0x00, 0x0B}), "its quantity is 11, not 10");
    // FC6's echo: the value too (000:405).
    EXPECT_EQ(differs(request("11 06 00 54 03 9E 4B D2"), {0x06, 0x00, 0x54, 0x03, 0x9F}),
              "its value is 927, not 926");
    // A coil's value in the words the specification gives it (000:385).
    EXPECT_EQ(differs(request("11 05 00 54 FF 00 CF 7A"), {0x05, 0x00, 0x55, 0x00, 0x00}),
              "its address is 85, not 84; its value is 0x0000, not 0xFF00");
    EXPECT_EQ(differs(make_mask_write_register(4, 0x00F2, 0x0025),  // AP §6.16's example
                      {0x16, 0x00, 0x04, 0x00, 0xF2, 0x00, 0x24}),
              "its OR mask is 0x0024, not 0x0025");
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
    EXPECT_EQ(other->differs, "its sub-function is 12, not 11");  // its data is that one's answer
    // Sub-function 0x0A (clear counters) echoes the request.
    const auto clear = make_diagnostics(0x0A, zero);
    EXPECT_FALSE(reply_misfit(clear, response_pdu({0x08, 0x00, 0x0A, 0x00, 0x00})).has_value());
    EXPECT_TRUE(reply_misfit(clear, response_pdu({0x08, 0x00, 0x0A, 0x00, 0x01})).has_value());
    // Sub-function 0x00 echoes its data (000:425).
    const auto echo = request("11 08 00 00 A5 37 D8 1D");
    const auto data = reply_misfit(echo, response_pdu({0x08, 0x00, 0x00, 0xA5, 0x38}));
    ASSERT_TRUE(data.has_value());
    EXPECT_EQ(data->differs, "its data is A5 38, not A5 37");
    // Long data is cut in the message (the frames carry all of it); a difference past the cut is named.
    std::vector<std::uint8_t> twenty(20, 0x00), changed(20, 0x00);
    changed[19] = 0x01;
    std::vector<std::uint8_t> reply = {0x08, 0x00, 0x00};
    reply.insert(reply.end(), changed.begin(), changed.end());
    const auto cut = reply_misfit(make_diagnostics(0x00, twenty), decode_response(reply).value());
    ASSERT_TRUE(cut.has_value());
    EXPECT_EQ(cut->differs, "its data's byte 20 is 0x01, not 0x00");
    changed[3] = 0xFF;
    reply.resize(3);
    reply.insert(reply.end(), changed.begin(), changed.end());
    const auto early = reply_misfit(make_diagnostics(0x00, twenty), decode_response(reply).value());
    ASSERT_TRUE(early.has_value());
    EXPECT_EQ(early->differs,
              "its data is 00 00 00 FF 00 00 00 00 00 00 00 00 00 00 00 00 ... (20 bytes), not "
              "00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 ... (20 bytes)");
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
