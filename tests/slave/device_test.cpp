// slave::Device mechanics that no one manual states: malformed requests, FC8 counters and listen-only mode,
// the write flag the state file relies on, the initial register image; and the server's unit routing
// (a unit configured at the address that disables communication).
#include <gtest/gtest.h>

#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test {
namespace {

using mb::Table;

TEST(Device, EmptyPduIsNotAnswered) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, ""), "");
}

// A request whose function code has the exception bit set is no function at all (AP §7: 01).
TEST(Device, ExceptionFunctionCodeInARequestIs01) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "83 00 00 00 01"), "83 01");
}

// AP §6 state diagrams: a request whose structure does not hold together is "illegal data value".
TEST(Device, TruncatedOrOverlongRequestIs03) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "03 00 00"), "83 03");
    EXPECT_EQ(ask(device, "03 00 00 00 01 FF"), "83 03");
    EXPECT_EQ(ask(device, "10 00 00 00 02 04 00 01"), "90 03");
}

// AP §6.11/§6.12: a byte count that disagrees with the quantity is 03.
TEST(Device, ByteCountMismatchIs03) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "10 00 00 00 02 02 00 01"), "90 03");
    EXPECT_EQ(ask(device, "0F 00 00 00 10 01 FF"), "8F 03");
}

TEST(Device, WriteFlagIsSetOnlyByAcceptedWrites) {
    Device device(profile("mmk-2030"), 1);
    const auto run = [&](std::string_view h) { return device.handle({bytes(h), false}); };
    EXPECT_TRUE(run("06 00 17 00 0A").wrote);
    EXPECT_FALSE(run("03 00 17 00 01").wrote);
    EXPECT_FALSE(run("06 00 17 00 FB").wrote);  // refused: 03
    EXPECT_FALSE(run("06 00 00 00 00").wrote);  // read-only: 02
    EXPECT_TRUE(run("10 00 60 00 02 04 00 0A 01 02").wrote);
    EXPECT_TRUE(device.handle({bytes("05 00 01 FF 00"), true}).wrote);  // broadcast, executed
}

// AP §6.8.1: sub-function 04 silences the device until 01 restarts communications; the restart itself is
// not answered when it leaves listen-only mode ("no response is returned"), and is answered otherwise.
TEST(Device, ListenOnlyModeAnswersNothingButRestart) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "08 00 04 00 00"), "");
    EXPECT_TRUE(device.listen_only());
    EXPECT_EQ(ask(device, "03 00 00 00 01"), "");
    EXPECT_EQ(ask(device, "06 00 00 12 34"), "");
    EXPECT_EQ(device.image().reg(Table::HoldingRegisters, 0), 0);
    EXPECT_EQ(ask(device, "08 00 01 00 00"), "");
    EXPECT_FALSE(device.listen_only());
    EXPECT_EQ(ask(device, "08 00 01 00 00"), "08 00 01 00 00");
    EXPECT_EQ(ask(device, "03 00 00 00 01"), "03 02 00 00");
}

// A broadcast runs only writes (SL §2.1): a broadcast sub-function 04 does not enter listen-only mode and a
// broadcast restart does not leave it (found by fuzz_slave: the oracle and the slave disagreed).
TEST(Device, BroadcastDiagnosticsNeitherEnterNorLeaveListenOnlyMode) {
    Device device(profile("modbus"), 1);
    EXPECT_TRUE(device.handle({bytes("08 00 04 00 00"), true}).pdu.empty());
    EXPECT_FALSE(device.listen_only());
    EXPECT_EQ(ask(device, "08 00 04 00 00"), "");
    ASSERT_TRUE(device.listen_only());
    EXPECT_TRUE(device.handle({bytes("08 00 01 00 00"), true}).pdu.empty());
    EXPECT_TRUE(device.listen_only());
    EXPECT_EQ(ask(device, "05 00 05 5B 05"), "");
    EXPECT_EQ(ask(device, "08 00 01 00 00"), "");
    EXPECT_FALSE(device.listen_only());
}

TEST(Device, RestartCommunicationsChecksItsData) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "08 00 01 12 34"), "88 03");
    EXPECT_EQ(ask(device, "08 00 01 FF 00"), "08 00 01 FF 00");
}

// A sub-function's query data is 00 00 (a counter, listen-only, clear), 00 00 or FF 00 (restart), a
// character and 00 (ASCII delimiter); other data is exception 03 (AP §6.8's state diagram) and does nothing.
TEST(Device, Fc8SubFunctionsRefuseDataTheyDoNotDefine) {
    Device device(profile("modbus"), 1);
    EXPECT_EQ(ask(device, "02 FF FF 00 02"), "82 02");
    EXPECT_EQ(ask(device, "08 00 0B 12 34"), "88 03");
    EXPECT_EQ(ask(device, "08 00 0D 00 01"), "88 03");
    EXPECT_EQ(ask(device, "08 00 0A 01 00"), "88 03");  // not cleared: four exceptions now
    EXPECT_EQ(ask(device, "08 00 0D 00 00"), "08 00 0D 00 04");
    EXPECT_EQ(ask(device, "08 00 04 00 01"), "88 03");
    EXPECT_FALSE(device.listen_only());
    EXPECT_EQ(ask(device, "08 00 03 3A 01"), "88 03");
    EXPECT_EQ(ask(device, "08 00 03 3A 00"), "08 00 03 3A 00");
    EXPECT_EQ(ask(device, "08 00 00 12 34"), "08 00 00 12 34");  // the echo takes any data
}

// AP §6.8.1 sub-functions 0x0B..0x0F, 0x0A clears them (SL §6.1 counters).
TEST(Device, Fc8CountersCountWhatTheServerAndDeviceSaw) {
    Device device(profile("modbus"), 1);
    device.count_frame(true);
    device.count_frame(true);
    device.count_frame(false);
    EXPECT_EQ(ask(device, "02 FF FF 00 02"), "82 02");           // one exception
    EXPECT_EQ(ask(device, "06 00 00 00 01", true), "");          // broadcast: no response
    EXPECT_EQ(ask(device, "08 00 0B 00 00"), "08 00 0B 00 03");  // bus messages
    EXPECT_EQ(ask(device, "08 00 0C 00 00"), "08 00 0C 00 01");  // bus communication errors
    EXPECT_EQ(ask(device, "08 00 0D 00 00"), "08 00 0D 00 01");  // exceptions
    EXPECT_EQ(ask(device, "08 00 0E 00 00"), "08 00 0E 00 06");  // server messages, this one included
    EXPECT_EQ(ask(device, "08 00 0F 00 00"), "08 00 0F 00 01");  // no response
    EXPECT_EQ(ask(device, "08 00 0A 00 00"), "08 00 0A 00 00");
    EXPECT_EQ(ask(device, "08 00 0E 00 00"), "08 00 0E 00 01");
    EXPECT_EQ(ask(device, "08 00 10 00 00"), "08 00 10 00 00");  // never naks
}

// The initial image follows the map (register_image.hpp): fixed values, an enumeration's first value, a
// range's minimum when zero lies outside it, floats in the profile's word order.
TEST(Device, InitialImageFollowsTheMap) {
    Device cth(profile("cth2265i"), 1);
    EXPECT_EQ(cth.image().reg(Table::HoldingRegisters, 4037), 0x55AA);
    Device walchem(profile("walchem-w600"), 1);
    EXPECT_EQ(walchem.image().f32(Table::HoldingRegisters, 148, mb::WordOrder::Cdab), 1.0f);  // range 1..1440
    EXPECT_EQ(ask(walchem, "03 00 94 00 02"), "03 04 00 00 3F 80");
    Device mk(profile("mmk-2030"), 1);
    for (const auto& pt : mk.profile().table(Table::HoldingRegisters)) {
        if (pt.encoding.type != mb::EncodingType::Enum || pt.encoding.values.empty()) continue;
        EXPECT_EQ(mk.image().reg(Table::HoldingRegisters, pt.address),
                  static_cast<std::uint16_t>(pt.encoding.values.front().value))
            << pt.source;
    }
}

// A new image counts no modifications, though making it stored the map's initial values (a fixed value,
// a range's minimum): "unchanged since made" is a count of zero, as after reset().
TEST(Device, NewImageCountsNoModifications) {
    for (const char* id : {"cth2265i", "walchem-w600", "mmk-2030", "dmy-2017", "modbus"}) {
        const Device device(profile(id), 1);
        EXPECT_EQ(device.image().modifications(), 0u) << id;
        EXPECT_TRUE(device.image().changes().empty()) << id;
    }
}

// reset() makes the device as it was made (the fuzz target reuses one device per profile and unit): the
// written registers read their initial values again, counters are zero, listen-only mode is left.
TEST(Device, ResetIsAsMade) {
    Device device(profile("walchem-w600"), 1);
    const Device made(profile("walchem-w600"), 1);
    EXPECT_EQ(ask(device, "10 00 94 00 02 04 00 00 40 00"), "10 00 94 00 02");
    EXPECT_EQ(ask(device, "06 7F 00 12 34").substr(0, 2), "86");
    ASSERT_NE(device.image().modifications(), 0u);
    device.reset();
    EXPECT_EQ(device.image().modifications(), 0u);
    EXPECT_TRUE(device.image().changes().empty());
    EXPECT_EQ(device.counters().server_messages, 0);
    EXPECT_EQ(device.counters().exceptions, 0);
    for (std::uint32_t a = 0; a < 65536; ++a)
        ASSERT_EQ(device.image().reg(Table::HoldingRegisters, static_cast<std::uint16_t>(a)),
                  made.image().reg(Table::HoldingRegisters, static_cast<std::uint16_t>(a)))
            << a;
    EXPECT_EQ(ask(device, "03 00 94 00 02"), "03 04 00 00 3F 80");
    // Written again after a reset, and reset again.
    EXPECT_EQ(ask(device, "06 00 94 00 07"), "06 00 94 00 07");
    device.reset();
    EXPECT_EQ(ask(device, "03 00 94 00 02"), "03 04 00 00 3F 80");

    Device generic(profile("modbus"), 1);
    EXPECT_EQ(ask(generic, "08 00 04 00 00"), "");
    ASSERT_TRUE(generic.listen_only());
    generic.reset();
    EXPECT_FALSE(generic.listen_only());
    EXPECT_EQ(ask(generic, "03 00 00 00 01"), "03 02 00 00");
}

// Tables a profile declares the same share storage: a write through FC6 reads back through FC4 (MK-FC04-01).
TEST(Device, SameAsTablesShareStorage) {
    Device device(profile("mmk-2030"), 1);
    EXPECT_EQ(ask(device, "06 00 17 00 0A"), "06 00 17 00 0A");
    EXPECT_EQ(ask(device, "04 00 17 00 01"), "04 02 00 0A");
}

// MK-ADR-01 (000:220): ENDER 0 disables communication — a unit configured at 0 on an MK profile answers
// nothing and executes no broadcast, while the unit beside it on the same line does.
TEST(ServerRouting, MK_ADR_01_UnitZeroConfiguredNeverCommunicates) {
    FaultSet faults;
    Device silent(profile("mmk-2030"), 0, &faults);
    Device active(profile("mmk-2030"), 2, &faults);
    auto endpoint = mb::transport::parse_endpoint("rtu-tcp://127.0.0.1:0");
    ASSERT_TRUE(endpoint.has_value());
    Server server(*endpoint, {&silent, &active}, faults, ServerOptions{});
    ASSERT_TRUE(server.open().has_value());
    std::atomic<bool> stop{false};
    std::thread thread([&] { (void)server.run(stop); });
    {
        Client client(server.port());
        ASSERT_TRUE(client.connected());
        // Broadcast FC6 register 23 := 10 (RTU, CRC written by hand), then read it from unit 2.
        client.send(mb::encode_rtu(0, bytes("06 00 17 00 0A")));
        EXPECT_EQ(hex(client.read(1, silence)), "");
        EXPECT_EQ(client.exchange(hex(mb::encode_rtu(2, bytes("03 00 17 00 01"))), 7),
                  "02 03 02 00 0A 7C 43");
        EXPECT_EQ(client.exchange(hex(mb::encode_rtu(0, bytes("03 00 17 00 01"))), 7, silence), "");
    }
    stop = true;
    thread.join();
    EXPECT_EQ(silent.image().reg(Table::HoldingRegisters, 23), 0);
    EXPECT_EQ(active.image().reg(Table::HoldingRegisters, 23), 10);
}

}  // namespace
}  // namespace mbscope::slave::test
