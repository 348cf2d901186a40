// The conversions a manual prints for a register, parsed as printed: the CTH2265I's current output
// (003:592-594, CTH-ENC-04: "I(mA) = ((16 / 65536) * R) + 4"; R = 0 gives 4 mA, 32768 gives 12 mA, 65535
// gives 19.99976 mA) and expressions a profile could hold by mistake or on purpose.
#include "modbus/formula.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace test_modbus_formula_test {

namespace mb = mbscope::modbus;

namespace {

double at(const std::string& expr, double raw) {
    auto f = mb::parse_formula(expr);
    EXPECT_TRUE(f.has_value()) << expr << ": " << (f ? "" : f.error());
    return f ? mb::evaluate(*f, raw) : std::nan("");
}

std::string error_of(const std::string& expr) {
    auto f = mb::parse_formula(expr);
    return f ? "" : f.error();
}

}  // namespace

TEST(Formula, TheCurrentOutputOfTheCthManual) {
    const std::string expr = "I(mA) = ((16 / 65536) * R) + 4";
    EXPECT_DOUBLE_EQ(at(expr, 0), 4.0);
    EXPECT_DOUBLE_EQ(at(expr, 32768), 12.0);
    EXPECT_NEAR(at(expr, 65535), 19.99976, 0.000005);
}

TEST(Formula, PrecedenceSignsCommasAndAnyOneName) {
    EXPECT_DOUBLE_EQ(at("4 + 16*x/65536", 32768), 12.0);
    EXPECT_DOUBLE_EQ(at("2 + 3 * 4 - 6 / 2", 0), 11.0);
    EXPECT_DOUBLE_EQ(at("(2 + 3) * 4", 0), 20.0);
    EXPECT_DOUBLE_EQ(at("-R + 1", 5), -4.0);
    EXPECT_DOUBLE_EQ(at("--R", 5), 5.0);
    EXPECT_DOUBLE_EQ(at("R * 0,5", 9), 4.5);  // a decimal comma, as the manuals print numbers
    EXPECT_DOUBLE_EQ(at("valor / 10 + valor", 10), 11.0);
    EXPECT_DOUBLE_EQ(at("7", 123), 7.0);
    EXPECT_TRUE(std::isinf(at("1 / R", 0)));  // the arithmetic's answer, shown as such
}

TEST(Formula, WhatCannotBeParsedSaysWhere) {
    EXPECT_EQ(error_of("4 + * R"), "unexpected '*' at character 5");
    EXPECT_EQ(error_of("I = (R + 1"), "')' missing at character 11");
    EXPECT_EQ(error_of("R + x"), "a second name \"x\" (the raw value is \"R\") at character 5");
    EXPECT_EQ(error_of("R +"), "expression ends early at character 4");
    EXPECT_EQ(error_of(""), "expression ends early at character 1");
    EXPECT_EQ(error_of("R 2"), "unexpected '2' at character 3");
    EXPECT_EQ(error_of("1.2.3"), "bad number \"1.2.3\" at character 1");
    EXPECT_EQ(error_of("R % 2"), "unexpected '%' at character 3");
    EXPECT_EQ(error_of(std::string(17, '(') + "R" + std::string(17, ')')),
              "nested deeper than 16 at character 18");
    EXPECT_EQ(error_of(std::string(300, '1')), "longer than 256 characters");
    EXPECT_EQ(error_of(std::string(16, '-') + "R"), "");
    EXPECT_NE(error_of(std::string(17, '-') + "R"), "");
}

TEST(Formula, AProgramNotMadeByTheParserIsCheckedAsItRuns) {
    using Op = mb::FormulaStep::Op;
    EXPECT_TRUE(std::isnan(mb::evaluate({}, 1)));
    EXPECT_TRUE(std::isnan(mb::evaluate({{Op::Add}}, 1)));
    EXPECT_TRUE(std::isnan(mb::evaluate({{Op::Negate}}, 1)));
    EXPECT_TRUE(std::isnan(mb::evaluate({{Op::Raw}, {Op::Raw}}, 1)));
    EXPECT_DOUBLE_EQ(mb::evaluate({{Op::Raw}, {Op::Number, 2}, {Op::Multiply}}, 3), 6.0);
}

}  // namespace test_modbus_formula_test
