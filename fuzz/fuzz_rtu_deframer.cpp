// The RTU deframers: the untimed stepper (raw dumps) and the timed one (t1.5/t3.5), fed in chunks whose
// sizes, and for the timed one whose arrival times and line speed, are drawn from the input. Property:
// every byte fed comes out exactly once, in a frame or an unparsed run, in stream order.
#include <fuzzer/FuzzedDataProvider.h>

#include <chrono>
#include <vector>

#include "fuzz/fuzz_support.hpp"
#include "modbus/rtu_deframer.hpp"

using namespace mbscope;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const bool timed = in.ConsumeBool();
    modbus::SerialLine line;
    line.baud = in.PickValueInArray<std::uint32_t>({1200, 9600, 19200, 115200});
    fuzz::StreamAccount account("fuzz_rtu_deframer");
    modbus::DeframeEvents& events = fuzz::reused_events();
    std::uint64_t total = 0;
    static fuzz::ExactChunks<FuzzedDataProvider> chunks(64);  // the largest chunk below
    // Made once and reset for every input, keeping their buffers (with ASan every allocation is filled and
    // lands on fresh memory); the fuzzing build's vector annotations still catch a read past a buffer's size.
    static modbus::RtuDeframer raw;
    static modbus::RtuTimedDeframer timed_deframer(line);
    raw.reset();
    timed_deframer.reset(line);
    modbus::Timestamp now{1'000'000'000};
    while (in.remaining_bytes() > 0) {
        const auto chunk_size = in.ConsumeIntegralInRange<std::size_t>(1, 64);
        const auto pause_us = in.ConsumeIntegralInRange<std::uint32_t>(0, 20'000);
        const auto chunk = chunks.take(in, chunk_size);
        if (chunk.empty()) break;
        total += chunk.size();
        now += std::chrono::microseconds(pause_us) + line.character_time() * static_cast<long>(chunk.size());
        events.clear();
        if (timed) {
            timed_deframer.advance(now - line.character_time() * static_cast<long>(chunk.size()), events);
            timed_deframer.feed(chunk, now, events);
        } else {
            raw.feed(chunk, events);
        }
        account.take(events);
    }
    events.clear();
    if (timed)
        timed_deframer.finish(events);
    else
        raw.finish(events);
    account.take(events);
    account.finish(total);
    return 0;
}
