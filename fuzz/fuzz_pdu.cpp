// PDU decoders, both directions, and the length predictor the deframers rely on. Properties: decoders never
// read outside the span (ASan); a PDU decoded without a violation encodes back to the same bytes; the
// predicted length of a PDU that decoded cleanly, when the predictor knows it, is its length.
#include <fuzzer/FuzzedDataProvider.h>

#include <vector>

#include "fuzz/fuzz_support.hpp"
#include "modbus/pdu.hpp"

using namespace mbscope;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const auto direction = (data[0] & 1) ? modbus::Direction::Response : modbus::Direction::Request;
    // An exact-size copy: a read past the PDU is a heap overflow, not a read of the next input byte.
    const std::vector<std::uint8_t> pdu(data + 1, data + size);
    auto decoded = modbus::decode_pdu(pdu, direction);
    if (!decoded) return 0;
    if (decoded->violations.empty()) {
        if (modbus::encode_pdu(*decoded) != pdu)
            fuzz::fail("fuzz_pdu", "a clean PDU does not encode back to its bytes");
        const auto predicted = modbus::predict_pdu_length(pdu, direction);
        // FC8 sub-function 00 echoes any number of bytes and 15 hex answers with a table: the predictor's
        // 5 is a first candidate there, which the deframers confirm with the CRC.
        const bool variable =
            pdu[0] == 8 && pdu.size() >= 3 && pdu[1] == 0 && (pdu[2] == 0 || pdu[2] == 0x15);
        if (predicted.kind == modbus::LengthPrediction::Kind::Known && !variable &&
            predicted.length != pdu.size())
            fuzz::fail("fuzz_pdu", "a clean PDU of " + std::to_string(pdu.size()) +
                                       " bytes is predicted as " + std::to_string(predicted.length));
    }
    (void)modbus::decode_pdu(pdu, direction == modbus::Direction::Request ? modbus::Direction::Response
                                                                          : modbus::Direction::Request);
    return 0;
}
