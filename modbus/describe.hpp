#pragma once
// Field-by-field description of frames and PDUs, in the specification's words, for people (text) and
// machines (JSON) alike: every field once, with its raw value and what it means (the Wireshark
// hf_register_info idea, as data rather than code).

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::modbus {

struct Field {
    std::string name;      // spec's word, snake_case: "starting_address", "byte_count"
    nlohmann::json value;  // number, string, bool or array of numbers
    std::string meaning;   // human explanation; empty when the value says it all
};

std::vector<Field> describe_pdu(const Pdu& pdu);
class JsonWriter;
// The PDU's fields after the function code, as one JSON object of name → value (the values of describe_pdu,
// in its order), written straight to a stream: what JSON lines carry for every frame.
void write_pdu_fields(const Pdu& pdu, JsonWriter& out);
// The framing's own fields (unit id, MBAP, CRC/LRC), not the PDU's.
std::vector<Field> describe_framing(const Frame& frame);

std::string hex_bytes(std::span<const std::uint8_t> bytes);  // "11 03 00 60"
std::string hex16(std::uint16_t v);                          // "0x0060"
std::string hex8(std::uint8_t v);                            // "0x03"

}  // namespace mbscope::modbus
