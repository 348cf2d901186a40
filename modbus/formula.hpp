#pragma once
// A conversion a manual gives for a register, as it prints it: "I(mA) = ((16 / 65536) * R) + 4" (CTH2265I
// 4011, 003:592-594). The right side of the last '=' is an arithmetic expression of numbers, + - * /,
// parentheses and one name for the register's raw value (R, x, or any other single name). Parsed once, when
// the profile loads, into a small program evaluated for every value shown; a profile is input like any
// other, so what cannot be parsed is an error that says where, and nothing here recurses or allocates
// without bound.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/result.hpp"

namespace mbscope::modbus {

struct FormulaStep {
    enum class Op : std::uint8_t { Number, Raw, Add, Subtract, Multiply, Divide, Negate };
    Op op = Op::Number;
    double number = 0;  // Op::Number
    bool operator==(const FormulaStep&) const = default;
};

// The steps in postfix order; evaluate() runs them.
using Formula = std::vector<FormulaStep>;

// The longest expression and the deepest nesting of parentheses taken.
inline constexpr std::size_t formula_max_length = 256;
inline constexpr int formula_max_depth = 16;

// The program for `expr`, or what is wrong with it and at which character.
Result<Formula, std::string> parse_formula(std::string_view expr);
// The formula's value for the raw value `raw` (a division by zero gives an infinity or NaN, as the
// arithmetic does: shown, not hidden).
double evaluate(const Formula& formula, double raw) noexcept;

}  // namespace mbscope::modbus
