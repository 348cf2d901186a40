#pragma once
// Decoding of one frame given as hex or text, and its rendering as text or JSON (shared by `mbscope frame`
// and its tests).

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::cli {

struct DecodedFrame {
    modbus::Framing framing = modbus::Framing::Rtu;
    std::vector<std::uint8_t> wire;      // the bytes as given
    std::optional<modbus::Frame> frame;  // set when the ADU structure was recovered
    std::optional<modbus::Pdu> pdu;      // set when the PDU structure was recovered
    std::string direction_note;          // e.g. "request (identical to its echo response)"
    std::string error;                   // why the ADU or PDU could not be decoded
    std::string source;                  // optional label (file line, manual reference)

    bool clean() const;  // decoded, checksum ok, no rule broken
};

// Parse "11 03 00 60", "1103 0060", "0x11,0x03" or, for ASCII, the frame text (":1103...\r\n", with the
// CR LF added when missing and written as literal \r\n). Returns nullopt and sets error on bad input.
std::optional<std::vector<std::uint8_t>> parse_hex(const std::vector<std::string>& tokens,
                                                   std::string& error);

DecodedFrame decode_frame(modbus::Framing framing, std::vector<std::uint8_t> wire,
                          modbus::Direction direction);

std::string render_text(const DecodedFrame& d);
nlohmann::json render_json(const DecodedFrame& d);

}  // namespace mbscope::cli
