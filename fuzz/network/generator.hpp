#pragma once
// Requests for the network fuzzer, made with knowledge of the grammar and of the device's map: function
// codes the profile supports (and the ones it does not), addresses at and around the ends of each table,
// quantities 0, 1, max, max+1 and 0xFFFF, byte counts that disagree with quantities, values at the ends of
// each point's range and enumeration, envelopes with bad checksums, MBAP lengths 0, 1, 255 and beyond, and
// frames split into pieces. Function codes that have broken other Modbus stacks (23, 20, 21, 43, 8) are
// drawn more often than their share.
//
// Feedback: a probe whose exchange showed something not seen before (a new response class: outcome,
// exception code, reply size, latency band, rule) is kept, and later probes are often mutations of kept
// ones: bytes flipped, 16-bit fields pushed to boundaries, bytes inserted or cut, envelopes and splits
// changed. Everything is drawn from one seeded generator, so a run is repeatable.

#include <cstdint>
#include <random>
#include <vector>

#include "fuzz/network/probe.hpp"
#include "modbus/profile.hpp"

namespace mbscope::fuzz::network {

struct GeneratorOptions {
    modbus::Framing framing = modbus::Framing::Tcp;
    bool serial_line = false;  // a real serial line (rtu:/ascii:), where splits are pauses on the wire
    std::chrono::nanoseconds t1_5{0};
    std::uint8_t unit = 1;
    bool read_only = false;
    std::uint64_t seed = 1;
    bool datagrams = false;  // Modbus/UDP: a request is one datagram, and a piece of one is no request
};

class Generator {
  public:
    Generator(const modbus::Profile& profile, GeneratorOptions options);

    // The next probe: made from the grammar, or a mutation of a kept one. Never a request that may write
    // under --read-only, never one that changes how the device talks (FC8 sub-functions 03, 04).
    Probe next();
    // A probe that showed a new response class: future probes mutate it.
    void keep(const Probe& probe);
    std::size_t kept() const noexcept { return pool_.size(); }

    // Whether `pdu` may be sent at all (the --read-only and device-safety filters above).
    bool allowed(const std::vector<std::uint8_t>& pdu) const;

  private:
    Probe generate();
    Probe mutate(const Probe& base);
    std::vector<std::uint8_t> read_pdu(std::uint8_t fc);
    std::vector<std::uint8_t> write_pdu(std::uint8_t fc);
    std::vector<std::uint8_t> diagnostics_pdu();
    std::vector<std::uint8_t> file_record_pdu(bool write);
    std::vector<std::uint8_t> device_id_pdu();
    std::vector<std::uint8_t> read_write_pdu();
    void envelope(Probe& p);

    std::uint16_t address_in(modbus::Table t, bool write = false);
    std::uint16_t quantity_for(std::uint8_t fc, bool write_part = false);
    std::uint16_t value_for(modbus::Table t, std::uint16_t address);
    std::uint8_t unit();
    bool chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
    std::uint32_t below(std::uint32_t n) { return n ? static_cast<std::uint32_t>(rng_() % n) : 0; }

    const modbus::Profile& profile_;
    GeneratorOptions options_;
    std::mt19937_64 rng_;
    std::vector<std::uint8_t> functions_;  // the profile's supported codes
    std::vector<Probe> pool_;
    std::vector<const modbus::Point*> writable_registers_, writable_coils_;
};

}  // namespace mbscope::fuzz::network
