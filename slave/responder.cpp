#include "slave/responder.hpp"

#include <cstdio>
#include <string>

#include "modbus/adu.hpp"

namespace mbscope::slave {

using modbus::Framing;

Responder::Responder(std::vector<Device*> units, FaultSet& faults, Framing framing, bool ip_network,
                     std::function<bool()> save)
    : units_(std::move(units)),
      faults_(faults),
      framing_(framing),
      ip_network_(ip_network),
      save_(std::move(save)) {}

Device* Responder::route(std::uint8_t unit) const {
    for (Device* d : units_)
        if (d->unit() == unit && !d->off_line()) return d;
    // Modbus/TCP: a device reached by its IP address answers unit 0xFF (TCP §4.4.1.2); Walchem answers
    // every non-zero unit id (002:213-215).
    if (ip_network_ && units_.size() == 1 &&
        (unit == 0xFF || units_.front()->profile().line.any_unit_answered))
        return units_.front();
    return nullptr;
}

std::vector<std::uint8_t> Responder::respond(const modbus::Frame& f) {
    last_copies_ = 1;
    for (Device* d : units_)
        if (!d->off_line()) d->count_frame(f.checksum_ok);
    if (!f.checksum_ok) return {};  // SL §2.5.1.2: a frame with a bad CRC/LRC is not answered
    // Not Modbus (TCP §3.1.3): discarded. Stacks that never look at the field serve it all the same.
    if (f.framing == Framing::Tcp && f.protocol_id() != 0 && !faults_.fires(Fault::AnyProtocolId)) return {};
    const std::uint16_t tid = f.framing == Framing::Tcp ? f.transaction_id() : std::uint16_t{0};
    auto pdu = answer(f.unit_id(), f.pdu());
    if (pdu.empty()) return {};
    auto adu = frame(f.unit_id(), tid, pdu);
    // One write holding the reply twice: a transmit buffer sent again (MK-MS-01 wants exactly one reply).
    if (faults_.fires(Fault::DuplicateReply)) {
        const auto once = adu;  // a vector cannot insert a range of itself
        adu.insert(adu.end(), once.begin(), once.end());
        last_copies_ = 2;
    }
    return adu;
}

// The response PDU, or nothing when the request is not answered.
std::vector<std::uint8_t> Responder::answer(std::uint8_t unit, std::span<const std::uint8_t> request) {
    if (faults_.enabled(Fault::CrashAfter) &&
        answered_ >= static_cast<std::uint64_t>(faults_.arg(Fault::CrashAfter)))
        return {};
    std::vector<std::uint8_t> pdu;
    if (unit == 0) {  // broadcast: every unit on the line executes it
        std::vector<Device*> wrote;
        for (Device* d : units_) {
            // Address 0 configured: communication disabled (MK 000:220); off the line: deaf to it.
            if (d->unit() == 0 || d->off_line()) continue;
            if (save_) d->image().begin_undo();
            Reply r = d->handle({request, true});
            if (r.wrote)
                wrote.push_back(d);
            else if (save_)
                d->image().keep();
            if (pdu.empty()) pdu = std::move(r.pdu);  // only with reply-to-broadcast
        }
        // No acknowledgement to take back, but the same promise: a write that could not be saved is not
        // kept (a master reading a broadcast's registers back would see a value a restart loses).
        if (!wrote.empty() && save_) {
            const bool saved = save_();
            for (Device* d : wrote) {
                if (saved) {
                    d->image().keep();
                } else {
                    d->image().undo();
                    d->take_back_write();
                }
            }
        }
    } else {
        Device* d = route(unit);
        if (!d || d->unit() == 0) return {};
        if (save_) d->image().begin_undo();
        Reply r = d->handle({request, false});
        // An acknowledgement promises the write is kept: when it cannot be saved, the device says it failed
        // (exception 04) instead, and takes the write back (a refused request changes nothing, AP §7).
        if (r.wrote && !r.pdu.empty() && save_ && !save_()) {
            d->image().undo();
            r.pdu = d->refuse_taken_back_write(request[0]);
        } else if (save_) {
            d->image().keep();
        }
        pdu = std::move(r.pdu);
    }
    if (pdu.empty()) return {};
    if (faults_.fires(Fault::NoReply)) return {};
    ++answered_;
    if (faults_.fires(Fault::WrongFunction))
        pdu[0] = static_cast<std::uint8_t>((((pdu[0] & 0x7F) + 1) & 0x7F) | (pdu[0] & 0x80));
    if (faults_.fires(Fault::ShortResponse) && pdu.size() > 1) pdu.pop_back();
    if (faults_.fires(Fault::ExtraBytes)) pdu.insert(pdu.end(), {0xDE, 0xAD});
    return pdu;
}

std::vector<std::uint8_t> Responder::frame(std::uint8_t request_unit, std::uint16_t transaction_id,
                                           const std::vector<std::uint8_t>& pdu) {
    const auto unit =
        static_cast<std::uint8_t>(faults_.fires(Fault::WrongUnit) ? request_unit + 1 : request_unit);
    switch (framing_) {
        case Framing::Tcp: {
            const auto tid =
                static_cast<std::uint16_t>(transaction_id + (faults_.fires(Fault::WrongTid) ? 1 : 0));
            return modbus::encode_tcp(tid, unit, pdu, faults_.fires(Fault::BadProtocolId) ? 1 : 0);
        }
        case Framing::Rtu: {
            auto adu = modbus::encode_rtu(unit, pdu);
            if (faults_.fires(Fault::BadCrc)) {
                adu[adu.size() - 1] ^= 0xFF;
                adu[adu.size() - 2] ^= 0xFF;
            }
            return adu;
        }
        case Framing::Ascii: {
            std::string text = modbus::encode_ascii(unit, pdu);
            if (faults_.fires(Fault::BadLrc) && text.size() >= 5) {
                // The two hex digits before CR LF are the LRC: replace them with LRC + 1.
                const unsigned lrc =
                    static_cast<unsigned>(std::stoul(text.substr(text.size() - 4, 2), nullptr, 16));
                char hex[3];
                std::snprintf(hex, sizeof hex, "%02X", (lrc + 1) & 0xFF);
                text[text.size() - 4] = hex[0];
                text[text.size() - 3] = hex[1];
            }
            return {text.begin(), text.end()};
        }
    }
    return {};
}

}  // namespace mbscope::slave
