// How long is the PDU that starts here? Asked by the deframers at every byte position of a stream in which
// they have not found a frame yet (garbage, a frame with a bad CRC, a dump that starts mid-frame), so the
// answer for each function code is looked up in a table made at compile time rather than found by a switch
// and lambdas: the lookup has no stack frame for AddressSanitizer to poison and few comparisons for a
// fuzzing build to trace, the two costs that made this the hottest function of the RTU deframer target.
#include <array>

#include "modbus/pdu.hpp"

namespace mbscope::modbus {
namespace {

using K = LengthPrediction::Kind;

// The shape of a function code's PDU in one direction.
struct LengthRule {
    enum class Form : std::uint8_t {
        Unknown,  // not a function code whose length this side can tell
        Fixed,    // always `length` bytes
        Counted,  // `length` bytes besides the ones counted by the byte at `count_at`
        Walked,   // found by walking the PDU (FIFO queue response, device identification)
    };
    Form form = Form::Unknown;
    std::uint8_t length = 0;
    std::uint8_t count_at = 0;
};
using LengthRules = std::array<LengthRule, 256>;

constexpr LengthRule fixed(std::uint8_t length) {
    return {LengthRule::Form::Fixed, length, 0};
}
constexpr LengthRule counted(std::uint8_t count_at, std::uint8_t besides) {
    return {LengthRule::Form::Counted, besides, count_at};
}
constexpr LengthRule walked{LengthRule::Form::Walked, 0, 0};

constexpr LengthRules request_rules() {
    LengthRules r{};
    for (std::uint8_t fc : {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x08})
        r[fc] = fixed(5);  // fc address value
    for (std::uint8_t fc : {0x07, 0x0B, 0x0C, 0x11})
        r[fc] = fixed(1);               // fc alone
    r[0x0F] = r[0x10] = counted(5, 6);  // fc address quantity count data
    r[0x14] = r[0x15] = counted(1, 2);  // fc count records
    r[0x16] = fixed(7);                 // fc address and-mask or-mask
    r[0x17] = counted(9, 10);           // fc read address quantity write address quantity count data
    r[0x18] = fixed(3);                 // fc FIFO address
    r[0x2B] = walked;                   // only the device identification request has a known length
    return r;
}

constexpr LengthRules response_rules() {
    LengthRules r{};
    for (std::uint8_t fc : {0x01, 0x02, 0x03, 0x04, 0x0C, 0x11, 0x14, 0x15, 0x17})
        r[fc] = counted(1, 2);  // fc count data
    for (std::uint8_t fc : {0x05, 0x06, 0x08, 0x0B, 0x0F, 0x10})
        r[fc] = fixed(5);  // fc and two words
    r[0x07] = fixed(2);    // fc status
    r[0x16] = fixed(7);    // the request echoed
    r[0x18] = walked;      // fc byte count (two bytes) FIFO count values
    r[0x2B] = walked;      // fc MEI code conformity more next count objects
    for (std::size_t fc = exception_bit; fc < r.size(); ++fc)
        r[fc] = fixed(2);  // an exception: fc code
    return r;
}

constexpr LengthRules request_length_rules = request_rules();
constexpr LengthRules response_length_rules = response_rules();

// The FIFO queue response: its byte count is two bytes wide.
LengthPrediction fifo_response(std::span<const std::uint8_t> p) noexcept {
    if (p.size() < 3) return {K::NeedMore, 3};
    return {K::Known, 3 + static_cast<std::size_t>((p[1] << 8) | p[2])};
}

// Encapsulated interface: only Read Device Identification has a length this side can tell.
LengthPrediction device_identification(std::span<const std::uint8_t> p, Direction direction) noexcept {
    if (p.size() < 2) return {K::NeedMore, 2};
    if (p[1] != mei_read_device_identification) return {K::Unknown, 0};
    if (direction == Direction::Request) return {K::Known, 4};  // fc MEI code object
    std::size_t pos = 7;                                        // fc MEI code conformity more next count
    if (p.size() < pos) return {K::NeedMore, pos};
    const unsigned objects = p[6];
    for (unsigned i = 0; i < objects; ++i) {  // each object: id length value
        if (p.size() < pos + 2) return {K::NeedMore, pos + 2};
        pos += 2 + p[pos + 1];
        if (pos > max_pdu_length) return {K::Unknown, 0};
    }
    return {K::Known, pos};
}

}  // namespace

LengthPrediction predict_pdu_length(std::span<const std::uint8_t> p, Direction direction) noexcept {
    if (p.empty()) return {K::NeedMore, 1};
    if (direction == Direction::Unknown) return {K::Unknown, 0};
    const LengthRule rule =
        (direction == Direction::Request ? request_length_rules : response_length_rules)[p[0]];
    switch (rule.form) {
        case LengthRule::Form::Fixed:
            return {K::Known, rule.length};
        case LengthRule::Form::Counted:
            if (p.size() <= rule.count_at) return {K::NeedMore, rule.count_at + 1u};
            return {K::Known, static_cast<std::size_t>(rule.length) + p[rule.count_at]};
        case LengthRule::Form::Walked:
            return p[0] == 0x18 ? fifo_response(p) : device_identification(p, direction);
        case LengthRule::Form::Unknown:
            break;
    }
    return {K::Unknown, 0};
}

}  // namespace mbscope::modbus
