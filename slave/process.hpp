#pragma once
// The simulated process behind a device, as its profile's "simulation" block describes it: measured values
// wander around a set value, totals integrate a flow, alarm outputs trip at their set-point and release past
// its hysteresis (set-points and hysteresis read from the image each step, so a client's write takes effect
// at once). Deterministic: the same --seed and the same number of elapsed steps give the same values,
// whatever the wall clock did (steps are fixed, `advance` counts how many are due). A point frozen by the
// stuck-value fault is left alone.

#include <chrono>
#include <cstdint>
#include <memory>

#include "slave/device.hpp"

namespace mbscope::slave {

class Process {
  public:
    static constexpr std::chrono::milliseconds step_length{100};

    Process(Device& device, std::uint64_t seed);
    ~Process();
    Process(Process&&) noexcept;
    Process& operator=(Process&&) noexcept;

    // Runs every step due between the first call and `now`.
    void advance(std::chrono::steady_clock::time_point now);
    // Runs exactly n steps (tests).
    void step(std::uint64_t n = 1);
    std::uint64_t steps() const noexcept;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace mbscope::slave
