#include "modbus/hex.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace test_modbus_hex_test {

namespace mb = mbscope::modbus;

static_assert(mb::hex_digit('0') == 0 && mb::hex_digit('9') == 9 && mb::hex_digit('A') == 10 &&
              mb::hex_digit('f') == 15 && mb::hex_digit('G') == -1 && mb::hex_digit(':') == -1);

// Every byte value against the C library's reading of one hex digit (strtol in the "C" locale).
TEST(Hex, EveryByteValueAgreesWithStrtol) {
    for (int c = 0; c < 256; ++c) {
        const char text[2] = {static_cast<char>(c), '\0'};
        char* end = nullptr;
        const long value = std::strtol(text, &end, 16);
        const bool one_digit = c != 0 && end == text + 1 && c != '+' && c != '-' && c != ' ';
        EXPECT_EQ(mb::hex_digit(static_cast<std::uint8_t>(c)), one_digit ? static_cast<int>(value) : -1)
            << "byte " << c;
        EXPECT_EQ(mb::hex_digit(static_cast<char>(c)), mb::hex_digit(static_cast<std::uint8_t>(c)));
        EXPECT_EQ(mb::is_lower_hex_letter(static_cast<std::uint8_t>(c)), c >= 'a' && c <= 'f')
            << "byte " << c;
    }
}

}  // namespace test_modbus_hex_test
