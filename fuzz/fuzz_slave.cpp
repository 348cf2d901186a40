// The reference slave's request handling for every bundled profile and framing, with the shared exchange
// oracle (conformance/oracle.hpp) judging each reply. The input is a profile, a framing, one or two units,
// then a sequence of requests; each request is an exact-size heap buffer (no padding to the largest ADU, so
// a read past the request is caught), framed correctly or sent as the raw bytes the input holds. Between
// requests the registers are compared, so a refused request that changed them is caught.
// Devices are made once per profile and unit and reset when an input ends (Device::reset: the register
// image drops the pages written since it was made), so every input meets devices exactly as new ones.
// A violated rule aborts with its id, the rule's source and what was expected and observed; with
// MBSCOPE_FUZZ_TRACE set every exchange is printed.
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "conformance/oracle.hpp"
#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "slave/device.hpp"
#include "slave/responder.hpp"

using namespace mbscope;
using modbus::Framing;

namespace {

slave::FaultSet no_faults;  // none: the clean slave must satisfy every rule

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
    std::vector<conformance::ExchangeOracle::Unit> oracle_units;
    for (auto* d : units)
        oracle_units.push_back({d->unit(), &d->profile()});
    slave::Responder responder(units, no_faults, framing, ip_network);
    conformance::ExchangeOracle oracle(framing, oracle_units, ip_network);

    std::uint16_t tid = 0;
    while (in.remaining_bytes() > 0) {
        const auto shape = in.ConsumeIntegral<std::uint8_t>();
        const auto length = in.ConsumeIntegralInRange<std::size_t>(0, 260);
        auto body = in.ConsumeBytes<std::uint8_t>(length);
        std::vector<std::uint8_t> adu;
        if ((shape & 0x03) !=
            0) {  // framed correctly: unit (often one that is served) and PDU from the input
            std::uint8_t unit = (shape & 0x04) ? units[(shape >> 3) % units.size()]->unit()
                                               : static_cast<std::uint8_t>(shape >> 3);
            if (framing == Framing::Tcp && (shape & 0x80)) unit = 0xFF;
            const std::span<const std::uint8_t> pdu(body.data(), std::min<std::size_t>(body.size(), 253));
            adu = modbus::encode_adu(framing, ++tid, unit, pdu);
        } else {
            adu = std::move(body);  // as the input holds it: checksum, MBAP header and all
        }
        const auto frame = modbus::decode_adu(framing, adu);
        if (!frame) continue;  // no frame: the server never hands such bytes to a unit
        ++requests_handled;

        std::uint64_t before = 0;
        for (auto* d : units)
            before += d->image().modifications();
        modbus::transport::Exchange ex;
        ex.sent = std::move(adu);  // the frame holds its own copy
        ex.received = responder.respond(*frame);
        if (!ex.received.empty()) {
            if (auto reply = modbus::decode_adu(framing, ex.received); reply) ex.response = std::move(*reply);
        }
        std::uint64_t after = 0;
        for (auto* d : units)
            after += d->image().modifications();
        const bool changed = after != before;
        static const bool trace = std::getenv("MBSCOPE_FUZZ_TRACE") != nullptr;
        if (trace)
            std::fprintf(stderr, "unit %s  %s -> %s\n", std::to_string(frame->unit_id()).c_str(),
                         modbus::hex_bytes(ex.sent).c_str(),
                         ex.received.empty() ? "(silence)" : modbus::hex_bytes(ex.received).c_str());
        for (const auto& v : oracle.judge(ex, changed))
            fuzz::fail("fuzz_slave", conformance::to_string(v) + "\n  profile " + first.id +
                                         (units.size() > 1 ? " + " + second.id : "") + "\n  request " +
                                         modbus::hex_bytes(ex.sent) + "\n  reply   " +
                                         modbus::hex_bytes(ex.received));
    }
    return 0;
}
