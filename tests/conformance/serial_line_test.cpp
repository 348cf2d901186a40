// The conformance runner over a true serial line: the slave on a pseudo-terminal it creates, the runner on
// the terminal's other side, with the line's t1.5 and t3.5 in force (gaps inside requests, silences between
// them). At 38400 baud t1.5 is 750 µs: the slave must be scheduled within that to see a gap, so these tests
// run alone (RUN_SERIAL in tests/CMakeLists.txt), never beside tests that keep both cores busy.
#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <thread>

#include "tests/conformance/runner_support.hpp"
#include "tests/support/process_support.hpp"

namespace mbscope::conformance::test_conformance_serial_line_test {
namespace {

using namespace mbscope::conformance::test;

// The reference slave serving mmk-2030 on a pseudo-terminal it creates, the line timed at `baud`.
class SlaveOnPty {
  public:
    SlaveOnPty(const std::string& framing, int baud, const std::vector<std::string>& faults = {}) {
        std::vector<slave::FaultSpec> specs;
        for (const auto& f : faults) {
            auto spec = slave::parse_fault(f);
            EXPECT_TRUE(spec.has_value()) << f;
            if (spec) specs.push_back(*spec);
        }
        faults_ = slave::FaultSet(specs, 7);
        auto listen = tp::parse_endpoint(framing + ":pty?baud=" + std::to_string(baud));
        EXPECT_TRUE(listen.has_value());
        if (!listen) return;
        device_ = std::make_unique<slave::Device>(slave::test::profile("mmk-2030"),
                                                  tp::line_state(*listen, 1), &faults_);
        slave::ServerOptions so;
        so.create_pty = true;
        server_ =
            std::make_unique<slave::Server>(*listen, std::vector<slave::Device*>{device_.get()}, faults_, so);
        auto opened = server_->open();
        EXPECT_TRUE(opened.has_value()) << (opened ? "" : opened.error());
        if (opened) thread_ = std::thread([this] { (void)server_->run(stop_); });
    }
    ~SlaveOnPty() { stop(); }
    void stop() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
    }
    std::string address() const { return server_ ? server_->address() : std::string(); }
    slave::Device& device() { return *device_; }

  private:
    slave::FaultSet faults_;
    std::unique_ptr<slave::Device> device_;
    std::unique_ptr<slave::Server> server_;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

class OverPseudoTerminal : public ::testing::TestWithParam<std::string> {};

TEST_P(OverPseudoTerminal, CertifiesWithNoFailureAndRestoresEverything) {
    const std::string framing = GetParam();
    SlaveOnPty slave(framing, 38400);
    auto target = tp::parse_endpoint(framing + ":" + slave.address() + "?baud=38400");
    ASSERT_TRUE(target.has_value());
    auto client = tp::Client::open(*target);
    ASSERT_TRUE(client.has_value()) << (client ? "" : client.error());
    CheckRun run;
    run.report =
        run_check(*client, slave::test::profile("mmk-2030"), options_for(std::chrono::milliseconds(500)));
    slave.stop();
    run.changes_after = slave.device().image().changes();
    expect_clean(run, 150);
    // The serial framing rules ran, with the line's timing.
    std::size_t framing_rules = 0;
    for (const auto& x : run.report.results)
        if (x.rule.id.starts_with("framing.") && x.outcome == Outcome::Pass) ++framing_rules;
    EXPECT_GE(framing_rules, 3u);
}

// The runner makes the pause inside a request on this host, where the scheduler, the kernel's tty buffers or
// a USB adapter can close it: a device that answers is asked again with a pause it cannot miss before it is
// failed. A device timing its line as at 1200 baud (t1.5 13.75 ms) hears the runner's 1.5 ms pause (38400
// baud) as none, as a device hears a pause this host failed to make, and the 50 ms one as a pause.
TEST(SerialLine, APauseTheDeviceDidNotHearIsTriedLongerBeforeTheDeviceFails) {
    SlaveOnPty slave("rtu", 1200);
    auto target = tp::parse_endpoint("rtu:" + slave.address() + "?baud=38400");
    ASSERT_TRUE(target.has_value());
    auto client = tp::Client::open(*target);
    ASSERT_TRUE(client.has_value()) << (client ? "" : client.error());
    auto options = options_for(std::chrono::milliseconds(500));
    options.run.rule_globs = {"framing.gap_inside"};
    const auto report = run_check(*client, slave::test::profile("mmk-2030"), options);
    const auto gap = std::find_if(report.results.begin(), report.results.end(),
                                  [](const RuleResult& x) { return x.rule.id == "framing.gap_inside"; });
    ASSERT_NE(gap, report.results.end());
    EXPECT_EQ(gap->outcome, Outcome::Pass) << gap->observed;
    EXPECT_NE(gap->observed.find("after 50 ms"), std::string::npos) << gap->observed;
}

// gap-inside-frame on a true serial line: every reply comes in two parts 2.5 character times apart, which
// SL §2.5.1.1 makes a broken frame (a silence over t1.5 inside it); a master on the line discards it. The
// device and the runner time the line at 1200 baud (t1.5 13.75 ms, t3.5 32 ms), so the pause (23 ms) is
// far from both the allowance for this host's timing (t1.5 + 1 ms) and the silence that splits a reply.
// Over RTU on a stream the fault shows only where two frames share one write (runner_test.cpp's table).
TEST(SerialLine, APauseInsideTheDevicesRepliesIsReported) {
    SlaveOnPty slave("rtu", 1200, {"gap-inside-frame=2.5"});
    auto target = tp::parse_endpoint("rtu:" + slave.address() + "?baud=1200");
    ASSERT_TRUE(target.has_value());
    auto client = tp::Client::open(*target);
    ASSERT_TRUE(client.has_value()) << (client ? "" : client.error());
    auto options = options_for(std::chrono::milliseconds(500));
    options.run.rule_globs = {"framing.*", "fc.supported.3"};
    const auto report = run_check(*client, slave::test::profile("mmk-2030"), options);
    slave.stop();
    const auto outcome = [&](const std::string& id) -> const RuleResult* {
        const auto it = std::find_if(report.results.begin(), report.results.end(),
                                     [&](const RuleResult& x) { return x.rule.id == id; });
        return it == report.results.end() ? nullptr : &*it;
    };
    const RuleResult* continuous = outcome("framing.reply_continuous");
    ASSERT_NE(continuous, nullptr);
    EXPECT_EQ(continuous->outcome, Outcome::Fail) << continuous->observed;
    EXPECT_EQ(continuous->rule.authority, Authority::Implied);
    EXPECT_NE(continuous->observed.find("5 of 5 normal replies held a pause"), std::string::npos)
        << continuous->observed;
    EXPECT_NE(continuous->observed.find("after byte 3 of 7"), std::string::npos) << continuous->observed;
    // The pause is shorter than the silence that ends a frame: each reply is still whole.
    const RuleResult* read = outcome("fc.supported.3");
    ASSERT_NE(read, nullptr);
    EXPECT_EQ(read->outcome, Outcome::Pass) << read->observed;
    EXPECT_EQ(report.failures_of(Authority::Specification) + report.failures_of(Authority::Manual), 0u)
        << failures(report);
}

// A device on a pseudo-terminal that keeps every byte it receives and answers the moment they hold one
// request of eight bytes, with one register of zeros: no timing of its own at all.
class InstantDevice {
  public:
    InstantDevice() {
        opened_ = ::openpty(&master_, &slave_, name_, nullptr, nullptr) == 0;
        if (!opened_) return;
        termios raw{};
        ::tcgetattr(slave_, &raw);
        ::cfmakeraw(&raw);
        ::tcsetattr(slave_, TCSANOW, &raw);
        thread_ = std::thread([this] { serve(); });
    }
    ~InstantDevice() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
        if (opened_) {
            ::close(master_);
            ::close(slave_);
        }
    }
    InstantDevice(const InstantDevice&) = delete;
    InstantDevice& operator=(const InstantDevice&) = delete;
    bool opened() const noexcept { return opened_; }
    std::string path() const { return name_; }

  private:
    void serve() {
        std::vector<std::uint8_t> got;
        while (!stop_) {
            pollfd p{master_, POLLIN, 0};
            if (::poll(&p, 1, 20) != 1) continue;
            std::uint8_t b[64];
            const ssize_t n = ::read(master_, b, sizeof b);
            if (n <= 0) break;
            got.insert(got.end(), b, b + n);
            if (got.size() != 8) continue;  // a frame is eight bytes from the first it kept: no resync
            const std::uint8_t pdu[] = {got[1], 0x02, 0x00, 0x00};
            const auto reply = modbus::encode_rtu(got[0], pdu);
            (void)!::write(master_, reply.data(), reply.size());
            got.clear();
        }
    }

    int master_ = -1, slave_ = -1;
    char name_[128] = {};
    bool opened_ = false;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

Report check_instant_device(const InstantDevice& device, std::vector<std::string> rules) {
    auto target = tp::parse_endpoint("rtu:" + device.path() + "?baud=1200");
    EXPECT_TRUE(target.has_value());
    auto client = tp::Client::open(*target);
    EXPECT_TRUE(client.has_value()) << (client ? "" : client.error());
    if (!client) return {};
    auto options = options_for(std::chrono::milliseconds(500));
    options.run.rule_globs = std::move(rules);
    return run_check(*client, slave::test::profile("mmk-2030"), options);
}

// It answers far sooner than the t3.5 of 1200 baud (32 ms): framing.reply_after_t3_5 failed it as a breach
// of the specification, though a pseudo-terminal has no line and this host's clock is all that times it
// (conformance/README.md: "a warning, timed by this host"). It is a warning: seen, and not counted.
TEST(SerialLine, AReplySoonerThanT35IsAWarningTimedByThisHost) {
    InstantDevice device;
    ASSERT_TRUE(device.opened());
    const auto report = check_instant_device(device, {"framing.reply_after_t3_5"});
    ASSERT_EQ(report.results.size(), 1u);
    const RuleResult& r = report.results.front();
    EXPECT_EQ(r.outcome, Outcome::Fail) << r.observed;
    EXPECT_EQ(r.rule.authority, Authority::Implied);
    EXPECT_EQ(verdict(report), 0) << failures(report);
}

// It keeps the first half of a truncated request after the silence (SL §2.5.1.1 wants it discarded) and so
// never answers again: framing.truncated passed on the silence alone, the rules after it failed in its place
// and the points the run had written stayed written. framing.truncated_discarded asks again after the
// silence, and fails.
TEST(SerialLine, ADeviceThatKeepsATruncatedRequestFailsTheRuleThatSentIt) {
    InstantDevice device;
    ASSERT_TRUE(device.opened());
    // (A read first, answered: a device that answers nothing in a run is a silent target, nothing judged.)
    const auto report = check_instant_device(device, {"fc.supported.3", "framing.truncated*"});
    ASSERT_EQ(report.results.size(), 3u) << failures(report);
    EXPECT_EQ(report.results[0].outcome, Outcome::Pass);
    EXPECT_EQ(report.results[2].rule.id, "framing.truncated");
    EXPECT_EQ(report.results[2].outcome, Outcome::Pass);  // silence it was
    const RuleResult& r = report.results[1];
    ASSERT_EQ(r.rule.id, "framing.truncated_discarded");
    EXPECT_EQ(r.outcome, Outcome::Fail) << r.observed;
    EXPECT_EQ(r.rule.authority, Authority::Specification);
    EXPECT_NE(r.observed.find("the next request: no reply"), std::string::npos) << r.observed;
}

// pymodbus (tests/conformance/pymodbus_serial_peer.py) as a serial slave on one end of a socat pair of
// pseudo-terminals, at 19200 baud, the runner on the other; skipped without python3-pymodbus or socat.
class PymodbusOnPty {
  public:
    PymodbusOnPty(const std::string& framing, const std::string& name, const std::string& option = "")
        : dir_(::testing::TempDir() + "conformance_pymodbus_" + name) {
        std::filesystem::remove_all(dir_);
        std::filesystem::create_directories(dir_);
        relay_ = std::make_unique<mbscope::test::Child>(
            std::vector<std::string>{"socat", "pty,raw,echo=0,link=" + dir_ + "/ttyA",
                                     "pty,raw,echo=0,link=" + dir_ + "/ttyB"},
            "/dev/null", dir_ + "/socat.err");
        if (!relay_->spawned() || !mbscope::test::wait_for([&] {
                return std::filesystem::exists(dir_ + "/ttyA") && std::filesystem::exists(dir_ + "/ttyB");
            }))
            return;
        std::vector<std::string> argv{
            "/usr/bin/python3",
            std::string(MBSCOPE_SOURCE_DIR) + "/tests/conformance/pymodbus_serial_peer.py", framing,
            dir_ + "/ttyA"};
        if (!option.empty()) argv.push_back(option);
        peer_ = std::make_unique<mbscope::test::Child>(argv, "/dev/null", dir_ + "/peer.err");
        if (!peer_->spawned()) return;
        // Ready once it answers a read (the interpreter takes a moment to start and open its end).
        auto target = tp::parse_endpoint(framing + ":" + dir_ + "/ttyB?baud=19200&parity=N");
        if (!target) return;
        auto c = tp::Client::open(*target);
        if (!c) return;
        const std::uint8_t read[] = {0x04, 0x00, 0x00, 0x00, 0x01};
        for (int i = 0; i < 50; ++i)
            if (c->transact(1, read, std::chrono::milliseconds(200)).response) {
                c->drain(std::chrono::milliseconds(50));
                client_.emplace(std::move(c).value());
                break;
            }
    }
    // Empty when socat or pymodbus did not start.
    std::optional<tp::Client>& client() { return client_; }
    std::string why() const { return mbscope::test::slurp(dir_ + "/peer.err"); }

  private:
    std::string dir_;
    std::unique_ptr<mbscope::test::Child> relay_;
    std::unique_ptr<mbscope::test::Child> peer_;
    std::optional<tp::Client> client_;
};

bool have_pymodbus_and_socat() {
    return ::access("/usr/bin/python3", X_OK) == 0 && mbscope::test::have("socat") &&
           std::system("/usr/bin/python3 -c 'import pymodbus.server' >/dev/null 2>&1") == 0;
}

Report check_generic(tp::Client& client, std::vector<std::string> rules,
                     std::chrono::milliseconds timeout = std::chrono::milliseconds(700)) {
    auto options = options_for(timeout);
    options.run.rule_globs = std::move(rules);
    return run_check(client, slave::test::profile("modbus"), options);
}

const RuleResult* result_of(const Report& report, const std::string& id) {
    const auto it = std::find_if(report.results.begin(), report.results.end(),
                                 [&](const RuleResult& x) { return x.rule.id == id; });
    return it == report.results.end() ? nullptr : &*it;
}

// A slave damaging every normal reply to FC3 (a bad CRC, or another unit's id under a CRC that holds) and
// nothing else: the generic profile's probing found no usable read of the holding registers, fc.supported.3
// and address.fc3.* skipped ("got no usable reply ...: unknown"), quantity.fc3.* skipped as "no valid
// address in the map", and the run passed, exit 0. A reply that came damaged fails fc.supported.3 now, and
// the rules that need the unknown map are in error, saying why; none skips as though the map were empty.
TEST(SerialLine, ADeviceDamagingEveryNormalReadFailsInsteadOfPassing) {
    if (!have_pymodbus_and_socat()) GTEST_SKIP() << "needs /usr/bin/python3 with pymodbus, and socat";
    for (const std::string damage : {"bad-crc", "wrong-unit"}) {
        SCOPED_TRACE(damage);
        PymodbusOnPty peer("rtu", "damaged_" + damage, "--damage-normal-fc3=" + damage);
        ASSERT_TRUE(peer.client().has_value()) << peer.why();
        const auto report = check_generic(
            *peer.client(),
            {"fc.supported.3", "fc.supported.4", "quantity.fc3*", "address.fc3*", "precedence.fc3*"});
        const RuleResult* fc3 = result_of(report, "fc.supported.3");
        ASSERT_NE(fc3, nullptr);
        EXPECT_EQ(fc3->outcome, Outcome::Fail) << fc3->reason << fc3->observed;
        EXPECT_NE(fc3->observed.find(damage == "bad-crc" ? "bad checksum" : "reply from unit 2"),
                  std::string::npos)
            << fc3->observed;
        const RuleResult* fc4 = result_of(report, "fc.supported.4");
        ASSERT_NE(fc4, nullptr);
        EXPECT_EQ(fc4->outcome, Outcome::Pass) << fc4->observed;
        for (const auto& x : report.results) {
            if (!x.rule.id.starts_with("address.fc3") && !x.rule.id.starts_with("quantity.fc3")) continue;
            // The exceptions are whole: the rules that expect one are judged as usual.
            if (x.rule.id == "address.fc3.overflow" || x.rule.id == "quantity.fc3.zero") {
                EXPECT_EQ(x.outcome, Outcome::Pass) << x.rule.id << ": " << x.observed;
                continue;
            }
            EXPECT_EQ(x.outcome, Outcome::Error) << x.rule.id << ": " << x.reason;
            EXPECT_NE(x.reason.find("damaged every reply"), std::string::npos)
                << x.rule.id << ": " << x.reason;
            EXPECT_EQ(x.reason.find("no valid address in the map"), std::string::npos) << x.reason;
        }
        EXPECT_EQ(verdict(report), 1) << failures(report);
        EXPECT_EQ(verdict_text(report), "fail");
    }
}

// pymodbus's ASCII framer stops answering for good after a request with a bad LRC: framing.bad_checksum
// passed on the silence alone, and the next run's reads found a target answering nothing. The rule asks
// again after the silence (SL §2.5.2.2: the frame is discarded, the slave listens on) and fails there.
TEST(SerialLine, ADeviceThatStopsAnsweringAfterABadChecksumFailsTheRuleThatSentIt) {
    if (!have_pymodbus_and_socat()) GTEST_SKIP() << "needs /usr/bin/python3 with pymodbus, and socat";
    PymodbusOnPty peer("ascii", "bad_lrc");
    ASSERT_TRUE(peer.client().has_value()) << peer.why();
    const auto report =
        check_generic(*peer.client(), {"framing.bad_checksum"}, std::chrono::milliseconds(300));
    const RuleResult* r = result_of(report, "framing.bad_checksum");
    ASSERT_NE(r, nullptr) << failures(report);
    EXPECT_EQ(r->outcome, Outcome::Fail) << r->reason << r->observed;
    EXPECT_EQ(r->rule.authority, Authority::Specification);
    EXPECT_NE(r->observed.find("the next request: no reply"), std::string::npos) << r->observed;
    EXPECT_EQ(verdict(report), 1);
}

// pymodbus's RTU framer keeps half a request until more bytes complete it: framing.truncated_discarded
// fails it (conformance/README.md: "a device that kept the half frame fails here, not the rules after it"),
// yet framing.truncated's own half frame made framing.back_to_back fail in a run of the two, where it passes
// alone. framing.truncated resynchronises the line before the rules after it.
TEST(SerialLine, TheHalfFrameOfFramingTruncatedDoesNotFailTheRulesAfterIt) {
    if (!have_pymodbus_and_socat()) GTEST_SKIP() << "needs /usr/bin/python3 with pymodbus, and socat";
    PymodbusOnPty peer("rtu", "truncated");
    ASSERT_TRUE(peer.client().has_value()) << peer.why();
    const auto report = check_generic(*peer.client(), {"framing.truncated", "framing.back_to_back"});
    const RuleResult* truncated = result_of(report, "framing.truncated");
    ASSERT_NE(truncated, nullptr) << failures(report);
    EXPECT_EQ(truncated->outcome, Outcome::Pass) << truncated->observed;
    const RuleResult* back_to_back = result_of(report, "framing.back_to_back");
    ASSERT_NE(back_to_back, nullptr) << failures(report);
    EXPECT_EQ(back_to_back->outcome, Outcome::Pass) << back_to_back->observed;
    EXPECT_EQ(verdict(report), 0) << failures(report);
}

// SL §2.1: on a multi-drop line only the addressed slave replies. The reference slave serves its unit
// alone and passes; pymodbus with a single context (its examples' setting) answers every unit as its own,
// unit 2 while certified as unit 1, and fails. The request for the other unit is a read: nothing is
// written whoever takes it.
TEST(SerialLine, ARequestForAnotherUnitIsNotAnswered) {
    {
        SlaveOnPty slave("rtu", 38400);
        auto target = tp::parse_endpoint("rtu:" + slave.address() + "?baud=38400");
        ASSERT_TRUE(target.has_value());
        auto client = tp::Client::open(*target);
        ASSERT_TRUE(client.has_value()) << (client ? "" : client.error());
        auto options = options_for(std::chrono::milliseconds(500));
        options.run.rule_globs = {"framing.other_unit"};
        const auto report = run_check(*client, slave::test::profile("mmk-2030"), options);
        slave.stop();
        ASSERT_EQ(report.results.size(), 1u) << failures(report);
        const RuleResult& r = report.results.front();
        EXPECT_EQ(r.outcome, Outcome::Pass) << r.observed;
        EXPECT_FALSE(r.rule.writes);
        EXPECT_EQ(r.rule.authority, Authority::Specification);
        ASSERT_GE(r.evidence.size(), 2u);
        EXPECT_EQ(r.evidence[0].sent.at(0), 2);  // unit 2 ...
        EXPECT_EQ(r.evidence[0].sent.at(1), 3);  // ... a read (FC3)
        EXPECT_TRUE(r.evidence[0].received.empty());
        EXPECT_EQ(verdict(report), 0) << failures(report);
        EXPECT_TRUE(slave.device().image().changes().empty());
    }
    if (!have_pymodbus_and_socat()) GTEST_SKIP() << "needs /usr/bin/python3 with pymodbus, and socat";
    PymodbusOnPty peer("rtu", "other_unit");
    ASSERT_TRUE(peer.client().has_value()) << peer.why();
    const auto report = check_generic(*peer.client(), {"framing.other_unit"});
    const RuleResult* r = result_of(report, "framing.other_unit");
    ASSERT_NE(r, nullptr) << failures(report);
    EXPECT_EQ(r->outcome, Outcome::Fail) << r->observed;
    EXPECT_NE(r->observed.find("for unit 2: normal response"), std::string::npos) << r->observed;
    EXPECT_EQ(verdict(report), 1);
}

INSTANTIATE_TEST_SUITE_P(Serial, OverPseudoTerminal, ::testing::Values("rtu", "ascii"));

}  // namespace
}  // namespace mbscope::conformance::test_conformance_serial_line_test
