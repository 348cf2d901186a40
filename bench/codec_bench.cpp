// Kernels of the codec, each measured next to a plain byte loop over the same buffer (the memory-speed
// reference); bench/README.md reports the ratios from one run, never lone absolute times.
#include <benchmark/benchmark.h>

#include <random>

#include "modbus/adu.hpp"
#include "modbus/ascii_deframer.hpp"
#include "modbus/checksum.hpp"
#include "modbus/pdu.hpp"
#include "modbus/rtu_deframer.hpp"
#include "modbus/tcp_deframer.hpp"

namespace mb = mbscope::modbus;

namespace {

constexpr std::size_t stream_bytes = 4 << 20;  // 4 MiB of traffic per iteration
constexpr std::size_t chunk = 4096;            // bytes per feed, like a read() from a capture

// A realistic polling mix: FC3 reads of 1..125 registers with replies, FC6/FC16 writes, exceptions.
std::vector<std::vector<std::uint8_t>> sample_pdus() {
    std::mt19937 rng(1);
    std::vector<std::vector<std::uint8_t>> pdus;
    for (int i = 0; i < 64; ++i) {
        const auto qty = static_cast<std::uint16_t>(1 + rng() % 125);
        pdus.push_back(
            mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, qty)));
        std::vector<std::uint16_t> regs(qty);
        for (auto& r : regs)
            r = static_cast<std::uint16_t>(rng());
        pdus.push_back(
            mb::encode_pdu(mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, regs)));
        pdus.push_back(mb::encode_pdu(mb::make_write_single_register(84, 926)));
        pdus.push_back(mb::encode_pdu(mb::make_exception(3, 2)));
    }
    return pdus;
}

struct Stream {
    std::vector<std::uint8_t> bytes;
    std::size_t frames = 0;
};

template <class Encode>
Stream build_stream(Encode encode) {
    Stream s;
    const auto pdus = sample_pdus();
    while (s.bytes.size() < stream_bytes) {
        for (const auto& p : pdus) {
            auto adu = encode(p);
            s.bytes.insert(s.bytes.end(), adu.begin(), adu.end());
            ++s.frames;
        }
    }
    return s;
}

const Stream& rtu_stream() {
    static const Stream s = build_stream([](const auto& p) { return mb::encode_rtu(17, p); });
    return s;
}
// The same traffic on a noisy RS-485 line: after one frame in eight a burst of 1..32 random bytes (a
// transceiver switching, a device starting up), and one frame in sixteen with one byte flipped (a bad CRC).
// The deframer spends its time on the bytes no frame explains.
const Stream& noisy_rtu_stream() {
    static const Stream s = [] {
        Stream n;
        std::mt19937 rng(2);
        const auto pdus = sample_pdus();
        while (n.bytes.size() < stream_bytes) {
            for (const auto& p : pdus) {
                auto adu = mb::encode_rtu(17, p);
                if (rng() % 16 == 0) adu[rng() % adu.size()] ^= static_cast<std::uint8_t>(1 + rng() % 255);
                n.bytes.insert(n.bytes.end(), adu.begin(), adu.end());
                ++n.frames;
                if (rng() % 8 == 0)
                    for (std::uint32_t i = 0, len = 1 + rng() % 32; i < len; ++i)
                        n.bytes.push_back(static_cast<std::uint8_t>(rng()));
            }
        }
        return n;
    }();
    return s;
}
const Stream& tcp_stream() {
    static std::uint16_t tid = 0;
    static const Stream s = build_stream([](const auto& p) { return mb::encode_tcp(++tid, 17, p); });
    return s;
}
const Stream& ascii_stream() {
    static const Stream s = build_stream([](const auto& p) {
        auto t = mb::encode_ascii(17, p);
        return std::vector<std::uint8_t>(t.begin(), t.end());
    });
    return s;
}

void finish(benchmark::State& state, const Stream& s) {
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * s.bytes.size()));
    state.counters["frames_per_s"] =
        benchmark::Counter(static_cast<double>(s.frames), benchmark::Counter::kIsIterationInvariantRate);
}

// ---- references: a plain per-byte loop (data-dependent, like any parser's byte loop) and a summing loop the
// compiler vectorises (memory bandwidth).
void BM_ReferenceByteLoop(benchmark::State& state) {
    const auto& s = rtu_stream();
    for (auto _ : state) {
        std::uint32_t h = 0;
        for (std::uint8_t b : s.bytes)
            h = (h << 5) - h + b;
        benchmark::DoNotOptimize(h);
    }
    finish(state, s);
}
BENCHMARK(BM_ReferenceByteLoop);

void BM_ReferenceVectorSum(benchmark::State& state) {
    const auto& s = rtu_stream();
    for (auto _ : state) {
        std::uint64_t sum = 0;
        for (std::uint8_t b : s.bytes)
            sum += b;
        benchmark::DoNotOptimize(sum);
    }
    finish(state, s);
}
BENCHMARK(BM_ReferenceVectorSum);

void BM_Crc16(benchmark::State& state) {
    const auto& s = rtu_stream();
    for (auto _ : state)
        benchmark::DoNotOptimize(mb::crc16(s.bytes));
    finish(state, s);
}
BENCHMARK(BM_Crc16);

void BM_Crc16Bitwise(benchmark::State& state) {
    const auto& s = rtu_stream();
    for (auto _ : state)
        benchmark::DoNotOptimize(mb::crc16_bitwise(s.bytes));
    finish(state, s);
}
BENCHMARK(BM_Crc16Bitwise);

template <class Feed>
void run_chunks(const Stream& s, mb::DeframeEvents& events, Feed feed) {
    for (std::size_t pos = 0; pos < s.bytes.size(); pos += chunk) {
        events.clear();
        feed(std::span<const std::uint8_t>(s.bytes.data() + pos, std::min(chunk, s.bytes.size() - pos)));
        benchmark::DoNotOptimize(events.data());
    }
}

// A deframer made for each pass over the stream, fed in chunks, its events cleared after each.
template <class Deframer>
void deframe_in_chunks(benchmark::State& state, const Stream& s) {
    mb::DeframeEvents events;
    events.reserve(1024);
    for (auto _ : state) {
        Deframer d;
        run_chunks(s, events, [&](auto bytes) { d.feed(bytes, events); });
        d.finish(events);
    }
    finish(state, s);
}

void BM_RtuDeframerUntimed(benchmark::State& state) {
    deframe_in_chunks<mb::RtuDeframer>(state, rtu_stream());
}
BENCHMARK(BM_RtuDeframerUntimed);

void BM_RtuDeframerUntimedNoisy(benchmark::State& state) {
    deframe_in_chunks<mb::RtuDeframer>(state, noisy_rtu_stream());
}
BENCHMARK(BM_RtuDeframerUntimedNoisy);

void BM_RtuDeframerTimed(benchmark::State& state) {
    const auto& s = rtu_stream();
    mb::DeframeEvents events;
    events.reserve(1024);
    const mb::SerialLine line{115200, 8, mb::Parity::Even, 1};
    for (auto _ : state) {
        mb::RtuTimedDeframer d(line);
        mb::Timestamp t{0};
        // Chunks of 64 bytes as a USB adapter delivers them, no silence between: frames are split by content.
        for (std::size_t pos = 0; pos < s.bytes.size(); pos += 64) {
            if (events.size() > 1024) events.clear();
            const auto n = std::min<std::size_t>(64, s.bytes.size() - pos);
            t += line.character_time() * static_cast<std::int64_t>(n);
            d.feed({s.bytes.data() + pos, n}, t, events);
        }
        d.finish(events);
        events.clear();
    }
    finish(state, s);
}
BENCHMARK(BM_RtuDeframerTimed);

void BM_TcpStreamDeframer(benchmark::State& state) {
    deframe_in_chunks<mb::TcpStreamDeframer>(state, tcp_stream());
}
BENCHMARK(BM_TcpStreamDeframer);

void BM_AsciiDeframer(benchmark::State& state) {
    deframe_in_chunks<mb::AsciiDeframer>(state, ascii_stream());
}
BENCHMARK(BM_AsciiDeframer);

void BM_DecodePdusOfRtuStream(benchmark::State& state) {
    const auto& s = rtu_stream();
    mb::RtuDeframer d;
    mb::DeframeEvents events;
    d.feed(s.bytes, events);
    d.finish(events);
    for (auto _ : state) {
        for (const auto& e : events)
            if (const auto* f = std::get_if<mb::Frame>(&e))
                benchmark::DoNotOptimize(mb::decode_pdu(f->pdu(), mb::Direction::Unknown));
    }
    finish(state, s);
}
BENCHMARK(BM_DecodePdusOfRtuStream);

}  // namespace

BENCHMARK_MAIN();
