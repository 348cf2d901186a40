#pragma once
// Checks for numeric options that CLI11's Range lets through: NaN compares false with both bounds, and a
// value past what a duration can hold (--timeout 1e300) overflowed its conversion to nanoseconds.
#include <CLI/CLI.hpp>
#include <cmath>
#include <sstream>
#include <string>

namespace mbscope::cli {

// A finite number from `low` to `high`, described as "`what` from LOW to HIGH".
inline CLI::Validator finite_between(double low, double high, const std::string& what) {
    const auto shown = [](double v) {
        std::ostringstream out;
        out << v;
        return out.str();
    };
    const std::string range = shown(low) + " to " + shown(high);
    return CLI::Validator(
        [=](std::string& text) -> std::string {
            double v = 0;
            try {
                std::size_t used = 0;
                v = std::stod(text, &used);
                if (used != text.size()) return what + ": not a number: '" + text + "'";
            } catch (...) {
                return what + ": not a number: '" + text + "'";
            }
            if (!std::isfinite(v) || v < low || v > high)
                return what + " from " + range + ", not '" + text + "'";
            return {};
        },
        "NUMBER in " + range);
}

}  // namespace mbscope::cli
