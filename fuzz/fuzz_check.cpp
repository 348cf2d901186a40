// The conformance runner (`mbscope check`) against a slave whose every answer the input decides. A firmware
// team's device under development replies with anything: the runner's own reading of replies (the address
// probe of an open map, read-backs of written values, the restore ledger, echoes, exception codes, what a
// framing or TCP rule saw) is a parser a hostile byte reaches, beyond the exchange oracle the reply target
// fuzzes. The slave is a loopback server (Modbus/TCP, RTU or ASCII over TCP) in front of the reference
// slave's device for a bundled profile: every request it can frame goes to the device, and the input then
// says what goes back: the device's own answer, silence, a closed connection, the answer changed (a byte of
// its PDU, its length, its header), late, twice, an exception with any code, or bytes of the input as they
// are.
//
// The input: a profile, a scheme, read-only or not, which rules to run (a family at a time: a whole run is
// hundreds of requests), then one action per request the slave receives; past the input's end the slave
// answers as the device does. Properties, after the run:
// - the report is whole: every failed rule says what it expected and what it saw, every error and skip
//   why, every touched point is restored or says why not, and the JSON, JUnit and text reports are written
//   (the JSON reads back);
// - under --read-only the device's registers were never changed;
// - when the slave gave the device's own answer to every request and the report says every touched point
//   was restored, the device holds its registers as made: nothing the runner wrote is lost, and it wrote
//   nothing it did not remember first.
// Timing is not a property: a reply the server thread sends late is one more thing the run must cope with.
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "conformance/report.hpp"
#include "conformance/runner.hpp"
#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/adu.hpp"
#include "modbus/transport/client.hpp"
#include "modbus/transport/endpoint.hpp"
#include "modbus/transport/socket.hpp"
#include "slave/device.hpp"
#include "slave/responder.hpp"

using namespace mbscope;
using modbus::Framing;
namespace tp = modbus::transport;

namespace {

constexpr const char* target = "fuzz_check";

// The input, read from the front; past its end every read is 0 (the slave's honest answer).
class Script {
  public:
    explicit Script(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
    std::uint8_t byte() { return at_ < bytes_.size() ? bytes_[at_++] : 0; }
    std::vector<std::uint8_t> bytes(std::size_t n) {
        n = std::min(n, bytes_.size() - at_);
        std::vector<std::uint8_t> out(bytes_.begin() + static_cast<long>(at_),
                                      bytes_.begin() + static_cast<long>(at_ + n));
        at_ += n;
        return out;
    }

  private:
    std::span<const std::uint8_t> bytes_;
    std::size_t at_ = 0;
};

// Rule selections (glob patterns of rule ids), one family or part of one per input.
constexpr const char* rule_globs[] = {"fc.supported.*", "fc.unsupported.*", "quantity.*",  "address.*",
                                      "first.*",        "precedence.*",     "access.*",    "value.*",
                                      "echo.*",         "data.*",           "broadcast.*", "framing.*",
                                      "tcp.*",          "robustness.*"};

slave::FaultSet no_faults;

// A loopback server whose answers the script decides; the device behind it answers every request it frames.
// One connection at a time: the runner connects again only after the connection closed, and a new one
// replaces the old.
class ScriptedSlave {
  public:
    ScriptedSlave(Framing framing, slave::Responder& responder, Script& script)
        : framing_(framing), responder_(responder), script_(script) {
        auto listener = tp::listen_tcp("127.0.0.1", 0, 4);
        if (!listener) fuzz::fail(target, "no loopback listener for the scripted slave: " + listener.error());
        listener_ = std::move(listener).value();
        thread_ = std::thread([this] { serve(); });
    }
    ~ScriptedSlave() {
        stop_ = true;
        thread_.join();
    }
    ScriptedSlave(const ScriptedSlave&) = delete;
    ScriptedSlave& operator=(const ScriptedSlave&) = delete;

    std::uint16_t port() const { return tp::bound_port(listener_.get()); }
    // Every request framed so far got the device's own answer, whole and at once.
    bool honest() const { return honest_.load(); }

  private:
    void serve() {
        while (!stop_) {
            pollfd watched[2] = {{listener_.get(), POLLIN, 0}, {connection_.get(), POLLIN, 0}};
            if (::poll(watched, connection_ ? 2 : 1, 1) <= 0) {
                // Bytes of a frame that never completes (a length field claiming more than follows, garbage)
                // are dropped after a silence, so they do not swallow the requests that come after (the
                // reference slave's server ends such bytes after 50 ms over RTU over TCP and closes a
                // Modbus/TCP connection whose frame stays partial; a shorter wait keeps runs fast).
                if (!pending_.empty() && std::chrono::steady_clock::now() - last_piece_ > frame_timeout)
                    pending_.clear();
                continue;
            }
            if (watched[0].revents & POLLIN) {
                if (tp::UniqueFd accepted(::accept4(listener_.get(), nullptr, nullptr, SOCK_CLOEXEC));
                    accepted) {
                    connection_ = std::move(accepted);
                    pending_.clear();
                    continue;
                }
            }
            if (!connection_ || !(watched[1].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            std::uint8_t piece[1024];
            const ssize_t n = ::read(connection_.get(), piece, sizeof piece);
            if (n <= 0)
                connection_.reset();
            else {
                last_piece_ = std::chrono::steady_clock::now();
                received({piece, static_cast<std::size_t>(n)});
            }
        }
    }

    // Requests are framed more simply than the reference slave's server frames them (it is the runner under
    // test here, not the framing): Modbus/TCP by the MBAP length (a header whose length no request can have
    // drops what was received), serial framings by what decodes: the bytes received so far, else the last
    // piece alone (after a frame that never decodes, a bad checksum).
    void received(std::span<const std::uint8_t> piece) {
        pending_.insert(pending_.end(), piece.begin(), piece.end());
        if (framing_ == Framing::Tcp) {
            while (connection_ && pending_.size() >= 7) {
                const std::size_t length = (std::size_t{pending_[4]} << 8) | pending_[5];
                if (length < 2 || length > 254) {
                    pending_.clear();
                    return;
                }
                if (pending_.size() < 6 + length) return;
                const std::vector<std::uint8_t> adu(pending_.begin(),
                                                    pending_.begin() + static_cast<long>(6 + length));
                pending_.erase(pending_.begin(), pending_.begin() + static_cast<long>(6 + length));
                if (auto frame = modbus::decode_adu(framing_, adu); frame) answer(*frame);
            }
            return;
        }
        auto frame = modbus::decode_adu(framing_, pending_);
        if (!frame) frame = modbus::decode_adu(framing_, piece);
        if (frame) {
            pending_.clear();
            answer(*frame);
        } else if (pending_.size() > 600) {
            pending_.erase(pending_.begin(), pending_.end() - 600);
        }
    }

    void send(std::span<const std::uint8_t> bytes) {
        if (connection_ && !bytes.empty())
            (void)::send(connection_.get(), bytes.data(), bytes.size(), MSG_NOSIGNAL);
    }

    std::vector<std::uint8_t> framed(const modbus::Frame& request, std::span<const std::uint8_t> pdu,
                                     std::uint16_t tid_xor = 0, std::uint8_t unit_xor = 0) {
        return modbus::encode_adu(framing_, static_cast<std::uint16_t>(request.transaction_id() ^ tid_xor),
                                  static_cast<std::uint8_t>(request.unit_id() ^ unit_xor),
                                  pdu.first(std::min<std::size_t>(pdu.size(), 253)));
    }

    void answer(const modbus::Frame& request) {
        // The device always sees the request: a device may act on a write and then answer wrongly or not.
        const std::vector<std::uint8_t> own = responder_.respond(request);
        std::vector<std::uint8_t> own_pdu;
        if (!own.empty())
            if (auto reply = modbus::decode_adu(framing_, own); reply)
                own_pdu.assign(reply->pdu().begin(), reply->pdu().end());
        const std::uint8_t action = script_.byte() % 16;
        if (action != 0 && action < 13) honest_ = false;
        switch (action) {
            case 1:  // silence
                break;
            case 2:  // the connection closes
                connection_.reset();
                pending_.clear();
                break;
            case 3: {  // one byte of the answer's PDU changed, framed correctly
                if (own_pdu.empty()) break;
                const std::size_t at = script_.byte() % own_pdu.size();
                own_pdu[at] = script_.byte();
                send(framed(request, own_pdu));
                break;
            }
            case 4: {  // a PDU from the input, framed correctly
                const auto pdu = script_.bytes(script_.byte());
                send(framed(request, pdu));
                break;
            }
            case 5: {  // an exception with any code
                const std::uint8_t fc = request.pdu().empty() ? 0 : request.pdu()[0];
                const std::uint8_t pdu[] = {static_cast<std::uint8_t>(fc | 0x80), script_.byte()};
                send(framed(request, pdu));
                break;
            }
            case 6:  // bytes of the input as they are
                send(script_.bytes(script_.byte()));
                break;
            case 7:  // the answer cut short
                if (!own.empty()) send(std::span(own).first(script_.byte() % own.size()));
                break;
            case 8: {  // the answer and bytes after it
                std::vector<std::uint8_t> longer = own;
                const auto more = script_.bytes(1 + script_.byte() % 8);
                longer.insert(longer.end(), more.begin(), more.end());
                send(longer);
                break;
            }
            case 9:  // the answer twice
                send(own);
                send(own);
                break;
            case 10: {  // the answer from another transaction or unit
                if (own.empty()) break;
                const std::uint8_t tid_xor = script_.byte();
                send(framed(request, own_pdu, tid_xor, script_.byte()));
                break;
            }
            case 11: {  // the answer in two pieces
                const std::size_t at = own.empty() ? 0 : script_.byte() % own.size();
                send(std::span(own).first(at));
                send(std::span(own).subspan(at));
                break;
            }
            case 12:  // the answer late: up to 25.5 ms, past the run's 10 ms timeout
                std::this_thread::sleep_for(std::chrono::microseconds(100 * script_.byte()));
                send(own);
                break;
            default:  // the device's own answer
                send(own);
                break;
        }
    }

    Framing framing_;
    slave::Responder& responder_;
    Script& script_;
    tp::UniqueFd listener_;
    tp::UniqueFd connection_;
    std::vector<std::uint8_t> pending_;  // received, not yet a request
    std::chrono::steady_clock::time_point last_piece_;
    static constexpr std::chrono::milliseconds frame_timeout{20};
    std::thread thread_;
    std::atomic<bool> stop_{false};
    std::atomic<bool> honest_{true};
};

std::string rule_text(const conformance::RuleResult& r) {
    return "rule " + r.rule.id + ": ";
}

void check_report(const conformance::Report& report, const std::string& run) {
    for (const auto& r : report.results) {
        if (r.rule.id.empty()) fuzz::fail(target, "a result without a rule id" + run);
        if (r.outcome == conformance::Outcome::Fail && (r.expected.empty() || r.observed.empty()))
            fuzz::fail(target, rule_text(r) + "failed without saying what it expected and saw" + run);
        if ((r.outcome == conformance::Outcome::Error || r.outcome == conformance::Outcome::Skip) &&
            r.reason.empty())
            fuzz::fail(target, rule_text(r) + "an error or skip without a reason" + run);
    }
    for (const auto& t : report.restored)
        if (!t.restored && t.problem.empty())
            fuzz::fail(target, std::string(modbus::to_string(t.table)) + " " + std::to_string(t.address) +
                                   ": neither restored nor why not" + run);
    const std::string json =
        conformance::to_json(report).dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
    if (nlohmann::json::parse(json, nullptr, false).is_discarded())
        fuzz::fail(target, "the JSON report does not read back" + run);
    std::ostringstream junit;
    conformance::write_junit(junit, report);
    const std::string xml = junit.str();
    if (xml.find("<testsuites") == std::string::npos || xml.find("</testsuites>") == std::string::npos)
        fuzz::fail(target, "the JUnit report is not whole" + run);
    std::ostringstream text;
    conformance::write_text(text, report, true);
    if (text.str().empty()) fuzz::fail(target, "the text report is empty" + run);
}

std::string changes_text(const slave::RegisterImage& image) {
    std::string out;
    for (const auto& [table, values] : image.changes())
        for (const auto& [address, value] : values)
            out += "\n  " + std::string(modbus::to_string(table)) + " " + std::to_string(address) + " = " +
                   std::to_string(value);
    return out;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    Script script({data, size});
    const auto& profiles = fuzz::bundled_profiles();
    const std::size_t profile_index = script.byte() % profiles.size();
    const modbus::Profile& profile = profiles[profile_index];
    constexpr tp::Scheme schemes[] = {tp::Scheme::Tcp, tp::Scheme::RtuOverTcp, tp::Scheme::AsciiOverTcp};
    const tp::Scheme scheme = schemes[script.byte() % 3];
    const bool read_only = script.byte() & 1;
    const std::string glob = rule_globs[script.byte() % std::size(rule_globs)];
    const std::uint8_t unit = fuzz::unit_within(profile, 1);
    slave::Device& device = fuzz::bundled_device(profile_index, unit);
    const std::vector<slave::Device*> units{&device};
    const fuzz::ResetAtEnd reset_at_end{units};
    slave::Responder responder(units, no_faults, tp::framing_of(scheme), scheme == tp::Scheme::Tcp);
    const std::string run = "\n  profile " + profile.id + ", " + std::string(tp::to_string(scheme)) +
                            (read_only ? ", read-only" : "") + ", rules " + glob;

    conformance::Report report;
    bool honest = false;
    {
        ScriptedSlave slave(tp::framing_of(scheme), responder, script);
        const auto endpoint = tp::parse_endpoint(std::string(tp::to_string(scheme)) +
                                                 "://127.0.0.1:" + std::to_string(slave.port()));
        if (!endpoint) fuzz::fail(target, "the loopback URI does not parse: " + endpoint.error());
        tp::ClientOptions client_options;
        client_options.settle = std::chrono::milliseconds(2);
        auto client = tp::Client::open(*endpoint, client_options);
        if (!client) fuzz::fail(target, "no connection to the scripted slave: " + client.error());
        conformance::CheckOptions options;
        options.session.unit = unit;
        // Loopback answers in microseconds: a reply later than this is one the script chose to delay.
        options.session.timeout = std::chrono::milliseconds(10);
        options.run.read_only = read_only;
        options.run.rule_globs = {glob};
        options.target = endpoint->text();
        report = conformance::run_check(*client, profile, options);
        honest = slave.honest();
    }  // the server thread stops: the device is the run's alone again

    static const bool trace = std::getenv("MBSCOPE_FUZZ_TRACE") != nullptr;
    if (trace) conformance::write_text(std::cerr, report, true);
    check_report(report, run);
    if (read_only && device.image().modifications() != 0)
        fuzz::fail(target, "registers changed under --read-only:" + changes_text(device.image()) + run);
    if (honest && report.all_restored() && !device.image().changes().empty())
        fuzz::fail(target, "the report restored everything, the device holds other values:" +
                               changes_text(device.image()) + run);
    return 0;
}
