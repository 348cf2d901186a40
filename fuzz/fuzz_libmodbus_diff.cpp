// Differential: the codec and libmodbus (Debian's libmodbus, an implementation nobody here wrote) read the
// same Modbus/TCP request ADU. They must agree on whether it is one complete, valid request, and the
// reference slave serving the generic profile (every address, every value 0) must answer it with the same
// PDU as libmodbus's modbus_reply over an all-zero mapping of the whole address space.
// Documented differences (fuzz/README.md, each shown by tests/fuzz/libmodbus_difference_test.cpp) are
// excluded by name below; anything else that differs aborts with both answers.
#include <algorithm>
#include <string>
#include <vector>

#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"
#include "fuzz/libmodbus_peer.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/pdu.hpp"
#include "slave/device.hpp"

using namespace mbscope;

namespace {

// Functions both serve from a register map. libmodbus answers FC7, FC8, FC11, FC12, FC20, FC21, FC24 and
// FC43 with exception 01 (it does not implement them) and FC17 with its own identification: difference 4.
bool compared_function(std::uint8_t fc) {
    return (fc >= 1 && fc <= 6) || fc == 15 || fc == 16 || fc == 22 || fc == 23;
}

const modbus::Profile& generic_profile() {
    static const modbus::Profile* p = [] {
        for (const auto& profile : fuzz::bundled_profiles())
            if (profile.id == "modbus") return &profile;
        fuzz::fail("fuzz_libmodbus_diff", "the generic profile 'modbus' is not bundled");
    }();
    return *p;
}

}  // namespace

// The bundled profiles are loaded before libFuzzer's clock starts: in the first input that needed them (5-7 s
// on a busy 2-core machine) they passed the smoke's 10 s timeout for one run, a false hang saved as a
// regression.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)generic_profile();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    constexpr const char* target = "fuzz_libmodbus_diff";
    if (size < 8 || size > 260) return 0;
    const std::vector<std::uint8_t> adu(data, data + size);
    const auto frame = modbus::decode_tcp(adu);
    // Difference 1: libmodbus takes a request's length from its function code and byte count, never from
    // the MBAP length field, and difference 2: it ignores the protocol identifier. Only ADUs whose header
    // is consistent are compared; the codec flags the others (tcp.length_mismatch, tcp.protocol_id_nonzero).
    if (!frame || frame->protocol_id() != 0 || !frame->findings.empty()) return 0;
    const auto pdu = frame->pdu();
    if (pdu.empty() || !compared_function(pdu[0])) return 0;
    const auto request = modbus::decode_request(pdu);
    // Difference 3: libmodbus executes FC15 whose byte count is larger than the quantity needs; the
    // specification answers exception 03 (AP §6.11), as the reference slave does.
    if (request && pdu[0] == 15 && request->violations.contains(modbus::FindingCode::PduByteCountMismatch))
        return 0;

    const auto theirs = fuzz::libmodbus_serve(adu);
    const bool whole = theirs.received == static_cast<int>(size);
    const bool their_normal = theirs.reply.size() > 7 && (theirs.reply[7] & 0x80) == 0;
    // The codec's verdict: a request whose structure it recovers and that breaks no rule of the
    // specification (quantities, byte counts, coil values, diagnostics data).
    const bool valid =
        request && std::none_of(request->violations.begin(), request->violations.end(),
                                [](auto c) { return modbus::info(c).severity == modbus::Severity::Error; });
    if (!valid) {
        // Invalid for the codec: libmodbus may wait for more bytes, refuse it or answer an exception, but
        // must not serve it.
        if (whole && their_normal)
            fuzz::fail(target, "libmodbus serves a request the codec finds invalid: " +
                                   modbus::hex_bytes(adu) + " -> " + modbus::hex_bytes(theirs.reply));
        return 0;
    }
    if (!whole)
        fuzz::fail(target, "the codec decodes a complete, valid request of " + std::to_string(size) +
                               " bytes, libmodbus read " + std::to_string(theirs.received) + ": " +
                               modbus::hex_bytes(adu));

    slave::Device device(generic_profile(), frame->unit_id());
    const auto ours = device.handle({pdu, false}).pdu;
    const std::span<const std::uint8_t> their_pdu =
        theirs.reply.size() > 7 ? std::span<const std::uint8_t>(theirs.reply).subspan(7)
                                : std::span<const std::uint8_t>{};
    if (!std::equal(ours.begin(), ours.end(), their_pdu.begin(), their_pdu.end()))
        fuzz::fail(target, "different answers to " + modbus::hex_bytes(adu) +
                               "\n  reference slave: " + modbus::hex_bytes(ours) +
                               "\n  libmodbus:       " + modbus::hex_bytes(their_pdu));
    return 0;
}
