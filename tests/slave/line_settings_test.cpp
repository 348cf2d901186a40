// MK-CFG-01 (000:218-226, 500-503): the MK instruments mirror their line settings in registers a master
// may write: PROT (8: 0 ASCII, 1 RTU), BAUD (9: 300 to 9600), PARID (10: none, even, odd). A device told a
// valid new code talks with it from then on (the manual gives no delay). The acknowledgement leaves with the
// old settings; a device alone on its line takes the line with it, one sharing a line with other units can
// no longer read a frame there and falls silent; a state file keeps what it was told across a restart.
#include <gtest/gtest.h>

#include <filesystem>
#include <mutex>

#include "slave/state_file.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_line_settings_test {
namespace {

using namespace std::chrono_literals;
using mb::Table;

std::string rtu(std::uint8_t unit, const char* pdu) {
    return hex(mb::encode_rtu(unit, bytes(pdu)));
}
// An ASCII frame's characters, as hex (what Client::exchange sends and returns).
std::string ascii(std::uint8_t unit, const char* pdu) {
    const std::string text = mb::encode_ascii(unit, bytes(pdu));
    return hex(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

// What the server says as the line follows a device, kept for the test to read once the server stopped.
struct Said {
    std::mutex m;
    std::vector<std::string> lines;
    ServerOptions options() {
        ServerOptions o;
        o.on_line_change = [this](const std::string& text) {
            std::lock_guard lock(m);
            lines.push_back(text);
        };
        return o;
    }
};

mb::LineState made_on(const std::string& uri, std::uint8_t unit) {
    return mb::transport::line_state(*mb::transport::parse_endpoint(uri), unit);
}

TEST(LineSettings, TheDeviceKnowsWhatItHoldsAndWhatItWasMadeWith) {
    Device mk(profile("mmk-2030"), made_on("rtu:/dev/null?baud=4800&parity=E", 1));
    EXPECT_EQ(mk.made_line().framing, mb::Framing::Rtu);
    EXPECT_EQ(mk.made_line().baud, 4800u);
    EXPECT_EQ(mk.made_line().parity, mb::Parity::Even);
    EXPECT_EQ(ask(mk, "10 00 08 00 03 06 00 00 00 01 00 02"), "10 00 08 00 03");
    EXPECT_EQ(mk.held_line().framing, mb::Framing::Ascii);
    EXPECT_EQ(mk.held_line().baud, 600u);
    EXPECT_EQ(mk.held_line().parity, mb::Parity::Odd);
    EXPECT_EQ(mk.made_line().baud, 4800u);
    // Codes the manual does not define are refused (BAUD := 6, MK-CFG-01's own test) and change nothing.
    EXPECT_EQ(ask(mk, "06 00 09 00 06"), "86 03");
    EXPECT_EQ(mk.held_line().baud, 600u);
    // A map that mirrors no setting holds none.
    Device plain(profile("modbus"), made_on("rtu:/dev/null?baud=4800", 1));
    EXPECT_FALSE(plain.held_line().framing.has_value());
    EXPECT_FALSE(plain.held_line().baud.has_value());
}

// Over a TCP stream (a serial server's) the framing is what the device sends and reads: PROT moves it. BAUD
// and PARID have no meaning on the stream and are stored only.
TEST(LineSettings, MK_CFG_01_AWrittenTransmissionModeSwitchesTheFraming) {
    RunningServer s({}, 1, "mmk-2030");
    Said said;
    s.serve("rtu-tcp://127.0.0.1:0", said.options());
    {
        Client client(s.server().port());
        ASSERT_TRUE(client.connected());
        EXPECT_EQ(client.exchange(rtu(1, "03 00 08 00 01"), 7), rtu(1, "03 02 00 01"));
        EXPECT_EQ(client.exchange(rtu(1, "06 00 08 00 02"), 5), rtu(1, "86 03"));  // no such mode
        // PROT := ASCII, acknowledged in RTU; then RTU goes unanswered and ASCII is answered.
        EXPECT_EQ(client.exchange(rtu(1, "06 00 08 00 00"), 8), rtu(1, "06 00 08 00 00"));
        EXPECT_EQ(client.exchange(rtu(1, "03 00 08 00 01"), 7, silence), "");
        const std::string reply = ascii(1, "03 02 00 00");
        EXPECT_EQ(client.exchange(ascii(1, "03 00 08 00 01"), reply.size() / 3 + 1), reply);
        // And back, acknowledged in ASCII.
        const std::string back = ascii(1, "06 00 08 00 01");
        EXPECT_EQ(client.exchange(back, back.size() / 3 + 1), back);
        EXPECT_EQ(client.exchange(rtu(1, "03 00 08 00 01"), 7), rtu(1, "03 02 00 01"));
        // BAUD := 2400: kept, and the stream goes on as it was.
        EXPECT_EQ(client.exchange(rtu(1, "06 00 09 00 03"), 8), rtu(1, "06 00 09 00 03"));
        EXPECT_EQ(client.exchange(rtu(1, "03 00 09 00 01"), 7), rtu(1, "03 02 00 03"));
    }
    s.stop();
    EXPECT_EQ(s.server().endpoint().scheme, mb::transport::Scheme::RtuOverTcp);
    ASSERT_EQ(said.lines.size(), 2u);
    EXPECT_NE(said.lines[0].find("unit 1 (mmk-2030) was told ASCII"), std::string::npos) << said.lines[0];
    EXPECT_NE(said.lines[1].find("was told RTU"), std::string::npos) << said.lines[1];
}

// Modbus/TCP has none of these settings on its wire: the codes are stored and read back, nothing else.
TEST(LineSettings, OverModbusTcpTheSettingsAreStoredOnly) {
    RunningServer s({}, 1, "mmk-2030");
    Said said;
    s.serve("tcp://127.0.0.1:0", said.options());
    {
        Client client(s.server().port());
        ASSERT_TRUE(client.connected());
        EXPECT_EQ(client.exchange("0001 0000 0006 01 06 0008 0000", 12),
                  "00 01 00 00 00 06 01 06 00 08 00 00");
        EXPECT_EQ(client.exchange("0002 0000 0006 01 03 0008 0001", 11), "00 02 00 00 00 05 01 03 02 00 00");
    }
    s.stop();
    EXPECT_TRUE(said.lines.empty());
}

// Devices sharing a line share its UART: the one told another framing cannot read the others' frames any
// more. It answers nothing, in either framing, and executes no broadcast, while the unit beside it is
// unaffected, until that unit is told the same: then the line follows, and both answer in the new framing.
// A broadcast write tells every unit at once.
TEST(LineSettings, ADeviceToldOtherSettingsLeavesALineItSharesUntilTheOthersFollow) {
    FaultSet faults;
    const std::string uri = "rtu-tcp://127.0.0.1:0";
    Device first(profile("mmk-2030"), made_on(uri, 1), &faults);
    Device second(profile("mmk-2030"), made_on(uri, 2), &faults);
    Said said;
    Server server(*mb::transport::parse_endpoint(uri), {&first, &second}, faults, said.options());
    ASSERT_TRUE(server.open().has_value());
    std::atomic<bool> stop{false};
    std::thread serving([&] { (void)server.run(stop); });
    const auto ascii_exchange = [](Client& client, std::uint8_t unit, const char* request,
                                   const char* reply) {
        const std::string expected = ascii(unit, reply);
        return client.exchange(ascii(unit, request), expected.size() / 3 + 1, silence) == expected;
    };
    {
        Client client(server.port());
        ASSERT_TRUE(client.connected());
        EXPECT_EQ(client.exchange(rtu(1, "06 00 08 00 00"), 8), rtu(1, "06 00 08 00 00"));
        EXPECT_EQ(client.exchange(rtu(1, "03 00 08 00 01"), 7, silence), "");
        EXPECT_EQ(client.exchange(ascii(1, "03 00 08 00 01"), 15, silence), "");
        client.send(mb::encode_rtu(0, bytes("06 00 17 00 0A")));
        EXPECT_EQ(hex(client.read(1, silence)), "");
        EXPECT_EQ(client.exchange(rtu(2, "03 00 17 00 01"), 7), rtu(2, "03 02 00 0A"));
        // Unit 2 told ASCII too: the line follows, and unit 1 is heard again.
        EXPECT_EQ(client.exchange(rtu(2, "06 00 08 00 00"), 8), rtu(2, "06 00 08 00 00"));
        EXPECT_TRUE(ascii_exchange(client, 1, "03 00 17 00 01", "03 02 00 00"));
        EXPECT_TRUE(ascii_exchange(client, 2, "03 00 17 00 01", "03 02 00 0A"));
        // A broadcast PROT := RTU moves both, and the line with them.
        client.send(bytes(ascii(0, "06 00 08 00 01")));
        EXPECT_EQ(hex(client.read(1, silence)), "");
        EXPECT_EQ(client.exchange(rtu(1, "03 00 08 00 01"), 7), rtu(1, "03 02 00 01"));
        EXPECT_EQ(client.exchange(rtu(2, "03 00 08 00 01"), 7), rtu(2, "03 02 00 01"));
    }
    stop = true;
    serving.join();
    EXPECT_FALSE(first.off_line());
    EXPECT_EQ(first.image().reg(Table::HoldingRegisters, 23), 0);
    EXPECT_EQ(server.endpoint().scheme, mb::transport::Scheme::RtuOverTcp);
    ASSERT_EQ(said.lines.size(), 3u);
    EXPECT_NE(said.lines[0].find("unit 1 (mmk-2030) was told ASCII: it cannot read the line"),
              std::string::npos)
        << said.lines[0];
    EXPECT_NE(said.lines[1].find("every unit on the line was told ASCII: the line follows"),
              std::string::npos)
        << said.lines[1];
    EXPECT_NE(said.lines[2].find("was told RTU"), std::string::npos) << said.lines[2];
    first.leave_line();
    first.reset();
    EXPECT_FALSE(first.off_line());
}

// On a serial line (a pseudo-terminal here) speed and parity are the port's: the slave sets them once the
// acknowledgement is out, as the terminal's settings show, and goes on answering with the new framing.
TEST(LineSettings, MK_CFG_01_OnASerialLineThePortFollowsTheDevice) {
    RunningServer s({}, 1, "mmk-2030");
    Said said;
    auto o = said.options();
    o.create_pty = true;
    s.serve("rtu:pty?baud=9600&parity=N", o);
    const int fd = open_terminal(s.server().address());
    ASSERT_GE(fd, 0);
    const auto exchange = [fd](const std::string& request_hex, std::size_t count) {
        const auto request = bytes(request_hex);
        EXPECT_EQ(::write(fd, request.data(), request.size()), static_cast<ssize_t>(request.size()));
        return hex(read_terminal(fd, count, 2s));
    };
    const auto speed = [fd] {
        termios t{};
        ::tcgetattr(fd, &t);
        return ::cfgetospeed(&t);
    };
    EXPECT_EQ(speed(), B9600);
    EXPECT_EQ(exchange(rtu(1, "06 00 09 00 03"), 8), rtu(1, "06 00 09 00 03"));
    for (int i = 0; i < 200 && speed() != B2400; ++i)
        std::this_thread::sleep_for(10ms);
    EXPECT_EQ(speed(), B2400);
    EXPECT_EQ(exchange(rtu(1, "06 00 0A 00 01"), 8), rtu(1, "06 00 0A 00 01"));
    EXPECT_EQ(exchange(rtu(1, "03 00 09 00 02"), 9), rtu(1, "03 04 00 03 00 01"));
    EXPECT_EQ(exchange(rtu(1, "06 00 08 00 00"), 8), rtu(1, "06 00 08 00 00"));
    std::this_thread::sleep_for(100ms);
    const std::string reply = ascii(1, "03 02 00 03");
    EXPECT_EQ(exchange(ascii(1, "03 00 09 00 01"), reply.size() / 3 + 1), reply);
    // PARID := none in ASCII: MK-CHR-02's two stop bits (the profile's line.stop_bits).
    const std::string none = ascii(1, "06 00 0A 00 00");
    EXPECT_EQ(exchange(none, none.size() / 3 + 1), none);
    std::this_thread::sleep_for(100ms);
    ::close(fd);
    s.stop();
    const auto now = s.server().endpoint();
    EXPECT_EQ(now.scheme, mb::transport::Scheme::AsciiSerial);
    EXPECT_EQ(now.line.baud, 2400u);
    EXPECT_EQ(now.line.parity, mb::Parity::None);
    EXPECT_EQ(now.line.data_bits, 7);  // MK-CHR-01
    EXPECT_EQ(now.line.stop_bits, 2);  // MK-CHR-02
    ASSERT_EQ(said.lines.size(), 4u);
    EXPECT_NE(said.lines[0].find("was told RTU, 2400 baud, no parity (8N1)"), std::string::npos)
        << said.lines[0];
    EXPECT_NE(said.lines[2].find("was told ASCII, 2400 baud, even parity (7E1)"), std::string::npos)
        << said.lines[2];
    EXPECT_NE(said.lines[3].find("was told ASCII, 2400 baud, no parity (7N2)"), std::string::npos)
        << said.lines[3];
}

// A device keeps what it was told: restarted from the state file, the line is opened with those settings.
TEST(LineSettings, TheSettingsAStateFileKeepsAreTheLinesAfterARestart) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("mbscope-line-" + std::to_string(::getpid()) + "-" +
                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "state.json").string();
    const std::string uri = "rtu:pty?baud=9600&parity=N";
    {
        Device told(profile("mmk-2030"), made_on(uri, 1));
        EXPECT_EQ(ask(told, "06 00 09 00 03"), "06 00 09 00 03");
        ASSERT_TRUE(save_state(path, {&told}).has_value());
    }
    FaultSet faults;
    Device restarted(profile("mmk-2030"), made_on(uri, 1), &faults);
    ASSERT_TRUE(load_state(path, {&restarted}).has_value());
    Said said;
    auto o = said.options();
    o.create_pty = true;
    Server server(*mb::transport::parse_endpoint(uri), {&restarted}, faults, o);
    ASSERT_TRUE(server.open().has_value());
    EXPECT_EQ(server.endpoint().line.baud, 2400u);
    EXPECT_EQ(server.endpoint().scheme, mb::transport::Scheme::RtuSerial);
    const int fd = open_terminal(server.address());
    ASSERT_GE(fd, 0);
    termios t{};
    ::tcgetattr(fd, &t);
    EXPECT_EQ(::cfgetospeed(&t), B2400);
    ::close(fd);
    ASSERT_EQ(said.lines.size(), 1u);
    EXPECT_NE(said.lines[0].find("holds RTU, 2400 baud, no parity (8N1) (the state file)"), std::string::npos)
        << said.lines[0];
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_line_settings_test
