// slave::Device mechanics that no one manual states: malformed requests, FC8 counters and listen-only mode,
// the write flag the state file relies on, the initial register image; and the server's unit routing
// (a unit configured at the address that disables communication, a device moved by a write to its address).
#include <gtest/gtest.h>

#include "modbus/profile_loader.hpp"
#include "slave/responder.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_device_test {
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

// A broadcast the device refuses (a byte count that disagrees with its quantity) forms an exception that is
// never sent: 0x0D counts exception responses returned, and counted it too, beside 0x0F's no response.
TEST(Device, Fc8ExceptionCountLeavesOutBroadcastsNotAnswered) {
    Device device(profile("modbus"), 1);
    for (int i = 0; i < 3; ++i)
        EXPECT_EQ(ask(device, "0F 00 00 00 08 02 FF", true), "");
    EXPECT_EQ(ask(device, "08 00 0D 00 00"), "08 00 0D 00 00");  // exceptions returned
    EXPECT_EQ(ask(device, "08 00 0F 00 00"), "08 00 0F 00 03");  // no response
    EXPECT_EQ(ask(device, "0F 00 00 00 08 02 FF"), "8F 03");     // addressed: returned, counted
    EXPECT_EQ(ask(device, "08 00 0D 00 00"), "08 00 0D 00 01");
}

// AP §4.1: a PDU holds at most 253 bytes. Over Modbus/TCP a longer one can arrive (the MBAP length field
// says up to 65535); echoed, an FC8 query of 254-256 bytes made a reply longer than the specification's
// 260-byte ADU. The device does not handle it: a character overrun, counted by sub-function 0x12 and
// cleared by 0x14 (AP §6.8.1).
TEST(Device, APduLongerThanTheDeviceTakesIsACharacterOverrun) {
    Device device(profile("modbus"), 1);
    std::string fits = "08 00 00";
    for (int i = 0; i < 250; ++i)
        fits += " 5A";
    const std::string too_long = fits + " 5A";
    EXPECT_EQ(ask(device, fits), fits);  // 253 bytes: echoed
    EXPECT_EQ(ask(device, too_long), "");
    EXPECT_EQ(ask(device, too_long, true), "");
    EXPECT_EQ(ask(device, "08 00 12 00 00"), "08 00 12 00 02");  // character overruns
    EXPECT_EQ(ask(device, "08 00 0E 00 00"), "08 00 0E 00 03");  // not messages processed
    EXPECT_EQ(ask(device, "08 00 14 00 00"), "08 00 14 00 00");  // clear overrun counter and flag
    EXPECT_EQ(ask(device, "08 00 12 00 00"), "08 00 12 00 00");
}

// Walchem's manual takes PDUs of 2 to 256 bytes (002:219, against AP §4.1), as its FC16 of 125 registers
// needs (002:362-381): the profile says so (line.pdu_max_bytes) and the device handles them.
TEST(Device, AManualsLongerPduLimitIsKept) {
    Device walchem(profile("walchem-w600"), 1);
    std::string fc16 = "10 00 00 00 7D FA";  // 125 registers: a 256-byte PDU
    for (int i = 0; i < 250; ++i)
        fc16 += " 00";
    EXPECT_NE(ask(walchem, fc16), "");
    EXPECT_EQ(ask(walchem, fc16 + " 00"), "");  // 257 bytes
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

// The alternative maps (002:750-776) serve their objects' own fields: W600 sensor 1 (sensor-1-1, holding
// registers 576.., x0577) as its primary value at 9216 (FC3 or FC4), its status at 9280 and its low alarm
// as coil 9344; they are read-only (a write is refused and changes nothing), and a value stored at an
// alternative address is its object's.
TEST(Device, AlternativeMapsReadTheirObjectsOwnFields) {
    Device w600(profile("walchem-w600"), 1);
    auto& image = w600.image();
    image.set_f32(Table::HoldingRegisters, 576, 7.5f, mb::WordOrder::Cdab);
    image.set_reg(Table::HoldingRegisters, 576 + 34, 12);
    image.set_reg(Table::HoldingRegisters, 576 + 28, 1);
    EXPECT_EQ(ask(w600, "04 24 00 00 02"), "04 04 00 00 40 F0");
    EXPECT_EQ(ask(w600, "04 24 00 00 02"), ask(w600, "04 02 40 00 02"));
    EXPECT_EQ(ask(w600, "03 24 00 00 02"), "03 04 00 00 40 F0");
    EXPECT_EQ(ask(w600, "03 24 40 00 01"), "03 02 00 0C");
    EXPECT_EQ(ask(w600, "01 24 80 00 01"), "01 01 01");
    const auto before = w600.image().modifications();
    EXPECT_EQ(ask(w600, "06 24 00 12 34").substr(0, 2), "86");
    EXPECT_EQ(w600.image().modifications(), before);
    image.set_reg(Table::HoldingRegisters, 9280, 3);
    EXPECT_EQ(w600.image().reg(Table::HoldingRegisters, 576 + 34), 3);
}

// stuck-value at an alternative address stops its value where it is held, its object's field: the
// simulation writes sensor 1's primary value at 576, which 9216 reads.
TEST(Device, AStuckAlternativeAddressIsStuckWhereItsValueIsHeld) {
    FaultSet faults({*parse_fault("stuck-value=9216")}, 1);
    const Device w600(profile("walchem-w600"), 1, &faults);
    EXPECT_TRUE(w600.frozen(Table::HoldingRegisters, 9216));
    EXPECT_TRUE(w600.frozen(Table::HoldingRegisters, 576));
    EXPECT_FALSE(w600.frozen(Table::HoldingRegisters, 577));  // the float's other half is not the one named
    EXPECT_FALSE(w600.frozen(Table::HoldingRegisters, 612));
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

// Devices on one line, served over rtu-tcp on a free loopback port until stop() or the end of the scope.
class ServedLine {
  public:
    ServedLine(std::vector<Device*> units, FaultSet& faults)
        : server_(*mb::transport::parse_endpoint("rtu-tcp://127.0.0.1:0"), std::move(units), faults,
                  ServerOptions{}) {
        opened_ = server_.open().has_value();
        if (opened_) thread_ = std::thread([this] { (void)server_.run(stop_); });
    }
    ~ServedLine() { stop(); }
    ServedLine(const ServedLine&) = delete;
    ServedLine& operator=(const ServedLine&) = delete;
    bool opened() const noexcept { return opened_; }
    std::uint16_t port() const noexcept { return server_.port(); }
    void stop() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
    }

  private:
    Server server_;
    bool opened_ = false;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

// The generic profile as unit 1 over rtu-tcp, and a client connected to it.
struct GenericRtuTcpLine {
    FaultSet faults;
    Device device{profile("modbus"), 1, &faults};
    ServedLine line{{&device}, faults};
    Client client{line.port()};
    bool ready() const { return line.opened() && client.connected(); }
};

// MK-ADR-01 (000:220): ENDER 0 disables communication — a unit configured at 0 on an MK profile answers
// nothing and executes no broadcast, while the unit beside it on the same line does.
TEST(ServerRouting, MK_ADR_01_UnitZeroConfiguredNeverCommunicates) {
    FaultSet faults;
    Device silent(profile("mmk-2030"), 0, &faults);
    Device active(profile("mmk-2030"), 2, &faults);
    ServedLine line({&silent, &active}, faults);
    ASSERT_TRUE(line.opened());
    {
        Client client(line.port());
        ASSERT_TRUE(client.connected());
        // Broadcast FC6 register 23 := 10 (RTU, CRC written by hand), then read it from unit 2.
        client.send(mb::encode_rtu(0, bytes("06 00 17 00 0A")));
        EXPECT_EQ(hex(client.read(1, silence)), "");
        EXPECT_EQ(client.exchange(hex(mb::encode_rtu(2, bytes("03 00 17 00 01"))), 7),
                  "02 03 02 00 0A 7C 43");
        EXPECT_EQ(client.exchange(hex(mb::encode_rtu(0, bytes("03 00 17 00 01"))), 7, silence), "");
    }
    line.stop();
    EXPECT_EQ(silent.image().reg(Table::HoldingRegisters, 23), 0);
    EXPECT_EQ(active.image().reg(Table::HoldingRegisters, 23), 10);
}

// MK-CFG-01 (000:218-226, 500): the slave address ENDER (register 7) is a register too, and a device obeys a
// valid new one at once. The write is acknowledged from the old address; from then on the device answers at
// the new one and not at the old, on the same line as a unit that stays where it was; 0 disables it
// (MK-ADR-01), broadcasts included. A value outside 0..99 is refused and moves nothing.
TEST(ServerRouting, MK_CFG_01_AWrittenAddressMovesTheDevice) {
    FaultSet faults;
    Device moving(profile("mmk-2030"), 1, &faults);
    Device staying(profile("mmk-2030"), 2, &faults);
    ServedLine line({&moving, &staying}, faults);
    ASSERT_TRUE(line.opened());
    const auto rtu = [](std::uint8_t unit, const char* pdu) { return hex(mb::encode_rtu(unit, bytes(pdu))); };
    {
        Client client(line.port());
        ASSERT_TRUE(client.connected());
        // ENDER := 100 (the manual's own example, 000:500): exception 03, the device stays at 1.
        EXPECT_EQ(client.exchange(rtu(1, "06 00 07 00 64"), 5), rtu(1, "86 03"));
        EXPECT_EQ(client.exchange(rtu(1, "03 00 07 00 01"), 7), rtu(1, "03 02 00 01"));
        // ENDER := 5: acknowledged from address 1, then address 5 answers and 1 does not.
        EXPECT_EQ(client.exchange(rtu(1, "06 00 07 00 05"), 8), rtu(1, "06 00 07 00 05"));
        EXPECT_EQ(client.exchange(rtu(1, "03 00 07 00 01"), 7, silence), "");
        EXPECT_EQ(client.exchange(rtu(5, "03 00 07 00 01"), 7), rtu(5, "03 02 00 05"));
        EXPECT_EQ(client.exchange(rtu(2, "03 00 07 00 01"), 7), rtu(2, "03 02 00 02"));
        // ENDER := 0 over FC16: acknowledged, then silent at every address, broadcasts executed by unit 2
        // only.
        EXPECT_EQ(client.exchange(rtu(5, "10 00 07 00 01 02 00 00"), 8), rtu(5, "10 00 07 00 01"));
        EXPECT_EQ(client.exchange(rtu(5, "03 00 07 00 01"), 7, silence), "");
        EXPECT_EQ(client.exchange(rtu(0, "03 00 07 00 01"), 7, silence), "");
        client.send(mb::encode_rtu(0, bytes("06 00 17 00 0A")));
        EXPECT_EQ(hex(client.read(1, silence)), "");
        EXPECT_EQ(client.exchange(rtu(2, "03 00 17 00 01"), 7), rtu(2, "03 02 00 0A"));
    }
    line.stop();
    EXPECT_EQ(moving.unit(), 0);
    EXPECT_EQ(moving.configured_unit(), 1);
    EXPECT_EQ(moving.image().reg(Table::HoldingRegisters, 23), 0);
    // As made again: the address it was made with.
    moving.reset();
    EXPECT_EQ(moving.unit(), 1);
}

// A write the server takes back (it could not be saved: exception 04) moves nothing either.
TEST(ServerRouting, AnAddressWriteTakenBackLeavesTheDeviceWhereItWas) {
    FaultSet faults;
    Device device(profile("mmk-2030"), 1, &faults);
    Responder responder({&device}, faults, mb::Framing::Rtu, false, [] { return false; });
    const auto request = mb::encode_rtu(1, bytes("06 00 07 00 05"));
    const auto frame = mb::decode_adu(mb::Framing::Rtu, request);
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(hex(responder.respond(*frame)), hex(mb::encode_rtu(1, bytes("86 04"))));
    EXPECT_EQ(device.unit(), 1);
    EXPECT_EQ(device.image().reg(Table::HoldingRegisters, 7), 1);
}

// A broadcast has no acknowledgement to take back, but the same promise holds: a write that could not be
// saved is not kept. It was: a master reading the register back (MK-BC-01: broadcasts are checked that
// way) saw a value a restart would lose, and the same write sent to the unit was refused with exception 04
// while the register read as if it had been taken.
TEST(ServerRouting, ABroadcastWriteThatCannotBeSavedIsTakenBack) {
    FaultSet faults;
    Device first(profile("mmk-2030"), 1, &faults);
    Device second(profile("mmk-2030"), 2, &faults);
    bool saves = true;
    Responder responder({&first, &second}, faults, mb::Framing::Rtu, false, [&] { return saves; });
    const auto send = [&](std::uint8_t unit, const char* pdu) {
        const auto request = mb::encode_rtu(unit, bytes(pdu));
        const auto frame = mb::decode_adu(mb::Framing::Rtu, request);
        return frame ? hex(responder.respond(*frame)) : std::string("undecodable");
    };
    // Register 23 (000:486-721): 10 kept when saved ...
    EXPECT_EQ(send(0, "06 00 17 00 0A"), "");
    EXPECT_EQ(first.image().reg(Table::HoldingRegisters, 23), 10);
    EXPECT_EQ(second.image().reg(Table::HoldingRegisters, 23), 10);
    // ... 11 taken back on every unit when not.
    saves = false;
    EXPECT_EQ(send(0, "06 00 17 00 0B"), "");
    EXPECT_EQ(first.image().reg(Table::HoldingRegisters, 23), 10);
    EXPECT_EQ(second.image().reg(Table::HoldingRegisters, 23), 10);
    EXPECT_EQ(send(1, "06 00 17 00 0B"), hex(mb::encode_rtu(1, bytes("86 04"))));
    EXPECT_EQ(first.image().reg(Table::HoldingRegisters, 23), 10);
    // An address (ENDER, 000:500) taken back with its write: the devices answer where they did.
    EXPECT_EQ(send(0, "06 00 07 00 05"), "");
    EXPECT_EQ(first.unit(), 1);
    EXPECT_EQ(second.unit(), 2);
    EXPECT_EQ(first.image().reg(Table::HoldingRegisters, 7), 1);
    EXPECT_EQ(send(1, "03 00 07 00 01"), hex(mb::encode_rtu(1, bytes("03 02 00 01"))));
}

// Over rtu-tcp a frame's end comes from its content, and FC8 sub-function 00 (Return Query Data, AP §6.8)
// echoes any number of data bytes: a request longer than the usual two data bytes is answered as soon as
// its CRC closes it, whatever its bytes (these, with their CRCs computed by pymodbus, were never answered:
// their first byte was dropped as garbage at the five-byte PDU's length), and the connection goes on.
TEST(ServerRouting, RtuOverTcpEchoesReturnQueryDataOfAnyLength) {
    GenericRtuTcpLine served;
    ASSERT_TRUE(served.ready());
    Client& client = served.client;
    for (const char* request :
         {"01 08 00 00 83 80 7D 50 28 50 12 59 62 56 0E",
          "01 08 00 00 6B 4A 84 CB D9 45 76 58 A2 6A 4A 6B 85 6E",
          "01 08 00 00 97 8B 21 5E EA 9A 79 A0 94 10 9B 03 E8 D6 78 42 8D 3B 31 D7 48"}) {
        const std::size_t size = bytes(request).size();
        EXPECT_EQ(client.exchange(request, size, silence), request);
    }
    EXPECT_EQ(client.exchange("01 03 00 00 00 01 84 0A", 7), "01 03 02 00 00 B8 44");
    // Data bytes that hold a frame of their own (an FC6 writing 0x1234 to register 5, its CRC right) are
    // echoed, not executed: a write nobody sent. (CRCs computed by pymodbus.)
    const char* hiding = "01 08 00 00 AA BB CC DD 01 06 00 05 12 34 94 BC DF 04";
    EXPECT_EQ(client.exchange(hiding, 18, silence), hiding);
    EXPECT_EQ(client.exchange("01 03 00 05 00 01 94 0B", 7), "01 03 02 00 00 B8 44");
}

// FC16 with quantity 123 and byte count 255, a length no RTU frame has (264 bytes), carrying `data_bytes` of
// data with a read of register 5 hidden in them, CRC right over all of it.
std::vector<std::uint8_t> fc16_of_impossible_length(std::size_t data_bytes) {
    std::vector<std::uint8_t> pdu{0x10, 0x00, 0x00, 0x00, 0x7B, 0xFF};
    std::vector<std::uint8_t> data(data_bytes, 0);
    const auto hidden = mb::encode_rtu(1, bytes("03 00 05 00 01"));
    std::copy(hidden.begin(), hidden.end(), data.begin() + 68);
    pdu.insert(pdu.end(), data.begin(), data.end());
    return mb::encode_rtu(1, pdu);
}

// Such a request over rtu-tcp, whole or split over two segments (as a TCP stack may deliver it), is taken as
// a serial port takes it, not skipped byte by byte until the frame whose CRC holds inside its data is
// answered instead: 255 bytes are one frame, refused (exception 03, AP §6.12); all 264 bytes its header
// gives are longer than any RTU frame and dropped unanswered; with its CRC damaged, either is dropped
// unanswered (the frame inside its data was found and answered after the silence).
TEST(ServerRouting, RtuOverTcpTakesAFrameOfAnImpossibleLengthAsASerialPortDoes) {
    GenericRtuTcpLine served;
    ASSERT_TRUE(served.ready());
    Client& client = served.client;
    const struct {
        std::size_t data_bytes;
        bool damaged;
        std::string reply;
    } cases[] = {{246, false, hex(mb::encode_rtu(1, bytes("90 03")))},
                 {255, false, ""},
                 {246, true, ""},
                 {255, true, ""}};
    for (const auto& c : cases) {
        auto request = fc16_of_impossible_length(c.data_bytes);
        ASSERT_EQ(request.size(), 9 + c.data_bytes);
        if (c.damaged) request.back() ^= 0x01;
        for (const std::size_t cut : {std::size_t{0}, std::size_t{40}, std::size_t{90}}) {
            SCOPED_TRACE(std::to_string(request.size()) + (c.damaged ? " damaged" : "") +
                         " bytes, first segment " + std::to_string(cut));
            const std::span<const std::uint8_t> whole(request);
            if (cut > 0) {
                client.send(whole.first(cut));
                EXPECT_EQ(hex(client.read(1, std::chrono::milliseconds(20))), "");
            }
            EXPECT_EQ(client.exchange(hex(whole.subspan(cut)), 5, silence), c.reply);
            EXPECT_EQ(client.exchange("01 03 00 05 00 01 94 0B", 7), "01 03 02 00 00 B8 44");
        }
    }
}

// A profile whose address register is read-only (CTH2265I 3999, 003:599) is never moved.
TEST(Device, AReadOnlyAddressRegisterMovesNothing) {
    Device device(profile("cth2265i"), 3);
    EXPECT_EQ(ask(device, "06 0F 9F 00 07").substr(0, 2), "86");
    EXPECT_EQ(device.unit(), 3);
}

// A device starts at the first value its enumeration lists that the register takes: one the manual does not
// allow, listed first ("forbidden"), made a device that refused to be written back to its own starting value
// (exception 03), so that a certification could not restore it.
TEST(Device, AnEnumerationStartsAtAValueItAllows) {
    const char* text = R"({
      "format": "mbscope-profile/1", "family": "test", "vendor": "test",
      "line": {"transports": ["tcp"]}, "functions": {"supported": [3, 6]},
      "tables": {"holding_registers": [
        {"address": 3, "name": "type", "access": "rw", "source": "test", "encoding": {"type": "enum", "values": [
          {"value": 0, "text": "não permitido", "forbidden": true}, {"value": 1, "text": "a"}, {"value": 2, "text": "b"}]}}]},
      "models": [{"id": "test"}]
    })";
    auto loaded = mb::parse_profiles(text, "test.json", nullptr, {});
    ASSERT_TRUE(loaded.errors.empty()) << mb::to_string(loaded.errors.front());
    ASSERT_EQ(loaded.profiles.size(), 1u);
    Device device(loaded.profiles[0], 1);
    EXPECT_EQ(device.image().reg(Table::HoldingRegisters, 3), 1);
    EXPECT_EQ(ask(device, "06 00 03 00 00"), "86 03");
    EXPECT_EQ(ask(device, "06 00 03 00 02"), "06 00 03 00 02");
    EXPECT_EQ(ask(device, "06 00 03 00 01"), "06 00 03 00 01");
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_device_test
