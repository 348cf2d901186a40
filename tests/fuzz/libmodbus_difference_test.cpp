// Where the codec and the reference slave knowingly differ from libmodbus 3.1.6 (Debian) reading the same
// Modbus/TCP request: the differences the differential fuzz target (fuzz/fuzz_libmodbus_diff.cpp) excludes by
// name, each shown here with bytes, so an exclusion that stops being true fails a test.
#include <gtest/gtest.h>

#include "fuzz/libmodbus_peer.hpp"
#include "modbus/adu.hpp"
#include "slave/responder.hpp"
#include "slave/slave_test_support.hpp"

namespace test_fuzz_libmodbus_difference_test {

namespace {

namespace mb = mbscope::modbus;
using mbscope::fuzz::libmodbus_serve;
using mbscope::slave::test::bytes;
using mbscope::slave::test::hex;

// The reference slave's reply (ADU) with the generic profile, as the server would send it.
std::vector<std::uint8_t> reference_reply(const std::vector<std::uint8_t>& adu) {
    static mbscope::slave::FaultSet none;
    mbscope::slave::Device device(mbscope::slave::test::profile("modbus"), 1, &none);
    mbscope::slave::Responder responder({&device}, none, mb::Framing::Tcp, true);
    const auto frame = mb::decode_tcp(adu);
    if (!frame) return {};
    return responder.respond(*frame);
}

std::string pdu_of(const std::vector<std::uint8_t>& adu) {
    return adu.size() > 7 ? hex(std::vector<std::uint8_t>(adu.begin() + 7, adu.end())) : "";
}

// Difference 1: libmodbus sizes a request by its function code and byte count and never reads the MBAP
// length field; the codec trusts the length (TCP §3.1.3) and flags a header that disagrees with the PDU.
TEST(LibmodbusDifference, MbapLengthIsIgnoredByLibmodbus) {
    const auto adu = bytes("00 01 00 00 00 09 01 03 00 00 00 01");  // length 9, six bytes follow
    const auto theirs = libmodbus_serve(adu);
    EXPECT_EQ(theirs.received, 12);
    EXPECT_EQ(pdu_of(theirs.reply), "03 02 00 00");
    const auto ours = mb::decode_tcp(adu);
    EXPECT_TRUE(!ours || !ours->findings.empty()) << "the codec accepts an inconsistent MBAP length";
}

// Difference 2: libmodbus answers a header whose protocol identifier is not 0; the specification reserves
// other values (TCP §3.1.3) and the reference slave discards such a frame.
TEST(LibmodbusDifference, ProtocolIdentifierIsIgnoredByLibmodbus) {
    const auto adu = bytes("00 01 00 07 00 06 01 03 00 00 00 01");
    EXPECT_EQ(pdu_of(libmodbus_serve(adu).reply), "03 02 00 00");
    EXPECT_TRUE(reference_reply(adu).empty());
}

// Difference 3: libmodbus executes FC15 whose byte count is larger than the quantity needs (it checks only
// that it is not smaller); the specification answers exception 03 (AP §6.11), as the reference slave does.
// For FC16 both refuse it.
TEST(LibmodbusDifference, ByteCountLargerThanTheQuantityIsExecutedByLibmodbus) {
    const auto coils = bytes("00 01 00 00 00 0A 01 0F 00 00 00 0A 03 FF 03 00");
    EXPECT_EQ(pdu_of(libmodbus_serve(coils).reply), "0F 00 00 00 0A");
    EXPECT_EQ(pdu_of(reference_reply(coils)), "8F 03");
    const auto registers = bytes("00 01 00 00 00 0B 01 10 00 00 00 01 04 00 0A 00 0B");
    EXPECT_EQ(pdu_of(libmodbus_serve(registers).reply), "90 03");
    EXPECT_EQ(pdu_of(reference_reply(registers)), "90 03");
    // Too small a byte count: both refuse.
    const auto short_count = bytes("00 01 00 00 00 08 01 0F 00 00 00 0A 01 FF");
    EXPECT_EQ(pdu_of(libmodbus_serve(short_count).reply), "8F 03");
    EXPECT_EQ(pdu_of(reference_reply(short_count)), "8F 03");
}

// Difference 4: libmodbus's server implements FC1-6, 15, 16, 17, 22 and 23 only; diagnostics (FC8) and device
// identification (FC43) get exception 01, where the generic profile serves them, and FC17 carries
// libmodbus's own identification.
TEST(LibmodbusDifference, FunctionsLibmodbusDoesNotServe) {
    const auto echo = bytes("00 01 00 00 00 06 01 08 00 00 A5 37");
    EXPECT_EQ(pdu_of(libmodbus_serve(echo).reply), "88 01");
    EXPECT_EQ(pdu_of(reference_reply(echo)), "08 00 00 A5 37");
    const auto identification = bytes("00 02 00 00 00 05 01 2B 0E 01 00");
    EXPECT_EQ(pdu_of(libmodbus_serve(identification).reply), "AB 01");
    EXPECT_EQ(pdu_of(reference_reply(identification)).substr(0, 8), "2B 0E 01");
}

// And where they agree, which is what the fuzz target checks everywhere else: the same read, the same
// refusal of a quantity past the specification's limit.
TEST(LibmodbusDifference, AgreeOnPlainRequests) {
    for (const char* request :
         {"00 01 00 00 00 06 01 03 00 10 00 02", "00 01 00 00 00 06 01 03 00 00 00 7E",
          "00 01 00 00 00 06 01 05 00 01 12 34", "00 01 00 00 00 06 01 01 FF FF 00 02"}) {
        SCOPED_TRACE(request);
        const auto adu = bytes(request);
        EXPECT_EQ(pdu_of(libmodbus_serve(adu).reply), pdu_of(reference_reply(adu)));
    }
}

}  // namespace

}  // namespace test_fuzz_libmodbus_difference_test
