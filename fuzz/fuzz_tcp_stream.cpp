// Modbus/TCP stream reassembly: one consistent byte stream cut into segments that arrive out of order,
// retransmitted, overlapping or never (holes), acknowledged past holes or not, with sequence numbers that
// may wrap, through the analyzer's TcpReassembler into the MBAP deframer. Properties: the reassembler
// delivers each stream byte at most once, with the content it had in the stream, and accounts for every
// position up to the end of the furthest segment as data or as a declared gap; the deframer accounts for
// every byte delivered, in order.
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <vector>

#include "analyzer/tcp_reassembler.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/tcp_deframer.hpp"

using namespace mbscope;

namespace {

constexpr const char* target = "fuzz_tcp_stream";

// What the reassembler's callbacks check, for the input being run. The reassembler and the deframer are
// made once and reset for every input, keeping their storage (with ASan every allocation is filled and lands
// on fresh memory; the fuzzing build's vector annotations still catch a read past a buffer's size), so the
// callbacks reach the input's state through this.
struct Run {
    Run() {
        deframer.observe_passively();
    }  // as the analyzer reads streams: its checks are the endpoint's and more
    std::span<const std::uint8_t> stream;
    std::uint64_t position = 0;  // stream position of the next byte the reassembler must deliver
    modbus::TcpStreamDeframer deframer;
    modbus::DeframeEvents* events = nullptr;
    fuzz::StreamAccount* account = nullptr;
};
Run run;

void delivered(std::span<const std::uint8_t> bytes, modbus::Timestamp t) {
    if (run.position + bytes.size() > run.stream.size())
        fuzz::fail(target, "bytes delivered past the stream");
    if (!std::equal(bytes.begin(), bytes.end(), run.stream.begin() + static_cast<long>(run.position)))
        fuzz::fail(target, "bytes delivered at stream position " + std::to_string(run.position) +
                               " differ from the stream");
    run.position += bytes.size();
    run.events->clear();
    run.deframer.feed(bytes, t, *run.events);
    run.account->take(*run.events);
}

void missing(std::uint64_t n, modbus::Timestamp) {
    run.position += n;
    run.events->clear();
    run.deframer.gap(n, *run.events);
    run.account->take(*run.events);
    run.account->skip(n);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const auto isn = in.ConsumeIntegral<std::uint32_t>();
    const auto stream_size = in.ConsumeIntegralInRange<std::size_t>(0, 2048);
    static fuzz::ExactChunks<FuzzedDataProvider> stream_buffer(2048);  // the largest stream above
    const auto stream = stream_buffer.take(in, stream_size);

    fuzz::StreamAccount account(target);
    run.stream = stream;
    run.position = 0;
    run.deframer.reset();
    // The ISN's low bit: the stream read as one whose SYN the capture did not show (its first header judged).
    if (isn & 1) run.deframer.start_unaligned();
    run.events = &fuzz::reused_events();
    run.account = &account;
    static analyzer::TcpReassembler reassembler(delivered, missing);
    reassembler.reset(in.ConsumeIntegralInRange<std::size_t>(64, 4096));

    modbus::Timestamp t{1'000'000'000};
    reassembler.segment(isn, true, {}, t);
    std::size_t furthest = 0;
    while (in.remaining_bytes() >= 3 && !stream.empty()) {
        const auto offset = in.ConsumeIntegralInRange<std::size_t>(0, stream.size() - 1);
        const auto length =
            in.ConsumeIntegralInRange<std::size_t>(1, std::min<std::size_t>(300, stream.size() - offset));
        // One byte per segment at least (a range of one value consumes none): the loop always ends.
        const auto pause = in.ConsumeIntegral<std::uint8_t>();
        t += std::chrono::milliseconds(1 + (pause & 0x7F));
        reassembler.segment(isn + 1 + static_cast<std::uint32_t>(offset), false,
                            std::span<const std::uint8_t>(stream.data() + offset, length), t);
        // Its high bit: the receiver acknowledges up to this segment's end, as if every byte before it had
        // reached it (those the input never sent were lost by the tap, and are given up as a gap).
        if (pause & 0x80) reassembler.acknowledged(isn + 1 + static_cast<std::uint32_t>(offset + length), t);
        furthest = std::max(furthest, offset + length);
    }
    reassembler.flush(t);
    if (run.position != furthest)
        fuzz::fail(target, "the stream reached position " + std::to_string(furthest) + " but " +
                               std::to_string(run.position) +
                               " positions were delivered or declared missing");
    run.events->clear();
    run.deframer.finish(*run.events);
    account.take(*run.events);
    account.finish(run.position);
    return 0;
}
