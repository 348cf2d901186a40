#include "analyzer/progress.hpp"

#include <cstdio>

namespace mbscope::analyzer {
namespace {

std::string grouped(std::uint64_t n) {
    std::string digits = std::to_string(n), out;
    for (std::size_t i = 0; i < digits.size(); ++i) {
        if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

std::string megabytes(std::uint64_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / 1e6);
    return buf;
}

std::string plural(std::uint64_t n, const char* word) {
    return grouped(n) + ' ' + word + (n == 1 ? "" : "s");
}

}  // namespace

std::string format_progress(const ProgressState& s) {
    std::string line = plural(s.packets, "packet") + ", " + megabytes(s.bytes_read);
    if (s.total_bytes > 0) {
        const auto done = s.bytes_read >= s.total_bytes ? 100 : s.bytes_read * 100 / s.total_bytes;
        line += " of " + megabytes(s.total_bytes) + " (" + std::to_string(done) + "%)";
    }
    return line + ", " + plural(s.frames, "frame") + ", " + plural(s.findings, "finding");
}

void ProgressMeter::update(const ProgressState& state) {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < interval_) return;
    last_ = now;
    // Carriage return, the line, then erase what a longer previous line left (ECMA-48 EL).
    out_ << '\r' << format_progress(state) << "\x1b[K" << std::flush;
    drawn_ = true;
}

void ProgressMeter::clear() {
    if (!drawn_) return;
    out_ << "\r\x1b[K" << std::flush;
    drawn_ = false;
}

}  // namespace mbscope::analyzer
