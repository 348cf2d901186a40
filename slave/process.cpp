#include "slave/process.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <vector>

namespace mbscope::slave {

namespace {

using modbus::SimulationSignal;
using Model = SimulationSignal::Model;

constexpr double step_seconds = std::chrono::duration<double>(Process::step_length).count();
// How strongly a walk is pulled back to its start each second: a measured value wanders, it does not drift
// off to a limit and stay there.
constexpr double reversion_per_second = 0.05;

// A standard normal draw from the generator's raw output (Box-Muller): the same sequence for the same seed
// on every standard library, which std::normal_distribution does not promise.
double normal(std::mt19937_64& rng) {
    const double u1 = (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53;
    const double u2 = static_cast<double>(rng() >> 11) * 0x1.0p-53;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
}

}  // namespace

struct Process::Impl {
    struct State {
        const SimulationSignal* signal = nullptr;
        const modbus::Point* point = nullptr;
        std::size_t source = 0;  // index of the followed signal (integrate, alarm)
        double value = 0;        // walk: the value; integrate: the total, fractions kept; alarm: 0 or 1
    };
    Device* device;
    std::mt19937_64 rng;
    std::uint64_t steps = 0;
    std::optional<std::chrono::steady_clock::time_point> start;
    std::vector<State> states;

    // A point's raw value as the image holds it (two-register points in their word order, signed where
    // the point is).
    double read(const modbus::PointRef& ref) const {
        const auto& p = device->profile();
        const modbus::Point* point = p.find(ref.table, ref.address);
        const auto& image = device->image();
        if (modbus::is_bit_table(ref.table)) return image.bit(ref.table, ref.address) ? 1 : 0;
        if (point && point->encoding.type == modbus::EncodingType::F32)
            return image.f32(ref.table, point->address, point->encoding.word_order);
        if (point && point->encoding.words == 2) {
            const std::uint32_t v = image.u32(ref.table, point->address, point->encoding.word_order);
            return point->encoding.is_signed ? static_cast<double>(static_cast<std::int32_t>(v)) : v;
        }
        const std::uint16_t v = image.reg(ref.table, ref.address);
        const bool is_signed =
            point && (point->encoding.type == modbus::EncodingType::S16 || point->encoding.is_signed);
        return is_signed ? static_cast<double>(static_cast<std::int16_t>(v)) : v;
    }

    // What a client reads: whole counts of an integer point (a total shows what it has completed), the
    // value itself for a float.
    static double shown(const State& s) {
        return s.point && s.point->encoding.type == modbus::EncodingType::F32 ? s.value : std::floor(s.value);
    }

    void write(const State& s, double value) {
        if (s.signal->hidden) return;  // nothing on the map shows it
        const auto& ref = s.signal->point;
        if (device->frozen(ref.table, ref.address)) return;  // stuck-value fault: the process cannot move it
        auto& image = device->image();
        if (modbus::is_bit_table(ref.table)) {
            image.set_bit(ref.table, ref.address, value != 0);
            return;
        }
        const auto v = static_cast<std::int64_t>(std::llround(value));
        const auto& e = s.point ? s.point->encoding : modbus::Encoding{};
        using T = modbus::EncodingType;
        if (s.point && e.pair &&
            (e.type == T::U32Low || e.type == T::U32High || e.type == T::Digits4Low ||
             e.type == T::Digits4High)) {
            // A value split over two points (CTH2265I's low/high words, MK's 8-digit values): both halves.
            const bool digits = e.type == T::Digits4Low || e.type == T::Digits4High;
            const auto u = static_cast<std::uint64_t>(std::max<std::int64_t>(v, 0));
            const auto hi = static_cast<std::uint16_t>(digits ? (u / 10000) % 10000 : (u >> 16) & 0xFFFF);
            const auto lo = static_cast<std::uint16_t>(digits ? u % 10000 : u & 0xFFFF);
            const bool high_here = e.type == T::U32High || e.type == T::Digits4High;
            image.set_reg(ref.table, ref.address, high_here ? hi : lo);
            if (!device->frozen(ref.table, *e.pair)) image.set_reg(ref.table, *e.pair, high_here ? lo : hi);
            return;
        }
        if (s.point && e.type == T::F32) {  // a float travels as its IEEE 754 bytes, not as an integer
            image.set_f32(ref.table, s.point->address, static_cast<float>(value), e.word_order);
            return;
        }
        if (s.point && s.point->encoding.words == 2)
            image.set_u32(ref.table, s.point->address, static_cast<std::uint32_t>(v),
                          s.point->encoding.word_order);
        else
            image.set_reg(ref.table, ref.address, static_cast<std::uint16_t>(v));
    }

    void run_step() {
        for (auto& s : states) {
            const SimulationSignal& sig = *s.signal;
            switch (sig.model) {
                case Model::Walk: {
                    const double pull = (sig.start - s.value) * reversion_per_second * step_seconds;
                    s.value += pull + normal(rng) * sig.step * std::sqrt(step_seconds);
                    s.value = std::clamp(s.value, sig.min, sig.max);
                    break;
                }
                case Model::Integrate: {
                    s.value += states[s.source].value * sig.per_second * step_seconds;
                    if (s.value >= sig.max) s.value = std::fmod(s.value, sig.max);  // the counter rolls over
                    if (s.value < 0) s.value = 0;
                    break;
                }
                case Model::Constant:
                    break;  // written again every step: only the process moves the points it names
                case Model::Alarm: {
                    const double pv = states[s.source].value;
                    const double sp = read(*sig.setpoint);
                    const double hyst = sig.hysteresis ? read(*sig.hysteresis) : 0;
                    const bool tripped = s.value != 0;
                    if (sig.high)
                        s.value = tripped ? (pv > sp - hyst ? 1 : 0) : (pv > sp ? 1 : 0);
                    else
                        s.value = tripped ? (pv < sp + hyst ? 1 : 0) : (pv < sp ? 1 : 0);
                    break;
                }
            }
            write(s, shown(s));
        }
    }
};

Process::Process(Device& device, std::uint64_t seed)
    : impl_(std::make_unique<Impl>(Impl{&device, std::mt19937_64(seed), 0, {}, {}})) {
    const auto& p = device.profile();
    for (const auto& sig : p.simulation.signals) {
        Impl::State s;
        s.signal = &sig;
        s.point = sig.hidden ? nullptr : p.find(sig.point.table, sig.point.address);
        for (std::size_t i = 0; i < impl_->states.size(); ++i)
            if (impl_->states[i].signal->id == sig.of) s.source = i;
        s.value = sig.model == Model::Alarm ? 0 : sig.start;
        impl_->states.push_back(s);
        impl_->write(impl_->states.back(), Impl::shown(impl_->states.back()));
    }
}
Process::~Process() = default;
Process::Process(Process&&) noexcept = default;
Process& Process::operator=(Process&&) noexcept = default;

void Process::advance(std::chrono::steady_clock::time_point now) {
    if (!impl_->start) impl_->start = now;
    const auto due = static_cast<std::uint64_t>((now - *impl_->start) / step_length);
    if (due > impl_->steps) step(due - impl_->steps);
}

void Process::step(std::uint64_t n) {
    for (std::uint64_t i = 0; i < n; ++i)
        impl_->run_step();
    impl_->steps += n;
}

std::uint64_t Process::steps() const noexcept {
    return impl_->steps;
}

}  // namespace mbscope::slave
