#include "modbus/checksum.hpp"

#include <gtest/gtest.h>

#include <random>

#include "test_util.hpp"

namespace test_modbus_checksum_test {

using mbscope::test::hex;
namespace mb = mbscope::modbus;

// CRC values below are from the manuals and the specification, not from this code.
TEST(Checksum, CrcOfMkAppendixBFrameIs0x1401) {
    // 000:4330 Appendix B: CRC of the FC16 request 11 10 00 60 00 02 04 00 0A 01 02 is 0x1401.
    EXPECT_EQ(mb::crc16(hex("11 10 00 60 00 02 04 00 0A 01 02")), 0x1401);
}

TEST(Checksum, LrcOfMkAppendixBFrameIs0x6C) {
    // 000:4330 Appendix B: LRC of the same request is 0x6C.
    EXPECT_EQ(mb::lrc(hex("11 10 00 60 00 02 04 00 0A 01 02")), 0x6C);
}

TEST(Checksum, CrcOfSpecificationExample) {
    // SL §6.2.2 example: 02 07 → CRC 0x1241, sent as 41 12.
    EXPECT_EQ(mb::crc16(hex("02 07")), 0x1241);
}

TEST(Checksum, CrcCheckValueOfCatalogue) {
    // CRC-16/MODBUS catalogue check value over "123456789" is 0x4B37.
    const std::string s = "123456789";
    EXPECT_EQ(mb::crc16({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()}), 0x4B37);
}

TEST(Checksum, LrcOfSpecificationExample) {
    // SL §6.2.1: LRC of 11 03 00 6B 00 03 is 0x7E.
    EXPECT_EQ(mb::lrc(hex("11 03 00 6B 00 03")), 0x7E);
}

TEST(Checksum, FastCrcEqualsBitwiseReferenceOnRandomBuffers) {
    std::mt19937 rng(1234);
    for (int n = 0; n < 300; ++n) {
        std::vector<std::uint8_t> buf(static_cast<std::size_t>(n));
        for (auto& b : buf)
            b = static_cast<std::uint8_t>(rng());
        ASSERT_EQ(mb::crc16(buf), mb::crc16_bitwise(buf)) << "length " << n;
    }
}

TEST(Checksum, CrcContinuesAcrossChunks) {
    auto buf = hex("11 10 00 60 00 02 04 00 0A 01 02");
    const std::span<const std::uint8_t> s(buf);
    EXPECT_EQ(mb::crc16(s.subspan(5), mb::crc16(s.first(5))), 0x1401);
}

TEST(Checksum, EmptyInputs) {
    EXPECT_EQ(mb::crc16({}), 0xFFFF);
    EXPECT_EQ(mb::lrc({}), 0x00);
}

}  // namespace test_modbus_checksum_test
