// Modbus/TCP (Messaging on TCP/IP V1.0b §3.1.3, §4): transaction ids echoed, protocol id 0 only, the length
// field trusted only when it is right, requests split over segments or pipelined in one, unit id handling,
// and a connection that survives an exception.
#include <algorithm>
#include <thread>

#include "conformance/context.hpp"
#include "modbus/adu.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance {

namespace tp = modbus::transport;

void check_tcp(Context& c) {
    if (c.serial_framing()) return;
    const bool udp = c.session.client().endpoint().scheme == tp::Scheme::Udp;
    const auto probe = c.probe_read().value_or(Context::ProbeRead{});  // run_with_probe skips without one
    const std::uint8_t fc = probe.fc;
    const auto& pdu = probe.pdu;
    const std::uint8_t unit = c.session.options().unit;
    const auto tid_of = [](const tp::Exchange& ex) -> std::optional<std::uint16_t> {
        if (!ex.response) return std::nullopt;
        return ex.response->transaction_id();
    };
    for (std::uint16_t tid : {std::uint16_t{0}, std::uint16_t{0x1234}, std::uint16_t{0xFFFF}}) {
        c.run_with_probe(
            {"tcp.tid_echo." + std::to_string(tid), "Modbus/TCP", "TCP §3.1.3",
             "Transaction id " + std::to_string(tid) + " is copied into the reply.", Authority::Specification,
             false},
            [&](RuleResult& r) {
                const auto ex = c.session.raw(modbus::encode_tcp(tid, unit, pdu),
                                              "transaction id " + std::to_string(tid));
                r.expected = "normal response with transaction id " + std::to_string(tid);
                r.observed =
                    describe(ex) + (tid_of(ex) ? ", transaction id " + std::to_string(*tid_of(ex)) : "");
                r.outcome = is_normal(ex, fc) && tid_of(ex) == tid ? Outcome::Pass : Outcome::Fail;
            });
    }
    c.run_with_probe({"tcp.protocol_id_nonzero", "Modbus/TCP", "TCP §3.1.3",
                      "A request with protocol id 1 gets no Modbus reply.", Authority::Specification, false},
                     [&](RuleResult& r) {
                         const auto ex = c.session.raw(modbus::encode_tcp(7, unit, pdu, 1), "protocol id 1");
                         r.expected = "no Modbus reply (silence or a closed connection)";
                         r.observed = describe(ex);
                         r.outcome = !is_normal(ex, fc) && !response_pdu(ex) ? Outcome::Pass : Outcome::Fail;
                         if (!udp) (void)c.session.client().reconnect();
                     });
    if (!udp) {
        c.run_with_probe({"tcp.length_too_large", "Modbus/TCP", "TCP §3.1.3",
                          "A request whose length field claims more bytes than follow gets no reply to it.",
                          Authority::Specification, false},
                         [&](RuleResult& r) {
                             auto adu = modbus::encode_tcp(8, unit, pdu);
                             adu[5] = static_cast<std::uint8_t>(adu[5] + 2);
                             const auto ex = c.session.raw(adu, "length field + 2");
                             r.expected = "no reply (the slave waits for bytes that never come, or closes)";
                             r.observed = describe(ex);
                             r.outcome = !response_pdu(ex) ? Outcome::Pass : Outcome::Fail;
                             (void)c.session.client().reconnect();
                         });
        c.run_with_probe(
            {"tcp.length_too_small", "Modbus/TCP", "TCP §3.1.3",
             "A request whose length field cuts its PDU short is not answered as if it were whole.",
             Authority::Specification, false},
            [&](RuleResult& r) {
                auto adu = modbus::encode_tcp(9, unit, pdu);
                adu[5] = static_cast<std::uint8_t>(adu[5] - 2);
                const auto ex = c.session.raw(adu, "length field - 2");
                r.expected = "no normal reply (silence, a closed connection or exception 03)";
                r.observed = describe(ex);
                r.outcome = !is_normal_of_function(ex, fc) ? Outcome::Pass : Outcome::Fail;
                (void)c.session.client().reconnect();
            });
        c.run_with_probe(
            {"tcp.split_segments", "Modbus/TCP", "TCP §4.2 (stream)",
             "A request split across two TCP segments is answered.", Authority::Specification, false},
            [&](RuleResult& r) {
                const auto adu = modbus::encode_tcp(10, unit, pdu);
                // Through the session: the rest is awaited as the whole request, whose transaction id tells
                // its reply from a late one to an earlier request.
                (void)c.session.send_part(std::span<const std::uint8_t>(adu.data(), 5));
                std::this_thread::sleep_for(std::chrono::milliseconds(30));
                const auto ex =
                    c.session.raw(std::span<const std::uint8_t>(adu.data() + 5, adu.size() - 5),
                                  "the request, its bytes after the first 5 sent 30 ms after them");
                expect_normal(r, ex, fc);
            });
        c.run_with_probe(
            {"tcp.pipelined", "Modbus/TCP", "TCP §4.2 (stream)",
             "Three requests pipelined in one segment are each answered, in order.", Authority::Specification,
             false},
            [&](RuleResult& r) {
                std::vector<std::uint8_t> all;
                for (std::uint16_t tid : {21, 22, 23}) {
                    const auto adu = modbus::encode_tcp(tid, unit, pdu);
                    all.insert(all.end(), adu.begin(), adu.end());
                }
                const auto ex = c.session.raw(all, "three requests in one write", 3);
                // The three replies, in order, each judged as a reply of its own: a normal response of the
                // probe's function to its request's transaction, from the unit asked (TCP §3.1.3, §4.4.1).
                // Late replies to earlier requests, set aside before them, are none of the three.
                r.expected = "three normal responses, function " + std::to_string(fc) +
                             ", transaction ids 21, "
                             "22, 23 in that order";
                r.observed.clear();
                bool all_right = true;
                std::size_t at = 0;
                for (std::uint16_t tid : {21, 22, 23}) {
                    tp::Exchange one;
                    one.sent = modbus::encode_tcp(tid, unit, pdu);
                    if (at + 6 <= ex.own_received().size()) {
                        const std::size_t length =
                            6u + ((std::size_t{ex.own_received()[at + 4]} << 8) | ex.own_received()[at + 5]);
                        const std::size_t end = std::min(at + length, ex.own_received().size());
                        one.received.assign(ex.own_received().begin() + static_cast<std::ptrdiff_t>(at),
                                            ex.own_received().begin() + static_cast<std::ptrdiff_t>(end));
                        if (auto frame = modbus::decode_tcp(one.received))
                            one.response = std::move(frame).value();
                        at = end;
                    }
                    all_right = all_right && is_normal(one, fc);
                    r.observed +=
                        (r.observed.empty() ? "" : "; ") + std::to_string(tid) + ": " + describe(one);
                }
                if (at < ex.own_received().size())
                    r.observed += "; then " + std::to_string(ex.own_received().size() - at) + " more bytes";
                r.outcome = all_right ? Outcome::Pass : Outcome::Fail;
            });
    }
    // A PDU one byte longer than the device takes (AP §4.1: 253 bytes; a manual may say more, Walchem 256,
    // 002:219): FC8's echo is the one request whose normal reply would carry it back, an ADU longer than the
    // framing holds, which a client with a serial line's buffer cannot take.
    const auto& diag = c.profile.functions.diagnostics;
    if (c.profile.functions.supports(8) && std::find(diag.begin(), diag.end(), 0) != diag.end()) {
        const std::size_t limit = c.profile.line.pdu_max_bytes;
        c.run({"tcp.pdu_too_long", "Modbus/TCP", "AP §4.1",
               "A request whose PDU is longer than " + std::to_string(limit) +
                   " bytes (an FC8 echo query) is not answered as if it fitted.",
               Authority::Specification, false},
              [&](RuleResult& r) {
                  const std::vector<std::uint8_t> data(limit - 2, 0x5A);  // function code, sub-function, data
                  const auto adu =
                      modbus::encode_tcp(11, unit, modbus::encode_pdu(modbus::make_diagnostics(0, data)));
                  const auto ex = c.session.raw(adu, "a " + std::to_string(limit + 1) + "-byte echo query");
                  r.expected = "no reply (silence or a closed connection), or exception 01 or 03";
                  r.observed = describe(ex);
                  const bool refused = is_exception(ex, 8, 0x01) || is_exception(ex, 8, 0x03);
                  r.outcome = !ex.response || refused ? Outcome::Pass : Outcome::Fail;
                  if (!udp) (void)c.session.client().reconnect();
              });
    }
    c.run_with_probe(
        {"tcp.survives_exception", "Modbus/TCP", "TCP §4.2",
         "After an exception the connection still serves a valid request.", Authority::Specification, false},
        [&](RuleResult& r) {
            const std::uint8_t bad[5] = {0x7F, 0x00, 0x00, 0x00, 0x01};  // a function code no device supports
            const auto a = c.session.request(bad, "function code 127");
            const auto b = c.session.request(pdu, "a valid request on the same connection");
            r.expected = "an exception, then a normal response";
            r.observed = describe(a) + "; " + describe(b);
            r.outcome = response_pdu(a) && response_pdu(a)->is_exception() && is_normal(b, fc)
                            ? Outcome::Pass
                            : Outcome::Fail;
        });
    if (c.profile.line.any_unit_answered) {
        for (std::uint8_t other : {2, 247, 255}) {
            c.run_with_probe(
                {"tcp.unit." + std::to_string(other), "Modbus/TCP", "002:213-215",
                 "Unit id " + std::to_string(other) + " is answered, echoing the unit id.", Authority::Manual,
                 false},
                [&](RuleResult& r) {
                    const auto ex = c.session.request(pdu, "unit " + std::to_string(other), other);
                    r.expected = "normal response with unit id " + std::to_string(other);
                    r.observed = describe(ex);
                    r.outcome =
                        is_normal(ex, fc) && ex.response->unit_id() == other ? Outcome::Pass : Outcome::Fail;
                });
        }
    }
}

}  // namespace mbscope::conformance
