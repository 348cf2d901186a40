// Modbus/TCP stream reassembly: one consistent byte stream cut into segments that arrive out of order,
// retransmitted, overlapping or never (holes), with sequence numbers that may wrap, through the analyzer's
// TcpReassembler into the MBAP deframer. Properties: the reassembler delivers each stream byte at most once,
// with the content it had in the stream, and accounts for every position up to the end of the furthest
// segment as data or as a declared gap; the deframer accounts for every byte delivered, in order.
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <vector>

#include "analyzer/tcp_reassembler.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/tcp_deframer.hpp"

using namespace mbscope;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    constexpr const char* target = "fuzz_tcp_stream";
    FuzzedDataProvider in(data, size);
    const auto isn = in.ConsumeIntegral<std::uint32_t>();
    const auto stream_size = in.ConsumeIntegralInRange<std::size_t>(0, 2048);
    const auto stream = in.ConsumeBytes<std::uint8_t>(stream_size);

    fuzz::StreamAccount account(target);
    modbus::TcpStreamDeframer deframer;
    modbus::DeframeEvents& events = fuzz::reused_events();
    std::uint64_t position = 0;  // stream position of the next byte the reassembler must deliver
    analyzer::TcpReassembler reassembler(
        [&](std::span<const std::uint8_t> bytes, modbus::Timestamp t) {
            if (position + bytes.size() > stream.size())
                fuzz::fail(target, "bytes delivered past the stream");
            if (!std::equal(bytes.begin(), bytes.end(), stream.begin() + static_cast<long>(position)))
                fuzz::fail(target, "bytes delivered at stream position " + std::to_string(position) +
                                       " differ from the stream");
            position += bytes.size();
            events.clear();
            deframer.feed(bytes, t, events);
            account.take(events);
        },
        [&](std::uint64_t missing, modbus::Timestamp) {
            position += missing;
            events.clear();
            deframer.gap(missing, events);
            account.take(events);
            account.skip(missing);
        },
        in.ConsumeIntegralInRange<std::size_t>(64, 4096));

    modbus::Timestamp t{1'000'000'000};
    reassembler.segment(isn, true, {}, t);
    std::size_t furthest = 0;
    while (in.remaining_bytes() >= 3 && !stream.empty()) {
        const auto offset = in.ConsumeIntegralInRange<std::size_t>(0, stream.size() - 1);
        const auto length =
            in.ConsumeIntegralInRange<std::size_t>(1, std::min<std::size_t>(300, stream.size() - offset));
        // One byte per segment at least (a range of one value consumes none): the loop always ends.
        t += std::chrono::milliseconds(1 + in.ConsumeIntegral<std::uint8_t>());
        reassembler.segment(isn + 1 + static_cast<std::uint32_t>(offset), false,
                            std::span<const std::uint8_t>(stream.data() + offset, length), t);
        furthest = std::max(furthest, offset + length);
    }
    reassembler.flush(t);
    if (position != furthest)
        fuzz::fail(target, "the stream reached position " + std::to_string(furthest) + " but " +
                               std::to_string(position) + " positions were delivered or declared missing");
    events.clear();
    deframer.finish(events);
    account.take(events);
    account.finish(position);
    return 0;
}
