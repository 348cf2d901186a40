#pragma once
// Shared by the conformance runner's tests: a certification run against the reference slave and what a
// clean run must look like.
#include <gtest/gtest.h>

#include <map>
#include <sstream>
#include <string>

#include "conformance/report.hpp"
#include "conformance/runner.hpp"
#include "modbus/transport/client.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::conformance::test {

namespace tp = modbus::transport;
using slave::test::RunningServer;

struct CheckRun {
    Report report;
    std::map<modbus::Table, std::map<std::uint16_t, std::uint16_t>> changes_after;  // slave image vs initial
};

inline CheckOptions options_for(std::chrono::milliseconds timeout = std::chrono::milliseconds(300)) {
    CheckOptions o;
    o.session.unit = 1;
    o.session.timeout = timeout;
    o.session.interval = std::chrono::milliseconds(0);  // the Walchem manual's 5 s polling is for plants
    o.run.idle = std::chrono::milliseconds(100);
    return o;
}

inline CheckRun certify(RunningServer& server, const std::string& scheme, const std::string& profile_id,
                        const CheckOptions& options = options_for()) {
    const std::uint16_t port = server.start(scheme);
    auto endpoint = tp::parse_endpoint(scheme + "://127.0.0.1:" + std::to_string(port));
    EXPECT_TRUE(endpoint.has_value());
    auto client = tp::Client::open(*endpoint);
    EXPECT_TRUE(client.has_value()) << (client ? "" : client.error());
    CheckRun run;
    if (!client) return run;
    run.report = run_check(*client, slave::test::profile(profile_id), options);
    server.stop();
    run.changes_after = server.device().image().changes();
    return run;
}

inline std::string failures(const Report& r) {
    std::ostringstream out;
    for (const auto& x : r.results)
        if (x.outcome == Outcome::Fail || x.outcome == Outcome::Error)
            out << "\n  " << x.rule.id << ": expected " << x.expected << ", observed " << x.observed
                << (x.reason.empty() ? "" : " (" + x.reason + ")");
    for (const auto& t : r.restored)
        if (!t.restored) out << "\n  not restored: " << modbus::to_string(t.table) << ' ' << t.address;
    return out.str();
}

inline void expect_clean(const CheckRun& run, std::size_t min_rules) {
    const Report& r = run.report;
    EXPECT_EQ(verdict(r), 0) << failures(r);
    EXPECT_EQ(r.count(Outcome::Fail), 0u) << failures(r);
    EXPECT_EQ(r.count(Outcome::Error), 0u) << failures(r);
    EXPECT_GE(r.count(Outcome::Pass), min_rules);
    EXPECT_TRUE(r.all_restored()) << failures(r);
    EXPECT_FALSE(r.stopped);
    // Nothing lost, nothing left behind: the slave holds its initial image again.
    std::string changed;
    for (const auto& [table, m] : run.changes_after)
        for (const auto& [address, value] : m)
            changed += " " + std::string(modbus::to_string(table)) + " " + std::to_string(address) + "=" +
                       std::to_string(value);
    EXPECT_EQ(changed, "") << "the run left values changed on the device";
}

}  // namespace mbscope::conformance::test
