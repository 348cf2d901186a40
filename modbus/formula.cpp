#include "modbus/formula.hpp"

#include <cctype>
#include <charconv>
#include <cmath>

namespace mbscope::modbus {

namespace {

using Op = FormulaStep::Op;

class Parser {
  public:
    // `offset`: where `text` starts in the expression as written (after its last '='), for the messages.
    Parser(std::string_view text, std::size_t offset) : offset_(offset), text_(text) {}

    Result<Formula, std::string> run() {
        expression(0);
        skip_space();
        if (error_.empty() && at_ < text_.size()) fail("unexpected '" + std::string(1, text_[at_]) + "'");
        if (!error_.empty()) return error_;
        return std::move(out_);
    }

  private:
    void fail(const std::string& why) {
        if (error_.empty()) error_ = why + " at character " + std::to_string(offset_ + at_ + 1);
    }
    void skip_space() {
        while (at_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[at_])))
            ++at_;
    }
    bool take(char c) {
        skip_space();
        if (at_ < text_.size() && text_[at_] == c) {
            ++at_;
            return true;
        }
        return false;
    }
    // expression := term (('+' | '-') term)*, term := factor (('*' | '/') factor)*: `sums` for the first.
    void expression(int depth, bool sums = true) {
        const auto operand = [&] { sums ? expression(depth, false) : factor(depth); };
        operand();
        while (error_.empty()) {
            Op op = Op::Add;
            if (take(sums ? '+' : '*'))
                op = sums ? Op::Add : Op::Multiply;
            else if (take(sums ? '-' : '/'))
                op = sums ? Op::Subtract : Op::Divide;
            else
                return;
            operand();
            out_.push_back({op});
        }
    }
    // factor := number | name | '(' expression ')' | '-' factor
    void factor(int depth) {
        if (!error_.empty()) return;
        if (depth > formula_max_depth) return fail("nested deeper than " + std::to_string(formula_max_depth));
        skip_space();
        if (at_ >= text_.size()) return fail("expression ends early");
        const char c = text_[at_];
        if (take('(')) {
            expression(depth + 1);
            if (error_.empty() && !take(')')) fail("')' missing");
            return;
        }
        if (take('-')) {
            factor(depth + 1);
            out_.push_back({Op::Negate});
            return;
        }
        if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
            double v = 0;
            // A decimal comma, as the manuals print numbers ("19,99976"), reads as a point.
            std::string digits;
            const std::size_t from = at_;
            for (; at_ < text_.size() && (std::isdigit(static_cast<unsigned char>(text_[at_])) ||
                                          text_[at_] == '.' || text_[at_] == ',');
                 ++at_)
                digits += text_[at_] == ',' ? '.' : text_[at_];
            const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
            if (ec != std::errc{} || end != digits.data() + digits.size()) {
                at_ = from;
                return fail("bad number \"" + digits + "\"");
            }
            out_.push_back({Op::Number, v});
            return;
        }
        if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
            const std::size_t from = at_;
            while (at_ < text_.size() &&
                   (std::isalnum(static_cast<unsigned char>(text_[at_])) || text_[at_] == '_'))
                ++at_;
            const std::string_view name = text_.substr(from, at_ - from);
            if (name_.empty()) name_ = name;
            if (name != name_) {
                at_ = from;
                return fail("a second name \"" + std::string(name) + "\" (the raw value is \"" +
                            std::string(name_) + "\")");
            }
            out_.push_back({Op::Raw});
            return;
        }
        fail("unexpected '" + std::string(1, c) + "'");
    }

    std::size_t offset_;
    std::string_view text_;
    std::size_t at_ = 0;
    std::string_view name_;
    Formula out_;
    std::string error_;
};

}  // namespace

Result<Formula, std::string> parse_formula(std::string_view expr) {
    if (expr.size() > formula_max_length)
        return "longer than " + std::to_string(formula_max_length) + " characters";
    const std::size_t equals = expr.rfind('=');
    const std::size_t from = equals == std::string_view::npos ? 0 : equals + 1;
    return Parser(expr.substr(from), from).run();
}

double evaluate(const Formula& formula, double raw) noexcept {
    // Each operand takes at least one character of the expression: a program parse_formula() made never
    // holds more than formula_max_length of them. One made otherwise is checked as it runs.
    double stack[formula_max_length];
    std::size_t top = 0;
    for (const FormulaStep& s : formula) {
        const bool operand = s.op == Op::Number || s.op == Op::Raw;
        if (operand ? top == formula_max_length : top < (s.op == Op::Negate ? 1u : 2u)) return std::nan("");
        switch (s.op) {
            case Op::Number:
                stack[top++] = s.number;
                break;
            case Op::Raw:
                stack[top++] = raw;
                break;
            case Op::Negate:
                stack[top - 1] = -stack[top - 1];
                break;
            case Op::Add:
            case Op::Subtract:
            case Op::Multiply:
            case Op::Divide: {
                const double b = stack[--top];
                double& a = stack[top - 1];
                a = s.op == Op::Add        ? a + b
                    : s.op == Op::Subtract ? a - b
                    : s.op == Op::Multiply ? a * b
                                           : a / b;
                break;
            }
        }
    }
    return top == 1 ? stack[0] : std::nan("");
}

}  // namespace mbscope::modbus
