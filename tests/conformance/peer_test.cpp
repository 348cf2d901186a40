// The conformance runner against Modbus servers nobody here wrote, with the generic profile (the
// specification's rules only): libmodbus's own server (tests/peers/libmodbus_server.c, built from Debian's
// libmodbus) and pymodbus's (tests/peers/pymodbus_server.py, Debian's python3-pymodbus). Each passes what
// it implements and fails exactly where it departs from the specification; those departures are listed
// here and in conformance/README.md, each checked against the bytes the server sent.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "conformance/runner.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/client.hpp"
#include "tests/support/process_support.hpp"

namespace mbscope::conformance::test_conformance_peer_test {
namespace {

namespace tp = modbus::transport;

// A free loopback port (bound, read and released: the peer binds it next).
std::uint16_t free_port() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    ::close(fd);
    return ntohs(a.sin_port);
}

// A peer server process, stopped when the object goes away.
class Peer : public mbscope::test::Child {
  public:
    explicit Peer(std::vector<std::string> argv) : Child(std::move(argv), "/dev/null", "/dev/null") {}
};

// Connects once the peer listens (a Python interpreter takes a moment to start).
std::optional<tp::Client> connect(const std::string& uri) {
    auto endpoint = tp::parse_endpoint(uri);
    if (!endpoint) return std::nullopt;
    for (int i = 0; i < 100; ++i) {
        auto c = tp::Client::open(*endpoint);
        if (c) return std::move(c).value();
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return std::nullopt;
}

// pymodbus's server (tests/peers/pymodbus_server.py SCHEME PORT [OPTIONS], the options separated by spaces)
// on a free loopback port, and a client connected to it once it listens; `client` is empty when it did not
// start.
struct PymodbusPeer {
    explicit PymodbusPeer(const std::string& scheme, const std::string& option = "")
        : port(free_port()),
          peer([&] {
              std::vector<std::string> argv{
                  "/usr/bin/python3", std::string(MBSCOPE_SOURCE_DIR) + "/tests/peers/pymodbus_server.py",
                  scheme, std::to_string(port)};
              std::istringstream words(option);
              for (std::string w; words >> w;)
                  argv.push_back(w);
              return argv;
          }()),
          client(peer.spawned() ? connect(scheme + "://127.0.0.1:" + std::to_string(port)) : std::nullopt) {}
    std::uint16_t port;
    Peer peer;
    std::optional<tp::Client> client;
};

const modbus::Profile& generic() {
    static const modbus::Profile p = [] {
        modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
        return store.load("modbus").value();
    }();
    return p;
}

std::set<std::string> failing(const Report& r) {
    std::set<std::string> out;
    for (const auto& x : r.results)
        if (x.outcome == Outcome::Fail || x.outcome == Outcome::Error) out.insert(x.rule.id);
    return out;
}

std::string listed(const std::set<std::string>& s) {
    std::string out;
    for (const auto& x : s)
        out += " " + x;
    return out;
}

Report certify(tp::Client& client, std::vector<std::string> globs) {
    CheckOptions o;
    o.session.timeout = std::chrono::milliseconds(1000);
    o.run.rule_globs = std::move(globs);
    return run_check(client, generic(), o);
}

// A server nobody here wrote, judged as an MK Controle MMK-2030 (read-only rules on quantities and the
// holding register map): such a server serves whatever its datastore holds, so the manual's limits (15
// registers, 30 coils per request) and its map's end are not there. Returns the report for more checks.
Report expect_mk2030_departures(tp::Client& client) {
    modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto mk = store.load("mmk-2030");
    EXPECT_TRUE(mk.has_value());
    if (!mk) return {};
    CheckOptions o;
    o.session.timeout = std::chrono::milliseconds(1000);
    o.run.read_only = true;
    o.run.rule_globs = {"quantity.fc3.*", "quantity.fc1.*", "address.fc3.*"};
    const auto report = run_check(client, *mk, o);
    const auto failed = failing(report);
    // 16 registers (the manual allows 15) and 31 coils (it allows 30) are answered, where the manual
    // implies exception 03 ...
    EXPECT_TRUE(failed.count("quantity.fc3.max_plus_one")) << listed(failed);
    EXPECT_TRUE(failed.count("quantity.fc1.max_plus_one")) << listed(failed);
    // ... the map's end is not an end ...
    EXPECT_TRUE(failed.count("address.fc3.past_end")) << listed(failed);
    // ... while what the manual allows is answered.
    for (const auto& x : report.results)
        if (x.rule.id == "quantity.fc3.max" || x.rule.id == "quantity.fc3.one" ||
            x.rule.id == "address.fc3.first") {
            EXPECT_EQ(x.outcome, Outcome::Pass) << x.rule.id << ": " << x.observed;
        }
    return report;
}

TEST(Peer, LibmodbusServerFailsExactlyWhereItDepartsFromTheSpecification) {
    const auto port = free_port();
    Peer peer({MBSCOPE_LIBMODBUS_SERVER, std::to_string(port)});
    ASSERT_TRUE(peer.spawned());
    auto client = connect("tcp://127.0.0.1:" + std::to_string(port));
    ASSERT_TRUE(client.has_value());
    // libmodbus sleeps its response timeout (500 ms) before every exception and then flushes what the
    // client sent meanwhile: the unsupported-function sweep alone would take a minute, so it is left out.
    const auto report = certify(*client, {"fc.supported.*", "quantity.*", "address.*", "value.*", "echo.*",
                                          "tcp.*", "precedence.*", "broadcast.*"});
    const std::set<std::string> departures = {
        "value.fc15.byte_count",    // FC15 byte count 2 for 1 coil is executed, not refused with 03
        "tcp.protocol_id_nonzero",  // MBAP protocol id 1 is answered as if it were 0
        "tcp.length_too_large",     // the MBAP length field is not checked against the PDU
        "tcp.length_too_small",
    };
    EXPECT_EQ(failing(report), departures) << "failing:" << listed(failing(report));
    // FC8 is not implemented (exception 01, as AP §7 allows of a device the generic profile knows nothing
    // of): the echo rule has nothing to judge. It used to fail.
    for (const auto& x : report.results)
        if (x.rule.id == "echo.fc8.0") {
            EXPECT_EQ(x.outcome, Outcome::Skip) << x.observed;
        }
    EXPECT_TRUE(report.all_restored());
    EXPECT_GT(report.count(Outcome::Pass), 50u);
}

// A function the profile says the device lacks, executed anyway: libmodbus implements FC23 (read/write
// multiple registers), which the MMK-2030 does not, and the rule's request writes 0 at register 0. Under
// --read-only the rule was run all the same (it changed the register), and without it the write was never
// restored while the report said every point was.
TEST(Peer, AnUnsupportedWriteTheDeviceExecutesIsRestoredAndNotSentUnderReadOnly) {
    const auto port = free_port();
    Peer peer({MBSCOPE_LIBMODBUS_SERVER, std::to_string(port)});
    ASSERT_TRUE(peer.spawned());
    auto client = connect("tcp://127.0.0.1:" + std::to_string(port));
    ASSERT_TRUE(client.has_value());
    modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto mk = store.load("mmk-2030");
    ASSERT_TRUE(mk.has_value());
    ASSERT_FALSE(mk->functions.supports(23));
    const auto register_0 = [&client] {
        const std::vector<std::uint8_t> read = {0x03, 0x00, 0x00, 0x00, 0x01};
        const auto ex = client->transact(1, read, std::chrono::milliseconds(1000));
        if (!ex.response || ex.response->pdu().size() != 4) return -1;
        return (ex.response->pdu()[2] << 8) | ex.response->pdu()[3];
    };
    const std::vector<std::uint8_t> set = {0x06, 0x00, 0x00, 0x12, 0x34};
    ASSERT_TRUE(client->transact(1, set, std::chrono::milliseconds(1000)).response);
    ASSERT_EQ(register_0(), 0x1234);

    CheckOptions o;
    o.session.timeout = std::chrono::milliseconds(1000);
    o.run.rule_globs = {"fc.unsupported.23"};
    o.run.read_only = true;
    auto report = run_check(*client, *mk, o);
    ASSERT_EQ(report.results.size(), 1u);
    EXPECT_EQ(report.results[0].outcome, Outcome::Skip) << report.results[0].observed;
    EXPECT_EQ(register_0(), 0x1234);  // nothing sent

    o.run.read_only = false;
    report = run_check(*client, *mk, o);
    ASSERT_EQ(report.results.size(), 1u);
    EXPECT_EQ(report.results[0].outcome, Outcome::Fail);  // executed: a normal FC23 reply, not exception 01
    EXPECT_TRUE(report.all_restored());
    ASSERT_EQ(report.restored.size(), 1u);
    EXPECT_EQ(report.restored[0].address, 0);
    EXPECT_EQ(report.restored[0].original, 0x1234);
    EXPECT_EQ(report.restored[0].problem, "") << "it said: read-only in the map, not written back";
    EXPECT_EQ(register_0(), 0x1234);  // written back (read-only in the map, but the device took the write)
}

// The same libmodbus server judged as an MK Controle MMK-2030: libmodbus serves whatever its mapping
// holds, so the manual's limits (15 registers, 30 coils per request) and its map's holes are not there.
TEST(Peer, LibmodbusServerAsAnMk2030BreaksTheManualsLimits) {
    const auto port = free_port();
    Peer peer({MBSCOPE_LIBMODBUS_SERVER, std::to_string(port)});
    ASSERT_TRUE(peer.spawned());
    auto client = connect("tcp://127.0.0.1:" + std::to_string(port));
    ASSERT_TRUE(client.has_value());
    const auto report = expect_mk2030_departures(*client);
    // The evidence shows the 16 registers coming back.
    for (const auto& x : report.results)
        if (x.rule.id == "quantity.fc3.max_plus_one") {
            ASSERT_FALSE(x.evidence.empty());
            EXPECT_EQ(x.evidence.back().received.size(), 9u + 2 * 16)
                << "MBAP 7 + FC + count + 32 data bytes";
        }
}

TEST(Peer, PymodbusServerFailsExactlyWhereItDepartsFromTheSpecification) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("tcp");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    auto& client = server.client;
    const auto report = certify(*client, {});
    const std::set<std::string> departures = {
        "value.fc5.invalid",        // FC5 value 0x1234 is accepted (and writes 0) instead of exception 03
        "echo.fc8.0",               // FC8/00 with four data bytes closes the connection
        "tcp.protocol_id_nonzero",  // MBAP protocol id 1 is answered
        "tcp.split_segments",       // a request split after 5 bytes closes the connection
    };
    EXPECT_EQ(failing(report), departures) << "failing:" << listed(failing(report));
    EXPECT_GT(report.count(Outcome::Pass), 150u);
}

// The same server with no holding register at the start of its map: the framing, Modbus/TCP and robustness
// rules send a read of one valid point, which was a holding register or nothing, and without one the whole
// Modbus/TCP family and two robustness rules were left out of the report, unsaid (with them pymodbus's
// departures). The read is now of the first table the device has a point in; every such rule is run.
TEST(Peer, PymodbusServerWithoutHoldingRegistersAtZeroStillGetsEveryTcpRule) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("tcp", "--holding-registers-at-50000");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    auto& client = server.client;
    const auto report = certify(*client, {"tcp.*", "robustness.*"});
    std::set<std::string> run;
    for (const auto& x : report.results)
        if (x.outcome != Outcome::Skip) run.insert(x.rule.id);
    for (const char* id :
         {"tcp.tid_echo.0", "tcp.protocol_id_nonzero", "tcp.split_segments", "tcp.pipelined",
          "tcp.survives_exception", "robustness.garbage_burst", "robustness.pipeline_after_exception"})
        EXPECT_TRUE(run.count(id)) << id << " not run; run:" << listed(run);
    EXPECT_EQ(failing(report), (std::set<std::string>{"tcp.protocol_id_nonzero", "tcp.split_segments"}))
        << "failing:" << listed(failing(report));
}

// A server nobody here wrote judged as a Walchem W600, whose alternative maps read their objects' own fields
// (002:750-776): pymodbus serves whatever its datastore holds at each address, so sensor 1's primary value
// (holding registers 576-577, 10.0 as a float, least significant word first) is not at 9216-9217. The rule
// fails, a warning (which field a column reads is the profile's reading of the manual); the other
// alternative maps, all zeros in both places, pass.
TEST(Peer, PymodbusServerAsAWalchemW600DoesNotMirrorItsAlternativeMap) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("tcp", "--register 577=0x4120");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto w600 = store.load("walchem-w600");
    ASSERT_TRUE(w600.has_value());
    CheckOptions o;
    o.session.timeout = std::chrono::milliseconds(1000);
    o.run.rule_globs = {"data.alternative.*"};
    const auto report = run_check(*server.client, *w600, o);
    std::set<std::string> run;
    for (const auto& x : report.results)
        if (x.outcome != Outcome::Skip) run.insert(x.rule.id);
    EXPECT_EQ(run.size(), 5u) << listed(run);  // sensors, digital inputs, virtual inputs, relays, outputs
    EXPECT_EQ(failing(report), (std::set<std::string>{"data.alternative.hr9216"})) << listed(failing(report));
    for (const auto& x : report.results)
        if (x.rule.id == "data.alternative.hr9216") {
            EXPECT_EQ(x.rule.authority, Authority::Implied);
            EXPECT_NE(x.expected.find("4120"), std::string::npos) << x.expected;
            EXPECT_EQ(x.observed, "0000 0000");
        }
}

// A server nobody here wrote judged as an MK DCY-2050, whose loop output registers are read-only in
// automatic mode (000:731, coil 0 the loop's mode, 000:918): pymodbus serves whatever its datastore holds,
// so the write is taken. The rule fails against the manual, which states the condition, and the coil and
// register it touched are restored.
TEST(Peer, PymodbusServerAsADcy2050TakesAWriteItsManualForbidsInAutomaticMode) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("tcp");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    auto& client = server.client;
    modbus::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    const auto dcy = store.load("dcy-2050");
    ASSERT_TRUE(dcy.has_value());
    CheckOptions o;
    o.session.timeout = std::chrono::milliseconds(1000);
    o.run.rule_globs = {"access.hr2.read_only_when"};
    const auto report = run_check(*client, *dcy, o);
    ASSERT_EQ(report.results.size(), 1u);
    const auto& r = report.results.front();
    EXPECT_EQ(r.outcome, Outcome::Fail) << r.observed;
    EXPECT_EQ(r.rule.authority, Authority::Manual);
    EXPECT_NE(r.observed.find("normal response"), std::string::npos) << r.observed;
    // The coil set and set back; the register was written with the value it held, which changes nothing
    // and is not the run's to put back (conformance/README.md, Restore).
    ASSERT_EQ(report.restored.size(), 1u);
    EXPECT_TRUE(report.all_restored());
}

// RTU over a stream has no silence between frames: two requests in one write are told apart only by content,
// which the specification never asks of a device, and nothing ends half a request. pymodbus's RTU framer
// keeps half a request until more bytes complete it (the request after it goes unanswered), and answers a
// request for any unit as its own (a single context), which through a gateway could be another slave's to
// answer: warnings, not failures of the specification. It answers two requests in one write: it failed
// framing.back_to_back only because framing.truncated's half frame, kept, spoiled that rule's first request,
// which framing.truncated now resynchronises away.
TEST(Peer, PymodbusRtuOverTcpPipeliningIsAWarning) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("rtu-tcp");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    auto& client = server.client;
    const auto report = certify(*client, {"framing.*", "robustness.pipeline_after_exception"});
    std::set<std::string> warned;
    for (const auto& x : report.results) {
        if (x.outcome != Outcome::Fail) continue;
        EXPECT_EQ(x.rule.authority, Authority::Implied) << x.rule.id << ": " << x.observed;
        warned.insert(x.rule.id);
    }
    EXPECT_EQ(warned, (std::set<std::string>{"framing.other_unit", "framing.truncated_discarded",
                                             "robustness.pipeline_after_exception"}));
    EXPECT_EQ(report.failures_of(Authority::Specification), 0u);
}

// pymodbus's RTU framer over a stream, given a request of a code whose length no function code tells,
// waits for the rest of it: silence, which over RTU on a stream nothing can end (a line's silence does, SL
// §2.5.1.1). check failed 113 fc.unsupported rules against the specification there: warnings now.
TEST(Peer, PymodbusRtuOverTcpSilenceToAnUnknownCodeIsAWarning) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("rtu-tcp");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    const auto report =
        certify(*server.client, {"fc.unsupported.9", "fc.unsupported.65", "fc.unsupported.100"});
    ASSERT_EQ(report.results.size(), 3u);
    for (const auto& x : report.results) {
        EXPECT_EQ(x.outcome, Outcome::Fail) << x.rule.id << ": " << x.observed;
        EXPECT_EQ(x.rule.authority, Authority::Implied) << x.rule.id;
        EXPECT_NE(x.rule.source.find("no end a device can find"), std::string::npos) << x.rule.source;
    }
    EXPECT_EQ(report.failures_of(Authority::Specification), 0u);
}

// ASCII's hex digits are 0-9 and A-F (SL §2.5.2.1; the MK manual, 000:258): pymodbus's ASCII framer writes
// its replies in upper case and reads a request in either. A request in lower case, which the specification
// leaves undefined, may be read or ignored; a reply in lower case fails the specification. Both rules used to
// be one, backwards: a device ignoring lower-case requests failed, one replying in lower case passed.
TEST(Peer, PymodbusAsciiServerRepliesInUpperCaseAndAReplyInLowerCaseFails) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    for (const bool lower : {false, true}) {
        SCOPED_TRACE(lower ? "replies in lower case" : "pymodbus as it is");
        PymodbusPeer server("ascii-tcp", lower ? "--lower-case-replies" : "");
        ASSERT_TRUE(server.client.has_value())
            << "pymodbus server did not start (python3-pymodbus installed?)";
        const auto report = certify(*server.client, {"framing.ascii_*"});
        std::map<std::string, Outcome> outcomes;
        for (const auto& x : report.results)
            outcomes[x.rule.id] = x.outcome;
        EXPECT_EQ(outcomes["framing.ascii_upper_case"], lower ? Outcome::Fail : Outcome::Pass);
        EXPECT_EQ(outcomes["framing.ascii_lower_case"], Outcome::Pass);
        EXPECT_EQ(report.failures_of(Authority::Specification), lower ? 1u : 0u);
    }
}

// pymodbus's server judged as an MMK-2030: like libmodbus's, it serves whatever its datastore holds.
TEST(Peer, PymodbusServerAsAnMk2030BreaksTheManualsLimits) {
    if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3 (python3-pymodbus)";
    PymodbusPeer server("tcp");
    ASSERT_TRUE(server.client.has_value()) << "pymodbus server did not start (python3-pymodbus installed?)";
    auto& client = server.client;
    expect_mk2030_departures(*client);
}

}  // namespace
}  // namespace mbscope::conformance::test_conformance_peer_test
