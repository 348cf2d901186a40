#include "fuzz/network/reply_latency.hpp"

#include <algorithm>
#include <cmath>

namespace mbscope::fuzz::network {

void ReplyLatency::add(std::chrono::nanoseconds sample) noexcept {
    const double r = std::max(0.0, static_cast<double>(sample.count()) / 1000.0);
    if (!any_) {
        smoothed_us_ = r;
        deviation_us_ = r / 2;
        any_ = true;
        return;
    }
    // RFC 6298 §2.3: the deviation first, from the smoothed value before this sample.
    deviation_us_ = 0.75 * deviation_us_ + 0.25 * std::abs(smoothed_us_ - r);
    smoothed_us_ = 0.875 * smoothed_us_ + 0.125 * r;
}

std::chrono::microseconds ReplyLatency::silence_wait(std::chrono::microseconds floor,
                                                     std::chrono::microseconds cap) const noexcept {
    if (!any_) return cap;
    const double us = std::ceil(2 * (smoothed_us_ + 4 * deviation_us_));
    const auto wait = std::chrono::microseconds(static_cast<long long>(std::min(us, 1e15)));
    return std::clamp(wait, std::min(floor, cap), cap);
}

}  // namespace mbscope::fuzz::network
