// Several units on one line or port, each with its own profile (a multi-drop RS-485 bus is several
// devices): the mbscope binary started with `--unit 1=cth2265i --unit 2=mmk-2030 --unit 3=modbus`, over
// Modbus/TCP, RTU over TCP and an RTU pseudo-terminal.
//  - each unit answers by its own profile: CTH2265I's reserved register 4037 reads 0x55AA (003), the
//    MMK-2030's map has no such address (exception 02), the generic profile serves every address;
//  - a unit nobody serves gets no reply, on every transport (the slave is not a gateway: it has no 0x0B to
//    give);
//  - a broadcast (unit 0) write over a serial line reaches every unit whose map has the point and is not
//    answered;
//  - writes are kept per unit, and the state file keeps them per unit across a restart;
//  - libmodbus, a client nobody here wrote, reads and writes each unit with modbus_set_slave.
#include <gtest/gtest.h>
#include <modbus.h>

#include <cerrno>
#include <filesystem>

#include "modbus/transport/client.hpp"
#include "tests/slave/slave_process.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_multi_unit_test {
namespace {

namespace fs = std::filesystem;
namespace tp = mb::transport;

const std::vector<std::string> three_units = {"--unit",     "1=cth2265i", "--unit",
                                              "2=mmk-2030", "--unit",     "3=modbus"};

// The slave serving the three units over `transport` ("tcp", "rtu-tcp", or "rtu" on a pseudo-terminal),
// with `extra` arguments.
SlaveProcess serve(const std::string& transport, std::vector<std::string> extra = {}) {
    std::vector<std::string> args = three_units;
    if (transport == "rtu") {
        args.insert(args.end(), {"--listen", "rtu:pty?baud=38400&parity=N", "--pty"});
    } else {
        args.insert(args.end(), {"--listen", transport + "://127.0.0.1:0"});
    }
    args.insert(args.end(), extra.begin(), extra.end());
    return SlaveProcess(std::move(args));
}

// Where a client connects: the URI the slave printed, or the pseudo-terminal as a serial endpoint.
std::string client_uri(const std::string& transport, const SlaveProcess& slave) {
    return transport == "rtu" ? "rtu:" + slave.address() + "?baud=38400&parity=N" : slave.address();
}

// A raw client on the slave's endpoint: one request to one unit, the reply's PDU as hex ("" for none).
class Line {
  public:
    Line(const std::string& transport, const SlaveProcess& slave) {
        auto endpoint = tp::parse_endpoint(client_uri(transport, slave));
        EXPECT_TRUE(endpoint.has_value()) << client_uri(transport, slave);
        if (!endpoint) return;
        auto opened = tp::Client::open(*endpoint);
        EXPECT_TRUE(opened.has_value()) << (opened ? "" : opened.error());
        if (opened) client_.emplace(std::move(opened.value()));
    }
    bool open() const { return client_.has_value(); }

    std::string ask(std::uint8_t unit, std::string_view pdu_hex,
                    std::chrono::milliseconds timeout = std::chrono::seconds(2)) {
        if (!client_) return "no client";
        const auto pdu = bytes(pdu_hex);
        const auto x = client_->transact(unit, pdu, timeout);
        if (!x.response) return x.received.empty() ? "" : "garbled: " + hex(x.received);
        EXPECT_TRUE(x.response->checksum_ok);
        EXPECT_EQ(x.response->unit_id(), unit) << "the reply names the unit asked";
        return hex(x.response->pdu());
    }

  private:
    std::optional<tp::Client> client_;
};

class MultiUnit : public ::testing::TestWithParam<std::string> {};

TEST_P(MultiUnit, EachUnitAnswersByItsOwnProfileAndAnUnservedUnitNotAtAll) {
    auto slave = serve(GetParam());
    ASSERT_FALSE(slave.address().empty());
    Line line(GetParam(), slave);
    ASSERT_TRUE(line.open());
    // Register 4037: CTH2265I's reserved 0x55AA; not on the MMK-2030's map; 0 on the generic profile.
    EXPECT_EQ(line.ask(1, "03 0F C5 00 01"), "03 02 55 AA");
    EXPECT_EQ(line.ask(2, "03 0F C5 00 01"), "83 02");
    EXPECT_EQ(line.ask(3, "03 0F C5 00 01"), "03 02 00 00");
    // The MMK-2030's own limit (15 registers, 000:351) is its alone: 16 registers are refused on unit 2 and
    // read on unit 3.
    EXPECT_EQ(line.ask(2, "03 00 00 00 10"), "83 03");
    EXPECT_EQ(line.ask(3, "03 00 00 00 10").substr(0, 5), "03 20");
    // Units 4 and 247 are not served: no reply (the same request to a served unit is answered at once).
    EXPECT_EQ(line.ask(4, "03 00 00 00 01", silence), "");
    EXPECT_EQ(line.ask(247, "03 00 00 00 01", silence), "");
    EXPECT_EQ(line.ask(3, "03 00 00 00 01"), "03 02 00 00") << "the line still works after the silence";
}

TEST_P(MultiUnit, WritesAreKeptPerUnit) {
    auto slave = serve(GetParam());
    Line line(GetParam(), slave);
    ASSERT_TRUE(line.open());
    // Register 29 (MMK-2030: hysteresis of channel 1's high alarm, 0-250, 000:523) on units 2 and 3.
    EXPECT_EQ(line.ask(2, "06 00 1D 00 07"), "06 00 1D 00 07");
    EXPECT_EQ(line.ask(3, "06 00 1D 01 2C"), "06 00 1D 01 2C");
    EXPECT_EQ(line.ask(2, "06 00 1D 01 2C"), "86 03")
        << "300 is past the MMK-2030's range, not the generic one's";
    EXPECT_EQ(line.ask(2, "03 00 1D 00 01"), "03 02 00 07");
    EXPECT_EQ(line.ask(3, "03 00 1D 00 01"), "03 02 01 2C");
    EXPECT_EQ(line.ask(1, "03 00 1D 00 01"), "83 02") << "the CTH2265I's map has no register 29";
}

// A broadcast is executed by every unit whose map has the point and answered by none (SL §2.1; MK
// 000:285, 313). Over Modbus/TCP several units behind one endpoint are a gateway's line, and a gateway
// passes unit 0 on to it as a broadcast (the TCP implementation guide allows unit 0 there; rules D7).
TEST_P(MultiUnit, ABroadcastWriteReachesEveryUnitWithThePointAndIsNotAnswered) {
    auto slave = serve(GetParam());
    Line line(GetParam(), slave);
    ASSERT_TRUE(line.open());
    EXPECT_EQ(line.ask(0, "06 00 1D 00 2A", silence), "");  // register 29 := 42
    EXPECT_EQ(line.ask(0, "06 0F AC 04 D2", silence), "");  // register 4012 := 1234
    EXPECT_EQ(line.ask(2, "03 00 1D 00 01"), "03 02 00 2A");
    EXPECT_EQ(line.ask(3, "03 00 1D 00 01"), "03 02 00 2A");
    EXPECT_EQ(line.ask(1, "03 0F AC 00 01"), "03 02 04 D2");  // CTH2265I alarm 1 set-point, low word
    EXPECT_EQ(line.ask(3, "03 0F AC 00 01"), "03 02 04 D2");
    EXPECT_EQ(line.ask(2, "03 0F AC 00 01"), "83 02");
}

INSTANTIATE_TEST_SUITE_P(Transports, MultiUnit, ::testing::Values("tcp", "rtu-tcp", "rtu"),
                         transport_test_name);

TEST(MultiUnitState, TheStateFileKeepsEachUnitsWritesAcrossARestart) {
    const fs::path dir = fs::temp_directory_path() / ("mbscope-multi-unit-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string state = (dir / "line.json").string();
    // Unit 1: CTH2265I register 4012 (alarm 1 set-point, low word); units 2 and 3: register 29.
    const struct {
        std::uint8_t unit;
        const char* address;
        const char* value;
    } writes[] = {{1, "0F AC", "00 11"}, {2, "00 1D", "00 22"}, {3, "00 1D", "00 33"}};
    {
        auto slave = serve("tcp", {"--state", state});
        Line line("tcp", slave);
        ASSERT_TRUE(line.open());
        for (const auto& w : writes) {
            const std::string pdu = std::string("06 ") + w.address + " " + w.value;
            EXPECT_EQ(line.ask(w.unit, pdu), pdu);
        }
        slave.kill(SIGKILL);
    }
    auto again = serve("tcp", {"--state", state});
    Line line("tcp", again);
    ASSERT_TRUE(line.open());
    for (const auto& w : writes) {
        EXPECT_EQ(line.ask(w.unit, std::string("03 ") + w.address + " 00 01"),
                  std::string("03 02 ") + w.value)
            << "unit " << int(w.unit);
    }
    EXPECT_EQ(line.ask(3, "03 0F AC 00 01"), "03 02 00 00") << "unit 1's write stayed on unit 1";
    fs::remove_all(dir);
}

// A run that serves fewer units keeps the others' saved writes in the file: unit 2 alone is written again,
// and units 1 and 3 still hold theirs when the whole line is served once more.
TEST(MultiUnitState, UnitsNotServedKeepTheirWrites) {
    const fs::path dir =
        fs::temp_directory_path() / ("mbscope-multi-unit-kept-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string state = (dir / "line.json").string();
    {
        auto slave = serve("tcp", {"--state", state});
        Line line("tcp", slave);
        ASSERT_TRUE(line.open());
        EXPECT_EQ(line.ask(1, "06 0F AC 00 11"), "06 0F AC 00 11");
        EXPECT_EQ(line.ask(3, "06 00 1D 00 33"), "06 00 1D 00 33");
    }
    {
        SlaveProcess alone({"--unit", "2=mmk-2030", "--listen", "tcp://127.0.0.1:0", "--state", state});
        Line line("tcp", alone);
        ASSERT_TRUE(line.open());
        EXPECT_EQ(line.ask(2, "06 00 1D 00 22"), "06 00 1D 00 22");
    }
    auto again = serve("tcp", {"--state", state});
    Line line("tcp", again);
    ASSERT_TRUE(line.open());
    EXPECT_EQ(line.ask(1, "03 0F AC 00 01"), "03 02 00 11");
    EXPECT_EQ(line.ask(2, "03 00 1D 00 01"), "03 02 00 22");
    EXPECT_EQ(line.ask(3, "03 00 1D 00 01"), "03 02 00 33");
    fs::remove_all(dir);
}

// libmodbus addresses each unit with modbus_set_slave over TCP and over the RTU pseudo-terminal.
class MultiUnitLibmodbus : public ::testing::TestWithParam<std::string> {};

TEST_P(MultiUnitLibmodbus, ReadsAndWritesEachUnitByItsProfile) {
    auto slave = serve(GetParam());
    ASSERT_FALSE(slave.address().empty());
    modbus_t* ctx = GetParam() == "tcp" ? modbus_new_tcp("127.0.0.1", slave.port())
                                        : modbus_new_rtu(slave.address().c_str(), 38400, 'N', 8, 1);
    ASSERT_NE(ctx, nullptr);
    modbus_set_response_timeout(ctx, 1, 0);
    ASSERT_EQ(modbus_connect(ctx), 0) << modbus_strerror(errno);
    std::uint16_t v = 0;
    modbus_set_slave(ctx, 1);
    EXPECT_EQ(modbus_read_registers(ctx, 4037, 1, &v), 1) << modbus_strerror(errno);
    EXPECT_EQ(v, 0x55AA);
    modbus_set_slave(ctx, 2);
    errno = 0;
    EXPECT_EQ(modbus_read_registers(ctx, 4037, 1, &v), -1);
    EXPECT_EQ(errno, EMBXILADD) << modbus_strerror(errno);
    EXPECT_EQ(modbus_write_register(ctx, 29, 250), 1) << modbus_strerror(errno);
    errno = 0;
    EXPECT_EQ(modbus_write_register(ctx, 29, 251), -1);
    EXPECT_EQ(errno, EMBXILVAL) << modbus_strerror(errno);
    modbus_set_slave(ctx, 3);
    EXPECT_EQ(modbus_write_register(ctx, 29, 251), 1) << modbus_strerror(errno);
    modbus_set_slave(ctx, 2);
    EXPECT_EQ(modbus_read_registers(ctx, 29, 1, &v), 1);
    EXPECT_EQ(v, 250);
    modbus_set_slave(ctx, 3);
    EXPECT_EQ(modbus_read_registers(ctx, 29, 1, &v), 1);
    EXPECT_EQ(v, 251);
    // An unserved unit: libmodbus times out.
    modbus_set_response_timeout(ctx, 0, static_cast<std::uint32_t>(silence.count()) * 1000);
    modbus_set_slave(ctx, 9);
    errno = 0;
    EXPECT_EQ(modbus_read_registers(ctx, 0, 1, &v), -1);
    EXPECT_EQ(errno, ETIMEDOUT) << modbus_strerror(errno);
    modbus_close(ctx);
    modbus_free(ctx);
}

INSTANTIATE_TEST_SUITE_P(Transports, MultiUnitLibmodbus, ::testing::Values("tcp", "rtu"),
                         transport_test_name);

}  // namespace
}  // namespace mbscope::slave::test::test_slave_multi_unit_test
