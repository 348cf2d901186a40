// The reference slave's request handling for every bundled profile and framing, with the shared exchange
// oracle judging each reply (fuzz/slave_harness.hpp). The input is a profile, a framing, one or two units,
// then a sequence of requests, so that state carried from one request to the next (listen-only mode,
// acknowledged writes read back) is fuzzed too; fuzz_slave_request fuzzes one request per input. Each request
// is an exact-size heap buffer (no padding to the largest ADU, so a read past the request is caught), framed
// correctly or sent as the raw bytes the input holds. Between requests the registers are compared, so a
// refused request that changed them is caught.
// Devices are made once per profile and unit and reset when an input ends (Device::reset: the register
// image drops the pages written since it was made), so every input meets devices exactly as new ones.
#include <fuzzer/FuzzedDataProvider.h>

#include <cstdio>
#include <cstdlib>
#include <vector>

#include "fuzz/bundled_profiles.hpp"
#include "fuzz/slave_harness.hpp"

using namespace mbscope;
using modbus::Framing;

namespace {

// Requests handed to the slave over the whole run: an input holds a sequence of them, so executions per
// second alone understate the target's rate (bench/fuzz_slave_vs_libmodbus.sh compares it with a harness of
// one request per input). Printed at exit when MBSCOPE_FUZZ_STATS is set.
std::uint64_t requests_handled = 0;

void print_requests() {
    std::fprintf(stderr, "fuzz_slave: requests handled: %llu\n",
                 static_cast<unsigned long long>(requests_handled));
}

}  // namespace

// The profiles are loaded before fuzzing starts (about 3 s under the sanitizers), so libFuzzer's time limit
// and executions per second count fuzzing only. The replay runner loads them with the first input instead.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    if (std::getenv("MBSCOPE_FUZZ_STATS") != nullptr) std::atexit(print_requests);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const auto& profiles = fuzz::bundled_profiles();
    const std::size_t first_index = in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1);
    const std::size_t second_index = in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1);
    const modbus::Profile& first = profiles[first_index];
    const modbus::Profile& second = profiles[second_index];
    const Framing framing = in.PickValueInArray({Framing::Rtu, Framing::Ascii, Framing::Tcp});
    const bool two_units = in.ConsumeBool();
    const bool ip_network = framing == Framing::Tcp && in.ConsumeBool();

    std::vector<slave::Device*> units;
    units.push_back(&fuzz::bundled_device(first_index, fuzz::unit_within(first, 1)));
    if (two_units && fuzz::unit_within(second, 2) != units.front()->unit())
        units.push_back(&fuzz::bundled_device(second_index, fuzz::unit_within(second, 2)));
    const fuzz::ResetAtEnd reset_at_end{units};
    fuzz::SlaveHarness slave("fuzz_slave", units, framing, ip_network,
                             first.id + (units.size() > 1 ? " + " + second.id : ""));

    std::uint16_t tid = 0;
    while (in.remaining_bytes() > 0) {
        const auto shape = in.ConsumeIntegral<std::uint8_t>();
        const auto length = in.ConsumeIntegralInRange<std::size_t>(0, 260);
        if (slave.exchange(
                fuzz::slave_request(framing, shape, units, ++tid, in.ConsumeBytes<std::uint8_t>(length))))
            ++requests_handled;
    }
    return 0;
}
