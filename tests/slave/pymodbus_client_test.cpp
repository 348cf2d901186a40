// The reference slave driven by pymodbus's client (Debian python3-pymodbus, tests/peers/pymodbus_client.py)
// for every bundled profile over every transport the slave serves (Modbus/TCP, Modbus/UDP, RTU and ASCII
// over TCP, RTU and ASCII on a pseudo-terminal): a value the manual allows is written and read back, one
// past the range is refused with exception 03 and leaves the register unchanged, FC17 (which no bundled
// device supports) gets exception 01.
//
// One case per transport serves every profile at once, each on its own port or pseudo-terminal, and one
// Python process visits them all: an interpreter importing pymodbus per profile would cost the test suite
// minutes. Each profile's result is checked on its own, with the profile named.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>

#include "conformance/context.hpp"
#include "tests/slave/slave_test_support.hpp"
#include "tests/support/process_support.hpp"

namespace mbscope::slave::test::test_slave_pymodbus_client_test {
namespace {

using mb::Table;

// One profile served for the client, and what the client must see.
class Case {
  public:
    Case(const std::string& id, const std::string& transport) : id_(id), slave_({}, 1, id) {
        const mb::Profile& p = slave_.device().profile();
        // A register the client may write, a value it allows, and one past its range where it has one.
        const mb::Point* w = nullptr;
        for (const auto& pt : p.table(Table::HoldingRegisters))
            if (!w && conformance::freely_writable(pt) && pt.max && *pt.max < 32767 &&
                pt.encoding.values.empty())
                w = &pt;
        for (const auto& pt : p.table(Table::HoldingRegisters))
            if (!w && conformance::freely_writable(pt)) w = &pt;
        if (w) {
            address_ = w->address;
            value_ = conformance::valid_alternative(
                         w, slave_.device().image().reg(Table::HoldingRegisters, address_))
                         .value_or(0);
            refusable_ = w->max && *w->max < 32767 && w->encoding.values.empty();
            bad_ = refusable_ ? static_cast<std::uint16_t>(*w->max + 1) : value_;
        }
        writable_ = w || p.open_address_space;
        fc17_ = p.functions.supports(17);

        const Server& server = slave_.serve_over(transport);
        const bool serial = transport == "rtu" || transport == "ascii";
        target_ = serial ? server.address() : "127.0.0.1:" + std::to_string(server.port());
    }

    const std::string& id() const { return id_; }
    bool writable() const { return writable_; }
    // The line the client reads: TARGET UNIT ADDRESS VALUE BAD.
    std::string request_line() const {
        return target_ + " 1 " + std::to_string(address_) + " " + std::to_string(value_) + " " +
               std::to_string(bad_) + "\n";
    }
    std::string expected() const {
        const std::string v = std::to_string(value_);
        return "write=ok read=" + v + (refusable_ ? " bad=exception:3" : " bad=ok") + " after=" + v +
               (fc17_ ? " fc17=ok" : " fc17=exception:1");
    }
    std::uint16_t address() const { return address_; }

  private:
    std::string id_;
    RunningServer slave_;
    std::uint16_t address_ = 0, value_ = 1234, bad_ = 1234;
    bool refusable_ = false, writable_ = false, fc17_ = false;
    std::string target_;
};

class PymodbusClient : public ::testing::TestWithParam<std::string> {};

TEST_P(PymodbusClient, EveryProfileWritesReadsBackAndGetsTheManualsExceptions) {
    ASSERT_EQ(::access("/usr/bin/python3", X_OK), 0) << "no /usr/bin/python3 (python3-pymodbus)";
    const std::string transport = GetParam();
    std::vector<std::unique_ptr<Case>> cases;
    for (const auto& id : profile_ids())
        cases.push_back(std::make_unique<Case>(id, transport));

    std::string input = ::testing::TempDir() + "pymodbus_targets_" + transport;
    std::replace(input.begin(), input.end(), '-', '_');
    {
        std::ofstream out(input);
        for (const auto& c : cases)
            out << c->request_line();
    }
    std::istringstream lines(mbscope::test::run("/usr/bin/python3 " + std::string(MBSCOPE_SOURCE_DIR) +
                                                "/tests/peers/pymodbus_client.py " + transport + " < " +
                                                input + " 2>&1"));
    for (const auto& c : cases) {
        SCOPED_TRACE(c->id() + " over " + transport + ", register " + std::to_string(c->address()));
        EXPECT_TRUE(c->writable()) << "no register a client may write";
        std::string got;
        EXPECT_TRUE(std::getline(lines, got)) << "no line from the client";
        EXPECT_EQ(got, c->expected());
    }
    std::string rest;
    EXPECT_FALSE(std::getline(lines, rest)) << "the client said more: " << rest;
}

INSTANTIATE_TEST_SUITE_P(EveryTransport, PymodbusClient,
                         ::testing::Values("tcp", "udp", "rtu-tcp", "ascii-tcp", "rtu", "ascii"),
                         transport_test_name);

}  // namespace
}  // namespace mbscope::slave::test::test_slave_pymodbus_client_test
