#include "slave/process.hpp"

#include <optional>
#include <random>

namespace mbscope::slave {

// Placeholder kept minimal until the process models land: counts steps only.
struct Process::Impl {
    Device* device;
    std::mt19937_64 rng;
    std::uint64_t steps = 0;
    std::optional<std::chrono::steady_clock::time_point> start;
};

Process::Process(Device& device, std::uint64_t seed)
    : impl_(std::make_unique<Impl>(Impl{&device, std::mt19937_64(seed), 0, {}})) {}
Process::~Process() = default;
Process::Process(Process&&) noexcept = default;
Process& Process::operator=(Process&&) noexcept = default;

void Process::advance(std::chrono::steady_clock::time_point now) {
    if (!impl_->start) impl_->start = now;
    const auto due = static_cast<std::uint64_t>((now - *impl_->start) / step_length);
    if (due > impl_->steps) step(due - impl_->steps);
}

void Process::step(std::uint64_t n) {
    impl_->steps += n;
}
std::uint64_t Process::steps() const noexcept {
    return impl_->steps;
}

}  // namespace mbscope::slave
