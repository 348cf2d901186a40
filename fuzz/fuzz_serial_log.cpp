// The serial capture readers (raw RTU and ASCII dumps, the text format, jpnevulator and socat logs) and the
// analyzer behind them, on bytes given to the reader as a file (an in-memory file, so the readers run
// exactly as `mbscope decode` runs them). The format, the line's character format and framing, and
// whether a bundled profile describes every device (so that a device told other line settings makes the
// line deframed again from there) are drawn from the last bytes. Properties: no crash, no leak, no undefined
// behaviour; a damaged log is an input error, not an abort.
#include <fuzzer/FuzzedDataProvider.h>
#include <sys/mman.h>
#include <unistd.h>

#include <ostream>
#include <streambuf>
#include <string>

#include "analyzer/analyzer.hpp"
#include "analyzer/serial_input.hpp"
#include "analyzer/sinks.hpp"
#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"

using namespace mbscope;

// The bundled profiles are loaded before libFuzzer's clock starts: in the first input that needed them (5-7 s
// on a busy 2-core machine) they passed the smoke's 10 s timeout for one run, a false hang saved as a
// regression.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    // Names, not enumerators: a format this build does not know falls back to detection.
    static const char* const formats[] = {"auto", "rtu", "ascii", "text", "jpnevulator", "socat"};
    const auto format = analyzer::parse_input_format(formats[in.ConsumeIntegralInRange<std::size_t>(0, 5)])
                            .value_or(analyzer::InputFormat::Auto);
    analyzer::AnalyzerOptions options;
    options.serial_line.baud = in.PickValueInArray<std::uint32_t>({1200, 9600, 19200, 115200});
    options.serial_line.parity = in.ConsumeBool() ? modbus::Parity::Even : modbus::Parity::None;
    if (in.ConsumeBool()) {
        const auto& profiles = fuzz::bundled_profiles();
        auto semantics = std::make_shared<analyzer::Semantics>();
        const auto& p = profiles[in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1)];
        semantics->add({}, std::make_shared<const modbus::Profile>(p));
        options.semantics = std::move(semantics);
    }
    // none: told from the line's bytes
    static const std::optional<modbus::Framing> framings[] = {std::nullopt, modbus::Framing::Rtu,
                                                              modbus::Framing::Ascii};
    options.serial_framing = framings[in.ConsumeIntegralInRange<std::size_t>(0, 2)];
    const auto log = in.ConsumeRemainingBytes<std::uint8_t>();

    const int fd = ::memfd_create("fuzz_serial_log", MFD_CLOEXEC);
    if (fd < 0) fuzz::fail("fuzz_serial_log", "memfd_create failed");
    std::size_t written = 0;
    while (written < log.size()) {
        const ssize_t n = ::write(fd, log.data() + written, log.size() - written);
        if (n <= 0) fuzz::fail("fuzz_serial_log", "write to the in-memory file failed");
        written += static_cast<std::size_t>(n);
    }
    fuzz::NullBuffer null_buffer;
    std::ostream nowhere(&null_buffer);
    analyzer::JsonSink sink(nowhere, true);
    analyzer::Analyzer a(options, sink);
    analyzer::read_input(a, "/proc/self/fd/" + std::to_string(fd), format);
    a.finish();
    ::close(fd);
    return 0;
}
