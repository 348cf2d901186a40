#include "fuzz/network/probe.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "modbus/adu.hpp"

namespace mbscope::fuzz::network {

std::string_view to_string(Envelope e) noexcept {
    switch (e) {
        case Envelope::Valid:
            return "valid";
        case Envelope::BadChecksum:
            return "bad-checksum";
        case Envelope::MbapLength:
            return "mbap-length";
        case Envelope::ProtocolId:
            return "protocol-id";
        case Envelope::LowerCaseHex:
            return "lower-case-hex";
    }
    return "?";
}

std::vector<std::uint8_t> Wire::joined() const {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts)
        out.insert(out.end(), p.begin(), p.end());
    return out;
}

Wire frame_probe(const Probe& probe, modbus::Framing framing, std::uint16_t transaction_id) {
    std::vector<std::uint8_t> adu;
    switch (framing) {
        case modbus::Framing::Rtu:
            adu = modbus::encode_rtu(probe.unit, probe.pdu);
            if (probe.envelope == Envelope::BadChecksum) adu.back() ^= 0x01;
            break;
        case modbus::Framing::Ascii: {
            std::string text = modbus::encode_ascii(probe.unit, probe.pdu);
            if (probe.envelope == Envelope::BadChecksum && text.size() >= 5) {
                // The LRC is the two hex digits before CR LF: add one to it.
                const std::size_t at = text.size() - 4;
                const unsigned lrc = static_cast<unsigned>(std::stoul(text.substr(at, 2), nullptr, 16));
                char digits[3];
                std::snprintf(digits, sizeof digits, "%02X", (lrc + 1) & 0xFF);
                text.replace(at, 2, digits);
            }
            if (probe.envelope == Envelope::LowerCaseHex)
                std::transform(text.begin(), text.end(), text.begin(), [](char c) {
                    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
                });
            adu.assign(text.begin(), text.end());
            break;
        }
        case modbus::Framing::Tcp:
            adu = modbus::encode_tcp(transaction_id, probe.unit, probe.pdu,
                                     probe.envelope == Envelope::ProtocolId ? probe.envelope_value : 0);
            if (probe.envelope == Envelope::MbapLength) {
                adu[4] = static_cast<std::uint8_t>(probe.envelope_value >> 8);
                adu[5] = static_cast<std::uint8_t>(probe.envelope_value);
            }
            break;
    }
    Wire w;
    w.pause = probe.pause;
    const std::size_t pieces = std::clamp<std::size_t>(probe.split, 1, std::max<std::size_t>(1, adu.size()));
    std::size_t at = 0;
    for (std::size_t i = 0; i < pieces; ++i) {
        const std::size_t end = i + 1 == pieces ? adu.size() : adu.size() * (i + 1) / pieces;
        w.parts.emplace_back(adu.begin() + static_cast<std::ptrdiff_t>(at),
                             adu.begin() + static_cast<std::ptrdiff_t>(end));
        at = end;
    }
    return w;
}

}  // namespace mbscope::fuzz::network
