#include "slave/faults.hpp"

#include <charconv>
#include <cmath>

namespace mbscope::slave {

namespace {

enum class ArgKind : std::uint8_t { Rate, RequiredRate, Milliseconds, Characters, Code, Address, Count };

struct FaultInfo {
    Fault fault;
    std::string_view name;
    ArgKind arg;
    std::string_view help;
};

constexpr FaultInfo faults[] = {
    {Fault::BadCrc, "bad-crc", ArgKind::Rate, "RTU: the response's CRC is wrong"},
    {Fault::BadLrc, "bad-lrc", ArgKind::Rate, "ASCII: the response's LRC is wrong"},
    {Fault::WrongByteCount, "wrong-byte-count", ArgKind::Rate,
     "read responses: byte count one more than the data"},
    {Fault::ShortResponse, "short-response", ArgKind::Rate, "the response PDU loses its last byte"},
    {Fault::ExtraBytes, "extra-bytes", ArgKind::Rate, "two bytes (0xDE 0xAD) appended to the response PDU"},
    {Fault::WrongUnit, "wrong-unit", ArgKind::Rate, "the response carries unit id + 1"},
    {Fault::WrongFunction, "wrong-function", ArgKind::Rate, "the response carries function code + 1"},
    {Fault::WrongTid, "wrong-tid", ArgKind::Rate, "TCP: the response carries transaction id + 1"},
    {Fault::BadProtocolId, "bad-protocol-id", ArgKind::Rate, "TCP: the response's protocol id is 1"},
    {Fault::AnyProtocolId, "any-protocol-id", ArgKind::Rate,
     "TCP: requests with a protocol id other than 0 are served as Modbus ones"},
    {Fault::ReplyToBroadcast, "reply-to-broadcast", ArgKind::Rate,
     "broadcasts (unit 0) are executed and answered"},
    {Fault::IgnoreMaxQuantity, "ignore-max-quantity", ArgKind::Rate,
     "the profile's quantity limits are not enforced (the specification's still are)"},
    {Fault::WrongException, "wrong-exception", ArgKind::Code, "=CODE: every exception response carries CODE"},
    {Fault::ExceptionForValid, "exception-for-valid", ArgKind::Rate,
     "valid requests are answered with exception 04"},
    {Fault::NoReply, "no-reply", ArgKind::RequiredRate,
     "=RATE: that share of requests is not answered (0..1)"},
    {Fault::SlowReply, "slow-reply", ArgKind::Milliseconds,
     "=MS: every response is sent MS milliseconds late"},
    {Fault::GapInsideFrame, "gap-inside-frame", ArgKind::Characters,
     "=CHARS: RTU/ASCII: a silence of CHARS character times in the middle of each response"},
    {Fault::WordSwap, "word-swap", ArgKind::Rate,
     "32-bit points, and 32-bit values the map gives as low and high words, are served and written with "
     "their two registers swapped"},
    {Fault::OffByOneAddress, "off-by-one-address", ArgKind::Rate, "every request is served at address + 1"},
    {Fault::StuckValue, "stuck-value", ArgKind::Address,
     "=ADDR: the register at ADDR never changes (writes acknowledged, process frozen); once per register"},
    {Fault::DropWrite, "drop-write", ArgKind::Rate, "writes are acknowledged and not kept"},
    {Fault::AcceptOutOfRange, "accept-out-of-range", ArgKind::Rate,
     "values outside the map's ranges and enumerations are accepted"},
    {Fault::NoEcho, "no-echo", ArgKind::Rate,
     "FC5, FC6 and FC8/00 answers carry the request's value inverted"},
    {Fault::CrashAfter, "crash-after", ArgKind::Count,
     "=N: after N answered requests the slave never answers again"},
    {Fault::DuplicateReply, "duplicate-reply", ArgKind::Rate,
     "every response is sent twice, back to back (the same bytes; over UDP two datagrams)"},
    {Fault::WrongQuantity, "wrong-quantity", ArgKind::Rate,
     "reads answer one register (one fewer at 125) or one byte of bits more than asked, the byte count "
     "to match; FC15 and FC16 acknowledge a quantity one more than written"},
};

const FaultInfo& info(Fault f) noexcept {
    return faults[static_cast<std::size_t>(f)];
}

// Instances at different addresses freeze different registers, all at once; every other argument (a rate,
// a delay, a code, a count) is one setting of the slave, which two instances would contend for.
bool repeatable(const FaultInfo& f) noexcept {
    return f.arg == ArgKind::Address;
}

// Why `next` cannot be planted beside `planted` (the specs accepted before it, `texts` their command-line
// text), nothing when it can.
std::optional<std::string> second_instance(const std::vector<FaultSpec>& planted,
                                           const std::vector<std::string>& texts, const FaultSpec& next,
                                           const std::string& next_text) {
    for (std::size_t i = 0; i < planted.size(); ++i) {
        if (planted[i].fault != next.fault) continue;
        const FaultInfo& f = info(next.fault);
        if (!repeatable(f))
            return "--fault " + next_text + ": " + std::string(f.name) + " is already planted (--fault " +
                   texts[i] + ") and acts once, with one argument; only stuck-value takes several";
        if (planted[i].arg == next.arg)
            return "--fault " + next_text + ": that register is already stuck (--fault " + texts[i] + ")";
    }
    return std::nullopt;
}

}  // namespace

std::string_view to_string(Fault f) noexcept {
    return info(f).name;
}

std::optional<std::string> fault_without_effect(Fault f, modbus::Framing framing) {
    using modbus::Framing;
    switch (f) {
        case Fault::BadCrc:
            if (framing != Framing::Rtu) return "it changes the CRC, which only RTU frames carry";
            break;
        case Fault::BadLrc:
            if (framing != Framing::Ascii) return "it changes the LRC, which only ASCII frames carry";
            break;
        case Fault::WrongTid:
            if (framing != Framing::Tcp)
                return "it changes the transaction id, which only MBAP headers carry";
            break;
        case Fault::BadProtocolId:
        case Fault::AnyProtocolId:
            if (framing != Framing::Tcp) return "it changes the protocol id, which only MBAP headers carry";
            break;
        case Fault::GapInsideFrame:
            if (framing == Framing::Tcp)
                return "it opens a silence inside a frame, which only RTU and ASCII framing delimit by time";
            break;
        default:
            break;
    }
    return std::nullopt;
}

std::string fault_help() {
    std::string out;
    for (const auto& f : faults) {
        std::string name(f.name);
        name.resize(22, ' ');
        out += "  " + name + std::string(f.help) + "\n";
    }
    out += "  Faults without =ARG take an optional =RATE (0..1, default 1: every response).\n";
    return out;
}

modbus::Result<FaultSpec, std::string> parse_fault(std::string_view text) {
    const auto eq = text.find('=');
    const std::string_view name = text.substr(0, eq);
    const std::string_view value = eq == std::string_view::npos ? std::string_view{} : text.substr(eq + 1);
    for (const auto& f : faults) {
        if (f.name != name) continue;
        FaultSpec spec{f.fault, 1.0};
        const bool needs_arg = f.arg != ArgKind::Rate;
        if (value.empty()) {
            if (needs_arg)
                return "--fault " + std::string(text) + ": needs " +
                       std::string(f.help.substr(0, f.help.find(':')));
            return spec;
        }
        double v = 0;
        auto [p, ec] = std::from_chars(value.data(), value.data() + value.size(), v);
        // from_chars reads "nan" and "inf": no rate, delay or count, and NaN passes every comparison below.
        if (ec != std::errc{} || p != value.data() + value.size() || !std::isfinite(v))
            return "--fault " + std::string(text) + ": '" + std::string(value) + "' is not a number";
        const bool is_rate = f.arg == ArgKind::Rate || f.arg == ArgKind::RequiredRate;
        if (is_rate && (v <= 0 || v > 1)) return "--fault " + std::string(text) + ": rate must be in (0, 1]";
        if (f.arg == ArgKind::Code && (v < 1 || v > 255 || v != static_cast<int>(v)))
            return "--fault " + std::string(text) + ": exception code must be 1..255";
        if (f.arg == ArgKind::Address && (v < 0 || v > 65535 || v != static_cast<int>(v)))
            return "--fault " + std::string(text) + ": address must be 0..65535";
        if ((f.arg == ArgKind::Milliseconds || f.arg == ArgKind::Characters || f.arg == ArgKind::Count) &&
            v < 0)
            return "--fault " + std::string(text) + ": must not be negative";
        // Upper bounds keep each argument's conversion (to milliseconds, a duration, a request count)
        // defined: slow-reply=1e300 or crash-after=1e300 overflowed it. An hour of delay and 100,000
        // character times are past any master's timeout; a count is a whole number.
        if (f.arg == ArgKind::Milliseconds && v > 3'600'000)
            return "--fault " + std::string(text) + ": at most 3600000 ms (an hour)";
        if (f.arg == ArgKind::Characters && v > 100'000)
            return "--fault " + std::string(text) + ": at most 100000 character times";
        if (f.arg == ArgKind::Count && (v > 1e15 || v != static_cast<double>(static_cast<std::uint64_t>(v))))
            return "--fault " + std::string(text) + ": a whole number of requests up to 1e15";
        spec.arg = v;
        return spec;
    }
    return "--fault " + std::string(text) + ": unknown fault '" + std::string(name) +
           "' (see mbscope slave --help)";
}

modbus::Result<std::vector<FaultSpec>, std::string> parse_faults(const std::vector<std::string>& texts) {
    std::vector<FaultSpec> specs;
    for (const auto& text : texts) {
        auto spec = parse_fault(text);
        if (!spec) return spec.error();
        if (auto why = second_instance(specs, texts, *spec, text)) return *why;
        specs.push_back(*spec);
    }
    return specs;
}

FaultSet::FaultSet(const std::vector<FaultSpec>& specs, std::uint64_t seed) : rng_(seed) {
    for (const auto& s : specs) {
        on_[static_cast<std::size_t>(s.fault)] = true;
        arg_[static_cast<std::size_t>(s.fault)] = s.arg;
        if (s.fault == Fault::StuckValue) stuck_.push_back(static_cast<std::uint16_t>(s.arg));
    }
}

bool FaultSet::fires(Fault f) {
    if (!enabled(f)) return false;
    const FaultInfo& i = info(f);
    if (i.arg != ArgKind::Rate && i.arg != ArgKind::RequiredRate) return true;
    const double rate = arg(f);
    if (rate >= 1.0) return true;
    // 53 random bits as a fraction: the same sequence on every standard library, unlike the distributions.
    return static_cast<double>(rng_() >> 11) * 0x1.0p-53 < rate;
}

bool FaultSet::any() const noexcept {
    for (bool b : on_)
        if (b) return true;
    return false;
}

}  // namespace mbscope::slave
