// The network fuzzer (`mbscope fuzz`) against the reference slave on loopback:
//  - every planted fault of the slave is found, with a rule that names its effect, within a bounded
//    number of requests from a fixed seed (well inside the 60 s the fuzzer is promised to need);
//  - the clean slave yields nothing in the same budget, on every transport;
//  - a test enumerates the slave's faults, so a new fault without a case here fails the build;
//  - a target slower than the timeout is found slow, and no late reply is judged as another request's;
//  - reproducers replay: saved, loaded, sent again, the same rule broken;
//  - written points are restored; --read-only writes nothing;
//  - the command's exit codes (0 nothing found, 1 findings, 2 unreachable) and its JSON summary.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <thread>

#include "conformance/report.hpp"
#include "fuzz/network/campaign.hpp"
#include "fuzz/network/reply_latency.hpp"
#include "fuzz/network/unanswered.hpp"
#include "fuzz/network/written_points.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/pdu.hpp"
#include "modbus/transport/socket.hpp"
#include "slave/slave_test_support.hpp"
#include "tests/support/garbage_peer.hpp"
#include "tests/support/map_device.hpp"
#include "tests/support/process_support.hpp"

namespace test_fuzz_network_fuzzer_test {

namespace {

namespace fz = mbscope::fuzz::network;
namespace sl = mbscope::slave;
using mbscope::modbus::Table;
using mbscope::slave::test::RunningServer;

struct FaultCase {
    std::string fault;
    std::string profile;
    std::string scheme;
    std::set<std::string> rules;  // any of these names the fault's effect
};

std::ostream& operator<<(std::ostream& out, const FaultCase& c) {
    return out << c.fault << " on " << c.profile << " over " << c.scheme;
}

fz::CampaignOptions options_for(const std::string& scheme, std::uint16_t port) {
    fz::CampaignOptions o;
    o.target = scheme + "://127.0.0.1:" + std::to_string(port);
    o.endpoint = *mbscope::modbus::transport::parse_endpoint(o.target);
    o.seed = 1;
    o.requests = 3000;
    o.duration = std::chrono::seconds(60);
    o.timeout = std::chrono::milliseconds(300);
    // Over Modbus/TCP the fuzzer's default: no wait where silence is due, a late reply matched to its
    // request by transaction id (unanswered.hpp). On the serial framings a fixed wait, so that a loaded
    // machine cannot make a reply late enough to be taken for the next request's.
    if (mbscope::modbus::transport::framing_of(o.endpoint.scheme) != mbscope::modbus::Framing::Tcp)
        o.silence_wait = std::chrono::milliseconds(20);
    o.slow = std::chrono::milliseconds(400);
    o.minimise_budget = 8;
    return o;
}

std::string listing(const fz::CampaignSummary& s) {
    std::string out;
    for (const auto& f : s.findings)
        out += "\n  " + f.rule + " on fc" + std::to_string(f.function) + ": expected " + f.expected +
               "; observed " + f.observed;
    return out.empty() ? " (none)" : out;
}

using Points = std::set<std::pair<Table, std::uint16_t>>;

// The points a run's summary says it left changed and not restored: not restored, in a range it could not
// read first, or reached unread by a write that drew no reply.
Points left_unrestored(const fz::CampaignSummary& s) {
    Points listed;
    for (const auto& r : s.not_read)
        for (std::uint32_t a = r.start; a < r.end(); ++a)
            listed.insert({r.table, static_cast<std::uint16_t>(a)});
    for (const auto& t : s.restored)
        if (!t.restored) listed.insert({t.table, t.address});
    for (const auto& u : s.unanswered_writes)
        listed.insert({u.table, u.address});
    for (const auto& r : s.unanswered_unread)
        for (std::uint32_t a = r.start; a < r.end(); ++a)
            listed.insert({r.table, static_cast<std::uint16_t>(a)});
    return listed;
}

std::vector<FaultCase> fault_cases() {
    return {
        {"bad-crc", "mmk-2030", "rtu-tcp", {"reply.checksum"}},
        {"bad-lrc", "mmk-2030", "ascii-tcp", {"reply.checksum"}},
        {"wrong-byte-count", "mmk-2030", "tcp", {"reply.malformed", "reply.byte_count"}},
        {"short-response", "mmk-2030", "tcp", {"reply.malformed"}},
        {"extra-bytes", "mmk-2030", "rtu-tcp", {"reply.malformed", "reply.trailing_bytes"}},
        {"wrong-unit", "mmk-2030", "tcp", {"reply.envelope"}},
        {"wrong-function", "mmk-2030", "tcp", {"reply.function"}},
        {"wrong-tid", "mmk-2030", "tcp", {"reply.envelope"}},
        {"bad-protocol-id", "walchem-w600", "tcp", {"reply.envelope"}},
        {"any-protocol-id", "walchem-w600", "tcp", {"silence.protocol_id"}},
        {"reply-to-broadcast", "mmk-2030", "rtu-tcp", {"silence.broadcast", "reply.late"}},
        {"ignore-max-quantity", "mmk-2030", "tcp", {"reply.quantity"}},
        {"wrong-exception=4",
         "mmk-2030",
         "tcp",
         {"reply.unsupported_function", "reply.quantity", "reply.address"}},
        {"exception-for-valid=0.5", "mmk-2030", "tcp", {"reply.exception_for_valid"}},
        {"no-reply=0.3", "mmk-2030", "tcp", {"reply.missing", "target.unresponsive"}},
        {"slow-reply=800", "cth2265i", "tcp", {"timing.slow_reply"}},
        {"gap-inside-frame=60", "mmk-2030", "rtu-tcp", {"reply.checksum", "reply.unframed", "reply.late"}},
        // Swapped both ways, a write reads back as written: the device refuses a valid float it reads as
        // another one, out of range, and takes an invalid one it reads as another in range.
        {"word-swap", "walchem-w600", "tcp", {"reply.exception_for_valid", "reply.rejected_write"}},
        {"off-by-one-address",
         "mmk-2030",
         "tcp",
         {"reply.exception_for_valid", "reply.address", "state.lost_write"}},
        // 21: square-root cut-off, channel 1 (0..5 %), a setpoint no process moves (000:486-721).
        {"stuck-value=21", "mmk-2030", "tcp", {"state.lost_write"}},
        {"drop-write", "mmk-2030", "tcp", {"state.lost_write"}},
        {"accept-out-of-range", "mmk-2030", "tcp", {"reply.rejected_write"}},
        {"no-echo", "mmk-2030", "tcp", {"reply.echo"}},
        {"crash-after=200", "cth2265i", "tcp", {"target.unresponsive", "reply.missing"}},
        {"duplicate-reply", "mmk-2030", "rtu-tcp", {"reply.duplicate"}},
        {"wrong-quantity", "mmk-2030", "tcp", {"reply.byte_count", "reply.echo"}},
    };
}

class PlantedFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(PlantedFault, IsFoundByTheNetworkFuzzerWithTheRuleItBreaks) {
    const auto& c = GetParam();
    RunningServer server({c.fault}, 7, c.profile);
    auto o = options_for(c.scheme, server.start(c.scheme));
    if (c.fault.starts_with("slow-reply")) o.timeout = std::chrono::milliseconds(2000);
    o.max_findings = 1;
    const auto s = fz::run_campaign(mbscope::slave::test::profile(c.profile), o);
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_FALSE(s.findings.empty()) << "nothing found in " << s.requests << " requests";
    const bool named = std::any_of(s.findings.begin(), s.findings.end(),
                                   [&](const auto& f) { return c.rules.count(f.rule); });
    EXPECT_TRUE(named) << "no finding names the fault's effect:" << listing(s);
    EXPECT_FALSE(s.findings.front().reproducer.steps.empty());
    // No reply came after the timeout (slow-reply's within it): the command must not suggest a longer one.
    EXPECT_EQ(s.replies_after_timeout, 0u);
    // Served where the rules want silence, which over Modbus/TCP is not waited for: the replies come after
    // their requests were given up, and are judged as theirs.
    if (c.fault == "any-protocol-id") {
        EXPECT_GT(s.late_replies, 0u);
    }
}

INSTANTIATE_TEST_SUITE_P(Slave, PlantedFault, ::testing::ValuesIn(fault_cases()), [](const auto& info) {
    std::string n = info.param.fault.substr(0, info.param.fault.find('='));
    for (auto& ch : n)
        if (ch == '-') ch = '_';
    return n;
});

TEST(PlantedFaults, EveryFaultOfTheSlaveHasANetworkFuzzingCase) {
    std::set<std::string> named;
    for (const auto& c : fault_cases())
        named.insert(c.fault.substr(0, c.fault.find('=')));
    for (std::size_t i = 0; i < sl::fault_count; ++i) {
        const std::string name(sl::to_string(static_cast<sl::Fault>(i)));
        EXPECT_TRUE(named.count(name)) << name << " has no network fuzzing case";
    }
}

struct CleanCase {
    std::string profile;
    std::string scheme;
};

class CleanSlave : public ::testing::TestWithParam<CleanCase> {};

// A test name from a case's profile and transport: "mmk_2030_rtu_tcp".
const auto profile_and_scheme = [](const auto& info) {
    std::string n = info.param.profile + "_" + info.param.scheme;
    std::replace(n.begin(), n.end(), '-', '_');
    return n;
};

// The same budget as the fault cases, against the slave without faults: nothing is found, and every point
// written is restored.
TEST_P(CleanSlave, YieldsNoFindingAndRestoresEveryWrite) {
    const auto& c = GetParam();
    RunningServer server({}, 7, c.profile);
    auto o = options_for(c.scheme, server.start(c.scheme));
    // RTU over a stream: requests whose length the function does not tell are waited for in full (the
    // slave ends them at a silence), so fewer in the same time.
    o.requests = c.scheme == "rtu-tcp" ? 600 : 1500;
    const auto s = fz::run_campaign(mbscope::slave::test::profile(c.profile), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_TRUE(s.findings.empty()) << listing(s);
    EXPECT_EQ(s.late_replies, 0u);
    EXPECT_EQ(s.requests, *o.requests);
    EXPECT_GT(s.response_classes, 10u);
    EXPECT_GT(s.exceptions, 0u);
    EXPECT_GT(s.replies, s.exceptions);
    for (const auto& t : s.restored)
        EXPECT_TRUE(t.restored) << mbscope::modbus::to_string(t.table) << " " << t.address << ": "
                                << t.problem;
}

INSTANTIATE_TEST_SUITE_P(Slave, CleanSlave,
                         ::testing::Values(CleanCase{"mmk-2030", "tcp"}, CleanCase{"mmk-2030", "rtu-tcp"},
                                           CleanCase{"mmk-2030", "ascii-tcp"},
                                           CleanCase{"cth2265i", "rtu-tcp"}, CleanCase{"walchem-w600", "tcp"},
                                           CleanCase{"modbus", "tcp"}, CleanCase{"mmk-2030", "udp"}),
                         profile_and_scheme);

// On a real serial line (a pseudo-terminal) the clean slave yields nothing either. A request split with a
// pause past t1.5 is void in RTU only: an ASCII frame may pause a second between characters, and its
// answer was judged a broken silence.gap_inside_request (and then taken for the next request's reply).
TEST(NetworkFuzzer, CleanSlaveOnASerialLineYieldsNothing) {
    for (const std::string framing : {"rtu", "ascii"}) {
        RunningServer server({}, 7, "mmk-2030");
        server.serve_over(framing);
        auto o = options_for("tcp", 1);
        o.target = framing + ":" + server.server().address() + "?baud=38400";
        o.endpoint = *mbscope::modbus::transport::parse_endpoint(o.target);
        o.silence_wait = std::chrono::milliseconds(20);
        o.requests = 300;
        const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
        ASSERT_TRUE(s.reachable) << framing << ": " << s.error;
        EXPECT_TRUE(s.findings.empty()) << framing << listing(s);
        for (const auto& t : s.restored)
            EXPECT_TRUE(t.restored) << framing << " " << mbscope::modbus::to_string(t.table) << " "
                                    << t.address;
    }
}

// The fuzzer makes its pause inside an RTU request on this host: the scheduler, the kernel's tty buffers or
// a USB adapter can close it before it reaches the line, and the device then rightly answers one whole
// request. A device timing the line as at 1200 baud (t1.5 13.75 ms) hears the fuzzer's 2 ms pause (38400
// baud) as no pause at all, as a device hears a pause this host failed to make, and the 50 ms one of the
// confirmation as a pause: no finding, the first reply counted unconfirmed.
TEST(NetworkFuzzer, AGapTheDeviceDidNotHearCountsOnlyWhenALongerOneIsAnsweredToo) {
    RunningServer server({}, 7, "mmk-2030");
    mbscope::slave::ServerOptions so;
    so.create_pty = true;
    server.serve("rtu:pty?baud=1200&parity=N", so);
    auto o = options_for("tcp", 1);
    o.target = "rtu:" + server.server().address() + "?baud=38400";
    o.endpoint = *mbscope::modbus::transport::parse_endpoint(o.target);
    // The device waits t3.5 at 1200 baud (32 ms) before it answers.
    o.silence_wait = std::chrono::milliseconds(150);
    o.timeout = std::chrono::milliseconds(600);
    o.requests = 120;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_TRUE(std::none_of(s.findings.begin(), s.findings.end(), [](const auto& f) {
        return f.rule == "silence.gap_inside_request";
    })) << listing(s);
    EXPECT_GT(s.unconfirmed, 0u) << listing(s);
}

// A target lost mid-run is not written to again, and the points written before are not passed over in
// silence: each is listed as not restored, with why.
TEST(NetworkFuzzer, PointsWrittenBeforeTheTargetWasLostAreListedAsNotRestored) {
    RunningServer server({"crash-after=300"}, 7, "modbus");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 1500;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("modbus"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_TRUE(s.target_lost) << listing(s);
    ASSERT_FALSE(s.restored.empty()) << "nothing was written before the target was lost";
    for (const auto& t : s.restored) {
        EXPECT_FALSE(t.restored);
        EXPECT_EQ(t.problem, "not restored: the target stopped answering");
    }
}

// A lax device executes writes its manual says it refuses (here: quantities over the manual's limits). Their
// points are read before they are sent too, so they are put back; and nothing is called restored that
// does not hold what it held before the run. Every point the run left changed is in the summary, as not
// restored, in a range whose values could not be read first, or reached unread by a write without a reply.
TEST(NetworkFuzzer, WritesALaxDeviceShouldHaveRefusedAreRestoredOrListed) {
    RunningServer server({"ignore-max-quantity", "accept-out-of-range"}, 7, "mmk-2030");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 1500;
    const auto& profile = mbscope::slave::test::profile("mmk-2030");
    ASSERT_TRUE(server.device().image().changes().empty());
    const sl::RegisterImage before(profile, mbscope::modbus::transport::line_state(o.endpoint, 1));
    const auto s = fz::run_campaign(profile, o);
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_FALSE(s.target_lost) << listing(s);
    EXPECT_NE(listing(s).find("reply.quantity"), std::string::npos) << listing(s);
    const auto& after = server.device().image();
    const auto value = [](const sl::RegisterImage& image, Table t, std::uint16_t a) {
        return mbscope::modbus::is_bit_table(t) ? static_cast<std::uint16_t>(image.bit(t, a))
                                                : image.reg(t, a);
    };
    const Points listed = left_unrestored(s);
    for (const auto& t : s.restored) {
        if (t.restored) {
            EXPECT_EQ(value(after, t.table, t.address), t.original)
                << "called restored: " << mbscope::modbus::to_string(t.table) << " " << t.address;
            EXPECT_EQ(value(before, t.table, t.address), t.original)
                << "original misread: " << mbscope::modbus::to_string(t.table) << " " << t.address;
        }
    }
    // What the simulated process moves (process values, a relay) is the process's; a write-only point (an
    // alarm acknowledge) is a command with no value to read or put back.
    std::set<std::pair<Table, std::uint16_t>> not_state;
    for (const auto& signal : profile.simulation.signals)
        not_state.insert({profile.resolve(signal.point.table), signal.point.address});
    for (const Table t : {Table::Coils, Table::HoldingRegisters})
        for (const auto& pt : profile.table(t))
            if (pt.access == mbscope::modbus::Access::Write) not_state.insert({t, pt.address});
    for (const auto& [t, changed] : after.changes()) {
        if (t != Table::Coils && t != Table::HoldingRegisters) continue;
        for (const auto& [address, now] : changed)
            if (!not_state.count({t, address})) {
                EXPECT_TRUE(listed.count({t, address}))
                    << "changed and not listed: " << mbscope::modbus::to_string(t) << " " << address << ": "
                    << value(before, t, address) << " -> " << now;
            }
    }
}

// The device's own process beside the master, through `client`, a connection of its own: every coil and
// holding register of [start, start + count) (count at most 123) takes a value other than the one it holds
// (a register's XOR 0x5A5A, a coil's opposite). Returns the values it set.
std::map<std::pair<Table, std::uint16_t>, std::uint16_t> device_moves(
    mbscope::modbus::transport::Client& client, std::uint16_t start, std::uint16_t count) {
    namespace mb = mbscope::modbus;
    std::map<std::pair<Table, std::uint16_t>, std::uint16_t> set;
    const auto ask = [&](const mb::Pdu& request) -> std::optional<mb::Pdu> {
        const auto ex = client.transact(1, mb::encode_pdu(request), std::chrono::milliseconds(1000));
        auto reply = ex.response ? mb::decode_response(ex.response->pdu()) : mb::decode_response({});
        if (!reply || reply.value().is_exception()) {
            ADD_FAILURE() << "the device's own process got no normal reply: " << mb::hex_bytes(ex.received);
            return std::nullopt;
        }
        return std::move(reply).value();
    };
    if (const auto regs = ask(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, start, count))) {
        auto values = std::get<mb::ReadRegistersResponse>(regs->body).values;
        for (std::uint16_t i = 0; i < count; ++i) {
            values[i] ^= 0x5A5A;
            set[{Table::HoldingRegisters, static_cast<std::uint16_t>(start + i)}] = values[i];
        }
        (void)ask(mb::make_write_multiple_registers(start, values));
    }
    if (const auto bits = ask(mb::make_read_request(mb::FunctionCode::ReadCoils, start, count))) {
        std::unique_ptr<bool[]> values(new bool[count]);
        for (std::uint16_t i = 0; i < count; ++i) {
            values[i] = !mb::bit_at(std::get<mb::ReadBitsResponse>(bits->body).values, i);
            set[{Table::Coils, static_cast<std::uint16_t>(start + i)}] = values[i] ? 1 : 0;
        }
        (void)ask(mb::make_write_multiple_coils(start, {values.get(), count}));
    }
    return set;
}

// On a serial line a broadcast draws no reply: in a step that also carries a write to the unit which the
// device refuses (exception 02), that refusal is not the broadcast's answer. It was, so the broadcast's
// point was kept as "not written" and, executed all the same, was neither restored nor listed.
TEST(NetworkFuzzer, ABroadcastInAStepTakesNoOtherRequestsRefusal) {
    RunningServer server({}, 1, "modbus");
    const auto port = server.start("rtu-tcp");
    auto client = mbscope::modbus::transport::Client::open(
        *mbscope::modbus::transport::parse_endpoint("rtu-tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value()) << client.error();
    const auto& p = mbscope::slave::test::profile("modbus");
    mbscope::conformance::Session session(*client, {1, std::chrono::milliseconds(1000), {}}, &p);
    session.watch_writes();
    ASSERT_TRUE(session.remember(Table::HoldingRegisters, 10, 1));
    const auto original = session.touched().at({Table::HoldingRegisters, 10}).original;
    const std::uint16_t value = original == 7 ? 8 : 7;
    fz::Step step;
    auto both = mbscope::modbus::encode_rtu(
        0, mbscope::modbus::encode_pdu(mbscope::modbus::make_write_single_register(10, value)));
    const auto refused = mbscope::modbus::encode_rtu(
        1, mbscope::modbus::encode_pdu(mbscope::modbus::make_write_single_register(20, 1)));
    both.insert(both.end(), refused.begin(), refused.end());
    step.parts.push_back(both);
    fz::ReplayedStep replayed;
    replayed.exchange.sent = both;
    replayed.exchange.received = mbscope::modbus::encode_rtu(1, std::vector<std::uint8_t>{0x86, 0x02});
    fz::note_step_writes(session, step, replayed);
    const auto& t = session.touched().at({Table::HoldingRegisters, 10});
    EXPECT_TRUE(t.changed) << "the broadcast may have run";
    EXPECT_FALSE(t.acknowledged);
    EXPECT_EQ(t.written, value);
}

// The campaign sends its probes over the session's client, and the session used to see none of them: the
// restore wrote back every point it had read before a write, the writes the device refused and those of the
// value a point held included, undoing what the device had changed itself since (the tester's counter at
// register 50, rewound after a refused FC16), and the ledger said "written": null of every point. Now each
// probe is told to the session as `mbscope check`'s rules are. Here the device's own process moves every
// coil and holding register just before the restore (announced at a polling interval). A point the ledger
// calls restored is back at its original, with what the run wrote there; one the device changed after a
// write it did not acknowledge (a broadcast, which the slave executes and does not answer) keeps the
// device's value, listed as its change; and a point the run did not change is not written back, keeping
// the device's value too.
TEST(NetworkFuzzer, TheRestorePutsBackOnlyWhatTheProbesChanged) {
    RunningServer server({}, 7, "modbus");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 1500;
    o.interval = std::chrono::milliseconds(1);  // the restore is announced (CampaignOptions::note)
    const auto& profile = mbscope::slave::test::profile("modbus");
    const sl::RegisterImage before(profile, mbscope::modbus::transport::line_state(o.endpoint, 1));
    std::map<std::pair<Table, std::uint16_t>, std::uint16_t> moved;
    o.note = [&](const std::string& text) {
        if (!text.starts_with("restoring")) return;
        auto process = mbscope::modbus::transport::Client::open(o.endpoint);
        ASSERT_TRUE(process.has_value()) << process.error();
        for (std::uint32_t start = 0; start < 0x10000; start += 123) {
            const auto count = static_cast<std::uint16_t>(std::min<std::uint32_t>(123, 0x10000 - start));
            const auto set = device_moves(process.value(), static_cast<std::uint16_t>(start), count);
            moved.insert(set.begin(), set.end());
        }
    };
    const auto s = fz::run_campaign(profile, o);
    server.stop();
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_FALSE(s.target_lost) << listing(s);
    ASSERT_FALSE(moved.empty()) << "the restore was not announced";
    std::map<std::pair<Table, std::uint16_t>, mbscope::conformance::Touched> ledger;
    for (const auto& t : s.restored)
        ledger[{t.table, t.address}] = t;
    const auto& after = server.device().image();
    const auto value = [](const sl::RegisterImage& image, Table t, std::uint16_t a) {
        return mbscope::modbus::is_bit_table(t) ? static_cast<std::uint16_t>(image.bit(t, a))
                                                : image.reg(t, a);
    };
    std::size_t acknowledged = 0, device_changed = 0, left = 0;
    for (const auto& [point, own] : moved) {
        const auto& [table, address] = point;
        const std::string where =
            std::string(mbscope::modbus::to_string(table)) + " " + std::to_string(address);
        const auto it = ledger.find(point);
        if (it == ledger.end()) {
            EXPECT_EQ(value(after, table, address), own) << where << ": written back, not changed by the run";
            ++left;
            continue;
        }
        const auto& t = it->second;
        if (t.device_changed) {
            EXPECT_FALSE(t.restored) << where;
            EXPECT_EQ(value(after, table, address), own) << where << ": the device's own value overwritten";
            EXPECT_EQ(t.left, std::optional<std::uint16_t>(own)) << where;
            ++device_changed;
        } else if (t.restored) {
            EXPECT_EQ(t.original, value(before, table, address)) << where;
            EXPECT_EQ(value(after, table, address), t.original) << where << ": called restored";
            EXPECT_TRUE(t.written || t.unknown_value) << where << ": listed, and the run wrote nothing known";
            acknowledged += t.acknowledged && t.written;
        }
    }
    EXPECT_GT(acknowledged, 0u) << "no acknowledged write in the ledger";
    EXPECT_GT(device_changed, 0u) << "no write the device did not acknowledge, changed by it since";
    EXPECT_GT(left, 0u);
}

// A register mirroring a line setting is never given another value: a real MK device would leave the line.
// The slave is made to show it: with the unit address (7) or the framing (8) stuck, a write that changed
// either would be found lost when read back (state.lost_write).
TEST(NetworkFuzzer, LineSettingsAreNeverChanged) {
    for (const char* fault : {"stuck-value=7", "stuck-value=8"}) {
        RunningServer server({fault}, 7, "mmk-2030");
        auto o = options_for("tcp", server.start("tcp"));
        o.requests = 1500;
        const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
        ASSERT_TRUE(s.reachable) << s.error;
        EXPECT_TRUE(s.findings.empty()) << fault << listing(s);
        EXPECT_GT(s.line_settings_kept, 0u) << fault;
    }
}

TEST(NetworkFuzzer, ReadOnlyNeverChangesTheDevice) {
    RunningServer server({}, 7, "mmk-2030");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 800;
    o.read_only = true;
    const auto before = server.device().image().modifications();
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_TRUE(s.findings.empty()) << listing(s);
    EXPECT_TRUE(s.restored.empty());
    EXPECT_EQ(server.device().image().modifications(), before);
}

TEST(NetworkFuzzer, TheSameSeedSendsTheSameRequests) {
    const auto run = [](std::uint64_t seed) {
        RunningServer server({}, 7, "mmk-2030");
        auto o = options_for("tcp", server.start("tcp"));
        o.requests = 300;
        o.seed = seed;
        const auto j = fz::to_json(fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o));
        EXPECT_EQ(j["requests"], 300);
        return j["requests_digest"].get<std::string>();
    };
    const auto first = run(3);
    EXPECT_EQ(first.size(), 16u);
    EXPECT_EQ(first, run(3));
    EXPECT_NE(first, run(4));
}

// Where no reply is due the fuzzer waits only briefly (over Modbus/TCP an MBAP length probe, after which
// the connection is dropped, waits the learnt silence wait: a fraction of a millisecond on loopback), so
// whether the reply the slave gives anyway is seen is up to the machine's load. It must not steer the
// requests: with a wait that never sees one and a wait that always does, the same seed sends the same.
TEST(NetworkFuzzer, ARepliesTimingWhereNoneWasDueDoesNotSteerTheRequests) {
    const auto run = [](std::chrono::milliseconds wait) {
        RunningServer server({}, 7, "mmk-2030");
        auto o = options_for("tcp", server.start("tcp"));
        o.requests = 400;
        o.seed = 3;
        o.silence_wait = wait;
        const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
        EXPECT_TRUE(s.findings.empty()) << listing(s);
        return s;
    };
    const auto unseen = run(std::chrono::milliseconds(0));
    const auto seen = run(std::chrono::milliseconds(100));
    // The slave answers a request whose MBAP length is one short (its PDU cut by a byte): only the longer
    // wait sees those replies, so the runs saw different things.
    EXPECT_LT(unseen.replies, seen.replies);
    EXPECT_EQ(unseen.requests, seen.requests);
    EXPECT_EQ(unseen.requests_digest, seen.requests_digest);
}

// ---- the wait where the rules demand silence, learnt from the replies

using std::chrono::microseconds;
using std::chrono::milliseconds;

TEST(ReplyLatency, TheTimeoutUntilAReplyWasSeen) {
    fz::ReplyLatency l;
    EXPECT_EQ(l.silence_wait(milliseconds(1), milliseconds(1000)), milliseconds(1000));
}

// RFC 6298's estimator, doubled: a first reply of 10 ms gives 2 * (10 + 4 * 5) = 60 ms; steady replies
// shrink the deviation and the wait with it, to the floor for replies of 50 us.
TEST(ReplyLatency, FollowsTheRepliesWithinTheFloorAndTheCap) {
    fz::ReplyLatency l;
    l.add(milliseconds(10));
    EXPECT_EQ(l.silence_wait(milliseconds(1), milliseconds(1000)), milliseconds(60));
    for (int i = 0; i < 200; ++i)
        l.add(milliseconds(10));
    EXPECT_EQ(l.silence_wait(milliseconds(1), milliseconds(1000)), milliseconds(20));
    EXPECT_EQ(l.silence_wait(milliseconds(1), milliseconds(15)), milliseconds(15));
    fz::ReplyLatency fast;
    for (int i = 0; i < 50; ++i)
        fast.add(microseconds(50));
    EXPECT_EQ(fast.silence_wait(milliseconds(1), milliseconds(1000)), milliseconds(1));
    EXPECT_EQ(fast.silence_wait(milliseconds(5), milliseconds(1000)), milliseconds(5));
}

// One slow reply among fast ones raises the wait at once (the deviation), and it comes down again.
TEST(ReplyLatency, ASlowReplyRaisesTheWaitForAWhile) {
    fz::ReplyLatency l;
    for (int i = 0; i < 50; ++i)
        l.add(microseconds(100));
    const auto before = l.silence_wait(milliseconds(1), milliseconds(1000));
    l.add(milliseconds(40));
    const auto after = l.silence_wait(milliseconds(1), milliseconds(1000));
    EXPECT_GE(after, milliseconds(80));  // 2 * (smoothed ~5 ms + 4 * deviation ~10 ms)
    for (int i = 0; i < 100; ++i)
        l.add(microseconds(100));
    EXPECT_EQ(l.silence_wait(milliseconds(1), milliseconds(1000)), before);
}

// Requests kept for their late reply: taken by transaction id, once only, however late the reply comes;
// kept while their id is within the window the client sets stale replies aside in.
TEST(Unanswered, AReplyTakesTheRequestWithItsTransactionIdOnce) {
    using namespace std::chrono;
    const auto request = [](std::uint16_t tid, std::uint8_t fc) {
        mbscope::modbus::transport::Exchange ex;
        ex.sent = mbscope::modbus::encode_tcp(tid, 1, std::vector<std::uint8_t>{fc, 0, 0, 0, 1});
        return ex;
    };
    fz::Unanswered kept;
    const auto t0 = fz::Unanswered::Clock::time_point{} + hours(1);
    EXPECT_EQ(kept.newest_due(), nullptr);
    kept.add(request(7, 3), t0, t0 + milliseconds(100), true);
    kept.add(request(8, 4), t0 + milliseconds(110), t0 + milliseconds(110), false);
    kept.add(request(9, 1), t0 + milliseconds(120), t0 + milliseconds(120), false);
    mbscope::modbus::transport::Exchange short_one;
    short_one.sent = {0x00, 0x0A, 0x00};
    kept.add(short_one, t0 + milliseconds(130), t0 + milliseconds(130), true);  // no MBAP header: no id
    EXPECT_EQ(kept.size(), 3u);
    ASSERT_NE(kept.newest_due(), nullptr);  // the first: the others want no reply
    EXPECT_EQ(kept.newest_due()->exchange.sent[7], 3);
    EXPECT_EQ(kept.newest_due()->given_up, t0 + milliseconds(100));
    EXPECT_EQ(kept.newest(), t0 + milliseconds(120));
    EXPECT_FALSE(kept.take(10));
    auto nine = kept.take(9);
    ASSERT_TRUE(nine);
    EXPECT_EQ(nine->exchange.sent[7], 1);
    EXPECT_EQ(nine->sent, t0 + milliseconds(120));
    EXPECT_FALSE(nine->reply_due);
    auto seven = kept.take(7);
    ASSERT_TRUE(seven);
    EXPECT_EQ(seven->exchange.sent[7], 3);
    EXPECT_TRUE(seven->reply_due);
    EXPECT_EQ(kept.newest_due(), nullptr);
    EXPECT_FALSE(kept.take(7));  // a request has one reply
    EXPECT_TRUE(kept.take(8));   // however late
    EXPECT_TRUE(kept.empty());

    // Ids 65,530 to 65,535 and, past the wrap, 0 to 300: a request is dropped once the newest id added is
    // more than the window ahead of its id.
    for (std::uint32_t i = 65530; i < 65536 + 301; ++i)
        kept.add(request(static_cast<std::uint16_t>(i), 3), t0, t0, true);
    EXPECT_EQ(kept.size(), fz::Unanswered::window + 1u);
    EXPECT_FALSE(kept.take(43));  // 300 - 257
    EXPECT_TRUE(kept.take(44));   // 300 - 256
    EXPECT_FALSE(kept.take(65535));
    EXPECT_TRUE(kept.take(300));
    kept.clear();
    EXPECT_TRUE(kept.empty());
}

// Without --silence-wait the campaign waits what the replies teach, not the reply timeout: a clean slave
// still yields nothing, and a slave that answers broadcasts is still caught.
TEST(NetworkFuzzer, SilenceWaitIsLearntFromTheReplies) {
    RunningServer server({}, 7, "mmk-2030");
    auto o = options_for("tcp", server.start("tcp"));
    o.silence_wait.reset();
    o.timeout = milliseconds(2000);
    o.requests = 400;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_TRUE(s.findings.empty()) << listing(s);
    EXPECT_GT(s.silences, 0u);
    EXPECT_LT(s.silence_wait, o.timeout);
    EXPECT_DOUBLE_EQ(fz::to_json(s)["silence_wait_ms"].get<double>(), s.silence_wait.count() / 1000.0);
}

TEST(NetworkFuzzer, ABroadcastReplyIsCaughtWithTheLearntSilenceWait) {
    RunningServer server({"reply-to-broadcast"}, 7, "mmk-2030");
    auto o = options_for("rtu-tcp", server.start("rtu-tcp"));
    o.silence_wait.reset();
    o.requests = 150;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    // Any of the broadcasts will do: on a loaded machine one reply may come after the wait learnt so far.
    EXPECT_TRUE(std::any_of(s.findings.begin(), s.findings.end(), [](const auto& f) {
        return f.rule == "silence.broadcast";
    })) << listing(s);
}

// Over Modbus/TCP the transaction id tells whose a late reply is: a frame that a kept request's id claims is
// taken for that request's, whichever came between; anything else is left, in order.
TEST(Unanswered, FramesAreClaimedByTransactionIdAndTheRestIsLeftInOrder) {
    const std::vector<std::uint8_t> read{0x03, 0x00, 0x00, 0x00, 0x01};
    const std::vector<std::uint8_t> reply{0x03, 0x02, 0x00, 0x2A};
    fz::Unanswered kept;
    const auto t0 = fz::Unanswered::Clock::now();
    for (std::uint16_t tid : {5, 6, 7}) {
        mbscope::modbus::transport::Exchange ex;
        ex.sent = mbscope::modbus::encode_tcp(tid, 1, read);
        kept.add(ex, t0, t0, tid != 5);
    }
    const auto to_six = mbscope::modbus::encode_tcp(6, 1, reply);
    const auto to_nine = mbscope::modbus::encode_tcp(9, 1, reply);  // no request kept with that id
    const auto to_five = mbscope::modbus::encode_tcp(5, 1, reply);
    const std::vector<std::uint8_t> tail{0x00, 0x05, 0x00};  // part of a header
    std::vector<std::uint8_t> bytes = to_six;
    for (const auto* part : {&to_nine, &to_five, &tail})
        bytes.insert(bytes.end(), part->begin(), part->end());
    fz::Unanswered::Claims claims;
    const auto rest = kept.claim_frames(bytes, claims);
    ASSERT_EQ(claims.size(), 2u);
    EXPECT_EQ(claims[0].first.exchange.sent, mbscope::modbus::encode_tcp(6, 1, read));
    EXPECT_TRUE(claims[0].first.reply_due);
    EXPECT_EQ(claims[1].first.exchange.sent, mbscope::modbus::encode_tcp(5, 1, read));
    EXPECT_FALSE(claims[1].first.reply_due);
    EXPECT_EQ(claims[1].second.transaction_id(), 5);
    std::vector<std::uint8_t> expected = to_nine;
    expected.insert(expected.end(), tail.begin(), tail.end());
    EXPECT_EQ(rest, expected);
    EXPECT_EQ(kept.size(), 1u);                                              // 7 only
    EXPECT_FALSE(kept.claim(*mbscope::modbus::decode_tcp(to_six), claims));  // a request has one reply
}

// A Modbus/TCP replay keeps the steps given up as the campaign does: a reply that comes any number of steps
// later is matched by its transaction id and judged as its own step's. Here the target answers 450 ms after
// each request, and also answers a request with protocol id 1, which it must discard (TCP §3.1.3): that
// reply comes two steps later, while the third waits, and is judged as the first step's; the second's
// comes during the third too, and the third's own is waited for after the last step.
TEST(NetworkFuzzer, AReplayOverTcpJudgesALateReplyAsItsOwnStepsHoweverLate) {
    RunningServer server({"slow-reply=450", "any-protocol-id"}, 7, "cth2265i");
    auto o = options_for("tcp", server.start("tcp"));
    auto client = mbscope::modbus::transport::Client::open(o.endpoint);
    ASSERT_TRUE(client);
    const auto& profile = mbscope::slave::test::profile("cth2265i");
    mbscope::conformance::ExchangeOracle oracle(mbscope::modbus::Framing::Tcp, {{1, &profile}}, true);
    const auto read = [&](std::uint16_t tid, std::uint8_t fc, std::uint8_t protocol) {
        fz::Step step;
        step.parts.push_back(
            mbscope::modbus::encode_tcp(tid, 1, std::vector<std::uint8_t>{fc, 0x0F, 0x9F, 0x00, 0x01}));
        step.parts.back()[3] = protocol;
        return step;
    };
    fz::ReplayOptions options;
    options.timeout = milliseconds(300);
    options.silence_wait = milliseconds(20);
    const auto replayed = fz::replay(*client, oracle, {read(1, 3, 1), read(2, 4, 0), read(3, 3, 0)}, options);
    ASSERT_EQ(replayed.size(), 3u);
    for (const auto& step : replayed)
        EXPECT_TRUE(step.exchange.own_received().empty()) << "a reply within 300 ms from a 450 ms target";
    EXPECT_TRUE(replayed[1].exchange.stale_replies.empty());
    EXPECT_EQ(replayed[2].exchange.stale_replies.size(), 2u);
    ASSERT_EQ(replayed[0].violations.size(), 1u);
    EXPECT_EQ(replayed[0].violations[0].rule, "silence.protocol_id");
    EXPECT_EQ(replayed[0].violations[0].observed.rfind("during a later request: ", 0), 0u)
        << replayed[0].violations[0].observed;
    for (std::size_t i = 1; i < replayed.size(); ++i) {
        ASSERT_EQ(replayed[i].violations.size(), 1u) << i;
        EXPECT_EQ(replayed[i].violations[0].rule, "reply.missing") << replayed[i].violations[0].observed;
    }
    EXPECT_TRUE(client->drain(milliseconds(0)).empty());  // the third step's reply was waited for
}

// A late reply is judged as its request's whatever that request's own exchange met: a slow target's
// request given up has often set aside the late reply to the one before it, which is not part of this one
// (a whole frame matched to its request, or bytes found after the request was given up).
TEST(NetworkFuzzer, ALateReplyIsJudgedWithoutTheRepliesItsRequestSetAside) {
    const auto& p = mbscope::slave::test::profile("modbus");
    mbscope::conformance::ExchangeOracle oracle(mbscope::modbus::Framing::Tcp, {{1, &p}}, true);
    const std::vector<std::uint8_t> read{0x03, 0x00, 0x00, 0x00, 0x01};
    const std::vector<std::uint8_t> reply{0x03, 0x02, 0x00, 0x00};
    mbscope::modbus::transport::Exchange given_up;
    given_up.sent = mbscope::modbus::encode_tcp(6, 1, read);
    const auto earlier = mbscope::modbus::encode_tcp(5, 1, reply);  // the reply to request 5, set aside
    given_up.received = earlier;
    given_up.stale_replies.push_back(*mbscope::modbus::decode_tcp(earlier));
    given_up.timed_out = true;
    const auto late = *mbscope::modbus::decode_tcp(mbscope::modbus::encode_tcp(6, 1, reply));
    EXPECT_TRUE(fz::judge_late_frame(oracle, given_up, late, "later: ").empty());
    const std::vector<std::uint8_t> bytes(late.adu().begin(), late.adu().end());
    EXPECT_TRUE(fz::late_bytes(oracle, mbscope::modbus::Framing::Tcp, given_up, bytes).empty());
    // And a wrong one is judged wrong, as coming late.
    const auto wrong = *mbscope::modbus::decode_tcp(
        mbscope::modbus::encode_tcp(6, 1, std::vector<std::uint8_t>{0x04, 0x02, 0x00, 0x00}));
    const auto found = fz::judge_late_frame(oracle, given_up, wrong, "later: ");
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].rule, "reply.function");
    EXPECT_EQ(found[0].observed.rfind("later: ", 0), 0u) << found[0].observed;
}

// A target slower than --timeout: its replies come after their requests were given up. Over RTU and ASCII
// nothing but content and timing tells whose reply a frame is: a late one is set aside when it could
// answer an owed request and not the current one, waited out before a request that could draw the same
// reply, and judged as its own request's; the second try of a missing reply measures that request's own
// reply (not the first try's, which came during it). What is found is that the target is slow, and
// nothing else: no reply judged against another request's rules, no value taken from another reply for
// restoring.
struct SlowCase {
    std::string profile;
    std::string scheme;
};

class SlowTarget : public ::testing::TestWithParam<SlowCase> {};

TEST_P(SlowTarget, IsFoundSlowAndNoReplyIsJudgedAsAnotherRequests) {
    const auto& c = GetParam();
    RunningServer server({"slow-reply=450"}, 7, c.profile);
    auto o = options_for(c.scheme, server.start(c.scheme));
    o.timeout = milliseconds(300);  // the replies come 150 ms after it, the second try's within its 1.2 s
    o.slow = milliseconds(350);
    o.requests = 16;
    const auto s = fz::run_campaign(mbscope::slave::test::profile(c.profile), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_EQ(s.requests, *o.requests);
    ASSERT_FALSE(s.findings.empty()) << "the slow target was not found slow";
    for (const auto& f : s.findings)
        EXPECT_EQ(f.rule, "timing.slow_reply") << listing(s);
    // Each late reply is attributed to its request and counted: over Modbus/TCP by its transaction id,
    // over RTU and ASCII by what it answers. All were due: none is to a request the rules want unanswered.
    EXPECT_GT(s.replies_after_timeout, 0u);
    EXPECT_EQ(s.replies_after_timeout, s.late_replies);
    const auto j = fz::to_json(s);
    EXPECT_EQ(j["late_replies"].get<std::uint64_t>(), s.late_replies);
    EXPECT_EQ(j["replies_after_timeout"].get<std::uint64_t>(), s.replies_after_timeout);
    for (const auto& t : s.restored)
        EXPECT_TRUE(t.restored) << mbscope::modbus::to_string(t.table) << " " << t.address << ": "
                                << t.problem;
}

INSTANTIATE_TEST_SUITE_P(Slave, SlowTarget,
                         ::testing::Values(SlowCase{"cth2265i", "rtu-tcp"}, SlowCase{"mmk-2030", "ascii-tcp"},
                                           SlowCase{"cth2265i", "tcp"}),
                         profile_and_scheme);

// A device that reads the two words of a CTH2265I 32-bit value crosswise and writes them as given (what
// the slave's word-swap did before it swapped writes too): a register reads what was written to its
// partner. The reference slave serves every request; the reads are rewritten.
class CrosswiseReads {
  public:
    explicit CrosswiseReads(const std::string& profile_id)
        : profile_(mbscope::slave::test::profile(profile_id)),
          device_(profile_, 1),
          map_([this](mbscope::test::MapDevice&, const std::vector<std::uint8_t>& pdu) {
              return answer(pdu);
          }) {}
    std::uint16_t port() const { return map_.port(); }

  private:
    std::optional<mbscope::test::MapDevice::Reply> answer(const std::vector<std::uint8_t>& pdu) {
        auto reply = device_.handle({pdu, false}).pdu;
        if (reply.empty()) return mbscope::test::MapDevice::Reply{};  // silence
        if (pdu.size() != 5 || pdu[0] != 3 || reply[0] != 3) return reply;
        const auto start = static_cast<std::uint16_t>(pdu[1] << 8 | pdu[2]);
        for (std::size_t i = 0; 3 + 2 * i < reply.size(); ++i) {
            const auto* p = profile_.find(Table::HoldingRegisters, static_cast<std::uint16_t>(start + i));
            const bool paired = p && p->encoding.pair &&
                                (p->encoding.type == mbscope::modbus::EncodingType::U32Low ||
                                 p->encoding.type == mbscope::modbus::EncodingType::U32High);
            if (!paired) continue;
            const std::uint16_t v = device_.image().reg(Table::HoldingRegisters, *p->encoding.pair);
            reply[2 + 2 * i] = static_cast<std::uint8_t>(v >> 8);
            reply[3 + 2 * i] = static_cast<std::uint8_t>(v);
        }
        return reply;
    }

    const mbscope::modbus::Profile& profile_;
    sl::Device device_;
    mbscope::test::MapDevice map_;  // last: its thread answers through the members above
};

// A finding's reproducer breaks its rule again when replayed against the same device. Two did not: a slow
// reply was never judged by the replay (no limit to judge it by), and a lost write found on a read after a
// health check had cleared the trace was saved without the write. The device: the reference slave slowed
// down, or dropping every write it acknowledges.
// A device reading a value's words crosswise has its lost write replayed on a device started afresh, as a
// user replays a reproducer on another device: the read shows the partner register's value, so the
// reproducer must hold the write that set the partner too. The minimisation, on the campaign's device that
// still held that write, dropped it, and the saved reproducer broke nothing elsewhere.
TEST(NetworkFuzzer, ReproducersOfASlowReplyAndALostWriteReplayAsFound) {
    struct Case {
        std::string fault, profile, rule;
        std::uint64_t seed = 1, requests = 2000;
        bool crosswise_reads = false;  // CrosswiseReads, replayed on a new one; `fault` only names the case
    };
    for (const Case& c : {Case{"slow-reply=450", "cth2265i", "timing.slow_reply"},
                          Case{"drop-write", "mmk-2030", "state.lost_write"},
                          Case{"crosswise reads", "cth2265i", "state.lost_write", 3, 3000, true}}) {
        SCOPED_TRACE(c.fault);
        std::optional<RunningServer> server;
        std::optional<CrosswiseReads> crosswise;
        std::uint16_t port = 0;
        if (c.crosswise_reads) {
            port = crosswise.emplace(c.profile).port();
        } else {
            port = server.emplace(std::vector<std::string>{c.fault}, 7, c.profile).start("tcp");
        }
        auto o = options_for("tcp", port);
        o.timeout = milliseconds(1000);
        o.requests = c.requests;
        if (c.rule == "timing.slow_reply") {  // each slow exchange takes half a second: nothing to restore
            o.max_findings = 1;
            o.read_only = true;
        }
        o.seed = c.seed;
        const auto& profile = mbscope::slave::test::profile(c.profile);
        const auto s = fz::run_campaign(profile, o);
        ASSERT_TRUE(s.reachable) << s.error;
        std::optional<CrosswiseReads> fresh;
        auto endpoint = o.endpoint;
        if (c.crosswise_reads) {
            crosswise.reset();
            endpoint = options_for("tcp", fresh.emplace(c.profile).port()).endpoint;
        }
        std::size_t checked = 0;
        for (const auto& f : s.findings) {
            if (f.rule != c.rule) continue;
            ++checked;
            const auto& r = f.reproducer;
            if (c.rule == "timing.slow_reply") {
                EXPECT_GT(r.slow_ms, 0u) << "the limit is saved with the finding";
            }
            const auto loaded = fz::reproducer_from_json(fz::to_json(r));
            ASSERT_TRUE(loaded) << loaded.error();
            EXPECT_EQ(loaded->slow_ms, r.slow_ms);
            // A serial line's limit adds its longest frames to --slow's 600,000 ms: such a file loads too.
            auto j = fz::to_json(r);
            j["slow_ms"] = 600'586u;
            EXPECT_TRUE(fz::reproducer_from_json(j));
            auto client = mbscope::modbus::transport::Client::open(endpoint);
            ASSERT_TRUE(client);
            mbscope::conformance::ExchangeOracle oracle(mbscope::modbus::Framing::Tcp, {{1, &profile}}, true);
            fz::ReplayOptions options;
            options.timeout = o.timeout;
            options.slow = milliseconds(loaded->slow_ms);
            const auto replayed = fz::replay(*client, oracle, loaded->steps, options);
            EXPECT_TRUE(fz::breaks(replayed, c.rule))
                << f.expected << "; " << f.observed << " (" << loaded->steps.size() << " steps)";
        }
        EXPECT_GT(checked, 0u) << "no " << c.rule << " found:" << listing(s);
    }
}

// A replay over RTU keeps owed steps as the campaign does: the first step's reply, late, comes while the
// second waits and is set aside as the first's; the second's own reply, late too, is waited for after
// the last step, so that nothing is left to come during what follows.
TEST(NetworkFuzzer, AReplayOverRtuJudgesALateReplyAsItsOwnSteps) {
    RunningServer server({"slow-reply=450"}, 7, "cth2265i");
    auto o = options_for("rtu-tcp", server.start("rtu-tcp"));
    auto client = mbscope::modbus::transport::Client::open(o.endpoint);
    ASSERT_TRUE(client);
    const auto& profile = mbscope::slave::test::profile("cth2265i");
    mbscope::conformance::ExchangeOracle oracle(mbscope::modbus::Framing::Rtu, {{1, &profile}}, false);
    const auto read = [&](std::uint8_t fc) {
        fz::Step step;
        step.parts.push_back(
            client->frame(1, std::vector<std::uint8_t>{fc, 0x0F, 0x9F, 0x00, 0x01}));  // 3999
        return step;
    };
    fz::ReplayOptions options;
    options.timeout = milliseconds(300);
    options.silence_wait = milliseconds(20);
    const auto replayed = fz::replay(*client, oracle, {read(3), read(4)}, options);
    ASSERT_EQ(replayed.size(), 2u);
    EXPECT_EQ(replayed[1].exchange.stale_replies.size(), 1u);
    EXPECT_TRUE(replayed[1].exchange.own_received().empty());
    for (const auto& step : replayed)
        for (const auto& v : step.violations)
            EXPECT_EQ(v.rule, "reply.missing") << v.observed;  // missing in time, and nothing else
    EXPECT_TRUE(client->drain(milliseconds(0)).empty());       // the second step's reply was waited for

    // Two steps of the same shape: the first's late reply could answer the second too, so it is waited out
    // before the second is sent, and the second is not taken to be answered by it.
    const auto same = fz::replay(*client, oracle, {read(3), read(3)}, options);
    ASSERT_EQ(same.size(), 2u);
    for (const auto& step : same) {
        EXPECT_TRUE(step.exchange.stale_replies.empty());
        EXPECT_TRUE(step.exchange.own_received().empty()) << "a reply within 300 ms from a 450 ms target";
        ASSERT_EQ(step.violations.size(), 1u);
        EXPECT_EQ(step.violations[0].rule, "reply.missing") << step.violations[0].observed;
    }
    EXPECT_TRUE(client->drain(milliseconds(0)).empty());
}

TEST(NetworkFuzzer, UnreachableTargetIsReportedNotFuzzed) {
    fz::CampaignOptions o = options_for("tcp", 1);  // nothing listens on port 1
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    EXPECT_FALSE(s.reachable);
    EXPECT_FALSE(s.error.empty());
    EXPECT_EQ(s.requests, 0u);
}

// A peer that answers every request with bytes that form no frame ("DE AD BE EF" three times) was never
// shown to be a Modbus slave: the first health check fails and nothing is fuzzed (exit 2), where before any
// byte passed it and the run went on to send nothing, every planned write skipped for points it could not
// read, and exited 0, "nothing found".
TEST(NetworkFuzzer, APeerWhoseBytesFormNoFrameIsNotFuzzed) {
    mbscope::test::GarbagePeer peer;
    auto o = options_for("tcp", peer.port());
    o.requests = 50;
    o.duration = std::chrono::seconds(5);
    const auto s = fz::run_campaign(mbscope::slave::test::profile("modbus"), o);
    EXPECT_FALSE(s.reachable);
    EXPECT_NE(s.error.find("health-check"), std::string::npos) << s.error;
    EXPECT_EQ(s.requests, 0u);
}

// A slave whose replies name neither the unit nor the function asked is still a Modbus slave over
// Modbus/TCP (its MBAP header delimits the frame): it is fuzzed and its faults found, not "cannot reach".
TEST(NetworkFuzzer, AFaultySlaveWhoseRepliesNameNothingAskedIsFuzzed) {
    RunningServer server({"wrong-unit", "wrong-function"}, 1, "modbus");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 30;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("modbus"), o);
    EXPECT_TRUE(s.reachable) << s.error;
    EXPECT_FALSE(s.findings.empty());
}

TEST(NetworkFuzzer, ReproducerIsSavedMinimisedAndReplaysTheSameRule) {
    const auto dir = std::filesystem::path(::testing::TempDir()) / "mbscope-netfuzz-artifacts";
    std::filesystem::remove_all(dir);
    RunningServer server({"no-echo"}, 7, "mmk-2030");
    const auto port = server.start("tcp");
    auto o = options_for("tcp", port);
    o.artifacts = dir.string();
    o.max_findings = 1;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_EQ(s.findings.size(), 1u) << listing(s);
    const auto& f = s.findings.front();
    EXPECT_EQ(f.rule, "reply.echo");
    ASSERT_FALSE(f.file.empty());
    const auto loaded = fz::load_reproducer(f.file);
    ASSERT_TRUE(loaded) << loaded.error();
    EXPECT_EQ(loaded->rule, "reply.echo");
    EXPECT_TRUE(loaded->minimised);
    // Sent once more on a new connection, as mbscope replay sends it: the missing echo is no accident of
    // the fuzzer's connection.
    EXPECT_EQ(loaded->replays_on_new_connection, std::optional<bool>(true));
    EXPECT_EQ(loaded->steps.size(), 1u);  // one request without its echo is the whole story

    auto client = mbscope::modbus::transport::Client::open(o.endpoint);
    ASSERT_TRUE(client);
    mbscope::conformance::ExchangeOracle oracle(mbscope::modbus::Framing::Tcp,
                                                {{1, &mbscope::slave::test::profile("mmk-2030")}}, true);
    const auto replayed = fz::replay(*client, oracle, loaded->steps, {});
    EXPECT_TRUE(fz::breaks(replayed, "reply.echo"));

    // A second run into the same directory keeps the first run's reproducer: its own takes the next name.
    const auto again = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_EQ(again.findings.size(), 1u) << listing(again);
    EXPECT_EQ(std::filesystem::path(again.findings.front().file).filename(),
              std::filesystem::path(f.file).stem().string() + "-2.json");
    EXPECT_TRUE(std::filesystem::exists(f.file));
    EXPECT_TRUE(fz::load_reproducer(again.findings.front().file));
}

TEST(NetworkFuzzer, DamagedReproducersAreRefusedWithTheReason) {
    const auto path = (std::filesystem::path(::testing::TempDir()) / "mbscope-bad-reproducer.json").string();
    const auto with = [&](const std::string& text) {
        std::ofstream(path) << text;
        auto r = fz::load_reproducer(path);
        return r ? std::string("loaded") : r.error();
    };
    EXPECT_NE(with("not json").find("not JSON"), std::string::npos);
    EXPECT_NE(with("{}").find("not an mbscope reproducer"), std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1})").find("steps"), std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["0G"]}]})").find("step 1"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":[7]}]})").find(path), std::string::npos);
    EXPECT_EQ(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"]}]})"), "loaded");
    // Numbers are whole and in range, or refused by name: a float would be cast (undefined behaviour for
    // 1e30 into an int; the reproducer fuzz target found it in "mbscope_reproducer"), a negative one wrapped.
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"unit":1e30,"steps":[{"parts":["01 03"]}]})").find("\"unit\""),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"unit":256,"steps":[{"parts":["01 03"]}]})").find("0..255"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"seed":-1,"steps":[{"parts":["01 03"]}]})").find("\"seed\""),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"original_steps":2.5,"steps":[{"parts":["01 03"]}]})")
                  .find("\"original_steps\""),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"],"pause_us":-5}]})").find("step 1"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"],"pause_ms":60001}]})")
                  .find("\"pause_ms\" is not a whole number in 0..60000"),
              std::string::npos);
    EXPECT_EQ(with(R"({"mbscope_reproducer":1,"seed":18446744073709551615,"steps":[{"parts":["01 03"]}]})"),
              "loaded");
    // Text `mbscope replay` prints is refused when it holds a control character (a file from elsewhere must
    // not drive the terminal), and a bad hex token is quoted escaped.
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"rule":"x\u001b[2J","steps":[{"parts":["01 03"]}]})")
                  .find("\"rule\" holds a control character"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"],"recipe":"\r"}]})")
                  .find("step 1: \"recipe\" holds a control character"),
              std::string::npos);
    // A field of the wrong type is refused by name, not with the JSON library's message; a file with no
    // steps has nothing to replay.
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"rule":5,"steps":[{"parts":["01 03"]}]})")
                  .find("\"rule\" is not a string"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"minimised":"yes","steps":[{"parts":["01 03"]}]})")
                  .find("\"minimised\" is not true or false"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"],"reconnect_after":1}]})")
                  .find("step 1: \"reconnect_after\" is not true or false"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[{"parts":["01 03"],"recipe":[]}]})")
                  .find("step 1: \"recipe\" is not a string"),
              std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[7]})").find("step 1: not an object"),
              std::string::npos);
    EXPECT_NE(
        with(R"({"mbscope_reproducer":1,"steps":[{"parts":[7]}]})").find("step 1: a part is not a string"),
        std::string::npos);
    EXPECT_NE(with(R"({"mbscope_reproducer":1,"steps":[]})").find("nothing to replay"), std::string::npos);
    const auto bad_token = with(R"({"mbscope_reproducer":1,"steps":[{"parts":["\u001b[31m"]}]})");
    EXPECT_NE(bad_token.find("'\\x1B[31m' is not a hex byte"), std::string::npos) << bad_token;
    // Sizes: a file from elsewhere is refused past what a reproducer may hold, by name, not parsed into
    // memory it has no use for (a million steps took half a gigabyte).
    const auto steps = [](std::size_t n, std::size_t parts) {
        std::string out = R"({"mbscope_reproducer":1,"steps":[)";
        for (std::size_t i = 0; i < n; ++i) {
            out += i ? R"(,{"parts":[)" : R"({"parts":[)";
            for (std::size_t k = 0; k < parts; ++k)
                out += k ? R"(,"01")" : R"("01")";
            out += "]}";
        }
        return out + "]}";
    };
    EXPECT_EQ(with(steps(fz::max_reproducer_steps, 1)), "loaded");
    EXPECT_NE(with(steps(fz::max_reproducer_steps + 1, 1)).find("10001 steps, more than the 10000"),
              std::string::npos);
    EXPECT_EQ(with(steps(1, fz::max_step_parts)), "loaded");
    EXPECT_NE(with(steps(2, fz::max_step_parts + 1)).find("step 1: 257 parts, more than the 256"),
              std::string::npos);
    const auto large = with(std::string(R"({"mbscope_reproducer":1,"recipe":")") +
                            std::string(fz::max_reproducer_size, 'x') + R"(","steps":[{"parts":["01"]}]})");
    EXPECT_NE(large.find(path), std::string::npos) << large.substr(0, 200);
    EXPECT_NE(large.find("larger than"), std::string::npos) << large.substr(0, 200);
}

// ---- the command

struct Run {
    int status = -1;
    std::string out;
};

// What a command started with popen printed, and its exit status.
Run finish(FILE* p) {
    Run r;
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p))
        r.out.append(buf, n);
    r.status = WEXITSTATUS(pclose(p));
    return r;
}

Run run(const std::string& arguments) {
    return finish(popen((std::string(MBSCOPE_BINARY) + " " + arguments + " 2>&1").c_str(), "r"));
}

TEST(FuzzCommand, ExitCodesSummaryAndReplay) {
    const auto dir = std::filesystem::path(::testing::TempDir()) / "mbscope-fuzz-command";
    std::filesystem::remove_all(dir);
    {
        RunningServer server({}, 7, "cth2265i");
        const auto port = server.start("tcp");
        const auto clean =
            run("fuzz --target tcp://127.0.0.1:" + std::to_string(port) +
                " --profile cth2265i --requests 300 --timeout 300 --silence-wait 20 --slow 400");
        EXPECT_EQ(clean.status, 0) << clean.out;
        EXPECT_NE(clean.out.find("\"requests\": 300"), std::string::npos) << clean.out;
        EXPECT_NE(clean.out.find("\"findings\": []"), std::string::npos) << clean.out;
    }
    RunningServer server({"wrong-function"}, 7, "cth2265i");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    const auto found =
        run("fuzz --target " + target +
            " --profile cth2265i --requests 300 --timeout 300 --silence-wait 20 --max-findings 1 "
            "--artifacts " +
            dir.string());
    EXPECT_EQ(found.status, 1) << found.out;
    EXPECT_NE(found.out.find("reply.function"), std::string::npos) << found.out;
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        files.push_back(e.path());
    ASSERT_EQ(files.size(), 1u);
    const auto replayed = run("replay --target " + target + " " + files.front().string());
    EXPECT_EQ(replayed.status, 1) << replayed.out;
    EXPECT_NE(replayed.out.find("reproduced: reply.function"), std::string::npos) << replayed.out;
    // Modbus/TCP frames sent to an RTU target drew nothing and "not reproduced", exit 0: refused instead.
    const auto other = run("replay --target rtu-tcp://127.0.0.1:1 " + files.front().string());
    EXPECT_EQ(other.status, 2) << other.out;
    EXPECT_NE(other.out.find("recorded with tcp framing and the target uses rtu"), std::string::npos)
        << other.out;

    const auto unreachable = run("fuzz --target tcp://127.0.0.1:1 --profile cth2265i --requests 10");
    EXPECT_EQ(unreachable.status, 2) << unreachable.out;
    EXPECT_NE(unreachable.out.find("cannot reach the target"), std::string::npos) << unreachable.out;
    EXPECT_EQ(run("fuzz --help").status, 0);
    EXPECT_EQ(run("replay --help").status, 0);
    EXPECT_EQ(run("replay " + (dir / "missing.json").string()).status, 2);
}

// A reproducer file of Modbus/TCP steps for unit 1 of the generic profile at `target`, each written whole.
std::filesystem::path save_adu_steps(const std::string& name, const std::string& target,
                                     const std::vector<std::vector<std::uint8_t>>& adus) {
    fz::Reproducer r;
    r.rule = "reply.function";
    r.source = "MB §6";
    r.target = target;
    r.profile = "modbus";
    r.framing = "tcp";
    for (const auto& adu : adus) {
        fz::Step s;
        s.parts.push_back(adu);
        r.steps.push_back(std::move(s));
    }
    const auto file = std::filesystem::path(::testing::TempDir()) / name;
    EXPECT_TRUE(fz::save_reproducer(r, file.string()));
    return file;
}

// The same with each PDU one step (transaction ids 1, 2, ...).
std::filesystem::path save_steps(const std::string& name, const std::string& target,
                                 const std::vector<std::vector<std::uint8_t>>& pdus) {
    std::vector<std::vector<std::uint8_t>> adus;
    for (const auto& pdu : pdus)
        adus.push_back(mbscope::modbus::encode_tcp(static_cast<std::uint16_t>(adus.size() + 1), 1, pdu));
    return save_adu_steps(name, target, adus);
}

// A replay sends what its steps write and, as `mbscope fuzz` and `mbscope check` do, puts back after them
// what those points held before; --no-restore leaves them as the steps left them.
TEST(FuzzCommand, ReplayRestoresWhatItsStepsWrote) {
    using mbscope::modbus::Table;
    RunningServer server({}, 7, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    auto& image = server.device().image();
    image.set_reg(Table::HoldingRegisters, 10, 0x1234);
    image.set_reg(Table::HoldingRegisters, 11, 0x5678);
    const auto file = save_steps("mbscope-replay-writes.json", target,
                                 {{0x10, 0x00, 0x0A, 0x00, 0x02, 0x04, 0xBE, 0xEF, 0xBE, 0xEF},  // FC16 10-11
                                  {0x05, 0x00, 0x03, 0xFF, 0x00},    // FC5 coil 3 on
                                  {0x03, 0x00, 0x0A, 0x00, 0x02}});  // FC3: writes nothing

    const auto replayed = run("replay --json " + file.string());
    EXPECT_EQ(replayed.status, 0) << replayed.out;  // the clean slave breaks no rule and all is put back
    const auto j = nlohmann::json::parse(replayed.out.substr(replayed.out.find('{')), nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << replayed.out;
    EXPECT_FALSE(j["reproduced"].get<bool>());
    EXPECT_FALSE(j["stopped"].get<bool>());
    ASSERT_EQ(j["restored"].size(), 3u) << replayed.out;
    for (const auto& t : j["restored"])
        EXPECT_TRUE(t["restored"].get<bool>()) << t.dump();
    EXPECT_TRUE(j["not_read"].empty());
    EXPECT_EQ(j["steps"][2]["received"].get<std::string>(),
              "00 03 00 00 00 07 01 03 04 BE EF BE EF")  // written, then read
        << j["steps"][2].dump();
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 10), 0x1234);
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 11), 0x5678);
    EXPECT_EQ(image.reg(Table::Coils, 3), 0);

    const auto kept = run("replay --no-restore " + file.string());
    EXPECT_EQ(kept.status, 0) << kept.out;
    EXPECT_EQ(kept.out.find("restored"), std::string::npos) << kept.out;
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 10), 0xBEEF);
    EXPECT_EQ(image.reg(Table::Coils, 3), 1);
}

// The JSON object in a command's output, between the first '{' and the last '}' (the command's messages on
// standard error follow it).
nlohmann::json json_in(const std::string& out) {
    const auto first = out.find('{');
    const auto last = out.rfind('}');
    if (first == std::string::npos || last == std::string::npos || last < first)
        return nlohmann::json::value_t::discarded;
    return nlohmann::json::parse(out.substr(first, last - first + 1), nullptr, false);
}

// libmodbus's own Modbus/TCP server (bench/libmodbus_server.c), a lax device: it sizes a request by its
// function code, and holds 10,000 registers (register i holds i) whatever a profile's map says.
class LaxServer {
  public:
    LaxServer()
        : port_file_(::testing::TempDir() + "mbscope-libmodbus-port.txt"),
          server_({MBSCOPE_LIBMODBUS_SERVER, "0"}, port_file_, "/dev/null") {
        if (!server_.spawned()) return;
        (void)mbscope::test::wait_for([&] {
            target_ = mbscope::test::slurp(port_file_);
            return target_.find('\n') != std::string::npos;
        });
        if (target_.find('\n') == std::string::npos) return;
        target_.resize(target_.find('\n'));
        started_ = true;
    }
    bool started() const { return started_; }
    const std::string& target() const { return target_; }
    // Holding register `address` as FC3 reads it, -1 when no read worked.
    int reg(std::uint16_t address) const {
        auto client =
            mbscope::modbus::transport::Client::open(*mbscope::modbus::transport::parse_endpoint(target_));
        EXPECT_TRUE(client.has_value());
        if (!client) return -1;
        const std::uint8_t pdu[] = {0x03, static_cast<std::uint8_t>(address >> 8),
                                    static_cast<std::uint8_t>(address), 0x00, 0x01};
        const auto ex = client.value().transact(1, pdu, std::chrono::milliseconds(1000));
        if (!ex.response || ex.response->pdu().size() != 4) return -1;
        return (ex.response->pdu()[2] << 8) | ex.response->pdu()[3];
    }

  private:
    std::string port_file_;
    mbscope::test::Child server_;
    std::string target_;
    bool started_ = false;
};

// The requests a replay restores after are read as a lax device reads them. libmodbus's server sizes a
// request by its function code and never reads the MBAP length (fuzz/README.md, "Differences from
// libmodbus"): a step whose length field says 0 still writes there, and a step may hold two requests. Both
// are put back, and with --no-restore the writes are shown to have landed.
TEST(FuzzCommand, AReplayRestoresWritesALaxServerExecutes) {
    LaxServer server;
    ASSERT_TRUE(server.started());
    const std::string target = server.target();
    const auto reg = [&](std::uint16_t address) { return server.reg(address); };
    // The server's register i holds i.
    ASSERT_EQ(reg(20), 20);
    ASSERT_EQ(reg(21), 21);
    ASSERT_EQ(reg(22), 22);

    // FC6 register 20 = 0xBEEF with MBAP length 0; FC6 registers 21 and 22 = 0xBEEF in one step.
    auto two = mbscope::modbus::encode_tcp(2, 1, std::vector<std::uint8_t>{0x06, 0x00, 0x15, 0xBE, 0xEF});
    const auto second =
        mbscope::modbus::encode_tcp(3, 1, std::vector<std::uint8_t>{0x06, 0x00, 0x16, 0xBE, 0xEF});
    two.insert(two.end(), second.begin(), second.end());
    const auto file =
        save_adu_steps("mbscope-replay-lax.json", target,
                       {{0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x01, 0x06, 0x00, 0x14, 0xBE, 0xEF}, two})
            .string();

    const auto replayed = run("replay --json --timeout 1000 " + file);
    const auto j = nlohmann::json::parse(replayed.out.substr(replayed.out.find('{')), nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << replayed.out;
    ASSERT_EQ(j["restored"].size(), 3u) << replayed.out;
    for (const auto& t : j["restored"])
        EXPECT_TRUE(t["restored"].get<bool>()) << t.dump();
    EXPECT_EQ(reg(20), 20);
    EXPECT_EQ(reg(21), 21);
    EXPECT_EQ(reg(22), 22);

    const auto kept = run("replay --no-restore --timeout 1000 " + file);
    EXPECT_EQ(reg(20), 0xBEEF) << kept.out;
    EXPECT_EQ(reg(21), 0xBEEF) << kept.out;
    EXPECT_EQ(reg(22), 0xBEEF) << kept.out;
}

// A write to a point outside the profile's map is not read first (there is nothing the map says to read);
// a lax device that acknowledges it changed the point all the same, and the replay lists it as not read,
// not restored (exit 1), where it changed it silently. A device that refuses it (the reference slave,
// exception 02) leaves nothing to list.
TEST(FuzzCommand, AReplayListsAWriteOutsideTheMapTheDeviceAcknowledged) {
    LaxServer server;
    ASSERT_TRUE(server.started());
    // FC6 register 5000 (outside mmk-2030's map) = 0xBEEF; FC6 register 2 (TAG character 1) = 'A'.
    const auto steps = std::vector<std::vector<std::uint8_t>>{{0x06, 0x13, 0x88, 0xBE, 0xEF},
                                                              {0x06, 0x00, 0x02, 0x00, 0x41}};
    const auto file = save_steps("mbscope-replay-outside-map.json", server.target(), steps).string();
    const auto lax = run("replay --json --profile mmk-2030 --timeout 1000 " + file);
    EXPECT_EQ(lax.status, 1) << lax.out;
    const auto j = json_in(lax.out);
    ASSERT_FALSE(j.is_discarded()) << lax.out;
    ASSERT_EQ(j["not_read"].size(), 1u) << lax.out;
    EXPECT_EQ(j["not_read"][0]["start"], 5000);
    EXPECT_EQ(j["not_read"][0]["count"], 1);
    ASSERT_EQ(j["restored"].size(), 1u) << lax.out;
    EXPECT_EQ(j["restored"][0]["address"], 2);
    EXPECT_TRUE(j["restored"][0]["restored"].get<bool>()) << lax.out;
    EXPECT_EQ(server.reg(2), 2);
    EXPECT_EQ(server.reg(5000), 0xBEEF);

    RunningServer reference({}, 1, "mmk-2030");
    const auto port = reference.start("tcp");
    const auto strict = run("replay --json --profile mmk-2030 --timeout 1000 --target tcp://127.0.0.1:" +
                            std::to_string(port) + " " + file);
    EXPECT_EQ(strict.status, 0) << strict.out;
    const auto k = json_in(strict.out);
    ASSERT_FALSE(k.is_discarded()) << strict.out;
    EXPECT_TRUE(k["not_read"].empty()) << strict.out;
}

// A broadcast step draws no reply, so nothing tells whether the device executed it. One to a point outside
// the profile's map (not read first) is read after the steps: a device that holds the point is listed as
// having it written by a step without a reply, with what it holds now (exit 1); before, it was in no list.
// A device that holds no such point (exception 02 to the read) leaves nothing to list; one that answers no
// read leaves it unknown, listed as such.
TEST(FuzzCommand, AReplayListsAPointABroadcastStepReachedThatTheDeviceHolds) {
    using mbscope::modbus::Table;
    RunningServer lax({}, 1, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(lax.start("tcp"));
    // FC6 register 5000 (outside mmk-2030's map) = 0xBEEF, to unit 0.
    const std::vector<std::uint8_t> write{0x06, 0x13, 0x88, 0xBE, 0xEF};
    const auto file =
        save_adu_steps("mbscope-replay-broadcast.json", target, {mbscope::modbus::encode_tcp(1, 0, write)})
            .string();
    const auto listed = run("replay --json --profile mmk-2030 --timeout 300 " + file);
    EXPECT_EQ(listed.status, 1) << listed.out;
    EXPECT_EQ(lax.device().image().reg(Table::HoldingRegisters, 5000), 0xBEEF);
    const auto j = json_in(listed.out);
    ASSERT_FALSE(j.is_discarded()) << listed.out;
    EXPECT_TRUE(j["not_read"].empty()) << listed.out;
    ASSERT_EQ(j["unanswered_writes"].size(), 1u) << listed.out;
    EXPECT_EQ(j["unanswered_writes"][0]["table"], "holding_registers");
    EXPECT_EQ(j["unanswered_writes"][0]["address"], 5000);
    EXPECT_EQ(j["unanswered_writes"][0]["value"], 0xBEEF);

    RunningServer strict({}, 1, "mmk-2030");
    const auto clean = run("replay --json --profile mmk-2030 --timeout 300 --target tcp://127.0.0.1:" +
                           std::to_string(strict.start("tcp")) + " " + file);
    EXPECT_EQ(clean.status, 0) << clean.out;
    const auto k = json_in(clean.out);
    ASSERT_FALSE(k.is_discarded()) << clean.out;
    EXPECT_TRUE(k["unanswered_writes"].empty()) << clean.out;

    // A device that answers nothing: the read after the step tells nothing, so the point is listed as
    // `unanswered_unread` (it may hold the step's value) and the replay exits 1; before, a read that drew no
    // answer was taken for a point the device does not hold, and the replay exited 0.
    RunningServer silent({"no-reply=1"}, 1, "modbus");
    const auto unknown = run("replay --json --profile mmk-2030 --timeout 200 --target tcp://127.0.0.1:" +
                             std::to_string(silent.start("tcp")) + " " + file);
    EXPECT_EQ(unknown.status, 1) << unknown.out;
    const auto u = json_in(unknown.out);
    ASSERT_FALSE(u.is_discarded()) << unknown.out;
    EXPECT_TRUE(u["unanswered_writes"].empty()) << unknown.out;
    ASSERT_EQ(u["unanswered_unread"].size(), 1u) << unknown.out;
    EXPECT_EQ(u["unanswered_unread"][0]["table"], "holding_registers");
    EXPECT_EQ(u["unanswered_unread"][0]["start"], 5000);
    EXPECT_EQ(u["unanswered_unread"][0]["count"], 1);
}

// What `mbscope replay` wrote back, by point: the JSON ledger's entries.
std::map<std::pair<std::string, int>, nlohmann::json> ledger_by_point(const nlohmann::json& j) {
    std::map<std::pair<std::string, int>, nlohmann::json> out;
    for (const auto& t : j["restored"])
        out[{t["table"].get<std::string>(), t["address"].get<int>()}] = t;
    return out;
}

// The tester's `repro_refused_write_pause.json` against a device whose register 50 counts by itself: a
// step's FC16 was refused (exception 03: nothing written), the device's counter moved meanwhile, and the
// restore wrote the value read before the steps back with FC6, undoing the device's own count, while the
// ledger said "restored": true, "device_changed": false. The replay now tells the session its steps, as
// `mbscope check`'s rules go through it: what a step changed goes back (an acknowledged FC6, the coils an
// FC15 changed); a point no step changed (its write refused, or of the value it held) is not written back
// nor listed, whatever the device did to it since; and one the device changed itself after a write it did
// not acknowledge (exception 04: perhaps executed) is left as the device set it and listed as its change.
TEST(FuzzCommand, AReplayPutsBackOnlyWhatItsStepsChanged) {
    using mbscope::test::MapDevice;
    MapDevice device(
        [](MapDevice& d, const std::vector<std::uint8_t>& pdu) -> std::optional<MapDevice::Reply> {
            // FC16 to 50-51 with byte count 3 for two registers: refused (exception 03) by the device's map.
            if (pdu.size() == 9 && pdu[0] == 0x10 && pdu[2] == 50 && pdu[5] == 3) {
                d.hr[50] = 0x0446;  // the device's counter, counting by itself
                return std::nullopt;
            }
            if (pdu == std::vector<std::uint8_t>{0x06, 0x00, 70, 0x00, 0x09}) {
                d.hr[70] = 4242;  // not executed, answered 04; the device's own value since
                return MapDevice::Reply{std::vector<std::uint8_t>{0x86, 0x04}};
            }
            if (!pdu.empty() && pdu[0] == 0x04) d.hr[80] = 7777;  // after a step wrote 80 the value it held
            return std::nullopt;
        });
    std::vector<std::uint8_t> coils{0x0F, 0x00, 0x00, 0x00, 100, 13};  // FC15 coils 0-99 on
    coils.insert(coils.end(), 12, 0xFF);
    coils.push_back(0x0F);
    const auto file =
        save_steps("mbscope-replay-own-changes.json", "tcp://127.0.0.1:" + std::to_string(device.port()),
                   {{0x10, 0x00, 50, 0x00, 0x02, 0x03, 0x00, 0x01, 0x00},
                    {0x06, 0x00, 60, 0x00, 0x05},
                    {0x06, 0x00, 70, 0x00, 0x09},
                    coils,
                    {0x06, 0x00, 80, 0x04, 0x38},  // 1080, the value it holds
                    {0x04, 0x00, 0x00, 0x00, 0x01}});
    const auto replayed = run("replay --json --timeout 1000 " + file.string());
    device.stop();
    EXPECT_EQ(replayed.status, 1) << replayed.out;  // register 70 is not put back
    EXPECT_EQ(device.hr[50], 0x0446) << "the device's own count was undone";
    EXPECT_EQ(device.hr[51], 1051);
    EXPECT_EQ(device.hr[60], 1060);
    EXPECT_EQ(device.hr[70], 4242) << "the device's own value was overwritten";
    EXPECT_EQ(device.hr[80], 7777) << "written back, though no step changed it";
    for (unsigned i = 0; i < MapDevice::points; ++i)
        EXPECT_EQ(device.co[i], i % 3 == 0) << "coil " << i;

    const auto j = json_in(replayed.out);
    ASSERT_FALSE(j.is_discarded()) << replayed.out;
    const auto ledger = ledger_by_point(j);
    for (const int address : {50, 51, 80})
        EXPECT_EQ(ledger.count({"holding_registers", address}), 0u) << address << ": no step changed it";
    ASSERT_EQ(ledger.count({"holding_registers", 60}), 1u) << replayed.out;
    const auto& acked = ledger.at({"holding_registers", 60});
    EXPECT_EQ(acked["written"], 5);
    EXPECT_EQ(acked["write_acknowledged"], true);
    EXPECT_EQ(acked["restored"], true);
    EXPECT_EQ(acked["device_changed"], false);
    ASSERT_EQ(ledger.count({"holding_registers", 70}), 1u) << replayed.out;
    const auto& own = ledger.at({"holding_registers", 70});
    EXPECT_EQ(own["written"], 9);
    EXPECT_EQ(own["write_acknowledged"], false);
    EXPECT_EQ(own["device_changed"], true);
    EXPECT_EQ(own["restored"], false);
    EXPECT_EQ(own["left"], 4242);
    EXPECT_EQ(own["left_from"], "read");
    std::size_t coils_listed = 0;
    for (const auto& [point, t] : ledger) {
        if (point.first != "coils") continue;
        ++coils_listed;
        EXPECT_NE(point.second % 3, 0) << "coil " << point.second << " held the value written";
        EXPECT_EQ(t["written"], 1) << t.dump();
        EXPECT_EQ(t["write_acknowledged"], true) << t.dump();
        EXPECT_EQ(t["restored"], true) << t.dump();
    }
    EXPECT_EQ(coils_listed, 66u);  // of 100, the 34 already on were not changed
}

// The tester's `repro_ack_write.json` (FC6 holding register 60 := 5, echoed) and an FC15 of 428 coils the
// device acknowledged: the ledger said "write_acknowledged": false, "written": null of each, the replay's
// writes unseen by the session. Each point a step changed is listed with the value written and the
// acknowledgement, and is back at its original in the reference slave's image.
TEST(FuzzCommand, AReplaysLedgerSaysWhatItsStepsWroteAndTheDeviceAcknowledged) {
    RunningServer server({}, 7, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    auto& image = server.device().image();
    image.set_reg(Table::HoldingRegisters, 60, 0x0431);
    // Coils 100-527: every other one on (0xAA a byte; the last 4 coils 0x0A).
    std::vector<std::uint8_t> coils{0x0F, 0x00, 100, 0x01, 0xAC, 54};
    coils.insert(coils.end(), 53, 0xAA);
    coils.push_back(0x0A);
    const auto file =
        save_steps("mbscope-replay-acknowledged.json", target, {{0x06, 0x00, 60, 0x00, 0x05}, coils});
    const auto replayed = run("replay --json --timeout 1000 " + file.string());
    EXPECT_EQ(replayed.status, 0) << replayed.out;
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 60), 0x0431);
    for (std::uint16_t a = 100; a < 528; ++a)
        EXPECT_FALSE(image.bit(Table::Coils, a)) << "coil " << a;

    const auto j = json_in(replayed.out);
    ASSERT_FALSE(j.is_discarded()) << replayed.out;
    const auto ledger = ledger_by_point(j);
    ASSERT_EQ(ledger.count({"holding_registers", 60}), 1u) << replayed.out;
    const auto& reg = ledger.at({"holding_registers", 60});
    EXPECT_EQ(reg["original"], 0x0431);
    EXPECT_EQ(reg["written"], 5);
    EXPECT_EQ(reg["write_acknowledged"], true);
    EXPECT_EQ(reg["restored"], true);
    EXPECT_EQ(reg["left"], 0x0431);
    std::size_t coils_listed = 0;
    for (const auto& [point, t] : ledger) {
        if (point.first != "coils") continue;
        ++coils_listed;
        EXPECT_EQ(point.second % 2, 1) << "coil " << point.second << " was written the value it held";
        EXPECT_EQ(t["written"], 1) << t.dump();
        EXPECT_EQ(t["write_acknowledged"], true) << t.dump();
        EXPECT_EQ(t["restored"], true) << t.dump();
    }
    EXPECT_EQ(coils_listed, 214u);
}

// A Modbus/TCP relay in front of port `upstream` (a device serving unit 1) that makes it a device ignoring
// the unit id, as many are: each request goes on for unit 1, and its reply comes back with the unit the
// request named. One client connection at a time, as many in turn as the client opens.
class IgnoresTheUnitId {
  public:
    explicit IgnoresTheUnitId(std::uint16_t upstream)
        : listener_(std::move(mbscope::modbus::transport::listen_tcp("127.0.0.1", 0).value())) {
        port_ = mbscope::modbus::transport::bound_port(listener_.get());
        thread_ = std::thread([this, upstream] {
            while (!stop_) {
                pollfd p{listener_.get(), POLLIN, 0};
                if (::poll(&p, 1, 50) != 1) continue;
                mbscope::modbus::transport::UniqueFd client(::accept(listener_.get(), nullptr, nullptr));
                auto device = mbscope::modbus::transport::connect_tcp("127.0.0.1", upstream,
                                                                      std::chrono::milliseconds(1000));
                if (client.get() >= 0 && device) relay(client.get(), device.value().get());
            }
        });
    }
    ~IgnoresTheUnitId() {
        stop_ = true;
        thread_.join();
    }
    std::uint16_t port() const { return port_; }

  private:
    // Whole MBAP frames off the front of `bytes`, each passed to `each` (which may change it) and sent to
    // `to`; a length field out of range passes the rest on as it is.
    template <typename Each>
    static void forward(std::vector<std::uint8_t>& bytes, int to, Each each) {
        while (bytes.size() >= 7) {
            const std::size_t length = (bytes[4] << 8) | bytes[5];
            const std::size_t size = length >= 2 && length <= 254 ? 6 + length : bytes.size();
            if (bytes.size() < size) break;
            std::vector<std::uint8_t> frame(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(size));
            bytes.erase(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(size));
            each(frame);
            (void)::send(to, frame.data(), frame.size(), MSG_NOSIGNAL);
        }
    }
    void relay(int client, int device) {
        std::vector<std::uint8_t> requests, replies;
        std::map<std::uint16_t, std::uint8_t> unit_of;  // by transaction id
        std::uint8_t buf[4096];
        while (!stop_) {
            pollfd p[2] = {{client, POLLIN, 0}, {device, POLLIN, 0}};
            if (::poll(p, 2, 20) <= 0) continue;
            for (int k = 0; k < 2; ++k) {
                if (!p[k].revents) continue;
                const ssize_t n = ::read(p[k].fd, buf, sizeof buf);
                if (n <= 0) return;
                (k == 0 ? requests : replies).insert((k == 0 ? requests : replies).end(), buf, buf + n);
            }
            forward(requests, device, [&](std::vector<std::uint8_t>& f) {
                unit_of[static_cast<std::uint16_t>((f[0] << 8) | f[1])] = f[6];
                f[6] = 1;
            });
            forward(replies, client, [&](std::vector<std::uint8_t>& f) {
                const auto it = unit_of.find(static_cast<std::uint16_t>((f[0] << 8) | f[1]));
                if (it != unit_of.end()) f[6] = it->second;
            });
        }
    }

    mbscope::modbus::transport::UniqueFd listener_;
    std::uint16_t port_ = 0;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

// The reference slave serving the generic map (registers the MMK's manual does not list) at `port`, fuzzed
// as an MMK-2030 over Modbus/TCP; the coils and holding registers outside the MMK's map it holds changed
// after the run, each expected among the points the summary lists.
Points changed_outside_the_mmk_map(std::uint16_t port, const sl::RegisterImage& image, std::uint64_t requests,
                                   fz::CampaignSummary& s,
                                   const std::function<void(fz::CampaignOptions&)>& adjust = {}) {
    auto o = options_for("tcp", port);
    o.requests = requests;
    o.minimise_budget = 0;
    if (adjust) adjust(o);
    const auto& mmk = mbscope::slave::test::profile("mmk-2030");
    s = fz::run_campaign(mmk, o);
    EXPECT_TRUE(s.reachable) << s.error;
    EXPECT_FALSE(s.target_lost) << listing(s);
    const Points listed = left_unrestored(s);
    Points outside;
    for (const auto& [t, changed] : image.changes()) {
        if (t != Table::Coils && t != Table::HoldingRegisters) continue;
        for (const auto& [address, now] : changed) {
            if (mmk.find(t, address)) continue;  // in the map: read first, restored
            outside.insert({t, address});
            EXPECT_TRUE(listed.count({t, address})) << mbscope::modbus::to_string(t) << " " << address
                                                    << " changed to " << now << " and not listed";
        }
    }
    return outside;
}

// Over Modbus/TCP a write to another unit is read first too (a device ignoring the unit id executes it), but
// its reply, which the rules do not want, is not waited for: it is matched to the write by transaction id
// when it comes. A device that executes it changed the points it reached that were not read first (outside
// the map), and they are listed as not read, as after a prompt acknowledgement; they were in neither list.
// The device: the reference slave serving the generic map, ignoring the unit id, fuzzed as an MMK-2030.
TEST(NetworkFuzzer, AWriteAcknowledgedAfterItsExchangeListsThePointsItReachedUnread) {
    RunningServer server({}, 1, "modbus");
    IgnoresTheUnitId relay(server.start("tcp"));
    fz::CampaignSummary s;
    const auto outside = changed_outside_the_mmk_map(relay.port(), server.device().image(), 1500, s);
    EXPECT_FALSE(outside.empty()) << "no write outside the map was executed";
}

// A broadcast draws no reply on a serial line, so nothing tells whether the device executed it (the reference
// slave takes unit 0 over Modbus/TCP as a broadcast too). One that reached points the fuzzer could not read
// first (outside the map) and that the device holds after all may have changed them: they are read when the
// run ends, and those that read normally are listed (`unanswered_writes`), not restored, with what they hold.
// Before, they were in no list. The same run against the MMK-2030 itself lists nothing, its exception 02
// saying it holds no such point.
TEST(NetworkFuzzer, ABroadcastThatReachedPointsUnreadListsThoseTheDeviceHolds) {
    RunningServer lax({}, 1, "modbus");
    const auto port = lax.start("tcp");
    const auto& image = lax.device().image();
    fz::CampaignSummary s;
    const auto outside = changed_outside_the_mmk_map(port, image, 6000, s);
    const auto& mmk = mbscope::slave::test::profile("mmk-2030");
    std::size_t unanswered_only = 0;
    for (const auto& u : s.unanswered_writes) {
        EXPECT_FALSE(mmk.find(u.table, u.address)) << "in the map, so read first";
        const std::uint16_t held = mbscope::modbus::is_bit_table(u.table)
                                       ? static_cast<std::uint16_t>(image.bit(u.table, u.address))
                                       : image.reg(u.table, u.address);
        EXPECT_EQ(u.value, held) << mbscope::modbus::to_string(u.table) << " " << u.address;
        unanswered_only += outside.count({u.table, u.address});
    }
    EXPECT_GT(unanswered_only, 0u) << "no write that drew no reply changed a point outside the map";

    RunningServer strict({}, 1, "mmk-2030");
    auto k = options_for("tcp", strict.start("tcp"));
    k.requests = 6000;
    k.minimise_budget = 0;
    const auto t = fz::run_campaign(mmk, k);
    ASSERT_TRUE(t.reachable) << t.error;
    EXPECT_TRUE(t.unanswered_writes.empty()) << listing(t);
}

// A second interrupt while the run stops ends the read-back of what writes without a reply reached (at a
// manual's polling interval it can take minutes): the points it did not reach are listed unread, none is
// left out, and the restore after it runs as it would have (the same seed without the interrupt restores the
// same points). The two runs are compared, so a reply a loaded machine delays past the timeout must not make
// a write unanswered in one of them only: the timeout is long (over Modbus/TCP silence is not waited for).
TEST(NetworkFuzzer, ASecondInterruptEndsTheReadBackButNotTheRestore) {
    const auto patient = [](fz::CampaignOptions& o) { o.timeout = std::chrono::seconds(5); };
    RunningServer plain({}, 1, "modbus");
    fz::CampaignSummary whole;
    (void)changed_outside_the_mmk_map(plain.start("tcp"), plain.device().image(), 6000, whole, patient);
    ASSERT_FALSE(whole.unanswered_writes.empty());
    EXPECT_FALSE(whole.read_back_interrupted);

    RunningServer lax({}, 1, "modbus");
    const std::atomic<bool> again{true};
    std::vector<std::string> notes;
    fz::CampaignSummary cut;
    const auto outside = changed_outside_the_mmk_map(
        lax.start("tcp"), lax.device().image(), 6000, cut, [&](fz::CampaignOptions& o) {
            patient(o);
            o.stop_again = &again;
            o.note = [&](const std::string& n) { notes.push_back(n); };
        });
    EXPECT_EQ(cut.requests_digest, whole.requests_digest) << "the same requests";
    EXPECT_FALSE(outside.empty());
    EXPECT_TRUE(cut.read_back_interrupted);
    EXPECT_TRUE(cut.unanswered_writes.empty()) << listing(cut);
    std::size_t unread = 0, read_before = 0;
    for (const auto& w : cut.unanswered_unread)
        unread += w.count;
    for (const auto& w : whole.unanswered_unread)
        read_before += w.count;
    EXPECT_GE(unread, whole.unanswered_writes.size() + read_before);
    ASSERT_EQ(notes.size(), 1u);
    EXPECT_NE(notes[0].find("that writes without a reply reached"), std::string::npos) << notes[0];
    ASSERT_FALSE(cut.restored.empty());
    EXPECT_EQ(mbscope::conformance::to_json(cut.restored), mbscope::conformance::to_json(whole.restored));
}

// At a polling interval the restore is announced too (at Walchem's 5 s, a minute for every 12 points).
TEST(NetworkFuzzer, TheRestoreAtAPollingIntervalIsAnnounced) {
    RunningServer server({}, 1, "mmk-2030");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 300;
    o.minimise_budget = 0;
    o.interval = std::chrono::milliseconds(1);
    std::vector<std::string> notes;
    o.note = [&](const std::string& n) { notes.push_back(n); };
    const auto s = fz::run_campaign(mbscope::slave::test::profile("mmk-2030"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_FALSE(s.restored.empty());
    ASSERT_FALSE(notes.empty());
    ASSERT_GT(s.restored.size(), 1u);
    EXPECT_EQ(notes.back(), "restoring the " + std::to_string(s.restored.size()) +
                                " points written, a request every 1 ms (the polling interval)");
}

// The originals of a write's points are read before it in blocks of consecutive points, each as long as the
// device's read allows: one read a point made one write of 60 registers to a Walchem W900, polled every 5 s
// as its manual asks, cost over four minutes before it was sent, and as long again to restore.
TEST(NetworkFuzzer, TheOriginalsOfAWriteAreReadInBlocksAsLongAsTheReadAllows) {
    for (const char* id : {"walchem-w900", "mmk-2030"}) {
        SCOPED_TRACE(id);
        RunningServer server({}, 1, id);
        const auto port = server.start("tcp");
        const auto& p = mbscope::slave::test::profile(id);
        const auto& first = p.table(Table::HoldingRegisters).front();
        const fz::WriteRange range{Table::HoldingRegisters, first.address, 60};
        const auto blocks = fz::read_blocks(p, range);
        std::size_t readable = 0, in_blocks = 0;
        for (std::uint32_t a = range.start; a < range.end(); ++a) {
            const auto* point = p.find(Table::HoldingRegisters, static_cast<std::uint16_t>(a));
            readable += point && point->access != mbscope::modbus::Access::Write;
        }
        for (const auto& b : blocks) {
            in_blocks += b.count;
            EXPECT_LE(b.count, p.functions.max_for(3));
            for (std::uint32_t a = b.start; a < b.end(); ++a)
                EXPECT_NE(p.find(Table::HoldingRegisters, static_cast<std::uint16_t>(a)), nullptr) << a;
        }
        EXPECT_EQ(in_blocks, readable);
        EXPECT_LT(blocks.size() * 4, readable) << "blocks, not points";

        auto client = mbscope::modbus::transport::Client::open(
            *mbscope::modbus::transport::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
        ASSERT_TRUE(client.has_value()) << client.error();
        mbscope::conformance::Session session(*client, {1, std::chrono::milliseconds(1000), {}}, &p);
        EXPECT_EQ(fz::reads_to_remember(session, p, range), blocks.size());
        ASSERT_TRUE(fz::remember_range(session, p, range));
        EXPECT_EQ(session.requests(), blocks.size());
        EXPECT_EQ(fz::reads_to_remember(session, p, range), 0u);
        EXPECT_EQ(session.touched().size(), readable);
        for (const auto& [where, t] : session.touched())
            EXPECT_EQ(t.original, server.device().image().reg(Table::HoldingRegisters, t.address))
                << t.address;
    }
}

// At a polling interval every request is paced, the reads before a write too: a write whose reads would
// run past --duration is not sent (`writes_past_deadline`), so that a run of a few seconds against a
// Walchem (5 s between requests) did not take minutes. The probes sent fit the duration's slots.
TEST(NetworkFuzzer, AtAPollingIntervalAWriteWhoseReadsWouldRunPastTheDurationIsNotSent) {
    RunningServer server({}, 1, "walchem-w900");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests.reset();
    o.duration = std::chrono::milliseconds(2000);
    o.interval = std::chrono::milliseconds(250);
    o.minimise_budget = 0;
    const auto s = fz::run_campaign(mbscope::slave::test::profile("walchem-w900"), o);
    ASSERT_TRUE(s.reachable) << s.error;
    EXPECT_TRUE(s.findings.empty()) << listing(s);
    EXPECT_GT(s.writes_past_deadline, 0u);
    EXPECT_GT(s.requests, 0u);
    EXPECT_LE(s.requests, 2000u / 250u + 1u);
    for (const auto& t : s.restored)
        EXPECT_TRUE(t.restored) << t.address << ": " << t.problem;
}

// At a manual's polling interval the single reads after a refusal are those that fit in about a minute.
TEST(NetworkFuzzer, TheSingleReadsAfterARefusalFitAMinuteOfThePollingInterval) {
    using std::chrono::milliseconds;
    EXPECT_EQ(fz::single_reads_within_a_minute(milliseconds(0)), 256u);
    EXPECT_EQ(fz::single_reads_within_a_minute(milliseconds(100)), 256u);
    EXPECT_EQ(fz::single_reads_within_a_minute(milliseconds(5000)), 12u);  // Walchem
    EXPECT_EQ(fz::single_reads_within_a_minute(milliseconds(120000)), 1u);
}

// The end of a run reads the points writes without a reply reached unread. A strict device refuses a read
// that takes in a point it does not hold (exception 02) and may hold the others of the range: a range
// refused as a whole is read again point by point. Here the MMK-2030's last holding register of a run and
// the one after it: the range is refused, the first point read alone; before, neither was read. Single reads
// are bounded: past the budget a refused range is listed as such.
TEST(NetworkFuzzer, ARangeTheDeviceRefusesAsAWholeIsReadPointByPoint) {
    RunningServer server({}, 1, "mmk-2030");
    const auto port = server.start("tcp");
    const auto& mmk = mbscope::slave::test::profile("mmk-2030");
    std::optional<std::uint16_t> last;
    for (std::uint32_t a = 0; a < 0xFFFF && !last; ++a)
        if (mmk.find(Table::HoldingRegisters, static_cast<std::uint16_t>(a)) &&
            !mmk.find(Table::HoldingRegisters, static_cast<std::uint16_t>(a + 1)))
            last = static_cast<std::uint16_t>(a);
    ASSERT_TRUE(last.has_value());
    auto client = mbscope::modbus::transport::Client::open(
        *mbscope::modbus::transport::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    ASSERT_TRUE(client.has_value()) << client.error();
    mbscope::conformance::Session session(*client, {1, std::chrono::milliseconds(1000), {}}, &mmk);
    const auto reading = fz::read_held(
        session,
        {{Table::HoldingRegisters, *last}, {Table::HoldingRegisters, static_cast<std::uint16_t>(*last + 1)}});
    ASSERT_EQ(reading.held.size(), 1u);
    EXPECT_EQ(reading.held[0].address, *last);
    EXPECT_EQ(reading.held[0].value, server.device().image().reg(Table::HoldingRegisters, *last));
    EXPECT_TRUE(reading.unread.empty());
    EXPECT_TRUE(reading.refused.empty());
    EXPECT_EQ(session.requests(), 3u) << "the range, then each of its points";

    // Point by point within a budget: a refused range longer than it is listed as refused, not read point by
    // point (coils the MMK-2030 does not have; a few broadcasts reach thousands).
    const std::uint16_t first = 40000;
    const auto beyond = static_cast<std::uint16_t>(fz::ReadHeldLimits{}.single_reads + 1);
    Points coils;
    for (std::uint16_t i = 0; i < beyond; ++i) {
        ASSERT_FALSE(mmk.find(Table::Coils, static_cast<std::uint16_t>(first + i)));
        coils.insert({Table::Coils, static_cast<std::uint16_t>(first + i)});
    }
    const auto refused = fz::read_held(session, coils);
    EXPECT_TRUE(refused.held.empty());
    EXPECT_TRUE(refused.unread.empty());
    ASSERT_EQ(refused.refused.size(), 1u);
    EXPECT_EQ(refused.refused[0].table, Table::Coils);
    EXPECT_EQ(refused.refused[0].start, first);
    EXPECT_EQ(refused.refused[0].count, beyond);
    EXPECT_EQ(session.requests(), 4u) << "the range only";

    // A smaller budget (a polling interval's): the last register and the one after it, refused as a range,
    // now past it.
    fz::ReadHeldLimits one;
    one.single_reads = 1;
    const auto past = fz::read_held(
        session,
        {{Table::HoldingRegisters, *last}, {Table::HoldingRegisters, static_cast<std::uint16_t>(*last + 1)}},
        one);
    EXPECT_TRUE(past.held.empty());
    ASSERT_EQ(past.refused.size(), 1u);
    EXPECT_EQ(past.refused[0].count, 2u);
    EXPECT_EQ(session.requests(), 5u) << "the range only";
}

// read_held of a coil and four ranges of holding registers (10-11, 20, 30, 40) of the generic map, from the
// reference slave planting `fault`, over TCP; with how many requests it sent.
const Points five_ranges{{Table::Coils, 7},
                         {Table::HoldingRegisters, 10},
                         {Table::HoldingRegisters, 11},
                         {Table::HoldingRegisters, 20},
                         {Table::HoldingRegisters, 30},
                         {Table::HoldingRegisters, 40}};
struct HeldFromSlave {
    fz::HeldReading reading;
    std::uint64_t requests = 0;
};
HeldFromSlave read_five_ranges(const std::string& fault, std::chrono::milliseconds timeout) {
    RunningServer server({fault}, 1, "modbus");
    const auto port = server.start("tcp");
    auto client = mbscope::modbus::transport::Client::open(
        *mbscope::modbus::transport::parse_endpoint("tcp://127.0.0.1:" + std::to_string(port)));
    if (!client) {
        ADD_FAILURE() << client.error();
        return {};
    }
    mbscope::conformance::Session session(*client, {1, timeout, {}},
                                          &mbscope::slave::test::profile("modbus"));
    auto reading = fz::read_held(session, five_ranges);
    return {std::move(reading), session.requests()};
}

// A read that draws no answer tells nothing about its points: they are listed as unread (whether the write
// changed them is unknown), not passed over as points the device does not hold. After three such reads in a
// row the device is taken to be gone, and the ranges left are listed without a request each waiting the
// timeout.
TEST(NetworkFuzzer, PointsNoReadAnsweredForAreListedUnread) {
    const auto [reading, requests] = read_five_ranges("no-reply=1", std::chrono::milliseconds(100));
    EXPECT_TRUE(reading.held.empty());
    Points unread;
    for (const auto& r : reading.unread)
        for (std::uint32_t a = r.start; a < r.end(); ++a)
            unread.insert({r.table, static_cast<std::uint16_t>(a)});
    EXPECT_EQ(unread, five_ranges);
    EXPECT_EQ(reading.unread.size(), 5u) << "ranges: coil 7, registers 10-11, 20, 30, 40";
    EXPECT_EQ(requests, fz::silent_reads_before_giving_up);
}

// A device that answers every read promptly but uselessly (here with another function code) is not gone:
// each range is read and listed unread, none passed over. Before, three such replies in a row counted as
// silence and the ranges after them were listed without being read.
TEST(NetworkFuzzer, AWrongButPromptReplyIsNoSignOfADeviceGone) {
    const auto [reading, requests] = read_five_ranges("wrong-function", std::chrono::milliseconds(500));
    EXPECT_TRUE(reading.held.empty());
    EXPECT_TRUE(reading.refused.empty());
    EXPECT_EQ(reading.unread.size(), 5u) << "ranges: coil 7, registers 10-11, 20, 30, 40";
    EXPECT_EQ(requests, 5u) << "every range read";
}

// A target lost mid-run is sent nothing more, so the points writes without a reply reached unread cannot be
// read at the end; they are listed as `unanswered_unread` (whether the device executed those writes is
// unknown), so that every point the run may have changed outside the map is in the summary. Before, they
// were in no list. The device: the reference slave serving the generic map, fuzzed as an MMK-2030, lost
// after 2,500 answers.
TEST(NetworkFuzzer, ALostTargetListsThePointsWritesWithoutAReplyReachedUnread) {
    RunningServer server({"crash-after=2500"}, 1, "modbus");
    auto o = options_for("tcp", server.start("tcp"));
    o.requests = 6000;
    o.minimise_budget = 0;
    const auto& mmk = mbscope::slave::test::profile("mmk-2030");
    const auto s = fz::run_campaign(mmk, o);
    ASSERT_TRUE(s.reachable) << s.error;
    ASSERT_TRUE(s.target_lost) << listing(s);
    EXPECT_TRUE(s.unanswered_writes.empty()) << "read after the target was lost";
    EXPECT_FALSE(s.unanswered_unread.empty()) << "no write without a reply reached a point outside the map";
    const Points listed = left_unrestored(s);
    for (const auto& [t, changed] : server.device().image().changes()) {
        if (t != Table::Coils && t != Table::HoldingRegisters) continue;
        for (const auto& [address, now] : changed) {
            if (mmk.find(t, address)) continue;  // in the map: read first
            EXPECT_TRUE(listed.count({t, address})) << mbscope::modbus::to_string(t) << " " << address
                                                    << " changed to " << now << " and not listed";
        }
    }
}

// `mbscope ARGUMENTS` started in the background, its process id known, what it prints collected.
class Background {
  public:
    Background(const std::string& arguments, const std::string& name)
        : pid_file_(std::filesystem::path(::testing::TempDir()) / (name + ".pid")) {
        std::filesystem::remove(pid_file_);
        pipe_ = popen(("{ " + std::string(MBSCOPE_BINARY) + " " + arguments + " & echo $! > " +
                       pid_file_.string() + "; wait $!; } 2>&1")
                          .c_str(),
                      "r");
    }
    ~Background() {
        if (pipe_) (void)test_fuzz_network_fuzzer_test::finish(std::exchange(pipe_, nullptr));
    }
    bool started() const { return pipe_ != nullptr; }
    pid_t pid() {
        if (pid_ <= 0)
            (void)mbscope::test::wait_for([&] {
                std::ifstream(pid_file_) >> pid_;
                return pid_ > 0;
            });
        return pid_;
    }
    void signal(int number) {
        if (pid() > 0) ::kill(pid_, number);
    }
    Run finish() { return test_fuzz_network_fuzzer_test::finish(std::exchange(pipe_, nullptr)); }

  private:
    std::filesystem::path pid_file_;
    FILE* pipe_ = nullptr;
    pid_t pid_ = 0;
};

// A replay whose first step writes holding register 20 = 0x7777, interrupted (SIGINT) `after` that write
// has landed; what it printed.
Run interrupt_after_the_write(const std::string& file, const std::string& name,
                              mbscope::slave::RegisterImage& image, std::chrono::milliseconds after) {
    using mbscope::modbus::Table;
    Background replay("replay " + file, name);
    EXPECT_TRUE(replay.started());
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (image.reg(Table::HoldingRegisters, 20) != 0x7777 && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::this_thread::sleep_for(after);
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 20), 0x7777) << "the write step did not land";
    replay.signal(SIGINT);
    return replay.finish();
}

// An interrupt stops a replay's steps, not the restore after them: a replay stopped half-way leaves the
// device as it was too, and says where it stopped.
TEST(FuzzCommand, AnInterruptedReplayStillRestores) {
    using mbscope::modbus::Table;
    RunningServer server({"slow-reply=250"}, 7, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    auto& image = server.device().image();
    image.set_reg(Table::HoldingRegisters, 20, 0x0042);
    std::vector<std::vector<std::uint8_t>> pdus{{0x06, 0x00, 0x14, 0x77, 0x77}};
    pdus.resize(39, {0x03, 0x00, 0x14, 0x00, 0x01});  // then ten seconds of reads at 250 ms each
    const auto file = save_steps("mbscope-replay-interrupted.json", target, pdus);
    // SIGINT once the write has landed: the steps are under way.
    const auto stopped = interrupt_after_the_write(file.string(), "mbscope-replay-interrupted", image,
                                                   std::chrono::milliseconds(0));
    // Steps left unsent cannot show the rule kept: not the 0 of a replay that did not reproduce.
    EXPECT_EQ(stopped.status, 2) << stopped.out;
    EXPECT_NE(stopped.out.find("not reproduced in the steps sent before the interrupt"), std::string::npos)
        << stopped.out;
    EXPECT_NE(stopped.out.find("stopped after step "), std::string::npos) << stopped.out;
    EXPECT_NE(stopped.out.find(" of 39 (interrupted)"), std::string::npos) << stopped.out;
    EXPECT_NE(stopped.out.find("restored 1 of 1 points"), std::string::npos) << stopped.out;
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 20), 0x0042);
}

// A pause inside a step (up to a minute, as many as the step has pieces) is cut short by an interrupt: the
// rest of the step is not sent, and what the steps wrote goes back. Over Modbus/TCP the piece sent would run
// into the restore's first request: the connection is opened again first.
TEST(FuzzCommand, AnInterruptCutsAPauseInsideAStep) {
    using mbscope::modbus::Table;
    RunningServer server({}, 7, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    auto& image = server.device().image();
    image.set_reg(Table::HoldingRegisters, 20, 0x0042);
    fz::Reproducer r;
    r.rule = "reply.function";
    r.target = target;
    r.profile = "modbus";
    r.framing = "tcp";
    fz::Step write;
    write.parts.push_back(
        mbscope::modbus::encode_tcp(1, 1, std::vector<std::uint8_t>{0x06, 0x00, 0x14, 0x77, 0x77}));
    r.steps.push_back(write);
    fz::Step paused;  // a read in three pieces, a minute apart
    const auto read =
        mbscope::modbus::encode_tcp(2, 1, std::vector<std::uint8_t>{0x03, 0x00, 0x14, 0x00, 0x01});
    paused.parts = {{read.begin(), read.begin() + 4},
                    {read.begin() + 4, read.begin() + 8},
                    {read.begin() + 8, read.end()}};
    paused.pause = std::chrono::seconds(60);
    r.steps.push_back(paused);
    const auto file = (std::filesystem::path(::testing::TempDir()) / "mbscope-replay-paused.json").string();
    ASSERT_TRUE(fz::save_reproducer(r, file));
    // Into the pause after the first piece.
    const auto stopped =
        interrupt_after_the_write(file, "mbscope-replay-paused", image, std::chrono::milliseconds(100));
    EXPECT_EQ(stopped.status, 2) << stopped.out;
    EXPECT_NE(stopped.out.find("stopped after step 1 of 2 (interrupted)"), std::string::npos) << stopped.out;
    EXPECT_NE(stopped.out.find("restored 1 of 1 points"), std::string::npos) << stopped.out;
    EXPECT_EQ(image.reg(Table::HoldingRegisters, 20), 0x0042);
}

// A campaign interrupted before it found anything did not complete its budget: exit 2, and it says so.
// Before, it exited 0 as a clean run does, and a CI job stopped by its timeout (SIGTERM) passed.
TEST(FuzzCommand, AnInterruptedCampaignWithoutFindingsIsNotAPass) {
    RunningServer server({}, 7, "modbus");
    const auto target = "tcp://127.0.0.1:" + std::to_string(server.start("tcp"));
    auto& image = server.device().image();
    Background fuzz("fuzz --target " + target + " --duration 60s --seed 1 --no-progress",
                    "mbscope-fuzz-interrupted");
    ASSERT_TRUE(fuzz.started());
    // Under way: a write has landed (the handler for the signal is installed before the first request).
    EXPECT_TRUE(mbscope::test::wait_for([&] { return image.modifications() > 0; }));
    fuzz.signal(SIGINT);
    const auto ended = fuzz.finish();
    EXPECT_EQ(ended.status, 2) << ended.out;
    EXPECT_NE(ended.out.find("interrupted after "), std::string::npos) << ended.out;
    EXPECT_NE(ended.out.find("\"stopped\": true"), std::string::npos) << ended.out;
    EXPECT_EQ(ended.out.find("finding "), std::string::npos) << ended.out;
}

// Until the target is open an interrupt or SIGTERM ends `mbscope replay` as any command: reading a FIFO no
// one writes to, it waited for ever and ignored both. (SIGTERM here: a command started in the background by
// a shell ignores SIGINT until it installs its own handler.)
TEST(FuzzCommand, AnInterruptEndsAReplayWaitingForItsFile) {
    const auto fifo = std::filesystem::path(::testing::TempDir()) / "mbscope-replay-fifo";
    std::filesystem::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    Background replay("replay " + fifo.string(), "mbscope-replay-fifo");
    ASSERT_TRUE(replay.started());
    const pid_t pid = replay.pid();
    ASSERT_GT(pid, 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // into the open() of the FIFO
    replay.signal(SIGTERM);
    // Should it not end, a writer gives it an empty document, and it ends refusing that (exit 2).
    if (!mbscope::test::wait_for([&] { return ::kill(pid, 0) != 0; })) std::ofstream(fifo) << "{}";
    const auto ended = replay.finish();
    EXPECT_EQ(ended.status, 128 + SIGTERM) << ended.out;
    std::filesystem::remove(fifo);
}

// What a request may write is read from its header, whatever follows it: the range a device that executes
// a malformed write would write, bounded by the function's limit.
TEST(WrittenPoints, TheRangeARequestMayWriteComesFromItsHeader) {
    using mbscope::modbus::Table;
    const auto range = [](std::vector<std::uint8_t> pdu) { return fz::write_range(pdu); };
    const auto fc23 = range({0x17, 0x00, 0x01, 0x00, 0x02, 0x00, 0x20, 0x00, 0x03, 0x06});  // no values
    ASSERT_TRUE(fc23);
    EXPECT_EQ(fc23->table, Table::HoldingRegisters);
    EXPECT_EQ(fc23->start, 0x20);  // the write part, not the read part
    EXPECT_EQ(fc23->count, 3);
    const auto fc15 = range({0x0F, 0x00, 0x05, 0x13, 0x88});  // 5,000 coils: more than one request may write
    ASSERT_TRUE(fc15);
    EXPECT_EQ(fc15->table, Table::Coils);
    EXPECT_EQ(fc15->count, mbscope::modbus::max_write_bits);
    const auto fc22 = range({0x16, 0x00, 0x07});
    ASSERT_TRUE(fc22);
    EXPECT_EQ(fc22->start, 7);
    EXPECT_EQ(fc22->count, 1);
    EXPECT_FALSE(range({0x03, 0x00, 0x00, 0x00, 0x01}));
    EXPECT_FALSE(range({0x06, 0x00}));
}

// A write keeps the value of the registers the campaign protects (the line-setting mirrors): the rest of
// the request, and every other register it writes, are sent as made.
TEST(WrittenPoints, AWriteCanBeMadeToKeepChosenRegisters) {
    const auto keep = [](std::vector<std::uint8_t> pdu) {
        fz::keep_registers(pdu, [](std::uint16_t address) -> std::optional<std::uint16_t> {
            if (address == 0x28) return 0x0011;
            return std::nullopt;
        });
        return mbscope::modbus::hex_bytes(pdu);
    };
    EXPECT_EQ(keep({0x06, 0x00, 0x28, 0x00, 0x05}), "06 00 28 00 11");
    EXPECT_EQ(keep({0x06, 0x00, 0x29, 0x00, 0x05}), "06 00 29 00 05");
    EXPECT_EQ(keep({0x10, 0x00, 0x27, 0x00, 0x03, 0x06, 0xAA, 0xAA, 0xBB, 0xBB, 0xCC, 0xCC}),
              "10 00 27 00 03 06 AA AA 00 11 CC CC");
    EXPECT_EQ(keep({0x10, 0x00, 0x27, 0x00, 0x03, 0x06, 0xAA, 0xAA, 0xBB}),  // too short to carry it
              "10 00 27 00 03 06 AA AA BB");
    EXPECT_EQ(keep({0x16, 0x00, 0x28, 0x00, 0xF0, 0x12, 0x34}), "16 00 28 FF FF 00 00");
    EXPECT_EQ(keep({0x17, 0x00, 0x28, 0x00, 0x01, 0x00, 0x28, 0x00, 0x01, 0x02, 0x12, 0x34}),
              "17 00 28 00 01 00 28 00 01 02 00 11");
    EXPECT_EQ(keep({0x05, 0x00, 0x28, 0xFF, 0x00}), "05 00 28 FF 00");  // a coil is not a register
}

}  // namespace

}  // namespace test_fuzz_network_fuzzer_test
