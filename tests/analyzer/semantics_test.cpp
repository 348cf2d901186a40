// Device semantics in the analyzer, on the fixture profile tests/fixtures/profiles/test-device.json
// (FC3/4/6/16, at most 15 registers; 17 decimal places 0..4, 18 flow scaled by 17 (read-only, m3/h),
// 23 filter 0.0..25.0 s): each profile.* finding triggered, and silent on clean traffic.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "analyzer/analyzer.hpp"
#include "analyzer/packet_parser.hpp"
#include "analyzer/serial_input.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_semantics_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

using mbscope::test::Collect;

namespace {

struct Harness {
    Collect sink;
    std::unique_ptr<an::Analyzer> analyzer;
    std::uint32_t seq[2] = {1, 1};
    std::uint64_t number = 0;
    mb::Timestamp t = 1s;
    std::uint16_t tid = 0;
    std::uint8_t unit = 1;  // of the exchanges to come
    // The fixture profile for every device, or a bundled one mapped to one unit (--map UNIT=ID), or one of
    // the profiles in `dir`.
    explicit Harness(const std::string& id = "test-device", std::optional<int> mapped_unit = std::nullopt,
                     const std::string& dir = {}) {
        mb::storage::ProfileStore store(
            {!dir.empty() ? dir
                          : std::string(MBSCOPE_SOURCE_DIR) +
                                (id == "test-device" ? "/tests/fixtures/profiles" : "/profiles")});
        auto p = store.load(id);
        EXPECT_TRUE(p.has_value());
        an::AnalyzerOptions o;
        o.semantics = std::make_shared<an::Semantics>();
        o.semantics->add({std::nullopt, mapped_unit},
                         std::make_shared<const mb::Profile>(std::move(p.value())));
        analyzer = std::make_unique<an::Analyzer>(o, sink);
    }
    void send(bool to_server, const mb::Pdu& pdu) {
        auto payload = mb::encode_tcp(tid, unit, mb::encode_pdu(pdu));
        auto bytes = mbscope::test::packet(to_server, seq[to_server ? 0 : 1], payload);
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
        an::Packet p;
        p.number = ++number;
        p.time = t += 1ms;
        p.linktype = 101;
        p.data = bytes;
        analyzer->packet("test", p);
    }
    void exchange(const mb::Pdu& request, mb::Pdu response) {
        ++tid;
        response.direction = mb::Direction::Response;
        send(true, request);
        send(false, response);
    }
};

const std::uint16_t fixture_values[] = {2, 1234};  // 17: two decimal places; 18: 12.34 m3/h

}  // namespace

TEST(Semantics, NamesAndScalesValuesWithNoFindingOnCleanTraffic) {
    Harness h;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, fixture_values));
    h.exchange(mb::make_write_single_register(23, 250), mb::make_write_single_register(23, 250));
    h.analyzer->finish();
    EXPECT_TRUE(h.sink.findings.empty()) << h.sink.findings[0].message;
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    const auto& v = h.sink.transactions[0].values;
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v[1].text, "12.34");
    EXPECT_EQ(v[1].point->unit, "m3/h");
    EXPECT_EQ(h.sink.transactions[1].values[0].text, "25.0");
}

// Coils written (FC5, FC15) are named from the map as registers written are (FC6, FC16): they were shown as
// bare addresses. MMK-2030's coils 78 and 79 enable outputs 1 and 2 (000:714).
TEST(Semantics, CoilsWrittenAreNamedFromTheMap) {
    Harness h("mmk-2030");
    h.exchange(mb::make_write_single_coil(78, true), mb::make_write_single_coil(78, true));
    const bool outputs[] = {false, true};
    h.exchange(mb::make_write_multiple_coils(78, outputs),
               mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleCoils, 78, 2));
    h.analyzer->finish();
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    const auto& one = h.sink.transactions[0].values;
    ASSERT_EQ(one.size(), 1u);
    ASSERT_NE(one[0].point, nullptr);
    EXPECT_EQ(one[0].point->name_en, "enable output 1");
    EXPECT_EQ(one[0].text, "1");
    const auto& two = h.sink.transactions[1].values;
    ASSERT_EQ(two.size(), 2u);
    ASSERT_NE(two[1].point, nullptr);
    EXPECT_EQ(two[0].address, 78);
    EXPECT_EQ(two[0].text, "0");
    EXPECT_EQ(two[1].point->name_en, "enable output 2");
    EXPECT_EQ(two[1].text, "1");
}

TEST(Semantics, ScaleRegisterRememberedFromAnEarlierRead) {
    Harness h;
    const std::uint16_t scale[] = {3};
    const std::uint16_t flow[] = {1234};
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, scale));
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 18, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, flow));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.transactions[1].values[0].text, "1.234");
}

// A reply after its request's timeout was only a finding: its values were not named, and what it read was
// not remembered (a scale register read late left later values unscaled).
TEST(Semantics, ALateReplyIsNamedAndRememberedLikeOneInTime) {
    Harness h;
    ++h.tid;
    h.send(true, mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2));
    h.t += 3500ms;  // past the 3 s timeout
    auto late = mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, fixture_values);
    late.direction = mb::Direction::Response;
    h.send(false, late);
    const std::uint16_t flow[] = {1234};
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 18, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, flow));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairNoResponse), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::PairLateResponse), 1);
    ASSERT_EQ(h.sink.transactions.size(), 3u);
    EXPECT_TRUE(h.sink.transactions[0].timed_out);
    const auto& t = h.sink.transactions[1];
    ASSERT_TRUE(t.late_past);
    EXPECT_EQ(t.profile, h.sink.transactions[2].profile);
    ASSERT_EQ(t.values.size(), 2u);
    EXPECT_EQ(t.values[1].text, "12.34");
    EXPECT_EQ(t.values[1].point->unit, "m3/h");
    EXPECT_EQ(h.sink.transactions[2].values[0].text, "12.34");  // two decimal places, as read late
}

// A reply whose CRC fails on a serial line: its values were named and remembered as if the device held
// them, so a decimal-point register read through a damaged reply scaled every later value wrong. It is
// shown raw, with its bad CRC, and what the device holds is what the last good reply said.
TEST(Semantics, AReplyWithABadCrcIsNotWhatTheDeviceHolds) {
    const auto line = [](const char* time, const char* dir, std::vector<std::uint8_t> adu) {
        return std::string(time) + " " + dir + " " + mb::hex_bytes(adu) + "\n";
    };
    const auto read = [](std::uint16_t address) {
        return mb::encode_rtu(
            1, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, address, 1)));
    };
    const auto reply = [](std::uint16_t value) {
        const std::uint16_t values[] = {value};
        return mb::encode_rtu(1, mb::encode_pdu(mb::make_read_registers_response(
                                     mb::FunctionCode::ReadHoldingRegisters, values)));
    };
    auto damaged = reply(4);  // "four decimal places", its CRC failing
    damaged.back() ^= 0x01;
    const auto path = mbscope::test::write_temp(
        "semantics_bad_crc.txt", line("1.0", ">", read(17)) + line("1.02", "<", reply(2)) +  //
                                     line("2.0", ">", read(17)) + line("2.02", "<", damaged) +
                                     line("3.0", ">", read(18)) + line("3.02", "<", reply(1234)));
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/tests/fixtures/profiles"});
    auto p = store.load("test-device");
    ASSERT_TRUE(p.has_value());
    Collect sink;
    an::AnalyzerOptions o;
    o.semantics = std::make_shared<an::Semantics>();
    o.semantics->add({}, std::make_shared<const mb::Profile>(std::move(p.value())));
    an::Analyzer a(o, sink);
    ASSERT_TRUE(an::read_input(a, path, an::InputFormat::Text));
    a.finish();
    ASSERT_EQ(sink.transactions.size(), 3u);
    EXPECT_FALSE(sink.transactions[1].response->frame.checksum_ok);
    EXPECT_TRUE(sink.transactions[1].values.empty());
    ASSERT_EQ(sink.transactions[2].values.size(), 1u);
    EXPECT_EQ(sink.transactions[2].values[0].text, "12.34");
    EXPECT_EQ(sink.count(mb::FindingCode::RtuCrcMismatch), 1);
}

TEST(Semantics, QuantityAboveTheManualsLimit) {
    Harness h;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 16),
               mb::make_exception(3, 3));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileQuantityAboveLimit), 1);
}

TEST(Semantics, FunctionTheManualDoesNotList) {
    Harness h;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadCoils, 0, 1), mb::make_exception(1, 1));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileFunctionUnsupported), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 0);  // exception 1 is right here
}

TEST(Semantics, AddressTheMapDoesNotHave) {
    Harness h;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 30, 1),
               mb::make_exception(3, 2));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileAddressUnknown), 1);
}

TEST(Semantics, ValueOutOfRangeAndReadOnlyWrites) {
    Harness h;
    h.exchange(mb::make_write_single_register(23, 251), mb::make_exception(6, 3));
    h.exchange(mb::make_write_single_register(18, 1), mb::make_exception(6, 2));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileValueOutOfRange), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::ProfileValueOutOfRange) {
            EXPECT_NE(f.message.find("0.0 a 25.0 segundos"), std::string::npos) << f.message;
        }
    }
}

// Addresses end at 65535. A read or write that runs past it (pdu.address_overflow) answered by a faulty
// slave: its items past the end are named by nothing and checked against nothing. Wrapped round, the write's
// would be read-only register 18 and filter 23 (out of range) and the read's would name register 17.
TEST(Semantics, NothingPastAddress65535IsTakenForTheRegistersAtZero) {
    Harness h;
    std::vector<std::uint16_t> words(30, 0xFFFF);
    h.exchange(mb::make_write_multiple_registers(65530, words),
               mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleRegisters, 65530, 30));
    words.resize(25);
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 65530, 25),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, words));
    h.analyzer->finish();
    EXPECT_GE(h.sink.count(mb::FindingCode::PduAddressOverflow), 2);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileValueOutOfRange), 0);
    for (const auto& f : h.sink.findings)
        EXPECT_EQ(f.message.find(" 17"), std::string::npos) << f.message;
    ASSERT_EQ(h.sink.transactions.size(), 2u);
    EXPECT_EQ(h.sink.transactions[0].values.size(), 6u);  // 65530..65535
    EXPECT_EQ(h.sink.transactions[1].values.size(), 6u);
    for (const auto& t : h.sink.transactions)
        for (const auto& v : t.values) {
            EXPECT_GE(v.address, 65530);
            EXPECT_EQ(v.point, nullptr) << v.address;
        }
}

TEST(Semantics, ExceptionToARequestTheMapSaysIsValid) {
    Harness h;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 17, 2),
               mb::make_exception(3, 2));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 1);
}

// The manual gives each refusal its code: 01 an unsupported function, 02 an address outside the map, 03 a
// value outside its range (MK 000:475-477). A device answering another was only "an exception" (a warning);
// the code the manual gives is now expected, the first in the specification's order. A code the manual only
// implies (MK's 03 for a quantity above its limit) holds nothing against the device.
TEST(Semantics, AnExceptionCodeOtherThanTheManualsIsTheDevicesError) {
    Harness h("mmk-2030");
    // Register 200 is not in the map; ENDER (7) takes 0 to 99 (000:500).
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 200, 1),
               mb::make_exception(3, 3));
    h.exchange(mb::make_write_single_register(7, 100), mb::make_exception(6, 2));
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 16),
               mb::make_exception(3, 2));
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 200, 1),
               mb::make_exception(3, 2));
    h.exchange(mb::make_write_single_register(7, 100), mb::make_exception(6, 3));
    h.analyzer->finish();
    std::vector<std::string> unexpected;
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::ProfileExceptionUnexpected) unexpected.push_back(f.message);
    ASSERT_EQ(unexpected.size(), 2u);
    EXPECT_EQ(unexpected[0].rfind("exception 3 where the manual of mmk-2030 answers exception 2 (", 0), 0u)
        << unexpected[0];
    EXPECT_EQ(unexpected[1].rfind("exception 2 where the manual of mmk-2030 answers exception 3 (", 0), 0u)
        << unexpected[1];
}

// AP §6.5's state diagram checks FC5's value (0000 or FF00) before its address, and MK-FC05-01 refuses
// another value with 03. An MK device answering 03 to value 1234 at coil 200 (outside the map) was held to
// 02, "exception 3 where the manual of mmk-2030 answers exception 2", while the reference slave answers 03.
TEST(Semantics, AnFc5ValueIsJudgedBeforeItsAddress) {
    Harness h("mmk-2030");
    const auto fc5 = [](std::uint16_t coil, std::uint16_t value) {
        const std::uint8_t bytes[] = {5, static_cast<std::uint8_t>(coil >> 8),
                                      static_cast<std::uint8_t>(coil), static_cast<std::uint8_t>(value >> 8),
                                      static_cast<std::uint8_t>(value)};
        return mb::decode_request(bytes).value();
    };
    h.exchange(fc5(200, 0x1234), mb::make_exception(5, 3));
    h.exchange(fc5(200, 0xFF00), mb::make_exception(5, 2));
    h.exchange(fc5(200, 0x1234), mb::make_exception(5, 2));
    h.analyzer->finish();
    std::vector<std::string> unexpected;
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::ProfileExceptionUnexpected) unexpected.push_back(f.message);
    ASSERT_EQ(unexpected.size(), 1u);
    EXPECT_EQ(unexpected[0],
              "exception 2 where the manual of mmk-2030 answers exception 3 (the request: single "
              "coil value is neither 0xFF00 nor 0x0000)");
}

// What a device's frames show of its line against its manual: the CTH2265I talks RTU only (003:460), an MK
// device answers at 1..99 (000:220). Traffic otherwise was decoded as if the manual allowed it. Said once per
// device; a frame over Modbus/TCP (a gateway's unit ids) says nothing.
TEST(Semantics, AFramingOrUnitTheManualDoesNotAllowIsSaidOncePerDevice) {
    const auto decode = [](const std::string& id, const std::string& log) {
        mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
        auto p = store.load(id);
        EXPECT_TRUE(p.has_value());
        auto sink = std::make_unique<Collect>();
        an::AnalyzerOptions o;
        o.semantics = std::make_shared<an::Semantics>();
        o.semantics->add({}, std::make_shared<const mb::Profile>(std::move(p.value())));
        an::Analyzer a(o, *sink);
        EXPECT_TRUE(
            an::read_input(a, mbscope::test::write_temp("line_" + id + ".txt", log), an::InputFormat::Text));
        a.finish();
        return sink;
    };
    const auto messages = [](const Collect& sink) {
        std::vector<std::string> out;
        for (const auto& f : sink.findings)
            if (f.code == mb::FindingCode::ProfileLineDeparture) out.push_back(f.message);
        return out;
    };
    // The MK manual's FC3 example in ASCII (000:4352-4369 frames E13-E16 style), twice, to unit 17: allowed.
    const std::string ascii_read = ":11030060000389\r\n";
    const auto mk = decode(
        "mmk-2030",
        "1.0 > " + mb::hex_bytes(std::vector<std::uint8_t>(ascii_read.begin(), ascii_read.end())) + "\n");
    EXPECT_TRUE(messages(*mk).empty());
    // The CTH2265I addressed in ASCII: said once, however many frames.
    const auto cth =
        decode("cth2265i",
               "1.0 > " + mb::hex_bytes(std::vector<std::uint8_t>(ascii_read.begin(), ascii_read.end())) +
                   "\n2.0 > " +
                   mb::hex_bytes(std::vector<std::uint8_t>(ascii_read.begin(), ascii_read.end())) + "\n");
    ASSERT_EQ(messages(*cth).size(), 1u);
    EXPECT_EQ(messages(*cth)[0], "cth2265i: the manual lists no ascii transport (rtu)");
    // An MK device at unit 150: outside 1..99.
    const auto far = decode(
        "mmk-2030",
        "1.0 > " +
            mb::hex_bytes(mb::encode_rtu(
                150, mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 1)))) +
            "\n");
    ASSERT_EQ(messages(*far).size(), 1u);
    EXPECT_NE(messages(*far)[0].find("unit 150 is outside the manual's addresses"), std::string::npos)
        << messages(*far)[0];
}

TEST(Semantics, SelectorsPickTheMostSpecificProfile) {
    an::Semantics s;
    auto a = std::make_shared<const mb::Profile>();
    auto b = std::make_shared<const mb::Profile>();
    auto c = std::make_shared<const mb::Profile>();
    s.add({}, a);
    s.add(*an::parse_selector("17"), b);
    s.add(*an::parse_selector("10.0.0.3:17"), c);
    EXPECT_EQ(s.profile_for("10.0.0.9:502", 1), a.get());
    EXPECT_EQ(s.profile_for("10.0.0.9:502", 17), b.get());
    EXPECT_EQ(s.profile_for("10.0.0.3:502", 17), c.get());
    EXPECT_FALSE(an::parse_selector("x:y").has_value());
    EXPECT_FALSE(an::parse_selector("300").has_value());
}

// A --map whose selector no device matched, or whose devices all took a more specific one, described
// nothing: the user hears of it (a mistyped address gave no sign). Selector uses follow the order of adding.
TEST(Semantics, EachSelectorSaysWhetherItDescribedADevice) {
    an::Semantics s;
    auto p = std::make_shared<const mb::Profile>();
    s.add(*an::parse_selector("17"), p);
    s.add(*an::parse_selector("10.0.0.3:17"), p);
    s.add(*an::parse_selector("10.0.0.9"), p);
    s.add(*an::parse_selector("10.0.0.3"), p);
    using Use = an::Semantics::SelectorUse;
    EXPECT_EQ(s.selector_uses(),
              (std::vector<Use>{Use::Unmatched, Use::Unmatched, Use::Unmatched, Use::Unmatched}));
    EXPECT_EQ(s.profile_for("10.0.0.3:502", 17), p.get());  // 10.0.0.3:17 over 17 and 10.0.0.3
    EXPECT_EQ(s.selector_uses(), (std::vector<Use>{Use::Shadowed, Use::Used, Use::Unmatched, Use::Shadowed}));
    EXPECT_EQ(s.profile_for("10.0.0.4:502", 17), p.get());  // 17 alone
    EXPECT_EQ(s.profile_for("10.0.0.4:502", 1), nullptr);
    EXPECT_EQ(s.selector_uses(), (std::vector<Use>{Use::Used, Use::Used, Use::Unmatched, Use::Shadowed}));

    // A device that moved to a unit a selector names keeps its profile there, and that selector described it.
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    auto mmk = store.load("mmk-2030");
    ASSERT_TRUE(mmk);
    an::Semantics moves;
    auto profile = std::make_shared<const mb::Profile>(std::move(mmk.value()));
    moves.add(*an::parse_selector("1"), profile);
    moves.add(*an::parse_selector("5"), profile);
    const auto write = mb::make_write_single_register(7, 5);
    EXPECT_TRUE(moves.follow_address("serial line", "serial line unit 1", *profile, write, write));
    EXPECT_EQ(moves.profile_for("serial line", 5), profile.get());
    EXPECT_EQ(moves.selector_uses(), (std::vector<Use>{Use::Unmatched, Use::Used}));
}

// IPv6 devices are named "[2001:db8::2]:502 unit N" (RFC 5952, as tshark prints them): --map takes the
// address bare, in brackets, with a unit after the brackets, and in any of its spellings. Before, any text
// without a "." was a unit id, and "--map 2001:db8::2=ID" was refused.
TEST(Semantics, IPv6SelectorsNameTheDeviceAsItIsPrinted) {
    an::Semantics s;
    auto host = std::make_shared<const mb::Profile>();
    auto unit = std::make_shared<const mb::Profile>();
    s.add(*an::parse_selector("2001:db8:0:0:0:0:0:2"), host);
    s.add(*an::parse_selector("[2001:DB8::2]:17"), unit);
    EXPECT_EQ(s.profile_for("[2001:db8::2]:502", 1), host.get());
    EXPECT_EQ(s.profile_for("[2001:db8::2]:502", 17), unit.get());
    EXPECT_EQ(s.profile_for("[2001:db8::3]:502", 17), nullptr);
    EXPECT_TRUE(an::parse_selector("[2001:db8::2]").has_value());
    EXPECT_FALSE(an::parse_selector("[2001:db8::2]:300").has_value());
    EXPECT_FALSE(an::parse_selector("[2001:db8::2").has_value());
    EXPECT_FALSE(an::parse_selector("2001:db8::zz").has_value());
    an::Endpoint e;
    e.v6 = true;
    e.address = {0x20, 0x01, 0x0d, 0xb8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2};
    e.port = 502;
    EXPECT_EQ(e.to_string(), "[2001:db8::2]:502");
}

// MK-CFG-01 (000:218-226, 500): ENDER (register 7) holds the device's address and a device obeys a new
// one at once. Its acknowledged write is a note, and the profile mapped to the old unit describes the
// device at the new one: the read that follows there is named in the manual's terms and judged by its rules.
// A refused value (100, outside 0..99) and a write elsewhere move nothing.
TEST(Semantics, AnAcknowledgedAddressWriteMovesTheDevicesProfileWithIt) {
    Harness h("mmk-2030", 1);
    h.exchange(mb::make_write_single_register(7, 100), mb::make_exception(6, 3));
    h.exchange(mb::make_write_single_register(23, 10), mb::make_write_single_register(23, 10));
    h.exchange(mb::make_write_single_register(7, 17), mb::make_write_single_register(7, 17));
    h.unit = 17;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 7, 16),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters,
                                                std::vector<std::uint16_t>(16, 17)));
    h.analyzer->finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::ProfileAddressMoved), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code != mb::FindingCode::ProfileAddressMoved) continue;
        EXPECT_NE(f.message.find("ENDER (register 7) := 17 acknowledged: the device answers at unit 17"),
                  std::string::npos)
            << f.message;
    }
    ASSERT_EQ(h.sink.transactions.size(), 4u);
    const auto& moved = h.sink.transactions[3];
    ASSERT_NE(moved.profile, nullptr);
    EXPECT_EQ(moved.profile->id, "mmk-2030");
    ASSERT_FALSE(moved.values.empty());
    // 16 registers where the manual allows 15: its rule applies at the new address too.
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileQuantityAboveLimit), 1);
}

// MK-CFG-01 (000:218-226, 501-503): PROT, BAUD and PARID (registers 8-10) mirror the line's framing, speed
// and parity, and a device told a valid new code talks with it from then on: a master that does not follow
// loses it, which a capture of a device that "went silent" after a configuration write shows. The
// acknowledged write is a note naming what the device now talks; a refused one, a code the manual does not
// define (a rule break of its own) and a value the registers were read holding before change nothing.
TEST(Semantics, AnAcknowledgedWriteOfTheLineSettingsIsANote) {
    Harness h("mmk-2030", 1);
    const auto fc16 = [](std::uint16_t start, std::vector<std::uint16_t> values) {
        return mb::make_write_multiple_registers(start, values);
    };
    const auto ack = [](std::uint16_t start, std::uint16_t count) {
        return mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleRegisters, start, count);
    };
    const std::vector<std::uint16_t> held{1, 5, 0};  // RTU, 9600 baud, no parity
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 8, 3),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, held));
    h.exchange(mb::make_write_single_register(9, 3), mb::make_exception(6, 4));              // refused
    h.exchange(fc16(8, {1, 5, 0}), ack(8, 3));                                               // what they held
    h.exchange(mb::make_write_single_register(9, 6), mb::make_write_single_register(9, 6));  // no such code
    h.exchange(fc16(8, {0, 3, 1}), ack(8, 3));
    h.analyzer->finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
    for (const auto& f : h.sink.findings) {
        if (f.code != mb::FindingCode::ProfileLineSettingsChanged) continue;
        EXPECT_NE(f.message.find("PROT. (register 8) := 0, BAUD (register 9) := 3, PARID (register 10) := 1 "
                                 "acknowledged: the device talks ASCII, 2400 baud, even parity from now on "
                                 "(mmk-2030's manual)"),
                  std::string::npos)
            << f.message;
    }
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileValueOutOfRange), 1);  // BAUD := 6
}

// What input registers (FC4) hold at the same addresses is not what the holding registers PROT, BAUD and
// PARID held: a write of PROT := 0 after an FC4 read of 0 at address 8 is still a change.
TEST(Semantics, AnInputRegisterReadIsNotWhatTheLineSettingsHeld) {
    const auto input = [](std::uint16_t value) {
        const std::vector<std::uint16_t> v{value};
        return mb::make_read_registers_response(mb::FunctionCode::ReadInputRegisters, v);
    };
    const auto read_input_8 = mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 8, 1);
    const auto prot_ascii = mb::make_write_single_register(8, 0);
    // FC4 reads 0 at 8: PROT := 0 is still a change.
    Harness first("mmk-2030", 1);
    first.exchange(read_input_8, input(0));
    first.exchange(prot_ascii, prot_ascii);
    first.analyzer->finish();
    EXPECT_EQ(first.sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
    // PROT := 0 acknowledged, then FC4 reads 1 at 8: PROT := 0 again is no change.
    Harness again("mmk-2030", 1);
    again.exchange(prot_ascii, prot_ascii);
    again.exchange(read_input_8, input(1));
    again.exchange(prot_ascii, prot_ascii);
    again.analyzer->finish();
    EXPECT_EQ(again.sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
}

// The same on a serial line, from a capture in the text format: the request at the new unit is judged by
// the manual's rules too (the line is its own server; the response side once took another name for it).
TEST(Semantics, AnAddressWriteOnASerialLineMovesTheProfileForRequestsAndReplies) {
    const auto rtu = [](std::uint8_t unit, std::vector<std::uint8_t> pdu) {
        std::string hex;
        for (auto b : mb::encode_rtu(unit, pdu)) {
            char x[4];
            std::snprintf(x, sizeof x, "%02X ", b);
            hex += x;
        }
        return hex;
    };
    const std::string path = ::testing::TempDir() + "address-moved.txt";
    std::ofstream(path) << "0.050 master " << rtu(1, {0x06, 0x00, 0x07, 0x00, 0x11}) << "\n"
                        << "0.100 slave " << rtu(1, {0x06, 0x00, 0x07, 0x00, 0x11}) << "\n"
                        << "0.150 master " << rtu(17, {0x03, 0x00, 0x07, 0x00, 0x10}) << "\n"
                        << "0.200 slave " << rtu(17, {0x83, 0x03}) << "\n"
                        << "0.250 master " << rtu(17, {0x03, 0x00, 0x17, 0x00, 0x01}) << "\n"
                        << "0.300 slave " << rtu(17, {0x03, 0x02, 0x00, 0x0A}) << "\n";
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    auto p = store.load("mmk-2030");
    ASSERT_TRUE(p.has_value());
    Collect sink;
    an::AnalyzerOptions o;
    o.semantics = std::make_shared<an::Semantics>();
    o.semantics->add({std::nullopt, 1}, std::make_shared<const mb::Profile>(std::move(p.value())));
    an::Analyzer a(o, sink);
    ASSERT_TRUE(an::read_input(a, path, an::InputFormat::Text));
    a.finish();
    EXPECT_EQ(sink.count(mb::FindingCode::ProfileAddressMoved), 1);
    EXPECT_EQ(sink.count(mb::FindingCode::ProfileQuantityAboveLimit), 1);  // FC3 of 16 at unit 17
    ASSERT_EQ(sink.transactions.size(), 3u);
    ASSERT_NE(sink.transactions[2].profile, nullptr);
    EXPECT_FALSE(sink.transactions[2].values.empty());
}

// DCY-2050 (000:731-738): a loop's control output is read-only while the loop is in automatic mode (coil 0
// or 1 holds 1), a program's repetitions while the program runs or is suspended (register 6 or 7 holds 1
// or 2). A write in the state the traffic showed is named; a refusal while the state was never seen is no
// departure from the manual; a refusal in the state that allows the write is one.
namespace {
mb::Pdu coils_response(std::initializer_list<bool> bits) {
    const std::vector<bool> v(bits);
    std::unique_ptr<bool[]> b(new bool[v.size()]);
    for (std::size_t i = 0; i < v.size(); ++i)
        b[i] = v[i];
    return mb::make_read_bits_response(mb::FunctionCode::ReadCoils, std::span<const bool>(b.get(), v.size()));
}
}  // namespace

TEST(Semantics, AWriteToAnOutputInAutomaticModeIsAWriteToAReadOnlyRegister) {
    Harness h("dcy-2050", 1);
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadCoils, 0, 2), coils_response({true, false}));
    h.exchange(mb::make_write_single_register(2, 500), mb::make_exception(6, 2));  // loop 1: automatic
    h.exchange(mb::make_write_single_register(3, 500), mb::make_write_single_register(3, 500));  // manual
    h.analyzer->finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 0);
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::ProfileWriteReadOnly) {
            EXPECT_NE(f.message.find("writes 500 to 2 "), std::string::npos) << f.message;
            EXPECT_NE(f.message.find("while coil 0 "), std::string::npos) << f.message;
            EXPECT_NE(f.message.find("holds 1"), std::string::npos) << f.message;
            EXPECT_NE(f.message.find("[000:731]"), std::string::npos) << f.message;
        }
}

TEST(Semantics, TheModeAWriteLeftIsTheModeLaterWritesAreJudgedIn) {
    Harness h("dcy-2050", 1);
    h.exchange(mb::make_write_single_coil(0, true), mb::make_write_single_coil(0, true));
    h.exchange(mb::make_write_single_register(2, 500), mb::make_exception(6, 2));
    h.exchange(mb::make_write_single_coil(0, false), mb::make_write_single_coil(0, false));
    h.exchange(mb::make_write_single_register(2, 500), mb::make_exception(6, 2));
    h.analyzer->finish();
    // In automatic mode the write is the master's mistake; in manual mode the refusal is the device's.
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 1);
}

TEST(Semantics, ARefusalWhileTheModeWasNeverSeenBlamesNobody) {
    Harness h("dcy-2050", 1);
    h.exchange(mb::make_write_single_register(2, 500), mb::make_exception(6, 2));
    h.exchange(mb::make_write_single_register(3, 500), mb::make_write_single_register(3, 500));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 0);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 0);
}

TEST(Semantics, ARunningProgramsRepetitionsAreReadOnlyAsAnInputRegisterReadShowed) {
    Harness h("dcy-2050", 1);
    const std::vector<std::uint16_t> running{2};  // suspended (000:735)
    // FC4 reads the same registers as FC3 on this model (MK-FC04-01).
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 6, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadInputRegisters, running));
    const std::vector<std::uint16_t> repetitions{10, 10};
    h.exchange(mb::make_write_multiple_registers(8, repetitions), mb::make_exception(16, 2));
    h.analyzer->finish();
    ASSERT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 1);  // 8; register 7 was never seen
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileExceptionUnexpected), 0);
    for (const auto& f : h.sink.findings) {
        if (f.code == mb::FindingCode::ProfileWriteReadOnly) {
            EXPECT_NE(f.message.find("while register 6 "), std::string::npos) << f.message;
        }
    }
}

// A 32-bit point is judged as one value: Walchem's network "Fluent update rate" (holding registers 148-149,
// float, least significant word first, 1..1440 minutes). Written whole by FC16, or a half at a time by FC6
// as the manual has clients do (002:499) with the other half the traffic showed.
TEST(Semantics, A32BitWriteIsJudgedAsOneValue) {
    Harness h("walchem-w600");
    const std::vector<std::uint16_t> ten{0x0000, 0x4120}, two_thousand{0x0000, 0x44FA}, nan{0x0000, 0x7FC0};
    h.exchange(mb::make_write_multiple_registers(148, ten),
               mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleRegisters, 148, 2));
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileValueOutOfRange), 0);
    h.exchange(mb::make_write_multiple_registers(148, two_thousand), mb::make_exception(16, 3));
    h.exchange(mb::make_write_multiple_registers(148, nan), mb::make_exception(16, 3));
    // 10.0 acknowledged above; its high half replaced by 2000.0's.
    h.exchange(mb::make_write_single_register(149, 0x44FA), mb::make_exception(6, 3));
    // A half whose other half was never seen is not judged.
    Harness unseen("walchem-w600");
    unseen.exchange(mb::make_write_single_register(149, 0x44FA), mb::make_exception(6, 3));
    h.analyzer->finish();
    unseen.analyzer->finish();
    EXPECT_EQ(unseen.sink.count(mb::FindingCode::ProfileValueOutOfRange), 0);
    ASSERT_EQ(h.sink.count(mb::FindingCode::ProfileValueOutOfRange), 3);
    std::vector<std::string> messages;
    for (const auto& f : h.sink.findings)
        if (f.code == mb::FindingCode::ProfileValueOutOfRange) messages.push_back(f.message);
    EXPECT_NE(messages[0].find("value 2000 above maximum 1440"), std::string::npos) << messages[0];
    EXPECT_NE(messages[1].find("not a finite number"), std::string::npos) << messages[1];
    EXPECT_NE(messages[2].find("one half of 148-149"), std::string::npos) << messages[2];
    EXPECT_NE(messages[2].find("value 2000 above maximum 1440"), std::string::npos) << messages[2];
}

// A read of Walchem's alternative map (002:752: "os valores primários para todos os sensores ... em um
// único ciclo ... FC4 iniciando no endereço 39217") is a read of the map: its values named by object and
// field, not profile.address_unknown.
TEST(Semantics, AReadOfAnAlternativeMapIsNamedByItsObjects) {
    Harness h("walchem-w600");
    const std::vector<std::uint16_t> values{0x0000, 0x40F0, 0x0000, 0x41C8};  // 7.5 and 25.0, cdab
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 9216, 4),
               mb::make_read_registers_response(mb::FunctionCode::ReadInputRegisters, values));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileAddressUnknown), 0);
    ASSERT_EQ(h.sink.transactions.size(), 1u);
    const auto& v = h.sink.transactions[0].values;
    ASSERT_GE(v.size(), 2u);
    ASSERT_NE(v[0].point, nullptr);
    EXPECT_NE(v[0].point->name.find("Sensor 1 (sensor-1-1): Valor primário"), std::string::npos)
        << v[0].point->name;
    EXPECT_EQ(v[0].text, "7.5");
    const auto second = std::find_if(v.begin(), v.end(), [](const auto& x) { return x.address == 9218; });
    ASSERT_NE(second, v.end());
    ASSERT_NE(second->point, nullptr);
    EXPECT_NE(second->point->name.find("Sensor 2 (sensor-1-2)"), std::string::npos) << second->point->name;
    EXPECT_EQ(second->number, std::optional<double>(25.0));
}

// What the traffic showed a device holding goes with it when it moves (MK ENDER, register 42 on the
// DCY-2050): device A, seen in automatic mode at unit 1, moves to 5; device B moves from 3 to 1. A write
// of loop 1's output at unit 1 is B's, whose mode was never seen; at unit 5 it is A's, in automatic mode.
TEST(Semantics, WhatADeviceWasSeenHoldingMovesWithItsAddress) {
    Harness h("dcy-2050");
    h.unit = 1;
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadCoils, 0, 2), coils_response({true, false}));
    h.exchange(mb::make_write_single_register(42, 5), mb::make_write_single_register(42, 5));
    h.unit = 3;
    h.exchange(mb::make_write_single_register(42, 1), mb::make_write_single_register(42, 1));
    h.unit = 1;
    h.exchange(mb::make_write_single_register(2, 500), mb::make_write_single_register(2, 500));
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 0);
    h.unit = 5;
    h.exchange(mb::make_write_single_register(2, 500), mb::make_exception(6, 2));
    h.analyzer->finish();
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileWriteReadOnly), 1);
    EXPECT_EQ(h.sink.count(mb::FindingCode::ProfileAddressMoved), 2);
}

// A device with an input register map of its own: a 32-bit input value read from its second half takes no
// first half from the holding register at the same address, and an input register read is no half of a
// holding register's value (a made-up 66036 kWh from set-point 500 and input register 11).
TEST(Semantics, A32BitValueTakesItsOtherHalfFromItsOwnTableOnly) {
    const std::string dir = ::testing::TempDir() + "semantics_two_maps";
    std::filesystem::create_directories(dir);
    std::ofstream(dir + "/two-maps.json") << R"({
  "format": "mbscope-profile/1", "family": "two-maps", "vendor": "Test Vendor", "title": "Two maps",
  "source": {"manual": "none", "section": "tests", "lines": "test:1"},
  "line": {"transports": ["tcp"], "unit_id": {"min": 1, "max": 247}},
  "functions": {"supported": [3, 4]},
  "tables": {
    "holding_registers": [
      {"address": 10, "name": "limite", "name_en": "limit", "access": "rw",
       "encoding": {"type": "u32", "word_order": "abcd"}, "source": "test:10"},
      {"address": 12, "name": "ajuste", "name_en": "setpoint", "access": "rw", "source": "test:12"}
    ],
    "input_registers": [
      {"address": 10, "name": "energia", "name_en": "energy", "access": "r", "unit": "kWh",
       "encoding": {"type": "u32", "word_order": "abcd"}, "source": "test:20"}
    ]
  },
  "models": [{"id": "two-maps", "name": "TWO-MAPS", "source": "test:1"}]
})";
    Harness h("two-maps", std::nullopt, dir);
    const std::uint16_t limit[] = {0x0001, 0x0002}, energy_low[] = {0x0003};
    // Holding 10-11 seen: 65538. Then input register 11 alone: its first half is input register 10, unseen.
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 10, 2),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, limit));
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 11, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadInputRegisters, energy_low));
    // And holding register 10 alone after it: its second half is holding register 11 (2), not input 11 (3).
    const std::uint16_t limit_high[] = {0x0001};
    h.exchange(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 10, 1),
               mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, limit_high));
    h.analyzer->finish();
    ASSERT_EQ(h.sink.transactions.size(), 3u);
    ASSERT_EQ(h.sink.transactions[0].values.size(), 1u);
    EXPECT_EQ(h.sink.transactions[0].values[0].text, "65538");
    ASSERT_EQ(h.sink.transactions[1].values.size(), 1u);
    const auto& energy = h.sink.transactions[1].values[0];
    EXPECT_TRUE(energy.partial);
    EXPECT_EQ(energy.text, "3 (second half only)");
    EXPECT_FALSE(energy.other_half_earlier.has_value());
    ASSERT_EQ(h.sink.transactions[2].values.size(), 1u);
    const auto& again = h.sink.transactions[2].values[0];
    EXPECT_EQ(again.text, "65538");
    EXPECT_EQ(again.other_half_earlier, std::optional<std::uint16_t>{11});
}

}  // namespace test_analyzer_semantics_test
