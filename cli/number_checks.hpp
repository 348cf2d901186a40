#pragma once
// Checks for numeric options that CLI11's Range lets through: NaN compares false with both bounds, and a
// value past what a duration can hold (--timeout 1e300) overflowed its conversion to nanoseconds.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <optional>
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

// "60s", "2m", "500ms", "1.5h", "90" (seconds): a positive time of at most 1e12 ms. NaN, infinity, zero and
// negative times are none (a run bounded by them would never stop, or never start).
inline std::optional<std::chrono::milliseconds> parse_duration(const std::string& text) {
    std::size_t used = 0;
    double value = 0;
    try {
        value = std::stod(text, &used);
    } catch (const std::exception&) {
        return std::nullopt;
    }
    const std::string unit = text.substr(used);
    double ms = 0;
    if (unit.empty() || unit == "s")
        ms = value * 1000;
    else if (unit == "ms")
        ms = value;
    else if (unit == "m" || unit == "min")
        ms = value * 60000;
    else if (unit == "h")
        ms = value * 3600000;
    else
        return std::nullopt;
    if (!(ms >= 1) || ms > 1e12) return std::nullopt;
    return std::chrono::milliseconds(static_cast<std::int64_t>(ms));
}

// A --duration option: refused at parse time unless parse_duration takes it.
inline CLI::Validator duration_text() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            if (parse_duration(text)) return {};
            return "a time such as 60s, 500ms or 5m (a bare number is seconds), not '" + text + "'";
        },
        "TIME");
}

// A whole number from 0 to 2^64-1 for an unsigned option. CLI11 converts "-1" to an unsigned 64-bit number by
// wrapping it (its Range check sees the wrapped value), so --seed -1 (a common spelling of "a random seed")
// ran with seed 18446744073709551615 and said nothing, and --max-findings -1 had no limit.
inline CLI::Validator whole_number(const std::string& name) {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            const bool digits = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
            if (digits && (text.size() < 20 || (text.size() == 20 && text <= "18446744073709551615")))
                return {};
            return "a whole number from 0 to 18446744073709551615, not '" + text + "'";
        },
        name);
}

inline CLI::Validator seed_value() {
    return whole_number("SEED");
}

}  // namespace mbscope::cli
