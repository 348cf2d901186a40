#include "analyzer/records.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace mbscope::analyzer {

std::string_view to_string(Carrier c) noexcept {
    switch (c) {
        case Carrier::Tcp:
            return "tcp";
        case Carrier::Udp:
            return "udp";
        case Carrier::Serial:
            return "serial";
        case Carrier::ExportedPdu:
            return "exported-pdu";
    }
    return "?";
}

std::optional<std::uint8_t> exception_code_of(const FrameRecord& response) noexcept {
    if (response.pdu) {
        if (const auto* e = std::get_if<modbus::ExceptionResponse>(&response.pdu->body))
            return e->exception_code;
        return std::nullopt;
    }
    const auto pdu = response.frame.pdu();
    if (pdu.size() >= 2 && (pdu[0] & 0x80) != 0) return pdu[1];
    return std::nullopt;
}

namespace {
int bucket_of(std::uint64_t ns) {
    if (ns < 32) return static_cast<int>(ns);
    const int e = std::bit_width(ns) - 6;  // ns >> e is in [32, 64)
    return 32 * e + static_cast<int>(ns >> e);
}
std::uint64_t bucket_low(int b) {
    if (b < 32) return static_cast<std::uint64_t>(b);
    const int e = b / 32 - 1;
    return static_cast<std::uint64_t>(b % 32 + 32) << e;
}
}  // namespace

void LatencyHistogram::add(modbus::Timestamp latency) {
    const std::uint64_t ns = latency.count() < 0 ? 0 : static_cast<std::uint64_t>(latency.count());
    const int b = std::min<int>(bucket_of(ns), static_cast<int>(buckets_.size()) - 1);
    ++buckets_[static_cast<std::size_t>(b)];
    if (count_ == 0 || latency < min_) min_ = latency;
    if (count_ == 0 || latency > max_) max_ = latency;
    ++count_;
}

bool NaturalOrder::operator()(std::string_view a, std::string_view b) const noexcept {
    const auto digit = [](char c) { return c >= '0' && c <= '9'; };
    std::size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        if (digit(a[i]) && digit(b[j])) {
            // Two runs of digits: by value (leading zeros skipped, then the longer run is the larger),
            // then the one with fewer leading zeros first, so that distinct names never compare equal.
            std::size_t za = i, zb = j;
            while (za < a.size() && a[za] == '0')
                ++za;
            while (zb < b.size() && b[zb] == '0')
                ++zb;
            std::size_t ea = za, eb = zb;
            while (ea < a.size() && digit(a[ea]))
                ++ea;
            while (eb < b.size() && digit(b[eb]))
                ++eb;
            if (ea - za != eb - zb) return ea - za < eb - zb;
            if (const int c = a.substr(za, ea - za).compare(b.substr(zb, eb - zb)); c != 0) return c < 0;
            if (za - i != zb - j) return za - i < zb - j;
            i = ea;
            j = eb;
            continue;
        }
        if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
        ++i;
        ++j;
    }
    return a.size() - i < b.size() - j;
}

// The nearest-rank quantile: the smallest latency that at least q of them do not exceed (the p99 of three
// latencies is the largest). Rounding the rank down, as before, gave the p99 of three as their median and
// understated the tail of a skewed set. Within its bucket the latency is taken at the bucket's middle
// (at most 1.5 % off); the first and last ranks are the exact min and max.
modbus::Timestamp LatencyHistogram::quantile(double q) const {
    if (count_ == 0) return modbus::Timestamp{0};
    const auto rank = std::clamp<std::uint64_t>(
        static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_))), 1, count_);
    if (rank == 1) return min_;
    if (rank == count_) return max_;
    std::uint64_t seen = 0;
    for (std::size_t b = 0; b < buckets_.size(); ++b) {
        seen += buckets_[b];
        if (seen >= rank) {
            const std::uint64_t low = bucket_low(static_cast<int>(b));
            const std::uint64_t middle = low + (bucket_low(static_cast<int>(b) + 1) - low) / 2;
            return std::clamp(modbus::Timestamp(static_cast<std::int64_t>(middle)), min_, max_);
        }
    }
    return max_;
}

}  // namespace mbscope::analyzer
