// The reference slave driven by pymodbus's client (Debian python3-pymodbus, tests/peers/pymodbus_client.py)
// for every bundled profile over every transport the slave serves (Modbus/TCP, Modbus/UDP, RTU and ASCII
// over TCP, RTU and ASCII on a pseudo-terminal): a value the manual allows is written and read back, one
// past the range is
// refused with exception 03 and leaves the register unchanged, FC17 (which no bundled device supports)
// gets exception 01.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>

#include "conformance/context.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test {
namespace {

using mb::Table;

std::string run(const std::string& command) {
    std::string out;
    if (FILE* f = ::popen(command.c_str(), "r")) {
        char buf[512];
        while (std::fgets(buf, sizeof buf, f))
            out += buf;
        ::pclose(f);
    }
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r'))
        out.pop_back();
    return out;
}

class PymodbusClient : public ::testing::TestWithParam<ClientCase> {};

TEST_P(PymodbusClient, WritesReadsBackAndGetsTheManualsExceptions) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    const ClientCase& c = GetParam();
    FaultSet faults;
    Device device(profile(c.profile), 1, &faults);
    const mb::Profile& p = device.profile();
    // A register the client may write, a value it allows, and one past its range where it has one.
    const mb::Point* w = nullptr;
    for (const auto& pt : p.table(Table::HoldingRegisters))
        if (!w && conformance::freely_writable(pt) && pt.max && *pt.max < 32767 && pt.encoding.values.empty())
            w = &pt;
    for (const auto& pt : p.table(Table::HoldingRegisters))
        if (!w && conformance::freely_writable(pt)) w = &pt;
    std::uint16_t address = 0, value = 1234, bad = 1234;
    bool refusable = false;
    if (w) {
        address = w->address;
        value = conformance::valid_alternative(w, device.image().reg(Table::HoldingRegisters, address))
                    .value_or(0);
        refusable = w->max && *w->max < 32767 && w->encoding.values.empty();
        bad = refusable ? static_cast<std::uint16_t>(*w->max + 1) : value;
    } else if (!p.open_address_space) {
        GTEST_SKIP() << c.profile << " has no register a client may write";
    }

    const bool serial = c.transport == "rtu" || c.transport == "ascii";
    auto endpoint = mb::transport::parse_endpoint(serial ? c.transport + ":pty?baud=38400&parity=N"
                                                         : c.transport + "://127.0.0.1:0");
    ASSERT_TRUE(endpoint.has_value());
    ServerOptions o;
    o.create_pty = serial;
    Server server(*endpoint, {&device}, faults, o);
    auto opened = server.open();
    ASSERT_TRUE(opened.has_value()) << (opened ? "" : opened.error());
    std::atomic<bool> stop{false};
    std::thread thread([&] { (void)server.run(stop); });
    const std::string target = serial ? server.address() : "127.0.0.1:" + std::to_string(server.port());
    const std::string got =
        run("/usr/bin/python3 " + std::string(MBSCOPE_SOURCE_DIR) + "/tests/peers/pymodbus_client.py " +
            c.transport + " " + target + " 1 " + std::to_string(address) + " " + std::to_string(value) + " " +
            std::to_string(bad) + " 2>&1");
    stop = true;
    thread.join();

    const std::string v = std::to_string(value);
    const std::string expected = "write=ok read=" + v + (refusable ? " bad=exception:3" : " bad=ok") +
                                 " after=" + v +
                                 (p.functions.supports(17) ? " fc17=ok" : " fc17=exception:1");
    EXPECT_EQ(got, expected) << "register " << address;
}

INSTANTIATE_TEST_SUITE_P(EveryProfile, PymodbusClient,
                         ::testing::ValuesIn(client_cases({"tcp", "udp", "rtu-tcp", "ascii-tcp", "rtu",
                                                           "ascii"})),
                         client_case_name);

}  // namespace
}  // namespace mbscope::slave::test
