// Robustness: a burst of malformed frames does not stop the device serving a valid request; a valid
// request right behind one that earns an exception is answered; response times are measured and held
// against the profile's limit where the manual gives one.
#include <algorithm>
#include <random>

#include "conformance/context.hpp"
#include "modbus/describe.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance {

namespace tp = modbus::transport;

void check_robustness(Context& c) {
    const auto probe = c.probe_read().value_or(Context::ProbeRead{});  // run_with_probe skips without one
    const std::uint8_t fc = probe.fc;
    const auto& pdu = probe.pdu;
    c.run_with_probe({"robustness.garbage_burst", "robustness", "SL §2.5, TCP §4.2",
                      "After a burst of 32 malformed frames, a valid request is still answered correctly.",
                      Authority::Specification, false},
                     [&](RuleResult& r) {
                         // On TCP the garbage goes over a second connection, which the device may close; the
                         // valid request goes over the first: one client's garbage must not affect another.
                         std::mt19937_64 rng(c.options.seed);
                         const bool tcp = !c.serial_framing();
                         std::optional<tp::Client> other;
                         if (tcp) {
                             auto o = tp::Client::open(c.session.client().endpoint());
                             if (o) other.emplace(std::move(o).value());
                         }
                         tp::Client& noisy = other ? *other : c.session.client();
                         for (int i = 0; i < 32; ++i) {
                             std::vector<std::uint8_t> junk(4 + rng() % 40);
                             for (auto& b : junk)
                                 b = static_cast<std::uint8_t>(rng());
                             if (!noisy.write(junk)) break;
                         }
                         if (!tcp) c.session.client().drain(std::chrono::milliseconds(200));
                         const auto ex = c.session.request(pdu, "a valid request after the burst");
                         expect_normal(r, ex, fc);
                     });
    if (!c.true_serial()) {
        // Over RTU on a stream nothing but content ends a frame, and an unsupported function's frame has no
        // length its content tells (see framing.back_to_back): a warning there, not a failure.
        const bool rtu_stream = c.session.client().framing() == modbus::Framing::Rtu;
        c.run_with_probe(
            {"robustness.pipeline_after_exception", "robustness",
             rtu_stream ? "AP §7 (RTU over a stream: common practice)" : "AP §7",
             "A valid request sent right behind one that earns an exception is answered too.",
             rtu_stream ? Authority::Implied : Authority::Specification, false},
            [&](RuleResult& r) {
                const std::uint8_t bad[5] = {0x7F, 0x00, 0x00, 0x00, 0x01};
                auto both = c.session.client().frame(c.session.options().unit, bad);
                const auto second = c.session.client().frame(c.session.options().unit, pdu);
                tp::Exchange ex;
                if (c.session.client().endpoint().scheme == tp::Scheme::Udp) {
                    // A datagram carries one ADU (TCP §4.2 over UDP): two datagrams back to back. The first
                    // goes as a request's first part, so that what arrives before the second is sent is
                    // taken as the pair's reply, not read first as a late one; both are awaited by their
                    // transaction ids.
                    (void)c.session.send_part(both);
                    ex = c.session.raw(second,
                                       "a valid read, in the datagram right behind one holding an "
                                       "unsupported function (" +
                                           std::to_string(both.size()) + " bytes)",
                                       2);
                } else {
                    both.insert(both.end(), second.begin(), second.end());
                    ex = c.session.raw(both, "an unsupported function, then a valid read, in one write", 2);
                }
                // Both replies judged: the second was counted by its bytes alone, so an exception 04 to
                // the valid read passed.
                const auto replies = replies_in(c, ex);
                const auto said = [&](std::size_t i) {
                    return i < replies.size() ? describe_reply(replies[i]) : std::string("none");
                };
                r.expected =
                    "two replies: an exception, then a normal response, function " + std::to_string(fc);
                r.observed = std::to_string(replies.size()) + " whole frames in " +
                             std::to_string(ex.own_received().size()) + " bytes: first " + said(0) +
                             ", second " + said(1);
                r.outcome = replies.size() >= 2 && replies[0] && replies[0]->is_exception() &&
                                    is_normal_reply(replies[1], fc)
                                ? Outcome::Pass
                                : Outcome::Fail;
            });
    }
}

// Run last: it reads the times of every exchange of the run.
void check_response_times(Context& c) {
    // Only replies to their request: one from another unit or for another transaction (or damaged) is
    // judged by the envelope rules, and how long it took says nothing about this device's answers.
    auto times = c.session.reply_times();
    const std::size_t others = c.session.response_times().size() - times.size();
    const std::string others_text = std::to_string(others) +
                                    (others == 1 ? " reply that did not answer its request"
                                                 : " replies that did not answer their requests") +
                                    " (a bad checksum, another unit or transaction id)";
    const auto limit = c.profile.line.response_timeout_ms;
    c.run(
        {"robustness.response_time", "robustness", limit ? c.profile.source : "SL §2.4.1 (response timeout)",
         limit ? "Every reply arrives within the manual's " + std::to_string(*limit) + " ms."
               : "Response times are measured (min / median / max); the manual gives no limit.",
         limit ? Authority::Manual : Authority::Specification, false},
        [&](RuleResult& r) {
            if (times.empty()) {
                r.outcome = Outcome::Skip;
                r.reason = others ? "no reply to its request was received in this run, only " + others_text
                                  : "no reply was received in this run";
                return;
            }
            std::sort(times.begin(), times.end());
            const auto us = [](std::chrono::nanoseconds d) {
                return std::to_string(d.count() / 1000) + " µs";
            };
            r.observed = "min " + us(times.front()) + ", median " + us(times[times.size() / 2]) + ", max " +
                         us(times.back()) + " over " + std::to_string(times.size()) + " replies" +
                         (others ? " (not counted: " + others_text + ")" : "");
            r.expected = limit ? "max ≤ " + std::to_string(*limit) + " ms" : "measured";
            r.outcome =
                !limit || times.back() <= std::chrono::milliseconds(*limit) ? Outcome::Pass : Outcome::Fail;
        });
}

// Run last: the first judges every exchange of the run, the second leaves the device alone. A slave only
// answers, once per request (SL §2.1; MK-MS-01, 000:246-248: "the master always initiates", exactly one
// reply; CTH-MS-01, 003:450-452; WA-GEN-02, 002:164: a server only, no unsolicited traffic).
void check_unsolicited(Context& c) {
    c.run({"reply.once", "robustness", "SL §2.1, AP §4.1",
           "Every request is answered once: no reply comes twice, in the same read or later.",
           Authority::Specification, false},
          [&](RuleResult& r) {
              const auto& repeated = c.session.repeated_replies();
              r.expected = "one reply to each request";
              if (repeated.empty()) {
                  r.observed = "no reply came twice in " + std::to_string(c.session.requests()) + " requests";
                  return;
              }
              r.observed = std::to_string(repeated.size()) + (repeated.size() == 1 ? " reply" : " replies") +
                           " came twice (first: " + repeated.front().note + ")";
              r.outcome = Outcome::Fail;
              // The first few are evidence enough; the count says how many.
              c.session.cite({repeated.begin(),
                              repeated.begin() +
                                  std::min<std::ptrdiff_t>(8, static_cast<std::ptrdiff_t>(repeated.size()))});
          });
    const auto idle = c.options.idle;
    c.run(
        {"silence.idle", "robustness", "AP §4.1, SL §2.1",
         "Left alone for " + std::to_string(idle.count()) +
             " ms, the device sends nothing: only the master initiates.",
         Authority::Specification, false},
        [&](RuleResult& r) {
            // --idle 0 listens to nothing: "nothing in 0 ms" passed a rule that was never tried.
            if (idle.count() == 0) {
                r.outcome = Outcome::Skip;
                r.reason = "--idle 0: nothing was listened for";
                return;
            }
            const auto heard = c.session.listen_idle(idle);
            r.expected = "no byte";
            r.observed =
                heard.received.empty()
                    ? "nothing in " + std::to_string(idle.count()) + " ms"
                    : std::to_string(heard.received.size()) + " bytes, " +
                          std::to_string(tp::frames_in(c.session.client().framing(), heard.received).size()) +
                          " whole frames: " +
                          modbus::hex_bytes(std::span(heard.received)
                                                .first(std::min<std::size_t>(heard.received.size(), 32))) +
                          (heard.received.size() > 32 ? " ..." : "");
            r.outcome = heard.received.empty() ? Outcome::Pass : Outcome::Fail;
        });
}

}  // namespace mbscope::conformance
