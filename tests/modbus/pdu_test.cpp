// The Modbus Application Protocol V1.1b3 examples of every function code (AP §6.x), decoded field by field
// and re-encoded byte for byte, plus the specification's limits reported as named violations.
#include <gtest/gtest.h>

#include "modbus/pdu.hpp"
#include "test_util.hpp"

namespace test_modbus_pdu_test {

using mbscope::test::hex;
namespace mb = mbscope::modbus;
using FC = mb::FindingCode;

struct SpecCase {
    const char* source;
    const char* pdu;
    mb::Direction direction;
    mb::PduBody body;
};

mb::Pdu as_pdu(const SpecCase& c) {
    mb::Pdu p;
    p.function_raw = hex(c.pdu)[0];
    p.direction = c.direction;
    p.body = c.body;
    return p;
}

using D = mb::Direction;

// Built statement by statement: one large initializer list of variants makes GCC 12 use >20 GB.
std::vector<SpecCase> make_spec_cases() {
    std::vector<SpecCase> c;
    c.push_back({"AP §6.1 request", "01 00 13 00 13", D::Request, mb::ReadRequest{19, 19}});
    c.push_back(
        {"AP §6.1 response", "01 03 CD 6B 05", D::Response, mb::ReadBitsResponse{3, {0xCD, 0x6B, 0x05}}});
    c.push_back({"AP §6.2 request", "02 00 C4 00 16", D::Request, mb::ReadRequest{196, 22}});
    c.push_back(
        {"AP §6.2 response", "02 03 AC DB 35", D::Response, mb::ReadBitsResponse{3, {0xAC, 0xDB, 0x35}}});
    c.push_back({"AP §6.3 request", "03 00 6B 00 03", D::Request, mb::ReadRequest{107, 3}});
    c.push_back({"AP §6.3 response", "03 06 02 2B 00 00 00 64", D::Response,
                 mb::ReadRegistersResponse{6, {555, 0, 100}}});
    c.push_back({"AP §6.4 request", "04 00 08 00 01", D::Request, mb::ReadRequest{8, 1}});
    c.push_back({"AP §6.4 response", "04 02 00 0A", D::Response, mb::ReadRegistersResponse{2, {10}}});
    c.push_back({"AP §6.5 request", "05 00 AC FF 00", D::Request, mb::WriteSingle{172, 0xFF00}});
    c.push_back({"AP §6.5 response", "05 00 AC FF 00", D::Response, mb::WriteSingle{172, 0xFF00}});
    c.push_back({"AP §6.6 request", "06 00 01 00 03", D::Request, mb::WriteSingle{1, 3}});
    c.push_back({"AP §6.6 response", "06 00 01 00 03", D::Response, mb::WriteSingle{1, 3}});
    c.push_back({"AP §6.7 request", "07", D::Request, mb::NoData{}});
    c.push_back({"AP §6.7 response", "07 6D", D::Response, mb::ReadExceptionStatusResponse{0x6D}});
    c.push_back({"AP §6.8 request", "08 00 00 A5 37", D::Request, mb::Diagnostics{0, {0xA5, 0x37}}});
    c.push_back({"AP §6.8 response", "08 00 00 A5 37", D::Response, mb::Diagnostics{0, {0xA5, 0x37}}});
    c.push_back({"AP §6.9 request", "0B", D::Request, mb::NoData{}});
    c.push_back(
        {"AP §6.9 response", "0B FF FF 01 08", D::Response, mb::CommEventCounterResponse{0xFFFF, 0x0108}});
    c.push_back({"AP §6.10 request", "0C", D::Request, mb::NoData{}});
    c.push_back({"AP §6.10 response", "0C 08 00 00 01 08 01 21 20 00", D::Response,
                 mb::CommEventLogResponse{8, 0x0000, 0x0108, 0x0121, {0x20, 0x00}}});
    c.push_back({"AP §6.11 request", "0F 00 13 00 0A 02 CD 01", D::Request,
                 mb::WriteMultipleCoilsRequest{19, 10, 2, {0xCD, 0x01}}});
    c.push_back({"AP §6.11 response", "0F 00 13 00 0A", D::Response, mb::WriteMultipleResponse{19, 10}});
    c.push_back({"AP §6.12 request", "10 00 01 00 02 04 00 0A 01 02", D::Request,
                 mb::WriteMultipleRegistersRequest{1, 2, 4, {0x000A, 0x0102}}});
    c.push_back({"AP §6.12 response", "10 00 01 00 02", D::Response, mb::WriteMultipleResponse{1, 2}});
    c.push_back({"AP §6.13 request", "11", D::Request, mb::NoData{}});
    c.push_back({"AP §6.14 request", "14 0E 06 00 04 00 01 00 02 06 00 03 00 09 00 02", D::Request,
                 mb::FileRecordRequest{0x0E, {{6, 4, 1, 2, {}}, {6, 3, 9, 2, {}}}}});
    c.push_back({"AP §6.14 response", "14 0C 05 06 0D FE 00 20 05 06 33 CD 00 40", D::Response,
                 mb::ReadFileRecordResponse{0x0C, {{5, 6, {0x0DFE, 0x0020}}, {5, 6, {0x33CD, 0x0040}}}}});
    c.push_back({"AP §6.15 request", "15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D", D::Request,
                 mb::FileRecordRequest{0x0D, {{6, 4, 7, 3, {0x06AF, 0x04BE, 0x100D}}}}});
    c.push_back({"AP §6.15 response", "15 0D 06 00 04 00 07 00 03 06 AF 04 BE 10 0D", D::Response,
                 mb::FileRecordRequest{0x0D, {{6, 4, 7, 3, {0x06AF, 0x04BE, 0x100D}}}}});
    c.push_back(
        {"AP §6.16 request", "16 00 04 00 F2 00 25", D::Request, mb::MaskWriteRegister{4, 0x00F2, 0x0025}});
    c.push_back(
        {"AP §6.16 response", "16 00 04 00 F2 00 25", D::Response, mb::MaskWriteRegister{4, 0x00F2, 0x0025}});
    c.push_back({"AP §6.17 request", "17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF", D::Request,
                 mb::ReadWriteMultipleRequest{3, 6, 14, 3, 6, {0x00FF, 0x00FF, 0x00FF}}});
    c.push_back({"AP §6.17 response", "17 0C 00 FE 0A CD 00 01 00 03 00 0D 00 FF", D::Response,
                 mb::ReadRegistersResponse{12, {0x00FE, 0x0ACD, 0x0001, 0x0003, 0x000D, 0x00FF}}});
    c.push_back({"AP §6.18 request", "18 04 DE", D::Request, mb::ReadFifoQueueRequest{0x04DE}});
    c.push_back({"AP §6.18 response", "18 00 06 00 02 01 B8 12 84", D::Response,
                 mb::ReadFifoQueueResponse{6, 2, {0x01B8, 0x1284}}});
    c.push_back({"AP §6.21 request", "2B 0E 01 00", D::Request, mb::ReadDeviceIdRequest{1, 0}});
    c.push_back({"AP §6.21 response layout", "2B 0E 01 01 00 00 02 00 03 41 42 43 01 02 58 31", D::Response,
                 mb::ReadDeviceIdResponse{1, 1, 0, 0, 2, {{0, {'A', 'B', 'C'}}, {1, {'X', '1'}}}}});
    c.push_back({"AP §6.19 CANopen", "2B 0D 01 02 03", D::Request, mb::MeiTransport{0x0D, {1, 2, 3}}});
    c.push_back({"AP §7 exception", "81 02", D::Response, mb::ExceptionResponse{2}});
    c.push_back({"AP §7 exception 0B", "83 0B", D::Response, mb::ExceptionResponse{0x0B}});
    return c;
}

const std::vector<SpecCase> spec_cases = make_spec_cases();

class SpecExample : public ::testing::TestWithParam<SpecCase> {};

TEST_P(SpecExample, Decodes) {
    const auto& c = GetParam();
    SCOPED_TRACE(c.source);
    auto r = mb::decode_pdu(hex(c.pdu), c.direction);
    ASSERT_TRUE(r.has_value()) << mb::to_string(r.error().code) << " at " << r.error().offset;
    EXPECT_EQ(r.value(), as_pdu(c));
    EXPECT_TRUE(r->violations.empty()) << mb::to_string(*r->violations.begin());
}

TEST_P(SpecExample, Encodes) {
    const auto& c = GetParam();
    SCOPED_TRACE(c.source);
    EXPECT_EQ(mb::encode_pdu(as_pdu(c)), hex(c.pdu));
}

INSTANTIATE_TEST_SUITE_P(ApplicationProtocol, SpecExample, ::testing::ValuesIn(spec_cases),
                         [](const auto& info) { return "Case" + std::to_string(info.index); });

// ---- limits are violations, not failures: the frame still decodes and says which rule it breaks

struct ViolationCase {
    const char* source;
    const char* pdu;
    mb::Direction direction;
    FC expected;
};

class SpecViolation : public ::testing::TestWithParam<ViolationCase> {};

TEST_P(SpecViolation, DecodesAndNamesTheRule) {
    const auto& c = GetParam();
    SCOPED_TRACE(c.source);
    auto r = mb::decode_pdu(hex(c.pdu), c.direction);
    ASSERT_TRUE(r.has_value()) << mb::to_string(r.error().code);
    EXPECT_TRUE(r->violations.contains(c.expected)) << "expected " << mb::to_string(c.expected);
}

INSTANTIATE_TEST_SUITE_P(
    Limits, SpecViolation,
    ::testing::Values(
        ViolationCase{"AP §6.1 quantity 0", "01 00 00 00 00", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.1 quantity 2001", "01 00 00 07 D1", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.2 quantity 2001", "02 00 00 07 D1", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.3 quantity 126", "03 00 00 00 7E", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.4 quantity 0", "04 00 00 00 00", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.3 address + quantity past 65535", "03 FF FF 00 02", D::Request,
                      FC::PduAddressOverflow},
        ViolationCase{"AP §6.5 value 1234", "05 00 54 12 34", D::Request, FC::PduCoilValueInvalid},
        ViolationCase{"AP §6.11 quantity 1969", "0F 00 00 07 B1 F7", D::Request, FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.11 byte count vs quantity", "0F 00 13 00 0A 01 CD", D::Request,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §6.11 byte count vs bytes", "0F 00 13 00 0A 03 CD 01", D::Request,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §6.11 padding bits", "0F 00 13 00 0A 02 CD FF", D::Request, FC::PduPaddingBitsSet},
        ViolationCase{"AP §6.12 quantity 124", "10 00 00 00 7C 02 00 01", D::Request,
                      FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.12 byte count 3", "10 00 01 00 02 03 00 0A 01", D::Request,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §6.17 write quantity 122", "17 00 00 00 01 00 00 00 7A 02 00 01", D::Request,
                      FC::PduQuantityOutOfRange},
        ViolationCase{"AP §6.3 response odd byte count", "03 03 00 01 02", D::Response,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §6.3 response byte count vs bytes", "03 04 00 01", D::Response,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §6.1 response byte count vs bytes", "01 02 01", D::Response,
                      FC::PduByteCountMismatch},
        ViolationCase{"AP §7 exception code 0x0C", "83 0C", D::Response, FC::PduUnknownExceptionCode},
        ViolationCase{"AP §5.1 user-defined 65", "41 01 02", D::Request, FC::PduUnknownFunction},
        ViolationCase{"AP §6.8.1 reserved sub-function", "08 00 05 00 00", D::Request,
                      FC::PduReservedSubFunction},
        ViolationCase{"AP §6.8.1 restart with five data bytes", "08 00 01 00 00 D9 08 25", D::Response,
                      FC::PduDiagnosticDataLength},
        ViolationCase{"AP §6.8.1 counter request without data", "08 00 0B", D::Request,
                      FC::PduDiagnosticDataLength},
        ViolationCase{"AP §6.14 reference type 7", "14 07 07 00 04 00 01 00 02", D::Request,
                      FC::PduFileRecordInvalid},
        ViolationCase{"AP §6.14 record number 10000", "14 07 06 00 04 27 10 00 02", D::Request,
                      FC::PduFileRecordInvalid},
        ViolationCase{"AP §6.14 response reading no record", "14 00", D::Response, FC::PduByteCountMismatch},
        ViolationCase{"AP §6.18 fifo count 32", "18 00 42 00 20", D::Response, FC::PduFifoCountTooLarge},
        ViolationCase{"AP §6.19 MEI type 0x0F", "2B 0F 00", D::Request, FC::PduMeiTypeUnknown},
        ViolationCase{"AP §6.21 read device id code 5", "2B 0E 05 00", D::Request,
                      FC::PduDeviceIdCodeInvalid}),
    [](const auto& info) { return "Case" + std::to_string(info.index); });

// ---- structural errors: precise code and offset

TEST(PduDecode, EmptyIsAnError) {
    auto r = mb::decode_request({});
    ASSERT_FALSE(r.has_value());
    EXPECT_EQ(r.error().code, mb::ErrorCode::EmptyPdu);
}

TEST(PduDecode, TruncatedReadRequestNamesTheOffset) {
    auto r = mb::decode_request(hex("03 00 6B 00"));
    ASSERT_FALSE(r.has_value());
    EXPECT_EQ(r.error().code, mb::ErrorCode::Truncated);
    EXPECT_EQ(r.error().offset, 3u);
}

TEST(PduDecode, TrailingBytesAfterFixedRequest) {
    auto r = mb::decode_request(hex("03 00 6B 00 03 FF"));
    ASSERT_FALSE(r.has_value());
    EXPECT_EQ(r.error().code, mb::ErrorCode::TrailingBytes);
    EXPECT_EQ(r.error().offset, 5u);
}

// A read reply cut short states its quantity in its byte count: the missing bytes are the byte count's
// mismatch, not a quantity of 0 as well. A byte count of 0, or above 125 registers, is the quantity's.
TEST(PduDecode, AReadReplyCutShortIsAByteCountMismatchOnly) {
    auto cut = mb::decode_response(hex("03 06"));  // the 11-byte reply of a log cut after five bytes
    ASSERT_TRUE(cut.has_value());
    EXPECT_TRUE(cut->violations.contains(mb::FindingCode::PduByteCountMismatch));
    EXPECT_FALSE(cut->violations.contains(mb::FindingCode::PduQuantityOutOfRange));
    for (const char* wrong : {"03 00", "04 FC"}) {
        auto r = mb::decode_response(hex(wrong));
        ASSERT_TRUE(r.has_value()) << wrong;
        EXPECT_TRUE(r->violations.contains(mb::FindingCode::PduQuantityOutOfRange)) << wrong;
    }
}

TEST(PduDecode, TruncatedDeviceIdObject) {
    auto r = mb::decode_response(hex("2B 0E 01 01 00 00 01 00 05 41 42"));
    ASSERT_FALSE(r.has_value());
    EXPECT_EQ(r.error().code, mb::ErrorCode::Truncated);
}

TEST(PduDecode, UnknownFunctionKeepsRawByteAndData) {
    auto r = mb::decode_request(hex("5A 00 01 02"));  // FC 90: Schneider UMAS, reserved in AP §5.1
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->function_raw, 0x5A);
    EXPECT_EQ(std::get<mb::RawPdu>(r->body).data, (std::vector<std::uint8_t>{0x00, 0x01, 0x02}));
}

TEST(PduDecode, ExceptionKeepsTheFunctionByte) {
    auto r = mb::decode_response(hex("90 03"));
    ASSERT_TRUE(r.has_value());
    EXPECT_TRUE(r->is_exception());
    EXPECT_EQ(r->function_code(), 0x10);
    EXPECT_EQ(std::get<mb::ExceptionResponse>(r->body).exception_code, 3);
}

TEST(PduDecode, UnknownDirectionPrefersTheCleanReading) {
    auto req = mb::decode_pdu(hex("03 00 6B 00 03"), D::Unknown);
    ASSERT_TRUE(req.has_value());
    EXPECT_EQ(req->direction, D::Request);
    auto rsp = mb::decode_pdu(hex("03 06 02 2B 00 00 00 64"), D::Unknown);
    ASSERT_TRUE(rsp.has_value());
    EXPECT_EQ(rsp->direction, D::Response);
}

// ---- length prediction (used by the RTU deframer without timing)

TEST(PduLength, RequestsAndResponses) {
    using K = mb::LengthPrediction::Kind;
    auto p = [](const char* h, D d) { return mb::predict_pdu_length(hex(h), d); };
    EXPECT_EQ(p("03", D::Request).length, 5u);
    EXPECT_EQ(p("03 06", D::Response).length, 8u);
    EXPECT_EQ(p("10 00 01 00 02 04", D::Request).length, 10u);
    EXPECT_EQ(p("10 00 01", D::Request).kind, K::NeedMore);
    EXPECT_EQ(p("83", D::Response).length, 2u);
    EXPECT_EQ(p("18 00 06", D::Response).length, 9u);
    EXPECT_EQ(p("17 00 03 00 06 00 0E 00 03 06", D::Request).length, 16u);
    EXPECT_EQ(p("2B 0E 01 01 00 00 02 00 03 41 42 43 01 02", D::Response).length, 16u);
    EXPECT_EQ(p("41", D::Request).kind, K::Unknown);
    EXPECT_EQ(p("", D::Request).kind, K::NeedMore);
}

}  // namespace test_modbus_pdu_test
