#pragma once
// Whether a normal response answers the request it is paired with, as far as the two PDUs tell (AP §6): a
// read returns as many items as it asked for, a write's reply echoes what it wrote. One judgement for the
// analyzer's pairing, the conformance rules and the fuzzing oracle; each names the breach in its own terms.

#include <optional>
#include <string>

#include "modbus/pdu.hpp"

namespace mbscope::modbus {

struct ReplyMisfit {
    enum class Kind : std::uint8_t {
        DataSize,  // a read's data is not as long as its quantity asks (FC1-4, FC23)
        Padding,   // FC1/FC2: bits of the last byte past the quantity asked are set
        Echo,  // FC5, 6, 22, FC8's echoing sub-functions: not the request; FC15/16: another start or quantity
    };
    Kind kind;
    std::string expected;  // what the request asks for, in words: "3 registers", "an echo of the request"
    const char* source;    // the specification's section: "AP §6.3"
    // DataSize: the data bytes the request asks for and those the response carries.
    std::size_t expected_bytes = 0;
    std::size_t got_bytes = 0;
    // Echo: the fields the response got wrong, each with what it carries and what was due: "its value is
    // 927, not 926" (for a reader who would otherwise compare the two frames byte by byte).
    std::string differs = {};
};

// The first way `response`, a normal (non-exception) response of the request's function, fails to answer
// `request`; nothing when it fits or when the function's reply says nothing checkable about the request
// (FC7, 11, 12, 17, 20, 21, 24, 43). FC8 echoes its sub-function always and its data where the
// specification says the reply is an echo (sub-functions 00, 01, 03, 0A, 14); the others return a value.
std::optional<ReplyMisfit> reply_misfit(const Pdu& request, const Pdu& response);

// Whether the bytes of a reply PDU of the request's function, damaged or not, are shaped as its reply: a
// read's byte count is the one the request needs or counts the bytes that follow it (a reply that miscounts
// its data still counts its own bytes), a multiple write's reply is five bytes or names the request's address
// and quantity (AP §6.1-6.4, §6.11, §6.12, §6.17). Other functions' replies always are. Where a frame cannot
// say which way it went, one that decodes cleanly as a request and as a reply only with violations is the
// device's malformed reply when it is so shaped, the master's next request (to other registers) when not.
bool reply_claims_to_answer(const Pdu& request, std::span<const std::uint8_t> reply_pdu) noexcept;

}  // namespace mbscope::modbus
