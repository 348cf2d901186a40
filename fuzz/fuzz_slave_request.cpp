// The reference slave's request handler, one request per input, for every bundled profile and framing, judged
// by the shared exchange oracle (fuzz/slave_harness.hpp). The input is a profile, a framing, the shape of the
// request (framed correctly for a unit, or raw) and then the request itself: all the bytes left, handed over
// as a heap buffer of exactly their size, so a read past the request is caught. fuzz_slave fuzzes sequences
// of requests (state carried from one to the next); this target spends all of libFuzzer's time on one
// request's decoding, handling and reply, at about ten times the inputs a second.
#include <fuzzer/FuzzedDataProvider.h>

#include <vector>

#include "fuzz/bundled_profiles.hpp"
#include "fuzz/slave_harness.hpp"

using namespace mbscope;
using modbus::Framing;

// The profiles are loaded before fuzzing starts, as in fuzz_slave.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const auto& profiles = fuzz::bundled_profiles();
    const std::size_t index = in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1);
    const modbus::Profile& profile = profiles[index];
    const Framing framing = in.PickValueInArray({Framing::Rtu, Framing::Ascii, Framing::Tcp});
    const bool ip_network = framing == Framing::Tcp && in.ConsumeBool();
    const auto shape = in.ConsumeIntegral<std::uint8_t>();
    const auto tid = in.ConsumeIntegral<std::uint16_t>();

    const std::vector<slave::Device*> units{&fuzz::bundled_device(index, fuzz::unit_within(profile, 1))};
    const fuzz::ResetAtEnd reset_at_end{units};
    fuzz::SlaveHarness slave("fuzz_slave_request", units, framing, ip_network, profile.id);
    slave.exchange(fuzz::slave_request(framing, shape, units, tid, in.ConsumeRemainingBytes<std::uint8_t>()));
    return 0;
}
