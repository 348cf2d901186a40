// The analyzer end to end on pcap/pcapng bytes read by libpcap from memory: link layers, IP, TCP
// reassembly, UDP, serial link types, exported PDUs, pairing, the device semantics of a bundled profile, and
// every output format (text and JSON lines) written to nowhere. Options are drawn from the first bytes.
// Properties: no crash, no leak, no undefined behaviour; the summary's frame count is what the sink saw.
#include <fuzzer/FuzzedDataProvider.h>

#include <ostream>
#include <streambuf>

#include "analyzer/analyzer.hpp"
#include "analyzer/capture_source.hpp"
#include "analyzer/semantics.hpp"
#include "analyzer/sinks.hpp"
#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"

using namespace mbscope;

namespace {

struct CountingSink : analyzer::Sink {
    std::uint64_t frames = 0;
    void frame(const analyzer::FrameRecord&) override { ++frames; }
};

}  // namespace

// The bundled profiles are loaded before libFuzzer's clock starts: in the first input that needed them (5-7 s
// on a busy 2-core machine) they passed the smoke's 10 s timeout for one run, a false hang saved as a
// regression.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    analyzer::AnalyzerOptions options;
    const auto flags = in.ConsumeIntegral<std::uint8_t>();
    if (flags & 0x01) options.user_dlt = (flags & 0x02) ? modbus::Framing::Ascii : modbus::Framing::Rtu;
    if ((flags & 0x41) == 0x40) options.user_dlt.emplace();  // USER records' framing told from their bytes
    if (flags & 0x04) options.rtu_over_tcp_ports = {502};
    if (flags & 0x08) options.tcp_ports.push_back(1502);
    if (flags & 0x10) options.word_order = modbus::WordOrder::Cdab;
    if (flags & 0x20) {
        const auto& profiles = fuzz::bundled_profiles();
        auto semantics = std::make_shared<analyzer::Semantics>();
        const auto& p = profiles[in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1)];
        semantics->add({}, std::make_shared<const modbus::Profile>(p));
        options.semantics = std::move(semantics);
    }
    const auto capture = in.ConsumeRemainingBytes<std::uint8_t>();

    fuzz::NullBuffer null_buffer;
    std::ostream nowhere(&null_buffer);
    analyzer::TextSink text(nowhere);
    analyzer::JsonSink json(nowhere, true);
    CountingSink counter;
    analyzer::TeeSink sink({&text, &json, &counter});
    analyzer::Analyzer a(options, sink);
    std::string error;
    if (auto source = analyzer::CaptureSource::open_memory(capture, error)) a.read_capture(*source);
    a.finish();
    if (a.summary().frames != counter.frames)
        fuzz::fail("fuzz_capture", "the summary counts " + std::to_string(a.summary().frames) +
                                       " frames, the sink saw " + std::to_string(counter.frames));
    return 0;
}
