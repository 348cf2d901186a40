// Every worked example frame of the device manuals, byte for byte, decoded and encoded.
// Expected fields are transcribed by hand from the manual lines cited in `source`.
#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_util.hpp"

namespace test_modbus_manual_examples_test {

using mbscope::test::hex;
namespace mb = mbscope::modbus;

struct Example {
    const char* source;
    const char* adu;
    mb::Direction direction;
    mb::Pdu expected;  // what the frame says, built with the builders from the manual's numbers
};

mb::Pdu response(mb::Pdu p) {
    p.direction = mb::Direction::Response;
    return p;
}

std::vector<Example> mk_examples() {
    using mb::FunctionCode;
    // 000:436: data CD 00 → coils 19..28 = 1,0,1,1,0,0,1,1,0,0 (LSB of CD is coil 19, AP §6.11).
    const bool fc15_bits[] = {1, 0, 1, 1, 0, 0, 1, 1, 0, 0};
    const std::uint16_t fc16_values[] = {0x000A, 0x0102};         // 000:456
    const std::uint16_t fc3_values[] = {0x022B, 0x0000, 0x0064};  // 000:365: 555, 0, 100
    mb::Pdu fc1_rsp;
    fc1_rsp.function_raw = 0x01;
    fc1_rsp.direction = mb::Direction::Response;
    fc1_rsp.body = mb::ReadBitsResponse{3, {0xB2, 0x0E, 0x1B}};  // 000:343
    return {
        {"000:330 MK-FC01-01", "11 01 00 13 00 15 0E 90", mb::Direction::Request,
         mb::make_read_request(FunctionCode::ReadCoils, 0x13, 0x15)},
        {"000:343 MK-FC01-03", "11 01 03 B2 0E 1B DA 92", mb::Direction::Response, fc1_rsp},
        {"000:356 MK-FC03-01", "11 03 00 60 00 03 07 45", mb::Direction::Request,
         mb::make_read_request(FunctionCode::ReadHoldingRegisters, 0x60, 3)},
        {"000:365 MK-FC03-02", "11 03 06 02 2B 00 00 00 64 C8 BA", mb::Direction::Response,
         mb::make_read_registers_response(FunctionCode::ReadHoldingRegisters, fc3_values)},
        {"000:376 MK-FC05-01", "11 05 00 54 FF 00 CF 7A", mb::Direction::Request,
         mb::make_write_single_coil(0x54, true)},
        {"000:385 MK-FC05-02 echo", "11 05 00 54 FF 00 CF 7A", mb::Direction::Response,
         response(mb::make_write_single_coil(0x54, true))},
        {"000:396 MK-FC06-01", "11 06 00 54 03 9E 4B D2", mb::Direction::Request,
         mb::make_write_single_register(0x54, 926)},
        {"000:405 MK-FC06-01 echo", "11 06 00 54 03 9E 4B D2", mb::Direction::Response,
         response(mb::make_write_single_register(0x54, 926))},
        {"000:416 MK-FC08-01", "11 08 00 00 A5 37 D8 1D", mb::Direction::Request,
         mb::make_diagnostics(0, std::vector<std::uint8_t>{0xA5, 0x37})},
        {"000:425 MK-FC08-01 echo", "11 08 00 00 A5 37 D8 1D", mb::Direction::Response,
         response(mb::make_diagnostics(0, std::vector<std::uint8_t>{0xA5, 0x37}))},
        {"000:436 MK-FC15-01", "11 0F 00 13 00 0A 02 CD 00 7E CB", mb::Direction::Request,
         mb::make_write_multiple_coils(0x13, std::span<const bool>(fc15_bits))},
        {"000:445 MK-FC15-02", "11 0F 00 13 00 0A 26 99", mb::Direction::Response,
         mb::make_write_multiple_response(FunctionCode::WriteMultipleCoils, 0x13, 10)},
        {"000:456 MK-FC16-01", "11 10 00 60 00 02 04 00 0A 01 02 01 14", mb::Direction::Request,
         mb::make_write_multiple_registers(0x60, fc16_values)},
        {"000:465 MK-FC16-02", "11 10 00 60 00 02 43 46", mb::Direction::Response,
         mb::make_write_multiple_response(FunctionCode::WriteMultipleRegisters, 0x60, 2)},
        {"000:484 MK-EXC-05", "11 81 02 C0 54", mb::Direction::Response, mb::make_exception(0x01, 0x02)},
    };
}

class MkManualExample : public ::testing::TestWithParam<Example> {};

TEST_P(MkManualExample, DecodesToTheManualsFields) {
    const auto& ex = GetParam();
    SCOPED_TRACE(ex.source);
    const auto adu = hex(ex.adu);
    auto frame = mb::decode_rtu(adu);
    ASSERT_TRUE(frame.has_value());
    EXPECT_TRUE(frame->checksum_ok);
    EXPECT_TRUE(frame->findings.empty());
    EXPECT_EQ(frame->unit_id(), 0x11);
    auto pdu = mb::decode_pdu(frame->pdu(), ex.direction);
    ASSERT_TRUE(pdu.has_value()) << mb::to_string(pdu.error().code);
    EXPECT_EQ(pdu.value(), ex.expected);
    EXPECT_TRUE(pdu->violations.empty());
}

TEST_P(MkManualExample, EncodesToTheManualsBytes) {
    const auto& ex = GetParam();
    SCOPED_TRACE(ex.source);
    EXPECT_EQ(mb::encode_rtu(0x11, mb::encode_pdu(ex.expected)), hex(ex.adu));
}

INSTANTIATE_TEST_SUITE_P(Manual000, MkManualExample, ::testing::ValuesIn(mk_examples()),
                         [](const auto& info) { return "Example" + std::to_string(info.index); });

TEST(MkManualExample, Fc15TextContradictsItsOwnFrame) {
    // 000:431-436: the text says coils 20, 22, 23, 26 and 27 become active, starting at coil 19, but the
    // frame's data CD 00 (LSB first, AP §6.11) switches on 19, 21, 22, 25 and 26. The text numbers the
    // coils 1-based as the specification's example does (AP §6.11 writes "outputs 20-29" for address 19).
    // The frame is the ground truth: its CRC verifies and the slave acts on bytes, not on prose.
    auto frame = mb::decode_rtu(hex("11 0F 00 13 00 0A 02 CD 00 7E CB"));
    ASSERT_TRUE(frame.has_value());
    auto pdu = mb::decode_request(frame->pdu());
    ASSERT_TRUE(pdu.has_value());
    const auto& body = std::get<mb::WriteMultipleCoilsRequest>(pdu->body);
    std::vector<int> on;
    for (int i = 0; i < body.quantity; ++i)
        if (mb::bit_at(body.values, static_cast<std::size_t>(i))) on.push_back(body.starting_address + i);
    EXPECT_EQ(on, (std::vector<int>{19, 21, 22, 25, 26}));
}

TEST(MkManualExample, AppendixBAsciiFrame) {
    // 000:4330 and 000:4351-4364 (TxStr): ":11100060000204000A01026C" CR LF is the FC16 request of 000:456 in
    // ASCII.
    const auto chars = mbscope::test::bytes_of(":11100060000204000A01026C\r\n");
    auto frame = mb::decode_ascii(chars);
    ASSERT_TRUE(frame.has_value());
    EXPECT_TRUE(frame->checksum_ok);
    EXPECT_EQ(frame->checksum_received(), 0x6C);
    EXPECT_EQ(frame->unit_id(), 0x11);
    const std::uint16_t values[] = {0x000A, 0x0102};
    auto pdu = mb::decode_request(frame->pdu());
    ASSERT_TRUE(pdu.has_value());
    EXPECT_EQ(pdu.value(), mb::make_write_multiple_registers(0x60, values));
    EXPECT_EQ(mb::encode_ascii(0x11, mb::encode_pdu(pdu.value())), ":11100060000204000A01026C\r\n");
}

TEST(MkManualExample, AsciiFc3ExampleOfTheRulesCatalogue) {
    // MK-ASC-02 (000:304-309): FC3 request and its reply in ASCII.
    auto req = mb::decode_ascii(mbscope::test::bytes_of(":11030060000389\r\n"));
    ASSERT_TRUE(req.has_value());
    EXPECT_TRUE(req->checksum_ok);
    auto rsp = mb::decode_ascii(mbscope::test::bytes_of(":110306022B0000006455\r\n"));
    ASSERT_TRUE(rsp.has_value());
    EXPECT_TRUE(rsp->checksum_ok);
    auto pdu = mb::decode_response(rsp->pdu());
    ASSERT_TRUE(pdu.has_value());
    EXPECT_EQ(std::get<mb::ReadRegistersResponse>(pdu->body).values,
              (std::vector<std::uint16_t>{555, 0, 100}));
}

TEST(MkManualExample, CorruptedCrcOfRulesCatalogueIsReportedNotRejected) {
    // MK-ERR-01: 11 03 00 60 00 03 07 46 has a corrupted CRC; the frame still decodes, flagged.
    auto frame = mb::decode_rtu(hex("11 03 00 60 00 03 07 46"));
    ASSERT_TRUE(frame.has_value());
    EXPECT_FALSE(frame->checksum_ok);
    EXPECT_TRUE(frame->findings.contains(mb::FindingCode::RtuCrcMismatch));
    EXPECT_EQ(frame->checksum_computed(), 0x4507);
}

}  // namespace test_modbus_manual_examples_test
