#pragma once
// What the two targets of the reference slave's request handling share (fuzz_slave: a sequence of requests
// per input; fuzz_slave_request: one): the request an input's shape byte asks for, and one exchange with the
// slave judged by the shared exchange oracle (conformance/oracle.hpp), with the registers compared around it
// so that a refused request that changed them is caught. A violated rule aborts with its id, the rule's
// source and what was expected and observed; with MBSCOPE_FUZZ_TRACE set every exchange is printed.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "conformance/oracle.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "slave/device.hpp"
#include "slave/responder.hpp"

namespace mbscope::fuzz {

// The ADU for one request. `shape` low bits 0: `body` as the input holds it (checksum, MBAP header and all);
// else `body` is the PDU (at most 253 bytes of it), framed correctly for a unit: a served one when bit 2 is
// set (bits 3-7 choose which), else the unit id bits 3-7 spell (0: broadcast), over Modbus/TCP 0xFF when
// bit 7 is set. The result has the request's exact size.
inline std::vector<std::uint8_t> slave_request(modbus::Framing framing, std::uint8_t shape,
                                               const std::vector<slave::Device*>& units, std::uint16_t tid,
                                               std::vector<std::uint8_t> body) {
    if ((shape & 0x03) == 0) return body;
    std::uint8_t unit =
        (shape & 0x04) ? units[(shape >> 3) % units.size()]->unit() : static_cast<std::uint8_t>(shape >> 3);
    if (framing == modbus::Framing::Tcp && (shape & 0x80)) unit = 0xFF;
    const std::span<const std::uint8_t> pdu(body.data(), std::min<std::size_t>(body.size(), 253));
    return modbus::encode_adu(framing, tid, unit, pdu);
}

// None: the clean slave must satisfy every rule. One for the process (a fault set seeds a random generator).
inline slave::FaultSet no_faults;

// The reference slave without faults serving `units` on one framing, and the oracle that judges it.
class SlaveHarness {
  public:
    // `target` and `profiles` name the target and the profiles served in a violation's message.
    SlaveHarness(const char* target, const std::vector<slave::Device*>& units, modbus::Framing framing,
                 bool ip_network, std::string profiles)
        : target_(target),
          units_(units),
          framing_(framing),
          profiles_(std::move(profiles)),
          responder_(units, no_faults, framing, ip_network),
          oracle_(framing, oracle_units(units), ip_network) {
        for (const auto* d : units)
            answering_.push_back(d->unit());
    }

    // Hands `adu` to the slave when it decodes as a frame (the server never hands other bytes to a unit) and
    // judges the reply; false when it is no frame.
    bool exchange(std::vector<std::uint8_t> adu) {
        const auto frame = modbus::decode_adu(framing_, adu);
        if (!frame) return false;
        const std::uint64_t before = modifications();
        modbus::transport::Exchange ex;
        ex.sent = std::move(adu);  // the frame holds its own copy
        ex.received = responder_.respond(*frame);
        if (!ex.received.empty()) {
            if (auto reply = modbus::decode_adu(framing_, ex.received); reply)
                ex.response = std::move(*reply);
        }
        const bool changed = modifications() != before;
        static const bool trace = std::getenv("MBSCOPE_FUZZ_TRACE") != nullptr;
        if (trace)
            std::fprintf(stderr, "unit %s  %s -> %s\n", std::to_string(frame->unit_id()).c_str(),
                         modbus::hex_bytes(ex.sent).c_str(),
                         ex.received.empty() ? "(silence)" : modbus::hex_bytes(ex.received).c_str());
        for (const auto& v : oracle_.judge(ex, changed))
            fail(target_, conformance::to_string(v) + "\n  profile " + profiles_ + "\n  request " +
                              modbus::hex_bytes(ex.sent) + "\n  reply   " + modbus::hex_bytes(ex.received));
        // A write to a device's address register moves it (MK ENDER; the slave's tests prove when): the
        // oracle follows, as it cannot see a broadcast write execute.
        for (std::size_t i = 0; i < units_.size(); ++i)
            if (units_[i]->unit() != answering_[i]) {
                oracle_.moved(i, units_[i]->unit());
                answering_[i] = units_[i]->unit();
            }
        return true;
    }

  private:
    static std::vector<conformance::ExchangeOracle::Unit> oracle_units(
        const std::vector<slave::Device*>& units) {
        std::vector<conformance::ExchangeOracle::Unit> out;
        for (auto* d : units)
            out.push_back({d->unit(), &d->profile()});
        return out;
    }
    std::uint64_t modifications() const {
        std::uint64_t sum = 0;
        for (auto* d : units_)
            sum += d->image().modifications();
        return sum;
    }

    const char* target_;
    const std::vector<slave::Device*>& units_;
    modbus::Framing framing_;
    std::string profiles_;
    slave::Responder responder_;
    conformance::ExchangeOracle oracle_;
    std::vector<std::uint8_t> answering_;  // each unit's address as the oracle knows it
};

}  // namespace mbscope::fuzz
