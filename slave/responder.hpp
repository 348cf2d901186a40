#pragma once
// The slave's answer to one frame, without any I/O: unit routing, broadcast, the devices behind the line and
// the planted faults that change a reply's bytes. The server adds what needs a clock or a socket (t3.5,
// slow-reply, gap-inside-frame, send queues); the fuzz target drives a Responder directly, one exact-size
// frame at a time.

#include <cstdint>
#include <functional>
#include <vector>

#include "modbus/frame.hpp"
#include "slave/device.hpp"
#include "slave/faults.hpp"

namespace mbscope::slave {

class Responder {
  public:
    // `ip_network`: Modbus/TCP reached by an IP address (tcp://, udp://), where a lone unit also answers
    // unit 0xFF (TCP §4.4.1.2) and a device whose manual says so answers every unit id. `save` persists an
    // acknowledged write; when it fails the device takes the write back and answers exception 04 instead
    // of acknowledging.
    Responder(std::vector<Device*> units, FaultSet& faults, modbus::Framing framing, bool ip_network,
              std::function<bool()> save = {});

    // The reply ADU to a frame seen on the line, framed like the request; empty when it is not answered
    // (bad CRC/LRC, foreign protocol id, broadcast, a unit not served, a device in listen-only mode).
    std::vector<std::uint8_t> respond(const modbus::Frame& frame);
    // How many copies of one ADU the last respond() returned back to back: 2 when duplicate-reply fired, else
    // 1. A stream sends them in one write; a datagram transport sends each copy as a datagram of its own,
    // as a device sending its reply twice does (one datagram holding both is no Modbus/UDP reply at all).
    std::size_t last_copies() const noexcept { return last_copies_; }

    Device* route(std::uint8_t unit) const;
    // The line's framing changed (a device told to talk ASCII instead of RTU, MK-CFG-01): replies follow.
    void set_framing(modbus::Framing framing) noexcept { framing_ = framing; }
    const std::vector<Device*>& units() const noexcept { return units_; }

  private:
    std::vector<std::uint8_t> answer(std::uint8_t unit, std::span<const std::uint8_t> pdu);
    std::vector<std::uint8_t> frame(std::uint8_t unit, std::uint16_t transaction_id,
                                    const std::vector<std::uint8_t>& pdu);

    std::vector<Device*> units_;
    FaultSet& faults_;
    modbus::Framing framing_;
    bool ip_network_;
    std::function<bool()> save_;
    std::uint64_t answered_ = 0;  // replies sent, for crash-after
    std::size_t last_copies_ = 1;
};

}  // namespace mbscope::slave
