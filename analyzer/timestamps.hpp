#pragma once
// Timestamps are nanoseconds since 1970 in 64 bits, which ends in April 2262. Capture files carry seconds
// in 64 bits (pcapng) or as decimal text (the text format), both able to go far beyond that: these
// conversions say so instead of overflowing.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>

#include "modbus/frame.hpp"

namespace mbscope::analyzer {

// `seconds` and a sub-second part in nanoseconds (0..999'999'999) as one timestamp, or nullopt when it
// is not representable.
inline std::optional<modbus::Timestamp> timestamp_from(std::int64_t seconds, std::int64_t nanoseconds) {
    constexpr std::int64_t limit = std::numeric_limits<std::int64_t>::max() / 1'000'000'000 - 1;
    if (seconds > limit || seconds < -limit || nanoseconds < 0 || nanoseconds >= 1'000'000'000)
        return std::nullopt;
    return modbus::Timestamp(seconds * 1'000'000'000 + nanoseconds);
}

// Non-negative decimal seconds (NaN and infinities are not) as a timestamp, or nullopt.
inline std::optional<modbus::Timestamp> timestamp_from_seconds(double seconds) {
    constexpr double limit = 9.2e9;  // below 2^63 ns
    if (!std::isfinite(seconds) || seconds < 0 || seconds >= limit) return std::nullopt;
    return modbus::Timestamp(static_cast<std::int64_t>(std::llround(seconds * 1e9)));
}

// The UTC time of day with microseconds, "14:03:07.123456": what a technician matches against other logs.
inline std::string time_of_day_text(modbus::Timestamp t) {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(t).count();
    const long long day_us = ((us % 86'400'000'000LL) + 86'400'000'000LL) % 86'400'000'000LL;
    char buf[32];
    std::snprintf(buf, sizeof buf, "%02lld:%02lld:%02lld.%06lld", day_us / 3'600'000'000LL,
                  day_us / 60'000'000 % 60, day_us / 1'000'000 % 60, day_us % 1'000'000);
    return buf;
}

// A duration as people read latencies: "1.912 ms".
inline std::string milliseconds_text(modbus::Timestamp d) {
    char text[40];
    std::snprintf(text, sizeof text, "%.3f ms", std::chrono::duration<double, std::milli>(d).count());
    return text;
}

}  // namespace mbscope::analyzer
