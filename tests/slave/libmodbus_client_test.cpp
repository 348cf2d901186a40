// The reference slave driven by a client nobody here wrote: libmodbus's (Debian libmodbus), for every
// bundled profile over Modbus/TCP, over RTU-over-TCP and over an RTU pseudo-terminal. libmodbus has no
// RTU-over-TCP client, so there it speaks RTU on a pseudo-terminal that socat relays to the slave's TCP
// port, as a serial-to-Ethernet gateway does. What the client writes reads back; reads return the slave's
// image; the exceptions libmodbus reports (errno EMBXILFUN, EMBXILADD, EMBXILVAL) are the ones the manual
// prescribes. One case per transport visits every profile in turn (a test process per profile and
// transport would cost the suite more in start-up than the exchanges take).
#include <gtest/gtest.h>
#include <modbus.h>

#include <cerrno>
#include <filesystem>

#include "conformance/context.hpp"
#include "tests/slave/slave_test_support.hpp"
#include "tests/support/process_support.hpp"

namespace mbscope::slave::test::test_slave_libmodbus_client_test {
namespace {

using mb::Table;

// A server for one case, on TCP port 0 or on a pseudo-terminal it creates; for rtu-tcp, socat's gateway
// from a pseudo-terminal to the server's port.
class Served {
  public:
    explicit Served(const ClientCase& c) : slave_({}, 1, c.profile) {
        Server& server = slave_.serve_over(c.transport);
        std::string serial = server.address();
        if (c.transport == "rtu-tcp") serial = start_gateway(c, server.port());
        ctx_ = c.transport == "tcp" ? modbus_new_tcp("127.0.0.1", server.port())
                                    : modbus_new_rtu(serial.c_str(), 38400, 'N', 8, 1);
        EXPECT_NE(ctx_, nullptr);
        if (ctx_) {
            modbus_set_slave(ctx_, 1);
            modbus_set_response_timeout(ctx_, 1, 0);
            connected_ = modbus_connect(ctx_) == 0;
        }
    }
    ~Served() {
        if (ctx_) {
            modbus_close(ctx_);
            modbus_free(ctx_);
        }
    }
    modbus_t* ctx() { return ctx_; }
    bool connected() const { return connected_; }
    Device& device() { return slave_.device(); }

  private:
    // socat between a pseudo-terminal (its path returned) and the server's TCP port.
    std::string start_gateway(const ClientCase& c, std::uint16_t port) {
        const std::string dir = ::testing::TempDir() + "libmodbus_gateway_" + c.profile;
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        const std::string link = dir + "/serial";
        gateway_ = std::make_unique<mbscope::test::Child>(
            std::vector<std::string>{"socat", "pty,raw,echo=0,link=" + link,
                                     "tcp:127.0.0.1:" + std::to_string(port)},
            "/dev/null", dir + "/socat.err");
        EXPECT_TRUE(mbscope::test::wait_for([&] { return std::filesystem::exists(link); }))
            << "socat did not make " << link;
        return link;
    }

    RunningServer slave_;  // declared first: stops last, after the gateway and the client are gone
    std::unique_ptr<mbscope::test::Child> gateway_;
    modbus_t* ctx_ = nullptr;
    bool connected_ = false;
};

// The checks on one served profile.
void reads_writes_and_exceptions_as_the_manual_says(Served& s) {
    ASSERT_TRUE(s.connected()) << modbus_strerror(errno);
    const mb::Profile& p = s.device().profile();
    const bool open = p.open_address_space;

    // A read of the first holding registers the map has returns the slave's image.
    const mb::Point* first =
        p.table(Table::HoldingRegisters).empty() ? nullptr : &p.table(Table::HoldingRegisters)[0];
    if (p.functions.supports(3) && (first || open)) {
        const std::uint16_t a = first ? first->address : 0;
        std::uint16_t v = 0xDEAD;
        ASSERT_EQ(modbus_read_registers(s.ctx(), a, 1, &v), 1) << modbus_strerror(errno);
        EXPECT_EQ(v, s.device().image().reg(Table::HoldingRegisters, a));
    }

    // A register the client may write: a value it allows reads back, one past its range is refused with
    // exception 03 (errno EMBXILVAL), the register unchanged.
    const mb::Point* w = nullptr;
    for (const auto& pt : p.table(Table::HoldingRegisters))
        if (!w && conformance::freely_writable(pt)) w = &pt;
    if (p.functions.supports(6) && w) {
        const auto now = s.device().image().reg(Table::HoldingRegisters, w->address);
        const auto other = conformance::valid_alternative(w, now);
        ASSERT_TRUE(other.has_value()) << "register " << w->address;
        ASSERT_EQ(modbus_write_register(s.ctx(), w->address, *other), 1) << modbus_strerror(errno);
        std::uint16_t back = 0;
        ASSERT_EQ(modbus_read_registers(s.ctx(), w->address, 1, &back), 1);
        EXPECT_EQ(back, *other);
        const bool is_signed = w->encoding.type == mb::EncodingType::S16 || w->encoding.is_signed;
        if (w->max && *w->max < (is_signed ? 32767 : 65535) && !w->encoding.values.size()) {
            errno = 0;
            EXPECT_EQ(modbus_write_register(s.ctx(), w->address, static_cast<std::uint16_t>(*w->max + 1)),
                      -1);
            EXPECT_EQ(errno, EMBXILVAL) << modbus_strerror(errno);
            ASSERT_EQ(modbus_read_registers(s.ctx(), w->address, 1, &back), 1);
            EXPECT_EQ(back, *other) << "a refused write changed the register";
        }
    }

    // A function the manual does not list gets exception 01 (errno EMBXILFUN): FC17 Report Server ID.
    if (!p.functions.supports(17)) {
        std::uint8_t id[256];
        errno = 0;
        EXPECT_EQ(modbus_report_slave_id(s.ctx(), sizeof id, id), -1);
        EXPECT_EQ(errno, EMBXILFUN) << modbus_strerror(errno);
    }

    // One register more than the manual allows in one read: exception 03 (the MK manuals: 15; Walchem and
    // the generic profile: the specification's 125, which libmodbus refuses to send itself).
    const int max = p.functions.max_for(3);
    if (p.functions.supports(3) && max > 0 && max < 125 && first) {
        std::vector<std::uint16_t> regs(static_cast<std::size_t>(max) + 1);
        errno = 0;
        EXPECT_EQ(modbus_read_registers(s.ctx(), first->address, max + 1, regs.data()), -1);
        EXPECT_EQ(errno, EMBXILVAL) << modbus_strerror(errno);
    }

    // An address past the map's end: exception 02 (errno EMBXILADD).
    if (p.functions.supports(3) && !open && !p.table(Table::HoldingRegisters).empty()) {
        const auto& end = p.table(Table::HoldingRegisters).back();  // a 32-bit value ends a word later
        const auto last = static_cast<std::uint16_t>(end.address + end.encoding.words - 1);
        if (last < 0xFFFF) {
            std::uint16_t v = 0;
            errno = 0;
            EXPECT_EQ(modbus_read_registers(s.ctx(), last + 1, 1, &v), -1);
            EXPECT_EQ(errno, EMBXILADD) << modbus_strerror(errno);
        }
    }
}

class LibmodbusClient : public ::testing::TestWithParam<std::string> {};

TEST_P(LibmodbusClient, EveryProfileReadsWritesAndGetsTheManualsExceptions) {
    for (const auto& id : profile_ids()) {
        SCOPED_TRACE(id + " over " + GetParam());
        Served s({id, GetParam()});
        reads_writes_and_exceptions_as_the_manual_says(s);
    }
}

INSTANTIATE_TEST_SUITE_P(EveryTransport, LibmodbusClient, ::testing::Values("tcp", "rtu-tcp", "rtu"),
                         transport_test_name);

}  // namespace
}  // namespace mbscope::slave::test::test_slave_libmodbus_client_test
