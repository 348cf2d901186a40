// Every planted fault of slave/faults.hpp: what it does on the wire, and that without it the wire is
// clean. Faults that live in the PDU are shown through slave::Device; faults that live in the ADU or in time
// through slave::Server on 127.0.0.1 port 0 in a thread, with a raw socket client (tcp://, rtu-tcp://,
// ascii-tcp://). Expected bytes are written by hand (CRCs and LRCs computed outside the code under test).
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_faults_test {
namespace {

using mb::Table;
using namespace std::chrono_literals;

std::vector<FaultSpec> specs(const std::string& text) {
    if (text.empty()) return {};
    auto spec = parse_fault(text);
    EXPECT_TRUE(spec.has_value()) << text;
    return spec ? std::vector<FaultSpec>{*spec} : std::vector<FaultSpec>{};
}

// ASCII frame text as the hex of its characters, so every expectation is compared the same way.
std::string ascii_hex(std::string_view text) {
    return hex(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

TEST(Faults, TwentySixAreDeclaredWithTheirCommandLineNames) {
    EXPECT_EQ(fault_count, 26u);
    std::set<std::string> names;
    for (std::size_t i = 0; i < fault_count; ++i) {
        const std::string name(to_string(static_cast<Fault>(i)));
        names.insert(name);
        EXPECT_NE(fault_help().find("  " + name), std::string::npos) << name;
    }
    EXPECT_EQ(names.size(), fault_count);
    EXPECT_EQ(to_string(Fault::ReplyToBroadcast), "reply-to-broadcast");
    EXPECT_EQ(to_string(Fault::CrashAfter), "crash-after");
    EXPECT_EQ(to_string(Fault::DuplicateReply), "duplicate-reply");
    EXPECT_EQ(to_string(Fault::WrongQuantity), "wrong-quantity");
}

TEST(Faults, ParseNamesTheProblem) {
    auto ok = parse_fault("no-reply=0.25");
    ASSERT_TRUE(ok.has_value());
    EXPECT_EQ(ok->fault, Fault::NoReply);
    EXPECT_DOUBLE_EQ(ok->arg, 0.25);
    EXPECT_EQ(parse_fault("bad-crc")->arg, 1.0);  // rate faults default to every response
    EXPECT_NE(parse_fault("no-such").error().find("unknown fault 'no-such'"), std::string::npos);
    EXPECT_NE(parse_fault("slow-reply").error().find("needs"), std::string::npos);
    EXPECT_NE(parse_fault("no-reply=1.5").error().find("rate must be in (0, 1]"), std::string::npos);
    EXPECT_NE(parse_fault("bad-crc=0").error().find("rate"), std::string::npos);
    EXPECT_NE(parse_fault("slow-reply=abc").error().find("not a number"), std::string::npos);
    EXPECT_NE(parse_fault("wrong-exception=0").error().find("1..255"), std::string::npos);
    EXPECT_NE(parse_fault("stuck-value=70000").error().find("0..65535"), std::string::npos);
    EXPECT_NE(parse_fault("crash-after=-1").error().find("negative"), std::string::npos);
    // NaN passed every range check (no-reply=nan was planted); huge values overflowed their conversions.
    for (const char* text : {"no-reply=nan", "bad-crc=nan", "wrong-exception=nan", "slow-reply=inf",
                             "stuck-value=-inf", "crash-after=nan"})
        EXPECT_NE(parse_fault(text).error().find("is not a number"), std::string::npos) << text;
    EXPECT_NE(parse_fault("slow-reply=1e300").error().find("at most 3600000 ms"), std::string::npos);
    EXPECT_NE(parse_fault("gap-inside-frame=1e9").error().find("at most 100000"), std::string::npos);
    EXPECT_NE(parse_fault("crash-after=1e300").error().find("whole number"), std::string::npos);
    EXPECT_NE(parse_fault("crash-after=2.5").error().find("whole number"), std::string::npos);
    EXPECT_DOUBLE_EQ(parse_fault("crash-after=40")->arg, 40.0);
    EXPECT_DOUBLE_EQ(parse_fault("gap-inside-frame=3.5")->arg, 3.5);
}

// Which faults a transport can show: each of those tied to one framing's fields is refused on the others
// (the slave will not plant it there), every other fault is accepted on every framing. Enumerated, so a
// new fault's place here is decided, not defaulted.
TEST(Faults, ThoseOfOneFramingAreWithoutEffectOnTheOthers) {
    using mb::Framing;
    const std::map<Fault, std::set<Framing>> shows_on = {
        {Fault::BadCrc, {Framing::Rtu}},        {Fault::BadLrc, {Framing::Ascii}},
        {Fault::WrongTid, {Framing::Tcp}},      {Fault::BadProtocolId, {Framing::Tcp}},
        {Fault::AnyProtocolId, {Framing::Tcp}}, {Fault::GapInsideFrame, {Framing::Rtu, Framing::Ascii}},
    };
    for (std::size_t i = 0; i < fault_count; ++i) {
        const auto f = static_cast<Fault>(i);
        const auto tied = shows_on.find(f);
        for (Framing framing : {Framing::Rtu, Framing::Ascii, Framing::Tcp}) {
            const bool shows = tied == shows_on.end() || tied->second.count(framing) == 1;
            const auto why = fault_without_effect(f, framing);
            EXPECT_EQ(why.has_value(), !shows) << to_string(f) << " over " << mb::to_string(framing);
            if (why) {
                EXPECT_NE(why->find("only"), std::string::npos) << *why;
            }
        }
    }
}

// A rate draws from the seeded generator: the same seed gives the same sequence of outcomes.
TEST(Faults, RateIsDeterministicUnderTheSameSeed) {
    const auto draws = [](std::uint64_t seed) {
        FaultSet f(specs("no-reply=0.5"), seed);
        std::vector<bool> out;
        for (int i = 0; i < 64; ++i)
            out.push_back(f.fires(Fault::NoReply));
        return out;
    };
    const auto a = draws(7);
    EXPECT_EQ(a, draws(7));
    EXPECT_NE(a, draws(8));
    const auto hits = std::count(a.begin(), a.end(), true);
    EXPECT_GT(hits, 8);
    EXPECT_LT(hits, 56);
    FaultSet none;
    EXPECT_FALSE(none.any());
    EXPECT_FALSE(none.fires(Fault::NoReply));
}

// ---------------------------------------------------------------------------------------------------------
// Faults in the PDU, through the Device.

struct Step {
    std::string request;
    std::string without;  // the reply with no fault planted
    std::string with;     // the reply with the fault planted
    bool broadcast = false;
};

struct PduFaultCase {
    std::string name;
    std::string fault;
    std::string profile;
    std::vector<Step> steps;
    std::function<void(RegisterImage&)> setup = {};
};

void PrintTo(const PduFaultCase& c, std::ostream* os) {
    *os << c.name;
}

class PduFault : public ::testing::TestWithParam<PduFaultCase> {};

TEST_P(PduFault, ShowsOnlyWhenPlanted) {
    const auto& c = GetParam();
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault " + c.fault : "no fault");
        FaultSet faults(planted ? specs(c.fault) : std::vector<FaultSpec>{}, 1);
        Device device(profile(c.profile), 1, &faults);
        if (c.setup) c.setup(device.image());
        for (const auto& s : c.steps) {
            SCOPED_TRACE(s.request);
            EXPECT_EQ(ask(device, s.request, s.broadcast), planted ? s.with : s.without);
        }
    }
}

constexpr Table HR = Table::HoldingRegisters;

const std::vector<PduFaultCase> pdu_faults = {
    {"WrongByteCount",
     "wrong-byte-count",
     "modbus",
     {{"03 00 00 00 01", "03 02 00 00", "03 03 00 00"}, {"01 00 00 00 01", "01 01 00", "01 02 00"}}},
    // The profile's limit (MK: 15 registers) is ignored, the specification's (125) still holds.
    {"IgnoreMaxQuantity",
     "ignore-max-quantity",
     "mmk-2030",
     {{"03 00 00 00 10", "83 03",
       "03 20 " +
           [] {
               std::string z;
               for (int i = 0; i < 32; ++i)
                   z += i ? " 00" : "00";
               return z;
           }()},
      {"03 00 00 00 7E", "83 03", "83 03"}},
     [](RegisterImage& i) {
         for (std::uint16_t a = 0; a < 16; ++a)
             i.set_reg(HR, a, 0);
     }},
    {"WrongException",
     "wrong-exception=7",
     "mmk-2030",
     {{"02 00 00 00 01", "82 01", "82 07"}, {"03 00 C8 00 01", "83 02", "83 07"}}},
    {"ExceptionForValid",
     "exception-for-valid",
     "modbus",
     {{"03 00 00 00 01", "03 02 00 00", "83 04"}, {"02 FF FF 00 02", "82 02", "82 02"}}},
    {"WordSwap",
     "word-swap",
     "walchem-w600",
     {{"03 00 94 00 02", "03 04 00 00 40 E0", "03 04 40 E0 00 00"}},
     [](RegisterImage& i) { i.set_f32(HR, 148, 7.0f, mb::WordOrder::Cdab); }},
    // CTH2265I's total is two points, low word at 4002 and high word at 4003: swapped the same way.
    {"WordSwapOfLowAndHighWords",
     "word-swap",
     "cth2265i",
     {{"03 0F A2 00 02", "03 04 00 02 00 01", "03 04 00 01 00 02"},
      {"03 0F A3 00 01", "03 02 00 01", "03 02 00 02"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 4002, 2);
         i.set_reg(HR, 4003, 1);
     }},
    {"OffByOneAddress",
     "off-by-one-address",
     "modbus",
     {{"03 00 0A 00 01", "03 02 11 11", "03 02 22 22"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 10, 0x1111);
         i.set_reg(HR, 11, 0x2222);
     }},
    {"StuckValue",
     "stuck-value=23",
     "mmk-2030",
     {{"06 00 17 00 0A", "06 00 17 00 0A", "06 00 17 00 0A"},
      {"03 00 17 00 01", "03 02 00 0A", "03 02 00 00"}}},
    {"DropWrite",
     "drop-write",
     "modbus",
     {{"06 00 00 12 34", "06 00 00 12 34", "06 00 00 12 34"},
      {"03 00 00 00 01", "03 02 12 34", "03 02 00 00"}}},
    // Ranges, enumerations and linked limits are not enforced; the address and access rules still are.
    {"AcceptOutOfRange",
     "accept-out-of-range",
     "mmk-2030",
     {{"06 00 07 00 64", "86 03", "06 00 07 00 64"},
      {"03 00 07 00 01", "03 02 00 01", "03 02 00 64"},  // ENDER reads the unit served (MK-CFG-01)
      {"06 00 57 02 58", "86 03", "06 00 57 02 58"},
      {"06 00 00 00 00", "86 02", "86 02"}}},
    // DCY-2050's loop 1 output (HR 2, -100.0 to 100.0 %) is read-only in automatic mode (coil 0 set,
    // MK-RO-02, 000:731): out of range and read-only now, the fault accepts the value but not the write.
    {"AcceptOutOfRangeKeepsConditionalAccess",
     "accept-out-of-range",
     "dcy-2050",
     {{"06 00 02 07 D0", "86 03", "86 02"}},
     [](RegisterImage& i) { i.set_bit(Table::Coils, 0, true); }},
    {"NoEcho",
     "no-echo",
     "modbus",
     {{"06 00 00 12 34", "06 00 00 12 34", "06 00 00 ED CB"},
      {"05 00 00 FF 00", "05 00 00 FF 00", "05 00 00 00 FF"},
      {"08 00 00 A5 37", "08 00 00 A5 37", "08 00 00 5A C8"}}},
    {"ReplyToBroadcast",
     "reply-to-broadcast",
     "modbus",
     {{"06 00 00 12 34", "", "06 00 00 12 34", true}, {"03 00 00 00 01", "03 02 12 34", "03 02 12 34"}}},
};

INSTANTIATE_TEST_SUITE_P(Device, PduFault, ::testing::ValuesIn(pdu_faults),
                         [](const auto& info) { return info.param.name; });

// stuck-value given at two registers freezes both: only the last one acted, while the slave announced both.
TEST(Faults, StuckValueAtTwoRegistersFreezesBoth) {
    FaultSet faults({*parse_fault("stuck-value=1"), *parse_fault("stuck-value=2")}, 1);
    Device device(profile("modbus"), 1, &faults);
    EXPECT_EQ(ask(device, "06 00 01 00 AA"), "06 00 01 00 AA");  // acknowledged, not kept
    EXPECT_EQ(ask(device, "06 00 02 00 BB"), "06 00 02 00 BB");
    EXPECT_EQ(ask(device, "06 00 03 00 CC"), "06 00 03 00 CC");  // not stuck: kept
    EXPECT_EQ(ask(device, "03 00 01 00 03"), "03 06 00 00 00 00 00 CC");
    EXPECT_TRUE(device.frozen(HR, 1));
    EXPECT_TRUE(device.frozen(HR, 2));
    EXPECT_FALSE(device.frozen(HR, 3));
}

// Faults that act once are refused a second time, so none is announced as planted without acting; a
// register stuck twice adds nothing and is refused too. Two registers stuck, or two different faults, pass.
TEST(Faults, ASecondInstanceIsRefusedUnlessBothAct) {
    for (const auto& [first, second] :
         std::vector<std::pair<std::string, std::string>>{{"slow-reply=100", "slow-reply=300"},
                                                          {"wrong-exception=2", "wrong-exception=3"},
                                                          {"no-reply=0.5", "no-reply=0.5"},
                                                          {"bad-crc", "bad-crc=0.5"},
                                                          {"crash-after=5", "crash-after=9"}}) {
        const auto refused = parse_faults({first, "word-swap", second});
        ASSERT_FALSE(refused.has_value()) << first << ", " << second;
        EXPECT_NE(refused.error().find("--fault " + second + ": "), std::string::npos) << refused.error();
        EXPECT_NE(refused.error().find("already planted (--fault " + first + ")"), std::string::npos)
            << refused.error();
    }
    const auto twice = parse_faults({"stuck-value=7", "stuck-value=7"});
    ASSERT_FALSE(twice.has_value());
    EXPECT_EQ(twice.error(), "--fault stuck-value=7: that register is already stuck (--fault stuck-value=7)");
    const auto both = parse_faults({"stuck-value=1", "slow-reply=10", "stuck-value=2"});
    ASSERT_TRUE(both.has_value()) << both.error();
    EXPECT_EQ(FaultSet(*both, 1).stuck_addresses(), (std::vector<std::uint16_t>{1, 2}));
    EXPECT_NE(parse_faults({"slow-reply"}).error().find("needs"), std::string::npos);  // parse_fault's
}

// word-swap is the wrong word order both ways: what the device answers, written back, leaves its value as
// it was, for a 32-bit point (Walchem's floats) and for a value the map gives as low and high words
// (CTH2265I). A register written alone lands where a read of it alone looks: the other register of its
// value, even past the block's edge.
TEST(Faults, WordSwapWritesTheWayItReads) {
    FaultSet faults(specs("word-swap"), 1);
    {
        SCOPED_TRACE("walchem-w600 float at 148");
        Device device(profile("walchem-w600"), 1, &faults);
        device.image().set_f32(HR, 148, 7.0f, mb::WordOrder::Cdab);
        EXPECT_EQ(ask(device, "03 00 94 00 02"), "03 04 40 E0 00 00");
        EXPECT_EQ(ask(device, "10 00 94 00 02 04 40 E0 00 00"), "10 00 94 00 02");
        EXPECT_EQ(device.image().f32(HR, 148, mb::WordOrder::Cdab), 7.0f);
        EXPECT_EQ(ask(device, "06 00 94 40 E0"), "06 00 94 40 E0");  // each half alone, as read alone
        EXPECT_EQ(ask(device, "06 00 95 00 00"), "06 00 95 00 00");
        EXPECT_EQ(device.image().f32(HR, 148, mb::WordOrder::Cdab), 7.0f);
        EXPECT_EQ(ask(device, "03 00 94 00 02"), "03 04 40 E0 00 00");
    }
    {
        SCOPED_TRACE("cth2265i K-factor 1 at 4042 (low) and 4043 (high)");
        Device device(profile("cth2265i"), 1, &faults);
        device.image().set_reg(HR, 4042, 2);
        device.image().set_reg(HR, 4043, 1);
        EXPECT_EQ(ask(device, "03 0F CA 00 02"), "03 04 00 01 00 02");
        EXPECT_EQ(ask(device, "10 0F CA 00 02 04 00 01 00 02"), "10 0F CA 00 02");
        EXPECT_EQ(ask(device, "06 0F CA 00 01"), "06 0F CA 00 01");
        EXPECT_EQ(device.image().reg(HR, 4042), 2);
        EXPECT_EQ(device.image().reg(HR, 4043), 1);
        // 4043 and 4044: K-factor 1's high word and K-factor 2's low word, each moved to its other half.
        EXPECT_EQ(ask(device, "10 0F CB 00 02 04 00 07 00 08"), "10 0F CB 00 02");
        EXPECT_EQ(device.image().reg(HR, 4042), 7);
        EXPECT_EQ(device.image().reg(HR, 4045), 8);
        EXPECT_EQ(ask(device, "03 0F CB 00 02"), "03 04 00 07 00 08");
    }
}

// ---------------------------------------------------------------------------------------------------------
// Faults in the ADU, through the Server.

struct WireFaultCase {
    std::string name;
    std::string fault;
    std::string scheme;
    std::string request;
    std::string without;
    std::string with;  // "" = no answer
};

void PrintTo(const WireFaultCase& c, std::ostream* os) {
    *os << c.name;
}

class WireFault : public ::testing::TestWithParam<WireFaultCase> {};

TEST_P(WireFault, ShowsOnlyWhenPlanted) {
    const auto& c = GetParam();
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault " + c.fault : "no fault");
        RunningServer server(planted ? std::vector<std::string>{c.fault} : std::vector<std::string>{});
        Client client(server.start(c.scheme));
        ASSERT_TRUE(client.connected());
        const std::string& expected = planted ? c.with : c.without;
        const std::size_t count = expected.empty() ? 1 : bytes(expected).size();
        EXPECT_EQ(client.exchange(c.request, count, expected.empty() ? silence : 5000ms), expected);
    }
}

// FC3 register 0 of unit 1 (value 0) in each framing: RTU CRC 0x0A84 / reply 0x44B8, ASCII LRC FB / FA.
const std::string tcp_request = "00 01 00 00 00 06 01 03 00 00 00 01";
const std::string tcp_reply = "00 01 00 00 00 05 01 03 02 00 00";

const std::vector<WireFaultCase> wire_faults = {
    {"BadCrc", "bad-crc", "rtu-tcp", "01 03 00 00 00 01 84 0A", "01 03 02 00 00 B8 44",
     "01 03 02 00 00 47 BB"},
    {"BadLrc", "bad-lrc", "ascii-tcp", ascii_hex(":010300000001FB\r\n"), ascii_hex(":0103020000FA\r\n"),
     ascii_hex(":0103020000FB\r\n")},
    {"WrongUnit", "wrong-unit", "tcp", tcp_request, tcp_reply, "00 01 00 00 00 05 02 03 02 00 00"},
    {"WrongUnitRtu", "wrong-unit", "rtu-tcp", "01 03 00 00 00 01 84 0A", "01 03 02 00 00 B8 44",
     "02 03 02 00 00 FC 44"},
    {"WrongTid", "wrong-tid", "tcp", tcp_request, tcp_reply, "00 02 00 00 00 05 01 03 02 00 00"},
    {"BadProtocolId", "bad-protocol-id", "tcp", tcp_request, tcp_reply, "00 01 00 01 00 05 01 03 02 00 00"},
    // Protocol id 1 is not Modbus (TCP §3.1.3): discarded, unless the stack never looks at the field.
    {"AnyProtocolId", "any-protocol-id", "tcp", "00 01 00 01 00 06 01 03 00 00 00 01", "", tcp_reply},
    {"ShortResponse", "short-response", "tcp", tcp_request, tcp_reply, "00 01 00 00 00 04 01 03 02 00"},
    {"ExtraBytes", "extra-bytes", "tcp", tcp_request, tcp_reply, "00 01 00 00 00 07 01 03 02 00 00 DE AD"},
    {"WrongFunction", "wrong-function", "tcp", tcp_request, tcp_reply, "00 01 00 00 00 05 01 04 02 00 00"},
    {"WrongFunctionOnException", "wrong-function", "tcp", "00 09 00 00 00 06 01 02 FF FF 00 02",
     "00 09 00 00 00 03 01 82 02", "00 09 00 00 00 03 01 83 02"},
    // Unit 0 (broadcast) FC6 register 0 := 0x1234.
    {"ReplyToBroadcast", "reply-to-broadcast", "tcp", "00 05 00 00 00 06 00 06 00 00 12 34", "",
     "00 05 00 00 00 06 00 06 00 00 12 34"},
    {"ReplyToBroadcastRtu", "reply-to-broadcast", "rtu-tcp", "00 06 00 00 12 34 85 6C", "",
     "00 06 00 00 12 34 85 6C"},
    {"CrashAfterZero", "crash-after=0", "tcp", tcp_request, tcp_reply, ""},
    {"NoReplyEveryRequest", "no-reply=1", "tcp", tcp_request, tcp_reply, ""},
    // The same bytes twice in one write: the transaction id too (TCP), the CRC too (RTU).
    {"DuplicateReply", "duplicate-reply", "tcp", tcp_request, tcp_reply, tcp_reply + " " + tcp_reply},
    {"DuplicateReplyRtu", "duplicate-reply", "rtu-tcp", "01 03 00 00 00 01 84 0A", "01 03 02 00 00 B8 44",
     "01 03 02 00 00 B8 44 01 03 02 00 00 B8 44"},
    // One register more than asked, its byte count to match; FC1's 8 coils in two bytes; FC16 and FC15
    // acknowledging one more than written.
    {"WrongQuantityRead", "wrong-quantity", "tcp", tcp_request, tcp_reply,
     "00 01 00 00 00 07 01 03 04 00 00 00 00"},
    {"WrongQuantityCoils", "wrong-quantity", "tcp", "00 04 00 00 00 06 01 01 00 00 00 08",
     "00 04 00 00 00 04 01 01 01 00", "00 04 00 00 00 05 01 01 02 00 00"},
    {"WrongQuantityWriteRegisters", "wrong-quantity", "tcp", "00 03 00 00 00 09 01 10 00 00 00 01 02 00 07",
     "00 03 00 00 00 06 01 10 00 00 00 01", "00 03 00 00 00 06 01 10 00 00 00 02"},
    {"WrongQuantityWriteCoils", "wrong-quantity", "tcp", "00 05 00 00 00 08 01 0F 00 00 00 03 01 05",
     "00 05 00 00 00 06 01 0F 00 00 00 03", "00 05 00 00 00 06 01 0F 00 00 00 04"},
};

INSTANTIATE_TEST_SUITE_P(Server, WireFault, ::testing::ValuesIn(wire_faults),
                         [](const auto& info) { return info.param.name; });

// Over UDP each copy of a reply sent twice is a datagram of its own: one datagram holding both is no
// Modbus/UDP reply, and a client reading it saw bytes that form no frame, not a reply that came twice.
TEST(ServerFaults, DuplicateReplyOverUdpIsTwoDatagrams) {
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault duplicate-reply" : "no fault");
        RunningServer server(planted ? std::vector<std::string>{"duplicate-reply"}
                                     : std::vector<std::string>{});
        const std::uint16_t port = server.start("udp");
        const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        ASSERT_GE(fd, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_port = htons(port);
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
        const auto request = bytes(tcp_request);
        ASSERT_EQ(::send(fd, request.data(), request.size(), 0), static_cast<ssize_t>(request.size()));
        std::vector<std::string> datagrams;
        for (pollfd p{fd, POLLIN, 0}; ::poll(&p, 1, datagrams.empty() ? 5000 : 300) > 0;) {
            std::uint8_t buf[300];
            const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
            if (n <= 0) break;
            datagrams.push_back(hex(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n))));
        }
        ::close(fd);
        EXPECT_EQ(datagrams, std::vector<std::string>(planted ? 2 : 1, tcp_reply));
    }
}

std::string tcp_read_request(std::uint16_t tid) {
    const std::uint8_t adu[] = {
        static_cast<std::uint8_t>(tid >> 8), static_cast<std::uint8_t>(tid), 0, 0, 0, 6, 1, 3, 0, 0, 0, 1};
    return hex(adu);
}

// crash-after=N: N requests answered, none after.
TEST(ServerFaults, CrashAfterAnswersNThenNothing) {
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault crash-after=2" : "no fault");
        RunningServer server(planted ? std::vector<std::string>{"crash-after=2"}
                                     : std::vector<std::string>{});
        Client client(server.start("tcp"));
        for (std::uint16_t tid = 1; tid <= 4; ++tid) {
            const bool answered = !planted || tid <= 2;
            const std::string reply = client.exchange(tcp_read_request(tid), 11, answered ? 5000ms : silence);
            EXPECT_EQ(bytes(reply).size(), answered ? 11u : 0u) << "request " << tid;
        }
    }
}

// no-reply=RATE: which requests go unanswered depends on the seed and the order of requests only.
TEST(ServerFaults, NoReplyRateIsTheSameSequenceUnderTheSameSeed) {
    const auto answered = [](const std::vector<std::string>& faults, std::uint64_t seed) {
        RunningServer server(faults, seed);
        Client client(server.start("tcp"));
        std::string burst;
        for (std::uint16_t tid = 1; tid <= 24; ++tid)
            burst += (tid > 1 ? " " : "") + tcp_read_request(tid);
        client.send(bytes(burst));
        std::vector<std::uint16_t> tids;
        for (;;) {
            const auto reply = client.read(11, silence);
            if (reply.size() < 11) break;
            tids.push_back(static_cast<std::uint16_t>(reply[0] << 8 | reply[1]));
        }
        return tids;
    };
    const auto all = answered({}, 3);
    ASSERT_EQ(all.size(), 24u);
    const auto first = answered({"no-reply=0.5"}, 3);
    EXPECT_EQ(first, answered({"no-reply=0.5"}, 3));
    EXPECT_GT(first.size(), 0u);
    EXPECT_LT(first.size(), 24u);
    EXPECT_NE(first, answered({"no-reply=0.5"}, 4));
}

// slow-reply=MS: the answer comes at least MS late. Only a generous lower bound is asserted (and, without the
// fault, that the answer is not that late).
TEST(ServerFaults, SlowReplyDelaysTheAnswer) {
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault slow-reply=800" : "no fault");
        RunningServer server(planted ? std::vector<std::string>{"slow-reply=800"}
                                     : std::vector<std::string>{});
        Client client(server.start("tcp"));
        const auto sent = std::chrono::steady_clock::now();
        EXPECT_EQ(client.exchange(tcp_request, 11), tcp_reply);
        const auto took = std::chrono::steady_clock::now() - sent;
        if (planted)
            EXPECT_GE(took, 750ms);
        else
            EXPECT_LT(took, 750ms);
    }
}

// gap-inside-frame=CHARS over rtu-tcp: the response arrives in two parts, CHARS character times apart
// (200 characters at the default 9600 baud: about 230 ms), which together are the whole frame.
TEST(ServerFaults, GapInsideFrameSplitsTheResponse) {
    for (bool planted : {false, true}) {
        SCOPED_TRACE(planted ? "--fault gap-inside-frame=200" : "no fault");
        RunningServer server(planted ? std::vector<std::string>{"gap-inside-frame=200"}
                                     : std::vector<std::string>{});
        Client client(server.start("rtu-tcp"));
        client.send(bytes("01 03 00 00 00 01 84 0A"));
        auto first = client.read_some(5000ms);
        EXPECT_EQ(first.size(), planted ? 3u : 7u);
        const auto rest = client.read(7 - first.size());
        first.insert(first.end(), rest.begin(), rest.end());
        EXPECT_EQ(hex(first), "01 03 02 00 00 B8 44");
    }
}

// The fault reaches every framing it names: bad-crc leaves TCP alone, bad-lrc leaves RTU alone.
TEST(ServerFaults, ChecksumFaultsTouchOnlyTheirFraming) {
    {
        RunningServer server({"bad-crc"});
        Client client(server.start("tcp"));
        EXPECT_EQ(client.exchange(tcp_request, 11), tcp_reply);
    }
    {
        RunningServer server({"bad-lrc"});
        Client client(server.start("rtu-tcp"));
        EXPECT_EQ(client.exchange("01 03 00 00 00 01 84 0A", 7), "01 03 02 00 00 B8 44");
    }
}

// Faults planted together each leave their mark on the same response: over rtu-tcp, wrong-unit,
// wrong-function and extra-bytes change the PDU and bad-crc the frame around it (the right CRC of
// 02 04 02 00 00 DE AD is D8 99); over tcp, wrong-tid, bad-protocol-id, wrong-unit and wrong-function.
TEST(ServerFaults, FaultsPlantedTogetherEachShow) {
    {
        RunningServer server({"wrong-unit", "wrong-function", "extra-bytes", "bad-crc"});
        Client client(server.start("rtu-tcp"));
        client.send(bytes("01 03 00 00 00 01 84 0A"));
        const auto reply = client.read(9);
        ASSERT_EQ(reply.size(), 9u);
        EXPECT_EQ(hex(std::span(reply).first(7)), "02 04 02 00 00 DE AD");
        EXPECT_NE(hex(std::span(reply).last(2)), "D8 99") << "bad-crc did not spoil the CRC";
    }
    {
        RunningServer server({"wrong-tid", "bad-protocol-id", "wrong-unit", "wrong-function"});
        Client client(server.start("tcp"));
        EXPECT_EQ(client.exchange(tcp_read_request(1), 11), "00 02 00 01 00 05 02 04 02 00 00");
    }
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_faults_test
