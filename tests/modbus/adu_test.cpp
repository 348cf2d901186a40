#include <gtest/gtest.h>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "test_util.hpp"

namespace test_modbus_adu_test {

using mbscope::test::bytes_of;
using mbscope::test::hex;
namespace mb = mbscope::modbus;

TEST(TcpAdu, SpecificationExampleOfTheMessagingGuide) {
    // TCP §3.1.3 layout; Walchem manual 002:204-210: 7-byte MBAP (transaction id copied into the reply,
    // protocol id 0, length = unit id + PDU bytes), then the PDU.
    const auto adu = hex("00 01 00 00 00 06 11 03 00 6B 00 03");
    auto f = mb::decode_tcp(adu);
    ASSERT_TRUE(f.has_value());
    EXPECT_EQ(f->transaction_id(), 1);
    EXPECT_EQ(f->protocol_id(), 0);
    EXPECT_EQ(f->length_field(), 6);
    EXPECT_EQ(f->unit_id(), 0x11);
    EXPECT_EQ(std::vector<std::uint8_t>(f->pdu().begin(), f->pdu().end()), hex("03 00 6B 00 03"));
    EXPECT_TRUE(f->findings.empty());
    EXPECT_EQ(mb::encode_tcp(1, 0x11, hex("03 00 6B 00 03")), adu);
}

TEST(TcpAdu, WalchemAddressingExampleAsInputRegisterRead) {
    // 002:494: firmware version, system map index 2..3 at x0037, read as input registers 30039-30040
    // (FC4). 30039 is reference 39 of the input registers, PDU address 38 = 0x0026.
    const auto adu = mb::encode_tcp(
        7, 1, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 0x26, 2)));
    EXPECT_EQ(adu, hex("00 07 00 00 00 06 01 04 00 26 00 02"));
}

TEST(TcpAdu, NonZeroProtocolIdIsAFindingNotAnError) {
    auto f = mb::decode_tcp(hex("00 01 00 01 00 06 11 03 00 6B 00 03"));
    ASSERT_TRUE(f.has_value());
    EXPECT_TRUE(f->findings.contains(mb::FindingCode::TcpProtocolIdNonzero));
}

TEST(TcpAdu, LengthFieldErrors) {
    EXPECT_EQ(mb::decode_tcp(hex("00 01 00 00 00 01 11 03")).error().code, mb::ErrorCode::LengthFieldInvalid);
    EXPECT_EQ(mb::decode_tcp(hex("00 01 00 00 00 07 11 03 00 6B 00 03")).error().code,
              mb::ErrorCode::Truncated);
    EXPECT_EQ(mb::decode_tcp(hex("00 01 00 00 00 05 11 03 00 6B 00 03")).error().code,
              mb::ErrorCode::LengthFieldInvalid);
    EXPECT_EQ(mb::decode_tcp(hex("00 01 00 00 00")).error().code, mb::ErrorCode::Truncated);
    EXPECT_EQ(mb::decode_tcp(hex("00 01 00 00 01 02 11 03")).error().code, mb::ErrorCode::LengthFieldInvalid);
}

TEST(TcpAdu, OverlongAduOfRealDevicesIsKeptAndFlagged) {
    // MBAP length 255 (UMAS traffic; Walchem's FC16 of 125 registers reaches 257): above TCP §3.1.3's 254.
    std::vector<std::uint8_t> adu = hex("00 07 00 00 00 FF 00 5A");
    adu.resize(6 + 255, 0x00);
    auto f = mb::decode_tcp(adu);
    ASSERT_TRUE(f.has_value());
    EXPECT_TRUE(f->findings.contains(mb::FindingCode::TcpLengthInvalid));
    EXPECT_EQ(f->length, 261);
}

TEST(RtuAdu, LimitsAndCrcOrder) {
    EXPECT_EQ(mb::decode_rtu(hex("11 03 07")).error().code, mb::ErrorCode::Truncated);
    std::vector<std::uint8_t> big(257, 0x11);
    EXPECT_EQ(mb::decode_rtu(big).error().code, mb::ErrorCode::TooLong);
    // CRC low byte first: the Appendix B CRC 0x1401 is sent 01 14 (000:4330, 000:4348-4349).
    auto adu = mb::encode_rtu(0x11, hex("10 00 60 00 02 04 00 0A 01 02"));
    EXPECT_EQ(adu[adu.size() - 2], 0x01);
    EXPECT_EQ(adu[adu.size() - 1], 0x14);
}

TEST(RtuAdu, ReservedUnitIdIsFlagged) {
    auto f = mb::decode_rtu(mb::encode_rtu(250, hex("03 00 00 00 01")));
    ASSERT_TRUE(f.has_value());
    EXPECT_TRUE(f->findings.contains(mb::FindingCode::RtuUnitIdReserved));
}

TEST(AsciiAdu, LowerCaseAcceptedAndFlagged) {
    auto f = mb::decode_ascii(bytes_of(":11100060000204000a01026c\r\n"));
    ASSERT_TRUE(f.has_value());
    EXPECT_TRUE(f->checksum_ok);
    EXPECT_TRUE(f->findings.contains(mb::FindingCode::AsciiLowercaseHex));
}

TEST(AsciiAdu, WrongLrcIsFlagged) {
    // MK-LRC-01: the Appendix B frame with LRC 6D instead of 6C.
    auto f = mb::decode_ascii(bytes_of(":11100060000204000A01026D\r\n"));
    ASSERT_TRUE(f.has_value());
    EXPECT_FALSE(f->checksum_ok);
    EXPECT_TRUE(f->findings.contains(mb::FindingCode::AsciiLrcMismatch));
}

TEST(AsciiAdu, StructuralErrorsNameTheCharacter) {
    EXPECT_EQ(mb::decode_ascii(bytes_of("11030060000389\r\n")).error().code,
              mb::ErrorCode::BadStartCharacter);
    EXPECT_EQ(mb::decode_ascii(bytes_of(":11030060000389")).error().code, mb::ErrorCode::BadEndCharacters);
    auto bad = mb::decode_ascii(bytes_of(":1103006G000389\r\n"));
    EXPECT_EQ(bad.error().code, mb::ErrorCode::BadHexDigit);
    EXPECT_EQ(bad.error().offset, 8u);
    // The first of several bad digits; a lower-case frame decodes and is flagged as such.
    auto two =
        mb::decode_ascii(bytes_of(":11\x1b"
                                  "3006Z000389\r\n"));
    EXPECT_EQ(two.error().code, mb::ErrorCode::BadHexDigit);
    EXPECT_EQ(two.error().offset, 3u);
    auto lower = mb::decode_ascii(bytes_of(":11030060000389\r\n"));
    ASSERT_TRUE(lower.has_value());
    EXPECT_FALSE(lower->findings.contains(mb::FindingCode::AsciiLowercaseHex));
    auto lower_case = mb::decode_ascii(bytes_of(":110300600003890a\r\n"));
    ASSERT_TRUE(lower_case.has_value());
    EXPECT_TRUE(lower_case->findings.contains(mb::FindingCode::AsciiLowercaseHex));
    EXPECT_EQ(lower_case->bytes[7], 0x0A);
    EXPECT_EQ(mb::decode_ascii(bytes_of(":1103006000389\r\n")).error().code, mb::ErrorCode::OddHexLength);
    // A bad digit left over after the pairs is a bad digit, not only an odd length.
    auto odd_bad = mb::decode_ascii(bytes_of(":11030060000389G\r\n"));
    EXPECT_EQ(odd_bad.error().code, mb::ErrorCode::BadHexDigit);
    EXPECT_EQ(odd_bad.error().offset, 15u);
    EXPECT_EQ(mb::decode_ascii(bytes_of(":1103\r\n")).error().code, mb::ErrorCode::Truncated);
}

// decode_adu is the framing's own decoder: the same frame, and the same error on bytes of another framing.
TEST(Adu, DecodeAduChoosesTheFramingsDecoder) {
    const std::vector<std::uint8_t> pdu{0x03, 0x00, 0x60, 0x00, 0x01};
    const auto rtu = mb::encode_rtu(0x11, pdu);
    const auto tcp = mb::encode_tcp(7, 0x11, pdu);
    const auto text = mb::encode_ascii(0x11, pdu);
    const std::vector<std::uint8_t> ascii(text.begin(), text.end());
    for (const auto& [framing, adu] : {std::pair{mb::Framing::Rtu, rtu}, std::pair{mb::Framing::Tcp, tcp},
                                       std::pair{mb::Framing::Ascii, ascii}}) {
        const auto frame = mb::decode_adu(framing, adu);
        ASSERT_TRUE(frame) << static_cast<int>(framing);
        EXPECT_EQ(frame->framing, framing);
        EXPECT_EQ(frame->unit_id(), 0x11);
        EXPECT_TRUE(frame->checksum_ok);
        EXPECT_EQ(std::vector<std::uint8_t>(frame->pdu().begin(), frame->pdu().end()), pdu);
    }
    EXPECT_EQ(mb::decode_adu(mb::Framing::Ascii, rtu).error().code, mb::ErrorCode::BadStartCharacter);
    EXPECT_EQ(mb::decode_adu(mb::Framing::Tcp, rtu).error().code, mb::ErrorCode::LengthFieldInvalid);
}

}  // namespace test_modbus_adu_test
