#pragma once
// Faults the reference slave plants on purpose, so the conformance runner and the fuzzers can be shown to
// catch what they claim to catch. Each is named as on the command line (--fault NAME[=ARG]); each is
// deterministic for a given --seed: a fault with a rate draws from the slave's own seeded generator, in the
// order requests arrive.

#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/framing.hpp"
#include "modbus/result.hpp"

namespace mbscope::slave {

enum class Fault : std::uint8_t {
    BadCrc,             // RTU: the response's CRC is wrong
    BadLrc,             // ASCII: the response's LRC is wrong
    WrongByteCount,     // read responses: byte count one more than the data
    ShortResponse,      // the response PDU loses its last byte
    ExtraBytes,         // two bytes appended to the response PDU
    WrongUnit,          // the response carries another unit id
    WrongFunction,      // the response carries another function code
    WrongTid,           // TCP: the response carries another transaction id
    BadProtocolId,      // TCP: the response's protocol id is 1
    AnyProtocolId,      // TCP: requests with a protocol id other than 0 are served as Modbus ones
    ReplyToBroadcast,   // broadcasts (unit 0) are answered
    IgnoreMaxQuantity,  // the profile's quantity limits are not enforced (the specification's still are)
    WrongException,     // every exception response carries ARG instead of the right code
    ExceptionForValid,  // valid requests are answered with exception 04 (at RATE, default every one)
    NoReply,            // requests are not answered at RATE
    SlowReply,          // responses are sent ARG ms late
    GapInsideFrame,     // RTU: a silence of ARG character times in the middle of the response
    WordSwap,           // 32-bit points are served and written with their two registers swapped
    OffByOneAddress,    // every request is served at address + 1
    StuckValue,         // the register at ARG never changes (writes acknowledged, process frozen); repeatable
    DropWrite,          // writes are acknowledged and not kept
    AcceptOutOfRange,   // values outside the map's ranges and enumerations are accepted
    NoEcho,             // FC5, FC6 and FC8/00 answers do not echo the request
    CrashAfter,         // after ARG answered requests the slave never answers again
    DuplicateReply,     // every response is sent twice, back to back
    WrongQuantity,      // reads answer one item more than asked, FC15/FC16 acknowledge one more than written
};
inline constexpr std::size_t fault_count = static_cast<std::size_t>(Fault::WrongQuantity) + 1;

std::string_view to_string(Fault f) noexcept;
// One line per fault: "bad-crc  RTU: the response's CRC is wrong", for --help and the README.
std::string fault_help();

struct FaultSpec {
    Fault fault;
    double arg = 0;  // rate (0..1], milliseconds, characters, code, address or count, as the fault needs
};
// "no-reply=0.25", "slow-reply=300", "bad-crc". Errors name the text and what was expected.
modbus::Result<FaultSpec, std::string> parse_fault(std::string_view text);
// Every --fault of a command line, each parsed. A fault planted at an address (stuck-value) may be given once
// per address, each one acting; any other acts once, with one argument (one reply delay, one exception code,
// one rate), so a second instance is refused: planted, it would be announced and not act.
modbus::Result<std::vector<FaultSpec>, std::string> parse_faults(const std::vector<std::string>& texts);

// Why `f` cannot show on a transport of `framing` (bad-crc over Modbus/TCP, whose frames carry no CRC),
// nothing when it can. A fault planted where it has no effect would make a run that catches nothing look
// like a clean device: the slave refuses it.
std::optional<std::string> fault_without_effect(Fault f, modbus::Framing framing);

class FaultSet {
  public:
    FaultSet() = default;
    // `specs` as parse_faults accepts them; of a fault given twice anyway, the last argument holds, except
    // stuck-value's addresses, which all hold.
    FaultSet(const std::vector<FaultSpec>& specs, std::uint64_t seed);

    bool enabled(Fault f) const noexcept { return on_[static_cast<std::size_t>(f)]; }
    double arg(Fault f) const noexcept { return arg_[static_cast<std::size_t>(f)]; }
    // Enabled and, for a fault with a rate, this draw hits. Draws only when the fault has a rate below 1, so
    // a run's sequence of outcomes depends on the seed and the order of requests only.
    bool fires(Fault f);
    bool any() const noexcept;
    // The registers stuck-value freezes, in the order given.
    const std::vector<std::uint16_t>& stuck_addresses() const noexcept { return stuck_; }

  private:
    std::array<bool, fault_count> on_{};
    std::array<double, fault_count> arg_{};
    std::vector<std::uint16_t> stuck_;
    std::mt19937_64 rng_{0};
};

}  // namespace mbscope::slave
