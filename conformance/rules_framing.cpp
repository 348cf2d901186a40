// Framing on serial lines and serial framing over TCP (SL §2.5): a bad CRC or LRC is never answered, nor a
// request for another unit (SL §2.1), and the device answers the next valid request after either; nor a
// truncated frame, nor one holding a silence above t1.5; the reply starts after t3.5 and holds no such
// silence either; requests back to back are each answered; ASCII replies are in upper-case hex, and a
// request in lower case is ignored or read as in upper case.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <thread>

#include "conformance/context.hpp"
#include "modbus/adu.hpp"

namespace mbscope::conformance {

void check_framing(Context& c) {
    if (!c.serial_framing()) return;  // Modbus/TCP framing is the TCP family's
    const bool ascii = c.session.client().framing() == modbus::Framing::Ascii;
    const auto probe = c.probe_read().value_or(Context::ProbeRead{});  // run_with_probe skips without one
    const std::uint8_t fc = probe.fc;
    const auto good = c.session.client().frame(c.session.options().unit, probe.pdu);
    const std::string check = ascii ? "LRC" : "CRC";
    // Silence alone passed a device that discarded the frame and never answered again (pymodbus's ASCII
    // framer): the rules after it failed in its place. SL §2.5.1.2 and §2.5.2.2 have the slave discard the
    // frame and go on listening, so a valid request follows the silence, as in framing.truncated_discarded.
    c.run_with_probe(
        {"framing.bad_checksum", "framing", ascii ? "SL §2.5.2.2" : "SL §2.5.1.2",
         "A request with a bad " + check + " gets no reply, and the valid request after it is answered.",
         Authority::Specification, false},
        [&](RuleResult& r) {
            auto bad = good;
            if (ascii)
                bad[bad.size() - 3] = bad[bad.size() - 3] == '0' ? '1' : '0';  // the LRC's low hex digit
            else
                bad.back() ^= 0xFF;
            const auto ex = c.session.raw(bad, "bad " + check);
            expect_silence(r, ex);
            if (r.outcome != Outcome::Pass) return;
            const auto next = c.session.raw(good, "a valid request after the silence");
            r.expected = "no reply, then a normal response to the valid request after it";
            r.observed = "no reply to the bad " + check + "; the next request: " + describe(next);
            r.outcome = is_normal(next, fc) ? Outcome::Pass : Outcome::Fail;
        });
    // SL §2.1: on a multi-drop line only the addressed slave replies; a slave answering every unit id (a
    // server that serves any unit as its own, as pymodbus's single context does) answers for its neighbours
    // too. The same read of the device's own point, for the next unit (1-247, SL §2.2), so that nothing is
    // written whoever takes it; then the device's own unit, which must still be answered (silence from a
    // device that stopped listening proves nothing). Over a stream the target may be a gateway, which passes
    // the request on to another slave of its line: a warning there. On a line, the device must be alone on
    // it, as for every rule.
    const std::uint8_t own_unit = c.session.options().unit;
    const auto other_unit = c.options.other_unit.value_or(static_cast<std::uint8_t>(own_unit % 247 + 1));
    c.run_with_probe(
        {"framing.other_unit", "framing",
         c.true_serial() ? "SL §2.1, §2.2" : "SL §2.1, §2.2 (a line; over a stream: a gateway's line)",
         "A request for another unit (" + std::to_string(other_unit) +
             ") gets no reply, and the request for the device's own unit after it is answered.",
         c.true_serial() ? Authority::Specification : Authority::Implied, false},
        [&](RuleResult& r) {
            if (other_unit == 0 || other_unit == own_unit) {
                r.outcome = Outcome::Skip;
                r.reason = other_unit == 0 ? "--other-unit 0: no unit was named that no device answers"
                                           : "--other-unit names the device's own unit";
                return;
            }
            const auto ex = c.session.request(
                probe.pdu, "the same read for unit " + std::to_string(other_unit), other_unit);
            expect_silence(r, ex);
            r.expected = "no reply for unit " + std::to_string(other_unit) +
                         ", then a normal response for unit " + std::to_string(own_unit);
            if (r.outcome != Outcome::Pass) {
                // On a line with other devices one of them may be that unit: --other-unit names a free
                // one.
                r.observed = "for unit " + std::to_string(other_unit) + ": " + describe(ex) +
                             (c.options.other_unit ? ""
                                                   : " (or another device on the line has that unit: "
                                                     "--other-unit names one no device answers)");
                return;
            }
            const auto next = c.session.raw(good, "the read for the device's own unit");
            r.observed = "no reply for unit " + std::to_string(other_unit) + "; for unit " +
                         std::to_string(own_unit) + ": " + describe(next);
            r.outcome = is_normal(next, fc) ? Outcome::Pass : Outcome::Fail;
        });
    // Silence alone passed a device that kept the half frame and never answered again: the rules after it
    // failed in its place, and the points written could not be restored. On a line the silence ends the half
    // frame (SL §2.5.1.1), in ASCII the next ':' does (SL §2.5.2.1); RTU over a stream has neither, and a
    // gateway's timeout is common practice, not the specification: a warning there. Before framing.truncated,
    // whose half frame a device that keeps it would otherwise complete with this rule's.
    const bool rtu_stream = !ascii && !c.true_serial();
    c.run_with_probe({"framing.truncated_discarded", "framing",
                      rtu_stream ? "SL §2.5.1.1 (a line; RTU over a stream: common practice)"
                                 : (ascii ? "SL §2.5.2.1" : "SL §2.5.1.1"),
                      "After a truncated request and a silence, the next request is answered: the half frame "
                      "was discarded.",
                      rtu_stream ? Authority::Implied : Authority::Specification, false},
                     [&](RuleResult& r) {
                         const std::vector<std::uint8_t> half(
                             good.begin(), good.begin() + static_cast<long>(good.size() / 2));
                         const auto first = c.session.raw(half, "first half of a request");
                         c.session.client().drain(std::chrono::milliseconds(150));
                         const auto next = c.session.raw(good, "a valid request after the silence");
                         r.expected = "a normal response to the request after the half one";
                         r.observed = "after the half request " + describe(first) +
                                      "; the next request: " + describe(next);
                         r.outcome = is_normal(next, fc) ? Outcome::Pass : Outcome::Fail;
                     });
    c.run_with_probe({"framing.truncated", "framing", "SL §2.5.1.1", "A truncated request gets no reply.",
                      Authority::Specification, false},
                     [&](RuleResult& r) {
                         const std::vector<std::uint8_t> half(
                             good.begin(), good.begin() + static_cast<long>(good.size() / 2));
                         expect_silence(r, c.session.raw(half, "first half of a request"));
                         // Over TCP the half frame may still sit in the slave's buffer: let its
                         // resynchronisation run.
                         c.session.client().drain(std::chrono::milliseconds(150));
                         // A device that keeps the half frame (pymodbus's RTU framer), which
                         // framing.truncated_discarded fails, would complete it with the first request of
                         // the rule after this one and fail that rule in its place (conformance/README.md:
                         // it fails there, not in the rules after it). Valid requests, not judged, until one
                         // is answered (three at most) give the rules after a resynchronised line.
                         for (int i = 0; i < 3; ++i) {
                             if (c.stop && c.stop->load()) break;
                             const auto ex = c.session.raw(good, "resynchronise the line (not judged)");
                             if (is_normal(ex, fc)) break;
                             c.session.client().drain(std::chrono::milliseconds(150));
                         }
                     });
    // RTU over a stream (rtu-tcp) has no silence to end a frame: two frames in one write are delimited only
    // by content, which the specification never asks of a device (on a line the silence does it, SL
    // §2.5.1.1). Gateways do it; one that does not earns a warning, not a failure.
    c.run_with_probe({"framing.back_to_back", "framing",
                      rtu_stream ? "SL §2.5.1.1 (a line; RTU over a stream: common practice)" : "SL §2.5.1.1",
                      "Two requests back to back are each answered.",
                      rtu_stream ? Authority::Implied : Authority::Specification, false},
                     [&](RuleResult& r) {
                         if (c.true_serial()) {
                             // On a line the second request may follow the first reply without delay.
                             const auto a = c.session.raw(good, "first request");
                             const auto b = c.session.raw(good, a.own_received().empty()
                                                                    ? "second request, the first unanswered"
                                                                    : "second request right after the reply");
                             r.expected = "two normal replies";
                             r.observed = describe(a) + "; " + describe(b);
                             r.outcome = is_normal(a, fc) && is_normal(b, fc) ? Outcome::Pass : Outcome::Fail;
                             return;
                         }
                         auto both = good;
                         both.insert(both.end(), good.begin(), good.end());
                         const auto ex = c.session.raw(both, "two requests in one write", 2);
                         r.expected = "two normal replies";
                         r.observed =
                             describe(ex) + " (" + std::to_string(ex.own_received().size()) + " bytes)";
                         // Each reply judged, not the bytes counted (a reply's size depends on the table
                         // read).
                         const auto replies = replies_in(c, ex);
                         r.outcome = replies.size() >= 2 && is_normal_reply(replies[0], fc) &&
                                             is_normal_reply(replies[1], fc)
                                         ? Outcome::Pass
                                         : Outcome::Fail;
                     });
    if (c.true_serial() && !ascii) {
        const auto& line = c.session.client().endpoint().line;
        c.run_with_probe(
            // Timed by this host from the end of the request's transmission: its scheduler and a USB adapter
            // move that by a millisecond or more, and a pseudo-terminal has no line to time at all (a prompt
            // device there answers in microseconds). A warning, as conformance/README.md says.
            {"framing.reply_after_t3_5", "framing", "SL §2.5.1.1 (as this host times it)",
             "The reply starts no sooner than t3.5 after the request.", Authority::Implied, false},
            [&](RuleResult& r) {
                const auto ex = c.session.raw(good, "a request");
                r.expected = "first reply byte ≥ " + std::to_string(line.t3_5().count() / 1000) +
                             " µs after the request";
                r.observed = describe(ex) + ", first byte after " +
                             std::to_string(ex.first_byte.count() / 1000) + " µs";
                r.outcome = is_normal(ex, fc) && ex.first_byte >= line.t3_5() ? Outcome::Pass : Outcome::Fail;
            });
        // The device's side of the same rule: its reply is one continuous stream. Pauses inside a reply are
        // timed by this host's reads, which its scheduler and a USB adapter's buffering move by a millisecond
        // or more (the allowance the client also adds to t3.5 before it ends a frame): a warning, seen in
        // most of several replies, not a failure. A pause over t3.5 splits the reply, which other rules fail.
        c.run_with_probe(
            {"framing.reply_continuous", "framing", "SL §2.5.1.1 (pauses as this host times them)",
             "The reply holds no silence above t1.5.", Authority::Implied, false},
            [&](RuleResult& r) {
                constexpr int replies = 5;
                const auto allowed = line.t1_5() + std::chrono::milliseconds(1);
                int normal = 0;
                int paused = 0;
                std::chrono::nanoseconds longest{0};
                std::size_t after = 0;
                std::size_t size = 0;
                for (int i = 0; i < replies; ++i) {
                    const auto ex = c.session.raw(good, "a request (reply " + std::to_string(i + 1) + " of " +
                                                            std::to_string(replies) + ")");
                    if (!is_normal(ex, fc)) continue;
                    ++normal;
                    if (ex.longest_pause <= allowed) continue;
                    ++paused;
                    if (ex.longest_pause > longest) {
                        longest = ex.longest_pause;
                        after = ex.pause_after;
                        size = ex.own_received().size();
                    }
                }
                r.expected = "no pause above t1.5 (" + std::to_string(line.t1_5().count() / 1000) +
                             " µs) + 1 ms inside a reply";
                if (normal == 0) {
                    r.outcome = Outcome::Skip;
                    r.reason = "no normal reply to time";
                    return;
                }
                r.observed =
                    std::to_string(paused) + " of " + std::to_string(normal) + " normal replies held a pause";
                if (paused > 0)
                    r.observed += ", the longest " + std::to_string(longest.count() / 1000) +
                                  " µs after byte " + std::to_string(after) + " of " + std::to_string(size);
                r.outcome = 2 * paused > normal ? Outcome::Fail : Outcome::Pass;
            });
        c.run_with_probe(
            {"framing.gap_inside", "framing", "SL §2.5.1.1",
             "A request with a silence above t1.5 inside it gets no reply.", Authority::Specification, false},
            [&](RuleResult& r) {
                const std::size_t half = good.size() / 2;
                const auto paused = [&](std::chrono::microseconds pause, const std::string& note) {
                    (void)c.session.send_part(std::span<const std::uint8_t>(good.data(), half));
                    std::this_thread::sleep_for(pause);
                    return c.session.raw(
                        std::span<const std::uint8_t>(good.data() + half, good.size() - half), note);
                };
                const auto pause = std::chrono::duration_cast<std::chrono::microseconds>(line.t1_5() * 2);
                const auto ex = paused(pause, "second half after a pause of 2 × t1.5");
                expect_silence(r, ex);
                if (r.outcome == Outcome::Pass) return;
                // Sent again with a pause the host cannot miss before the device is failed.
                const auto longer = confirming_pause(pause);
                const std::string again_note =
                    "second half after a pause of " + std::to_string(longer.count() / 1000) + " ms";
                const auto again = paused(longer, again_note);
                expect_silence(r, again);
                r.observed = describe(ex) + " after a pause of 2 × t1.5, " + describe(again) + " after " +
                             std::to_string(longer.count() / 1000) + " ms";
            });
    }
    if (ascii) {
        c.run_with_probe({"framing.ascii_upper_case", "framing", "SL §2.5.2.1",
                          "A reply is written in the hex digits 0-9 and A-F only (upper case).",
                          Authority::Specification, false},
                         [&](RuleResult& r) {
                             const auto ex = c.session.raw(good, "a valid request");
                             r.expected = "a normal response in upper-case hex";
                             r.observed = describe(ex);
                             if (!is_normal(ex, fc)) {
                                 r.outcome = Outcome::Error;
                                 r.reason = "the valid request got no normal reply: nothing to judge";
                                 return;
                             }
                             const bool lower =
                                 ex.response->findings.contains(modbus::FindingCode::AsciiLowercaseHex);
                             if (lower) r.observed += ", in lower-case hex";
                             r.outcome = lower ? Outcome::Fail : Outcome::Pass;
                         });
        // The specification allows upper case only and says nothing of a request in lower case: a device
        // may ignore it (the MK manual lists '0'-'9' and 'A'-'F' alone, 000:258) or read it as its
        // upper-case twin. What it must not do is misread it, so only a different answer is a warning.
        c.run_with_probe(
            {"framing.ascii_lower_case", "framing", "SL §2.5.2.1 (lower case undefined)",
             "A request in lower-case hex is ignored or answered as the same request in upper "
             "case, never misread.",
             Authority::Implied, false},
            [&](RuleResult& r) {
                auto lower = good;
                std::transform(lower.begin(), lower.end(), lower.begin(),
                               [](std::uint8_t ch) { return static_cast<std::uint8_t>(std::tolower(ch)); });
                const auto ex = c.session.raw(lower, "lower-case hex");
                r.expected = "no reply, or a normal response to function " + std::to_string(fc);
                r.observed = describe(ex);
                r.outcome = ex.own_received().empty() || is_normal(ex, fc) ? Outcome::Pass : Outcome::Fail;
            });
    }
}

}  // namespace mbscope::conformance
