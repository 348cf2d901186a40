// The exchange oracle (conformance/oracle.hpp) that the slave's fuzz target and `mbscope fuzz` share:
//  - every bundled profile, served by the clean reference slave, passes a script of requests derived from its
//    map (both ends of each table, one past the manual's quantity limit, writes read back, out-of-range
//    values, unsupported functions, broadcasts, bad checksums) with no violation, over RTU, ASCII and TCP;
//  - every planted fault the Responder applies breaks a named rule of the oracle on the same script;
//  - the faults that live in time (slow-reply, gap-inside-frame) are named as the ones left to the network
//    fuzzer and the conformance runner, so a new fault must be classified here.
#include "conformance/oracle.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <set>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "slave/responder.hpp"
#include "slave/slave_test_support.hpp"

namespace test_fuzz_oracle_test {

namespace {

namespace mb = mbscope::modbus;
namespace cf = mbscope::conformance;
namespace sl = mbscope::slave;
using mb::Framing;
using mb::Table;

std::vector<std::uint8_t> u16(std::uint16_t v) {
    return {static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
}

std::vector<std::uint8_t> pdu(std::uint8_t fc, std::initializer_list<std::uint16_t> words) {
    std::vector<std::uint8_t> out{fc};
    for (auto w : words) {
        const auto b = u16(w);
        out.insert(out.end(), b.begin(), b.end());
    }
    return out;
}

// An RTU request to `unit` and its reply (none when empty), judged.
std::vector<cf::OracleViolation> judge_rtu(cf::ExchangeOracle& oracle, std::uint8_t unit,
                                           const std::vector<std::uint8_t>& request,
                                           const std::vector<std::uint8_t>& reply) {
    mbscope::modbus::transport::Exchange ex;
    ex.sent = mb::encode_rtu(unit, request);
    if (!reply.empty()) {
        ex.received = mb::encode_rtu(unit, reply);
        ex.response = *mb::decode_rtu(ex.received);
    }
    return oracle.judge(ex);
}

struct Step {
    std::uint8_t unit;  // 0: broadcast
    std::vector<std::uint8_t> pdu;
    bool corrupt = false;  // the checksum (RTU CRC / ASCII LRC) is broken; over TCP, protocol id 1
};

// Requests derived from the profile's map: what a careful tester sends first.
std::vector<Step> script(const mb::Profile& p, std::uint8_t unit, Framing framing) {
    std::vector<Step> steps;
    const auto add = [&](std::vector<std::uint8_t> bytes) { steps.push_back({unit, std::move(bytes)}); };
    const std::pair<Table, std::uint8_t> reads[] = {{Table::Coils, 1},
                                                    {Table::DiscreteInputs, 2},
                                                    {Table::InputRegisters, 4},
                                                    {Table::HoldingRegisters, 3}};
    for (auto [table, fc] : reads) {
        if (!p.functions.supports(fc)) continue;
        const auto& points = p.table(table);
        const std::uint16_t first = points.empty() ? 0 : points.front().address;
        const std::uint16_t last = points.empty() ? 0 : points.back().address;
        const int max = p.functions.max_for(fc);
        add(pdu(fc, {first, 1}));
        add(pdu(fc, {last, 1}));
        add(pdu(fc, {first, static_cast<std::uint16_t>(max + 1)}));
    }
    // Writes inside the range, read back; a value past the range.
    int written = 0;
    for (const auto& pt : p.table(Table::HoldingRegisters)) {
        // Points with a documented range: a value inside it is known to be accepted, one past it refused.
        // Not a line setting: a valid address moves the device (MK ENDER), as it would a real one.
        if (written == 3 || pt.access != mb::Access::ReadWrite || pt.encoding.words != 1 || pt.reserved ||
            !p.functions.supports(6) || pt.fixed_value || pt.min_from || pt.max_from || !pt.max ||
            pt.encoding.type == mb::EncodingType::Enum || pt.mirrors)
            continue;
        const std::uint16_t value = static_cast<std::uint16_t>(pt.max.value_or(pt.min.value_or(0) + 1));
        add(pdu(6, {pt.address, value}));
        add(pdu(3, {pt.address, 1}));
        if (pt.max && *pt.max < 0xFFFF && *pt.max >= 0)
            add(pdu(6, {pt.address, static_cast<std::uint16_t>(*pt.max + 1)}));
        ++written;
    }
    // A 32-bit value in the middle of its range, written whole in the point's word order and read back.
    for (const auto& pt : p.table(Table::HoldingRegisters)) {
        if (pt.access != mb::Access::ReadWrite || pt.encoding.words != 2 || pt.reserved || !pt.min ||
            !pt.max || !p.functions.supports(16))
            continue;
        const double middle = (static_cast<double>(*pt.min) + static_cast<double>(*pt.max)) / 2;
        const std::uint32_t raw = pt.encoding.type == mb::EncodingType::F32
                                      ? std::bit_cast<std::uint32_t>(static_cast<float>(middle))
                                      : static_cast<std::uint32_t>(static_cast<std::int64_t>(middle));
        const auto words = mb::split_words(raw, pt.encoding.word_order);
        std::vector<std::uint8_t> w = pdu(16, {pt.address, 2});
        w.push_back(4);
        for (auto v : words)
            for (auto x : u16(v))
                w.push_back(x);
        add(w);
        add(pdu(3, {pt.address, 2}));
        break;
    }
    for (const auto& pt : p.table(Table::Coils)) {
        if (pt.access != mb::Access::ReadWrite || !p.functions.supports(5)) continue;
        add(pdu(5, {pt.address, 0xFF00}));
        add(pdu(1, {pt.address, 1}));
        add(pdu(5, {pt.address, 0x1234}));
        break;
    }
    if (p.functions.supports(8)) add(pdu(8, {0x0000, 0xA537}));
    add({0x41, 0x01});
    if (framing == Framing::Tcp) steps.push_back({unit, pdu(3, {0, 1}), true});  // not Modbus: discarded
    // A broadcast write of the first written value, and a read broadcast (never executed, never answered).
    if (framing != Framing::Tcp) {
        for (const auto& s : std::vector<Step>(steps))
            if (s.pdu[0] == 6) {
                steps.push_back({0, s.pdu});
                break;
            }
        steps.push_back({0, pdu(3, {0, 1})});
        steps.push_back({unit, pdu(3, {0, 1}), true});
    }
    return steps;
}

std::vector<std::uint8_t> frame(Framing framing, std::uint8_t unit, const std::vector<std::uint8_t>& p,
                                std::uint16_t tid, bool corrupt) {
    std::vector<std::uint8_t> adu;
    switch (framing) {
        case Framing::Rtu:
            adu = mb::encode_rtu(unit, p);
            if (corrupt) adu.back() ^= 0x5A;
            break;
        case Framing::Ascii: {
            auto text = mb::encode_ascii(unit, p);
            if (corrupt) text[text.size() - 3] = text[text.size() - 3] == '0' ? '1' : '0';
            adu.assign(text.begin(), text.end());
            break;
        }
        case Framing::Tcp:
            adu = mb::encode_tcp(tid, unit, p, corrupt ? 1 : 0);
            break;
    }
    return adu;
}

mb::Result<mb::Frame> decode(Framing framing, std::span<const std::uint8_t> adu) {
    if (framing == Framing::Rtu) return mb::decode_rtu(adu);
    if (framing == Framing::Ascii) return mb::decode_ascii(adu);
    return mb::decode_tcp(adu);
}

// Runs the script through a Responder with `faults` and judges every exchange; returns the violations.
std::vector<cf::OracleViolation> run(const mb::Profile& p, Framing framing, sl::FaultSet& faults) {
    const auto unit = static_cast<std::uint8_t>(std::clamp(1, std::max(1, p.line.unit_min), p.line.unit_max));
    sl::Device device(p, unit, &faults);
    sl::Responder responder({&device}, faults, framing, framing == Framing::Tcp);
    cf::ExchangeOracle oracle(framing, {{unit, &p}}, framing == Framing::Tcp);
    std::vector<cf::OracleViolation> found;
    std::uint16_t tid = 0;
    for (const Step& s : script(p, unit, framing)) {
        mbscope::modbus::transport::Exchange ex;
        ex.sent = frame(framing, s.unit, s.pdu, ++tid, s.corrupt);
        const auto f = decode(framing, ex.sent);
        if (!f) {
            ADD_FAILURE() << "the script's frame does not decode";
            continue;
        }
        const auto before = device.image().modifications();
        ex.received = responder.respond(*f);
        // The reply found in what came as the client finds it: the first frame (a reply sent twice is two).
        mbscope::modbus::transport::ReplyScanner(framing, false, 1).scan(ex, true);
        for (auto& v : oracle.judge(ex, device.image().modifications() != before))
            found.push_back(std::move(v));
    }
    return found;
}

std::string listing(const std::vector<cf::OracleViolation>& vs) {
    std::string out;
    for (const auto& v : vs)
        out += "\n  " + cf::to_string(v);
    return out;
}

// ---- the clean slave satisfies the oracle for every profile and framing

struct CleanCase {
    std::string profile;
    Framing framing;
};

class CleanSlave : public ::testing::TestWithParam<CleanCase> {};

TEST_P(CleanSlave, BreaksNoRule) {
    const auto& c = GetParam();
    sl::FaultSet none;
    const auto found = run(mbscope::slave::test::profile(c.profile), c.framing, none);
    EXPECT_TRUE(found.empty()) << listing(found);
}

std::vector<CleanCase> clean_cases() {
    std::vector<CleanCase> out;
    for (const auto& id : mbscope::slave::test::profile_ids())
        for (auto f : {Framing::Rtu, Framing::Ascii, Framing::Tcp})
            out.push_back({id, f});
    return out;
}

INSTANTIATE_TEST_SUITE_P(Profiles, CleanSlave, ::testing::ValuesIn(clean_cases()), [](const auto& info) {
    std::string n = info.param.profile + "_" +
                    (info.param.framing == Framing::Rtu     ? "rtu"
                     : info.param.framing == Framing::Ascii ? "ascii"
                                                            : "tcp");
    for (auto& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    return n;
});

// ---- every fault the Responder plants breaks a named rule

struct FaultCase {
    std::string fault;  // as on the command line; "stuck-value" gets the first written register
    std::string profile;
    Framing framing;
    std::set<std::string> rules;  // at least one of these must be broken
};

std::ostream& operator<<(std::ostream& out, const FaultCase& c) {
    return out << c.fault << " on " << c.profile;
}

// Faults that delay or split a reply in time: the Responder never sees them (the server's send queue
// applies them), so the network fuzzer and the conformance runner catch them (tests/conformance).
const std::set<std::string> timing_faults = {"slow-reply", "gap-inside-frame"};

std::vector<FaultCase> fault_cases() {
    return {
        {"bad-crc", "mmk-2030", Framing::Rtu, {"reply.checksum"}},
        {"bad-lrc", "mmk-2030", Framing::Ascii, {"reply.checksum"}},
        {"wrong-byte-count", "mmk-2030", Framing::Tcp, {"reply.malformed"}},
        {"short-response", "mmk-2030", Framing::Tcp, {"reply.malformed"}},
        {"extra-bytes", "mmk-2030", Framing::Rtu, {"reply.malformed"}},
        {"wrong-unit", "mmk-2030", Framing::Rtu, {"reply.envelope"}},
        {"wrong-function", "mmk-2030", Framing::Tcp, {"reply.function"}},
        {"wrong-tid", "mmk-2030", Framing::Tcp, {"reply.envelope"}},
        {"bad-protocol-id", "walchem-w600", Framing::Tcp, {"reply.envelope"}},
        {"any-protocol-id", "walchem-w600", Framing::Tcp, {"silence.protocol_id"}},
        {"reply-to-broadcast", "mmk-2030", Framing::Rtu, {"silence.broadcast"}},
        {"ignore-max-quantity", "mmk-2030", Framing::Tcp, {"reply.quantity"}},
        {"wrong-exception=4", "mmk-2030", Framing::Tcp, {"reply.unsupported_function", "reply.quantity"}},
        {"exception-for-valid", "mmk-2030", Framing::Tcp, {"reply.exception_for_valid"}},
        {"no-reply=1", "mmk-2030", Framing::Rtu, {"reply.missing"}},
        // Swapped both ways, a write reads back as written; a valid float the device reads as another,
        // out of its range, is refused.
        {"word-swap", "walchem-w600", Framing::Tcp, {"reply.exception_for_valid"}},
        {"off-by-one-address", "mmk-2030", Framing::Tcp, {"reply.exception_for_valid", "state.lost_write"}},
        {"stuck-value", "mmk-2030", Framing::Tcp, {"state.lost_write"}},
        {"drop-write", "mmk-2030", Framing::Rtu, {"state.lost_write"}},
        {"accept-out-of-range", "mmk-2030", Framing::Tcp, {"reply.rejected_write"}},
        {"no-echo", "mmk-2030", Framing::Tcp, {"reply.echo"}},
        {"crash-after=3", "cth2265i", Framing::Rtu, {"reply.missing"}},
        {"duplicate-reply", "mmk-2030", Framing::Rtu, {"reply.duplicate"}},
        {"wrong-quantity", "mmk-2030", Framing::Tcp, {"reply.byte_count"}},
    };
}

class PlantedFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(PlantedFault, BreaksTheRuleMeantToCatchIt) {
    const auto& c = GetParam();
    const auto& p = mbscope::slave::test::profile(c.profile);
    std::string text = c.fault;
    if (text == "stuck-value") {
        // The first register the script writes.
        for (const auto& s : script(p, 1, c.framing))
            if (s.pdu[0] == 6) {
                text += "=" + std::to_string((s.pdu[1] << 8) | s.pdu[2]);
                break;
            }
    }
    const auto spec = sl::parse_fault(text);
    ASSERT_TRUE(spec) << spec.error();
    sl::FaultSet faults({*spec}, 7);
    const auto found = run(p, c.framing, faults);
    ASSERT_FALSE(found.empty()) << "the oracle did not notice " << c.fault;
    const bool named =
        std::any_of(found.begin(), found.end(), [&](const auto& v) { return c.rules.count(v.rule); });
    EXPECT_TRUE(named) << "none of the expected rules broken:" << listing(found);
}

INSTANTIATE_TEST_SUITE_P(Slave, PlantedFault, ::testing::ValuesIn(fault_cases()), [](const auto& info) {
    std::string n = info.param.fault.substr(0, info.param.fault.find('='));
    for (auto& ch : n)
        if (ch == '-') ch = '_';
    return n;
});

TEST(PlantedFaults, EveryFaultIsCaughtByTheOracleOrNamedAsATimingFault) {
    std::set<std::string> named = timing_faults;
    for (const auto& c : fault_cases())
        named.insert(c.fault.substr(0, c.fault.find('=')));
    for (std::size_t i = 0; i < sl::fault_count; ++i) {
        const std::string name(sl::to_string(static_cast<sl::Fault>(i)));
        EXPECT_TRUE(named.count(name)) << name << " has no oracle case";
    }
}

// ---- single rules, with the bytes written out

TEST(ExchangeOracle, SilenceIsDemandedForABadCrcAndARepliedOneIsAViolation) {
    const auto& p = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
    mbscope::modbus::transport::Exchange ex;
    ex.sent = mb::encode_rtu(1, pdu(3, {0, 1}));
    ex.sent.back() ^= 1;
    EXPECT_EQ(oracle.expectation(ex.sent), "no reply");
    EXPECT_TRUE(oracle.judge(ex).empty());
    ex.received = mb::encode_rtu(1, std::vector<std::uint8_t>{0x03, 0x02, 0x00, 0x00});
    ex.response = *mb::decode_rtu(ex.received);
    const auto v = oracle.judge(ex);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "silence.bad_checksum");
    EXPECT_EQ(v[0].source, "SL §2.5.1.2");
}

// AP §4.1: a PDU holds at most 253 bytes; over Modbus/TCP a longer one can be sent. The reference slave
// echoed an FC8 query of 254 bytes in a 261-byte ADU, and the oracle expected the echo. No reply, or a
// refusal, is right; a normal reply is a violation. Walchem's manual takes 256 (002:219).
TEST(ExchangeOracle, APduLongerThanTheDeviceTakesIsNotAnsweredNormally) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    std::vector<std::uint8_t> echo = {0x08, 0x00, 0x00};
    echo.resize(254, 0x5A);
    mbscope::modbus::transport::Exchange ex;
    ex.sent = mb::encode_tcp(1, 1, echo);
    EXPECT_EQ(oracle.expectation(ex.sent),
              "no reply or exception 01 (Illegal Function) or exception 03 (Illegal Data Value)");
    EXPECT_TRUE(oracle.judge(ex).empty());
    ex.received = mb::encode_tcp(1, 1, std::vector<std::uint8_t>{0x88, 0x03});
    ex.response = *mb::decode_tcp(ex.received);
    EXPECT_TRUE(oracle.judge(ex).empty());
    ex.received = ex.sent;
    ex.response = *mb::decode_tcp(ex.received);
    const auto v = oracle.judge(ex);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "silence.pdu_too_long");
    EXPECT_EQ(v[0].source, "AP §4.1");
    echo.pop_back();  // 253 bytes: the echo is due
    ex.sent = mb::encode_tcp(2, 1, echo);
    ex.received = ex.sent;
    ex.response = *mb::decode_tcp(ex.received);
    EXPECT_TRUE(oracle.judge(ex).empty());
}

// The generic profile knows no device's map or functions: a device that refuses an address it lacks (02),
// a value out of its range (03) or a function it does not implement (01) answers as AP §7 says. Against
// libmodbus's server (10,000 registers, no FC8) every such refusal was "exception for valid". A mapped
// profile still demands the normal reply, and the generic one still refuses another code for a read.
TEST(ExchangeOracle, TheGenericProfileAllowsTheRefusalsOfADeviceItDoesNotKnow) {
    const auto& generic = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Rtu, {{1, &generic}}, false);
    const auto rules = [](const std::vector<cf::OracleViolation>& v) {
        std::string out;
        for (const auto& x : v)
            out += x.rule + " ";
        return out;
    };
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(3, {54188, 125}), {0x83, 0x02})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(1, {60000, 16}), {0x81, 0x02})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(6, {20000, 7}), {0x86, 0x02})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(6, {20, 0xBEEF}), {0x86, 0x03})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(8, {0, 0x1234}), {0x88, 0x01})), "");
    // A diagnostics request one byte short (libmodbus answered 01, "expected exception 03"): the function
    // code is tested before the data (AP §6), so 01 is right too; another code is not.
    const std::vector<std::uint8_t> short_fc8{0x08, 0x00, 0x0C, 0xFF};
    EXPECT_EQ(rules(judge_rtu(oracle, 1, short_fc8, {0x88, 0x01})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, short_fc8, {0x88, 0x03})), "");
    EXPECT_NE(rules(judge_rtu(oracle, 1, short_fc8, {0x88, 0x04})), "");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(3, {0, 1}), {0x83, 0x04})), "reply.exception_for_valid ");
    EXPECT_EQ(rules(judge_rtu(oracle, 1, pdu(3, {0, 1}), {0x83, 0x03})), "reply.exception_for_valid ");

    const auto& mapped = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle strict(Framing::Rtu, {{1, &mapped}}, false);
    EXPECT_EQ(rules(judge_rtu(strict, 1, pdu(3, {0, 1}), {0x83, 0x02})), "reply.exception_for_valid ");
    EXPECT_NE(rules(judge_rtu(strict, 1, std::vector<std::uint8_t>{0x03, 0x00, 0x00, 0x00}, {0x83, 0x01})),
              "");
}

// A reply to 21 coils answers them in three bytes, the last one's three high bits padded with zeros (AP
// §6.1; the MK manual's example, 000:343, answers B2 0E 1B).
TEST(ExchangeOracle, PaddingBitsSetInACoilReplyAreAViolation) {
    const auto& p = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle oracle(Framing::Rtu, {{17, &p}}, false);
    const auto request = pdu(1, {0x13, 0x15});
    EXPECT_TRUE(judge_rtu(oracle, 17, request, {0x01, 0x03, 0xB2, 0x0E, 0x1B}).empty());
    const auto v = judge_rtu(oracle, 17, request, {0x01, 0x03, 0xB2, 0x0E, 0xFB});
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "reply.padding");
    EXPECT_EQ(v[0].source, "AP §6.1");
}

// Over Modbus/TCP the client sets aside a late reply to an earlier request (its transaction id) but keeps its
// bytes in `received`, before this request's own. They are not this request's reply: not trailing bytes
// after it, and no reply where silence is due.
TEST(ExchangeOracle, ALateReplyToAnEarlierRequestIsNotThisRequests) {
    const auto& p = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    const auto late = mb::encode_tcp(4, 1, std::vector<std::uint8_t>{0x83, 0x02});
    mbscope::modbus::transport::Exchange ex;
    ex.sent = mb::encode_tcp(5, 1, pdu(3, {0, 1}));
    const auto own = mb::encode_tcp(5, 1, std::vector<std::uint8_t>{0x03, 0x02, 0x00, 0x00});
    ex.received = late;
    ex.received.insert(ex.received.end(), own.begin(), own.end());
    ex.stale_replies.push_back(*mb::decode_tcp(late));
    ex.response = *mb::decode_tcp(own);
    EXPECT_TRUE(oracle.judge(ex).empty()) << listing(oracle.judge(ex));
    ex.received.insert(ex.received.end(), {0xDE, 0xAD});  // after its own reply: trailing bytes
    auto v = oracle.judge(ex);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "reply.trailing_bytes");

    // Protocol id 1 must go unanswered: a late reply to another request is no answer.
    mbscope::modbus::transport::Exchange silent;
    silent.sent = mb::encode_tcp(6, 1, pdu(3, {0, 1}), 1);
    silent.received = late;
    silent.stale_replies.push_back(*mb::decode_tcp(late));
    EXPECT_TRUE(oracle.judge(silent).empty()) << listing(oracle.judge(silent));
    // A due reply that did not come is missing, whatever else came.
    silent.sent = mb::encode_tcp(6, 1, pdu(3, {0, 1}));
    v = oracle.judge(silent);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "reply.missing");
}

// Over Modbus/TCP a server reached by its IP address has no use for the unit id (TCP §4.4.1.2): a lone
// device may answer unit 74 as its own (pymodbus with one context does), refuse it as a gateway (0A, 0B) or
// not answer. Its normal reply was reply.other_unit, a finding saved against a device doing what the
// specification allows. Served as its own, the request is judged as the device's; and a write it took for
// unit 74 leaves what its own points hold unknown (no state.lost_write when they read it back). On a line,
// another unit's request still goes unanswered.
TEST(ExchangeOracle, OverTcpALoneDeviceMayServeAnyUnitAsItsOwn) {
    const auto& p = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    const auto exchange = [](std::uint16_t tid, std::uint8_t unit, const std::vector<std::uint8_t>& request,
                             const std::vector<std::uint8_t>& reply) {
        mbscope::modbus::transport::Exchange ex;
        ex.sent = mb::encode_tcp(tid, unit, request);
        if (!reply.empty()) {
            ex.received = mb::encode_tcp(tid, unit, reply);
            ex.response = *mb::decode_tcp(ex.received);
        }
        return ex;
    };
    const auto read = pdu(3, {0, 1});
    for (const auto& reply : {std::vector<std::uint8_t>{0x03, 0x02, 0x00, 0x07}, std::vector<std::uint8_t>{},
                              std::vector<std::uint8_t>{0x83, 0x0A}, std::vector<std::uint8_t>{0x83, 0x0B}}) {
        const auto v = oracle.judge(exchange(1, 74, read, reply));
        EXPECT_TRUE(v.empty()) << listing(v);
    }
    // Judged as the device's own: a read of a point it has refused with 02 is a refusal it may not make.
    auto v = oracle.judge(exchange(2, 74, read, {0x83, 0x02}));
    ASSERT_EQ(v.size(), 1u) << listing(v);
    EXPECT_NE(v[0].rule, "reply.other_unit");
    // Unit 1 wrote 3 to register 21 (square-root cut-off, 0 to 5), unit 74 wrote 4 there, and unit 1 reads
    // 4: the device took unit 74's write as its own, no write of unit 1 was lost.
    const auto cut_off = pdu(3, {21, 1});
    v = oracle.judge(exchange(3, 1, pdu(6, {21, 3}), pdu(6, {21, 3})));
    EXPECT_TRUE(v.empty()) << listing(v);
    v = oracle.judge(exchange(4, 74, pdu(6, {21, 4}), pdu(6, {21, 4})));
    EXPECT_TRUE(v.empty()) << listing(v);
    v = oracle.judge(exchange(5, 1, cut_off, {0x03, 0x02, 0x00, 4}));
    EXPECT_TRUE(v.empty()) << listing(v);
    // A write of unit 1 is still held against it.
    v = oracle.judge(exchange(6, 1, pdu(6, {21, 3}), pdu(6, {21, 3})));
    EXPECT_TRUE(v.empty()) << listing(v);
    v = oracle.judge(exchange(7, 1, cut_off, {0x03, 0x02, 0x00, 4}));
    ASSERT_EQ(v.size(), 1u) << listing(v);
    EXPECT_EQ(v[0].rule, "state.lost_write");

    cf::ExchangeOracle line(Framing::Rtu, {{1, &p}}, false);
    v = judge_rtu(line, 74, read, {0x03, 0x02, 0x00, 0x07});
    ASSERT_EQ(v.size(), 1u) << listing(v);
    EXPECT_EQ(v[0].rule, "silence.other_unit");
}

// What a sender waits for, from the same expectations: a reply due, silence demanded (a broadcast, a bad CRC,
// another unit on a line), both allowed (another unit to a lone device over Modbus/TCP, an RTU request whose
// length its function does not predict), no opinion (no frame).
TEST(ExchangeOracle, AnswerDueFollowsTheExpectation) {
    using Answer = cf::ExchangeOracle::Answer;
    const auto& p = mbscope::slave::test::profile("mmk-2030");
    cf::ExchangeOracle tcp(Framing::Tcp, {{1, &p}}, true);
    EXPECT_EQ(tcp.answer_due(mb::encode_tcp(1, 1, pdu(3, {0, 1}))), Answer::Reply);
    EXPECT_EQ(tcp.answer_due(mb::encode_tcp(1, 74, pdu(3, {0, 1}))), Answer::Optional);
    EXPECT_EQ(tcp.expectation(mb::encode_tcp(1, 74, pdu(3, {0, 1}))).ends_with(", or no reply"), true);
    EXPECT_EQ(tcp.answer_due(mb::encode_tcp(1, 0, pdu(3, {0, 1}))), Answer::Unjudged);
    EXPECT_EQ(tcp.answer_due({0x00, 0x01, 0x00}), Answer::Unjudged);

    cf::ExchangeOracle rtu(Framing::Rtu, {{1, &p}}, false);
    EXPECT_EQ(rtu.answer_due(mb::encode_rtu(1, pdu(3, {0, 1}))), Answer::Reply);
    EXPECT_EQ(rtu.answer_due(mb::encode_rtu(0, pdu(6, {21, 3}))), Answer::Silence);
    EXPECT_EQ(rtu.answer_due(mb::encode_rtu(74, pdu(3, {0, 1}))), Answer::Silence);
    auto corrupt = mb::encode_rtu(1, pdu(3, {0, 1}));
    corrupt.back() ^= 1;
    EXPECT_EQ(rtu.answer_due(corrupt), Answer::Silence);
    // FC3 with one byte too many: its length is not the one its function gives.
    EXPECT_EQ(
        rtu.answer_due(mb::encode_rtu(1, std::vector<std::uint8_t>{0x03, 0x00, 0x00, 0x00, 0x01, 0x00})),
        Answer::Optional);
}

// 01 0C 00 25 00 is two CRC-valid RTU requests at once: FC12 with one data byte up to the silence, and
// FC12 as its function code ends it after four bytes (CRC 0x2500; the fifth byte 00 keeps the longer
// frame's CRC valid too). A slave that ends frames by content answers the four bytes normally, one that
// waits for the silence refuses the five with exception 03: both keep the rules, a reply to neither does
// not.
// Found by `mbscope fuzz` against the reference slave over rtu-tcp, reported as reply.malformed_request.
TEST(ExchangeOracle, AnRtuRequestWithAValidShorterFrameInsideMayBeAnsweredAsEither) {
    const auto& p = mbscope::slave::test::profile("modbus");
    const auto judge = [&](const std::vector<std::uint8_t>& reply_pdu) {
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        mbscope::modbus::transport::Exchange ex;
        ex.sent = {0x01, 0x0C, 0x00, 0x25, 0x00};
        ex.received = mb::encode_rtu(1, reply_pdu);
        ex.response = *mb::decode_rtu(ex.received);
        return oracle.judge(ex);
    };
    EXPECT_TRUE(judge({0x0C, 0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01}).empty());  // the four bytes' reply
    EXPECT_TRUE(judge({0x8C, 0x03}).empty());                                      // the five bytes'
    const auto v = judge({0x8C, 0x0A});  // neither: the generic profile allows 01-04 for FC12
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "reply.malformed_request");
}

// What the generic profile expects of a read: a device it does not know may lack the function or address.
const std::string generic_read =
    "a normal response or exception 01 (Illegal Function) or exception 02 (Illegal Data Address)";

TEST(ExchangeOracle, ListenOnlyModeSilencesEverythingUntilAValidRestart) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
    const auto send = [&](const std::vector<std::uint8_t>& request, const std::vector<std::uint8_t>& reply) {
        return judge_rtu(oracle, 1, request, reply);
    };
    EXPECT_TRUE(send(pdu(8, {4, 0}), {}).empty());
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), "no reply");
    const auto answered = send(pdu(3, {0, 1}), {0x03, 0x02, 0x00, 0x00});
    ASSERT_EQ(answered.size(), 1u);
    EXPECT_EQ(answered[0].rule, "silence.listen_only");
    // A frame the device never takes (a bad CRC) does not end the mode.
    mbscope::modbus::transport::Exchange corrupt;
    corrupt.sent = mb::encode_rtu(1, pdu(8, {1, 0}));
    corrupt.sent.back() ^= 1;
    EXPECT_TRUE(oracle.judge(corrupt).empty());
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), "no reply");
    EXPECT_TRUE(send(pdu(8, {1, 0x4500}), {}).empty());  // a restart with data the mode does not act on
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), "no reply");
    EXPECT_TRUE(send(pdu(8, {1, 0}), {}).empty());  // the restart, unanswered
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), generic_read);
}

// Force listen-only mode with data other than 00 00 may be refused with exception 03 (AP §6.8's state
// diagram; the reference slave does) or obeyed: silence, and the mode follows.
TEST(ExchangeOracle, ListenOnlyWithOtherDataMayBeRefusedOrObeyed) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
    const auto send = [&](const std::vector<std::uint8_t>& request, const std::vector<std::uint8_t>& reply) {
        return judge_rtu(oracle, 1, request, reply);
    };
    EXPECT_TRUE(send(pdu(8, {4, 1}), {0x88, 0x03}).empty());
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), generic_read);
    const auto wrong = send(pdu(8, {4, 1}), {0x88, 0x02});
    ASSERT_EQ(wrong.size(), 1u);
    EXPECT_EQ(wrong[0].rule, "silence.listen_only");
    EXPECT_TRUE(send(pdu(8, {4, 0}), {0x88, 0x03}).size() == 1u);  // 00 00 is the mode's own data
    EXPECT_TRUE(send(pdu(8, {4, 1}), {}).empty());
    EXPECT_EQ(oracle.expectation(mb::encode_rtu(1, pdu(3, {0, 1}))), "no reply");
}

// Whether a broadcast FC8 01/04 acts is said nowhere (SL §2.1 lets a broadcast carry writes, AP §6.8.1
// speaks of the addressed device): after one the device's mode is unknown and neither its silence nor its
// reply is judged, until it answers or is sent an addressed restart. The reference slave ignores both
// broadcasts; a device that obeyed them must not be reported either.
TEST(ExchangeOracle, ABroadcastListenOnlyDiagnosticsLeavesTheModeUnknownUntilTheDeviceSpeaks) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
    const auto send = [&](std::uint8_t unit, const std::vector<std::uint8_t>& request,
                          const std::vector<std::uint8_t>& reply) {
        return judge_rtu(oracle, unit, request, reply);
    };
    const auto read = mb::encode_rtu(1, pdu(3, {0, 1}));
    // A device that obeyed a broadcast 04: silent, and not reported.
    EXPECT_TRUE(send(0, pdu(8, {4, 0}), {}).empty());
    EXPECT_EQ(oracle.expectation(read), "");
    EXPECT_TRUE(send(1, pdu(3, {0, 1}), {}).empty());
    // An addressed restart brings it back either way; unanswered, since it was in the mode.
    EXPECT_TRUE(send(1, pdu(8, {1, 0}), {}).empty());
    EXPECT_EQ(oracle.expectation(read), generic_read);

    // A device that ignored a broadcast 04 answers, and from then on is judged again.
    EXPECT_TRUE(send(0, pdu(8, {4, 0}), {}).empty());
    EXPECT_TRUE(send(1, pdu(3, {0, 1}), {0x03, 0x02, 0x00, 0x00}).empty());
    EXPECT_EQ(oracle.expectation(read), generic_read);
    EXPECT_EQ(send(1, pdu(3, {0, 1}), {}).at(0).rule, "reply.missing");

    // In the mode by an addressed 04, a broadcast restart may or may not have left it.
    EXPECT_TRUE(send(1, pdu(8, {4, 0}), {}).empty());
    EXPECT_EQ(oracle.expectation(read), "no reply");
    EXPECT_TRUE(send(0, pdu(8, {1, 0}), {}).empty());
    EXPECT_EQ(oracle.expectation(read), "");
    EXPECT_TRUE(send(1, pdu(5, {5, 0x5B05}), {}).empty());  // still in it: silence is not reported
    EXPECT_TRUE(send(1, pdu(8, {1, 0}), {0x08, 0x00, 0x01, 0x00, 0x00}).empty());  // was out: the echo
    EXPECT_EQ(oracle.expectation(read), generic_read);
}

TEST(ExchangeOracle, AnAcknowledgedWriteMustReadBack) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    mbscope::modbus::transport::Exchange write;
    write.sent = mb::encode_tcp(1, 1, pdu(6, {7, 0x1234}));
    write.received = write.sent;  // the echo
    write.response = *mb::decode_tcp(write.received);
    EXPECT_TRUE(oracle.judge(write).empty());
    mbscope::modbus::transport::Exchange read;
    read.sent = mb::encode_tcp(2, 1, pdu(3, {7, 1}));
    read.received = mb::encode_tcp(2, 1, std::vector<std::uint8_t>{0x03, 0x02, 0x00, 0x00});
    read.response = *mb::decode_tcp(read.received);
    const auto v = oracle.judge(read);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v[0].rule, "state.lost_write");
    EXPECT_NE(v[0].expected.find("4660"), std::string::npos);
}

// A write the reply does not settle may have been done or not: a later read owes the earlier value nothing.
// With slave --fault no-echo, FC15 set coil 38, FC5 cleared it with a reply that was no echo (FF FF), and the
// read of 0 was "state.lost_write: expected 1, the value written" though 0 was the last value written.
TEST(ExchangeOracle, AWriteTheReplyDoesNotSettleLeavesThePointUnknown) {
    const auto& p = mbscope::slave::test::profile("modbus");
    const auto read_coil = [](std::uint8_t value) { return std::vector<std::uint8_t>{0x01, 0x01, value}; };
    const auto read_register = [](std::uint16_t value) {
        return std::vector<std::uint8_t>{0x03, 0x02, static_cast<std::uint8_t>(value >> 8),
                                         static_cast<std::uint8_t>(value)};
    };
    const std::vector<std::uint8_t> set_38{0x0F, 0x00, 0x26, 0x00, 0x01, 0x01, 0x01};
    const std::vector<std::uint8_t> set_38_ack{0x0F, 0x00, 0x26, 0x00, 0x01};
    {
        // A malformed acknowledgement (FC5's value is 0000 or FF00): the read of either value is no finding.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        EXPECT_TRUE(judge_rtu(oracle, 1, set_38, set_38_ack).empty());
        EXPECT_EQ(judge_rtu(oracle, 1, pdu(5, {38, 0}), pdu(5, {38, 0xFFFF})).at(0).rule, "reply.malformed");
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(1, {38, 1}), read_coil(0)).empty());
    }
    {
        // An echo unlike the request (another value): which one was stored is not known.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(6, {7, 100}), pdu(6, {7, 100})).empty());
        EXPECT_EQ(judge_rtu(oracle, 1, pdu(6, {7, 200}), pdu(6, {7, 0xFF37})).at(0).rule, "reply.echo");
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(3, {7, 1}), read_register(200)).empty());
    }
    {
        // No reply: the write may have been done before the reply was lost.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(6, {7, 100}), pdu(6, {7, 100})).empty());
        EXPECT_EQ(judge_rtu(oracle, 1, pdu(6, {7, 200}), {}).at(0).rule, "reply.missing");
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(3, {7, 1}), read_register(200)).empty());
    }
    {
        // What the unsettled write named is unknown, nothing else: a lost write elsewhere is still found.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(6, {7, 100}), pdu(6, {7, 100})).empty());
        EXPECT_EQ(judge_rtu(oracle, 1, pdu(6, {8, 5}), pdu(6, {8, 6})).at(0).rule, "reply.echo");
        const auto v = judge_rtu(oracle, 1, pdu(3, {7, 1}), read_register(0));
        ASSERT_EQ(v.size(), 1u);
        EXPECT_EQ(v[0].rule, "state.lost_write");
    }
    {
        // An acknowledgement like the request, sent twice, still settles the write (reply.duplicate is the
        // fault), and a read with a reply of the wrong shape forgets nothing.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        mbscope::modbus::transport::Exchange twice;
        twice.sent = mb::encode_rtu(1, pdu(6, {7, 100}));
        twice.received = twice.sent;
        twice.received.insert(twice.received.end(), twice.sent.begin(), twice.sent.end());
        twice.response = *mb::decode_rtu(twice.sent);
        EXPECT_EQ(oracle.judge(twice).at(0).rule, "reply.duplicate");
        EXPECT_FALSE(judge_rtu(oracle, 1, pdu(3, {9, 1}), {0x03, 0x04, 0, 0, 0, 0}).empty());
        const auto v = judge_rtu(oracle, 1, pdu(3, {7, 1}), read_register(0));
        ASSERT_EQ(v.size(), 1u);
        EXPECT_EQ(v[0].rule, "state.lost_write");
    }
    {
        // A refusal settles it: the value acknowledged before must still read back.
        cf::ExchangeOracle oracle(Framing::Rtu, {{1, &p}}, false);
        EXPECT_TRUE(judge_rtu(oracle, 1, pdu(6, {7, 100}), pdu(6, {7, 100})).empty());
        judge_rtu(oracle, 1, pdu(6, {7, 200}), {0x86, 0x04});
        const auto v = judge_rtu(oracle, 1, pdu(3, {7, 1}), read_register(200));
        ASSERT_EQ(v.size(), 1u);
        EXPECT_EQ(v[0].rule, "state.lost_write");
    }
}

// An acknowledged write that ran past 65535 breaks reply.address; what it held past the end is no
// register's, so it is not remembered as written at 0, 1, ... (a later read there owes it nothing).
TEST(ExchangeOracle, AWritePastTheLastAddressIsNotRememberedAtZero) {
    const auto& p = mbscope::slave::test::profile("modbus");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    mbscope::modbus::transport::Exchange write;
    write.sent = mb::encode_tcp(
        1, 1, std::vector<std::uint8_t>{0x10, 0xFF, 0xFF, 0x00, 0x02, 0x04, 0x11, 0x11, 0x22, 0x22});
    write.received = mb::encode_tcp(1, 1, std::vector<std::uint8_t>{0x10, 0xFF, 0xFF, 0x00, 0x02});
    write.response = *mb::decode_tcp(write.received);
    const auto refused = oracle.judge(write);
    ASSERT_EQ(refused.size(), 1u);
    EXPECT_EQ(refused[0].rule, "reply.address");
    mbscope::modbus::transport::Exchange read;
    read.sent = mb::encode_tcp(2, 1, pdu(3, {0, 1}));
    read.received = mb::encode_tcp(2, 1, std::vector<std::uint8_t>{0x03, 0x02, 0x00, 0x00});
    read.response = *mb::decode_tcp(read.received);
    EXPECT_TRUE(oracle.judge(read).empty());
}

}  // namespace

namespace {
// A lone half of a 32-bit value is judged by the device with the other half it holds (002:499 has clients
// write a Walchem set-point with FC6): the oracle, which does not know that half, takes a normal reply or
// 03; the whole value written by FC16 it judges itself. Booleans in a register take 0 or 1 (002:424-429).
TEST(ExchangeOracle, ALoneHalfOfA32BitValueMayBeRefusedAndABooleanTakesZeroOrOne) {
    const auto& p = mbscope::slave::test::profile("walchem-w600");
    cf::ExchangeOracle oracle(Framing::Tcp, {{1, &p}}, true);
    const auto expect = [&](std::vector<std::uint8_t> request) {
        return oracle.expectation(mb::encode_tcp(1, 1, request));
    };
    EXPECT_EQ(expect(pdu(6, {0x95, 0x44FA})), "a normal response or exception 03 (Illegal Data Value)");
    EXPECT_EQ(expect({0x10, 0x00, 0x94, 0x00, 0x02, 0x04, 0x00, 0x00, 0x44, 0xFA}),
              "exception 03 (Illegal Data Value)");
    EXPECT_EQ(expect(pdu(6, {0x2300, 0xFFFF})), "exception 03 (Illegal Data Value)");
    EXPECT_EQ(expect(pdu(6, {0x2300, 1})), "a normal response");
}
}  // namespace

}  // namespace test_fuzz_oracle_test
