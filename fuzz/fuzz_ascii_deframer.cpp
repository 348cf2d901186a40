// The ASCII deframer (':' ... LRC CR LF, 1 s inter-character timeout), fed in chunks whose sizes and arrival
// times are drawn from the input. Property: every character fed comes out exactly once, in a frame or an
// unparsed run, in stream order.
#include <fuzzer/FuzzedDataProvider.h>

#include <chrono>
#include <vector>

#include "fuzz/fuzz_support.hpp"
#include "modbus/ascii_deframer.hpp"

using namespace mbscope;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const bool timed = in.ConsumeBool();
    fuzz::StreamAccount account("fuzz_ascii_deframer");
    modbus::AsciiDeframer deframer;
    modbus::DeframeEvents& events = fuzz::reused_events();
    std::uint64_t total = 0;
    static fuzz::ExactChunks<FuzzedDataProvider> chunks(64);  // the largest chunk below
    modbus::Timestamp now{1'000'000'000};
    while (in.remaining_bytes() > 0) {
        const auto chunk_size = in.ConsumeIntegralInRange<std::size_t>(1, 64);
        const auto pause_ms = in.ConsumeIntegralInRange<std::uint32_t>(0, 1500);
        const auto chunk = chunks.take(in, chunk_size);
        if (chunk.empty()) break;
        total += chunk.size();
        now += std::chrono::milliseconds(pause_ms);
        events.clear();
        deframer.feed(chunk, timed ? now : modbus::Timestamp{0}, events);
        account.take(events);
    }
    events.clear();
    deframer.finish(events);
    account.take(events);
    account.finish(total);
    return 0;
}
