#include "fuzz/network/reproducer.hpp"

#include "fuzz/network/unanswered.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/storage/text_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>
#include <tuple>

namespace mbscope::fuzz::network {

namespace {

// `received`, which came after `request` was given up, judged as all the request received: not with the
// late replies to earlier requests that the request set aside (own_received() would count them off the
// front of these bytes, and the oracle find the reply missing) nor with its time-out. Every observation
// begins with `when`.
std::vector<conformance::OracleViolation> judge_late(conformance::ExchangeOracle& oracle,
                                                     const modbus::transport::Exchange& request,
                                                     std::vector<std::uint8_t> received,
                                                     std::optional<modbus::Frame> response,
                                                     std::string_view when) {
    modbus::transport::Exchange ex;
    ex.sent = request.sent;
    ex.received = std::move(received);
    ex.response = std::move(response);
    auto found = oracle.judge(ex);
    for (auto& v : found)
        v.observed = std::string(when) + v.observed;
    return found;
}

modbus::Result<std::vector<std::uint8_t>, std::string> unhex(const std::string& text) {
    std::vector<std::uint8_t> out;
    std::istringstream in(text);
    for (std::string token; in >> token;) {
        if (token.size() != 2 || !std::isxdigit(static_cast<unsigned char>(token[0])) ||
            !std::isxdigit(static_cast<unsigned char>(token[1])))
            return modbus::quote_excerpt(token) + " is not a hex byte";
        out.push_back(static_cast<std::uint8_t>(std::stoul(token, nullptr, 16)));
    }
    return out;
}

// A whole number field, at most `most`, `fallback` when absent. nlohmann's value()/get() convert a float
// with a cast (1e30 into an int is undefined behaviour) and wrap a negative number into an unsigned type,
// so the type and the range are checked here and anything else is refused by name.
modbus::Result<std::uint64_t, std::string> count(const nlohmann::json& j, const char* key, std::uint64_t most,
                                                 std::uint64_t fallback) {
    const auto it = j.find(key);
    if (it == j.end()) return fallback;
    if (!it->is_number_unsigned() || it->get<std::uint64_t>() > most)
        return std::string("\"") + key + "\" is not a whole number in 0.." + std::to_string(most);
    return it->get<std::uint64_t>();
}

// A text field into `out`, `fallback` when absent; a value of another type is refused by name (it used to
// end as the JSON library's own message, naming no field). The error, if any.
std::optional<std::string> text(const nlohmann::json& j, const char* key, const char* fallback,
                                std::string& out) {
    const auto it = j.find(key);
    if (it == j.end()) {
        out = fallback;
        return std::nullopt;
    }
    if (!it->is_string()) return std::string("\"") + key + "\" is not a string";
    out = it->get<std::string>();
    return std::nullopt;
}

// A true/false field, false when absent.
modbus::Result<bool, std::string> flag(const nlohmann::json& j, const char* key) {
    const auto it = j.find(key);
    if (it == j.end()) return false;
    if (!it->is_boolean()) return std::string("\"") + key + "\" is not true or false";
    return it->get<bool>();
}

// Sleeps `pause`, looking at `stop` every 20 ms at most (a step's pause may be up to a minute). False when
// stopped.
bool pause_unless_stopped(std::chrono::microseconds pause, const std::atomic<bool>* stop) {
    if (!stop) {
        std::this_thread::sleep_for(pause);
        return true;
    }
    const auto until = std::chrono::steady_clock::now() + pause;
    for (;;) {
        if (stop->load()) return false;
        const auto now = std::chrono::steady_clock::now();
        if (now >= until) return true;
        std::this_thread::sleep_for(
            std::min<std::chrono::steady_clock::duration>(until - now, std::chrono::milliseconds(20)));
    }
}

}  // namespace

std::vector<std::uint8_t> Step::joined() const {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts)
        out.insert(out.end(), p.begin(), p.end());
    return out;
}

nlohmann::json to_json(const Reproducer& r) {
    nlohmann::json steps = nlohmann::json::array();
    for (const auto& s : r.steps) {
        nlohmann::json parts = nlohmann::json::array();
        for (const auto& p : s.parts)
            parts.push_back(modbus::hex_bytes(p));
        nlohmann::json j{{"parts", parts}, {"recipe", s.recipe}};
        if (s.pause.count()) j["pause_us"] = s.pause.count();
        if (s.reconnect_after) j["reconnect_after"] = true;
        if (s.void_by_gap) j["void_by_gap"] = true;
        steps.push_back(std::move(j));
    }
    nlohmann::json j{{"mbscope_reproducer", 1},
                     {"rule", r.rule},
                     {"source", r.source},
                     {"expected", r.expected},
                     {"observed", r.observed},
                     {"target", r.target},
                     {"profile", r.profile},
                     {"unit", r.unit},
                     {"framing", r.framing},
                     {"seed", r.seed},
                     {"request", r.request},
                     {"minimised", r.minimised},
                     {"slow_ms", r.slow_ms},
                     {"original_steps", r.original_steps},
                     {"steps", steps},
                     {"replay", "mbscope replay --target " + r.target + " --profile " + r.profile +
                                    " --unit " + std::to_string(r.unit) + " FILE"}};
    if (r.replays_on_new_connection) j["replays_on_new_connection"] = *r.replays_on_new_connection;
    return j;
}

modbus::Result<Reproducer, std::string> reproducer_from_json(const nlohmann::json& j) {
    try {
        if (!j.is_object() || !j.contains("mbscope_reproducer") || j["mbscope_reproducer"] != 1)
            return std::string("not an mbscope reproducer (no \"mbscope_reproducer\": 1)");
        Reproducer r;
        for (const auto& [key, field, fallback] :
             {std::tuple<const char*, std::string*, const char*>{"rule", &r.rule, ""},
              {"source", &r.source, ""},
              {"expected", &r.expected, ""},
              {"observed", &r.observed, ""},
              {"target", &r.target, ""},
              {"profile", &r.profile, "modbus"},
              {"framing", &r.framing, ""}}) {
            if (auto error = text(j, key, fallback, *field)) return *error;
        }
        const auto unit = count(j, "unit", 255, 1);
        const auto seed = count(j, "seed", UINT64_MAX, 0);
        const auto request = count(j, "request", UINT64_MAX, 0);
        const auto original = count(j, "original_steps", SIZE_MAX, 0);
        const auto slow = count(j, "slow_ms", UINT32_MAX, 0);  // --slow's 600,000 and a serial line's frames
        for (const auto* field : {&unit, &seed, &request, &original, &slow})
            if (!*field) return field->error();
        r.slow_ms = static_cast<std::uint32_t>(slow.value());
        r.unit = static_cast<std::uint8_t>(unit.value());
        r.seed = seed.value();
        r.request = request.value();
        r.original_steps = static_cast<std::size_t>(original.value());
        const auto minimised = flag(j, "minimised");
        if (!minimised) return minimised.error();
        r.minimised = minimised.value();
        if (j.contains("replays_on_new_connection")) {
            const auto fresh = flag(j, "replays_on_new_connection");
            if (!fresh) return fresh.error();
            r.replays_on_new_connection = fresh.value();
        }
        if (!j.contains("steps") || !j["steps"].is_array()) return std::string("no \"steps\" array");
        if (j["steps"].empty()) return std::string("\"steps\" is empty: nothing to replay");
        if (j["steps"].size() > max_reproducer_steps)
            return std::string(std::to_string(j["steps"].size()) + " steps, more than the " +
                               std::to_string(max_reproducer_steps) + " a reproducer may hold");
        std::size_t index = 0;
        for (const auto& s : j["steps"]) {
            ++index;
            Step step;
            if (!s.is_object()) return std::string("step " + std::to_string(index) + ": not an object");
            if (!s.contains("parts") || !s["parts"].is_array() || s["parts"].empty())
                return std::string("step " + std::to_string(index) + ": no \"parts\"");
            if (s["parts"].size() > max_step_parts)
                return std::string("step " + std::to_string(index) + ": " +
                                   std::to_string(s["parts"].size()) + " parts, more than the " +
                                   std::to_string(max_step_parts) + " a step may hold");
            for (const auto& p : s["parts"]) {
                if (!p.is_string())
                    return std::string("step " + std::to_string(index) +
                                       ": a part is not a string of hex bytes");
                auto bytes = unhex(p.get<std::string>());
                if (!bytes) return std::string("step " + std::to_string(index) + ": " + bytes.error());
                step.parts.push_back(std::move(bytes).value());
            }
            // Microseconds; reproducers written before stream pauses were finer say milliseconds.
            const bool micro = s.contains("pause_us");
            const auto pause = micro ? count(s, "pause_us", 60'000'000, 0) : count(s, "pause_ms", 60'000, 0);
            if (!pause) return std::string("step " + std::to_string(index) + ": " + pause.error());
            step.pause =
                std::chrono::microseconds((micro ? 1 : 1000) * static_cast<std::int64_t>(pause.value()));
            const auto reconnect = flag(s, "reconnect_after");
            const auto gap = flag(s, "void_by_gap");
            const auto recipe = text(s, "recipe", "", step.recipe);
            for (const auto* field : {&reconnect, &gap})
                if (!*field) return std::string("step " + std::to_string(index) + ": " + field->error());
            if (recipe) return std::string("step " + std::to_string(index) + ": " + *recipe);
            step.reconnect_after = reconnect.value();
            step.void_by_gap = gap.value();
            if (modbus::first_unprintable(step.recipe))
                return std::string("step " + std::to_string(index) +
                                   ": \"recipe\" holds a control character");
            r.steps.push_back(std::move(step));
        }
        // `mbscope replay` prints these as they are: a file from elsewhere must not carry escape sequences to
        // a terminal.
        for (const auto& [key, text] : {std::pair<const char*, const std::string*>{"rule", &r.rule},
                                        {"source", &r.source},
                                        {"expected", &r.expected},
                                        {"observed", &r.observed},
                                        {"target", &r.target},
                                        {"profile", &r.profile},
                                        {"framing", &r.framing}})
            if (modbus::first_unprintable(*text))
                return std::string("\"") + key + "\" holds a control character";
        return r;
    } catch (const nlohmann::json::exception& e) {
        return std::string(e.what());
    }
}

modbus::Result<Reproducer, std::string> load_reproducer(const std::string& path) {
    std::string error;
    const auto text = modbus::storage::read_text_file(path, error, max_reproducer_size);
    if (!text) return std::string(path + ": " + error);
    const auto j = nlohmann::json::parse(*text, nullptr, false);
    if (j.is_discarded()) return std::string(path + ": not JSON");
    auto r = reproducer_from_json(j);
    if (!r) return std::string(path + ": " + r.error());
    return r;
}

modbus::Result<void, std::string> save_reproducer(const Reproducer& r, const std::string& path) {
    const std::string temporary = path + ".tmp";
    {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        out << to_json(r).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
        out.flush();
        if (!out) return std::string(path + ": cannot write");
    }
    if (std::rename(temporary.c_str(), path.c_str()) != 0) {
        ::unlink(temporary.c_str());
        return std::string(path + ": cannot write");
    }
    return {};
}

ReplayedStep send_step(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                       const Step& step, const ReplayOptions& options,
                       std::span<const modbus::transport::OwedRequest> owed) {
    ReplayedStep r;
    const auto whole = step.joined();
    // Where the rules demand silence (or have no opinion: no frame, unit 0 over TCP) the wait is short; a
    // reply after it is judged when the next step begins (late_bytes). Where silence is merely allowed (an
    // RTU request whose length its function does not predict, which a slave may end at a silence or drop)
    // a reply may come after the slave's own silence: it is waited for in full, so that it is not taken
    // for the next request's.
    // Over Modbus/TCP a reply carries its request's transaction id, and one that comes after the wait is
    // judged as that request's all the same (unanswered.hpp): where silence is allowed there (another unit's
    // request, which a lone device may serve or ignore), waiting --timeout for it made each such request
    // cost the whole timeout against a device that ignores other units.
    using Answer = conformance::ExchangeOracle::Answer;
    const Answer answer = oracle.answer_due(whole);
    const bool silence = step.void_by_gap || answer == Answer::Unjudged || answer == Answer::Silence ||
                         (answer == Answer::Optional && client.framing() == modbus::Framing::Tcp);
    r.reply_due = !silence;
    for (std::size_t i = 0; i + 1 < step.parts.size(); ++i) {
        (void)client.write(step.parts[i]);
        if (!pause_unless_stopped(step.pause, options.stop)) {
            r.interrupted = true;
            r.reply_due = false;
            return r;
        }
    }
    r.exchange =
        client.raw(step.parts.back(), silence ? options.silence_wait : options.timeout, 1, whole, owed);
    if (step.void_by_gap) {
        // The slave must drop a request with a silence over t1.5 inside it (SL §2.5.1.1); the oracle judges
        // bytes, not their timing, so this rule is judged here.
        if (!r.exchange.received.empty())
            r.violations.push_back({"silence.gap_inside_request", "SL §2.5.1.1",
                                    "no reply to a request with a silence over t1.5 inside it",
                                    std::to_string(r.exchange.received.size()) +
                                        " bytes: " + modbus::hex_bytes(r.exchange.received)});
    } else {
        r.violations = oracle.judge(r.exchange);
    }
    return r;
}

std::vector<std::uint8_t> await_owed(modbus::transport::Client& client, modbus::transport::OwedRequests& owed,
                                     std::chrono::steady_clock::time_point until,
                                     std::vector<modbus::transport::SettledRequest>& settled) {
    std::vector<std::uint8_t> rest;
    for (;;) {
        const auto list = owed.list();
        const auto due = std::find_if(list.begin(), list.end(), [](const auto& o) { return o.reply_due; });
        const auto now = std::chrono::steady_clock::now();
        if (due == list.end() || now >= until) break;
        // Listens as for the oldest due request's reply; a reply to another owed request is heard too. The
        // device answers in order: the oldest first.
        const auto sent = due->sent;
        const auto heard =
            client.raw({}, std::chrono::duration_cast<std::chrono::microseconds>(until - now), 1, sent);
        if (heard.received.empty()) break;
        const std::size_t before = settled.size();
        const auto unexplained = owed.settle_frames(client.framing(), heard.received, settled);
        rest.insert(rest.end(), unexplained.begin(), unexplained.end());
        if (settled.size() == before) break;  // nothing owed was answered: the line says something else
    }
    return rest;
}

std::optional<modbus::Frame> step_request(modbus::Framing framing, const Step& step) {
    if (framing == modbus::Framing::Tcp || step.void_by_gap) return std::nullopt;
    auto frame = modbus::decode_adu(framing, step.joined());
    if (!frame) return std::nullopt;
    return std::move(frame).value();
}

std::vector<conformance::OracleViolation> late_bytes(conformance::ExchangeOracle& oracle,
                                                     modbus::Framing framing,
                                                     const modbus::transport::Exchange& previous,
                                                     std::vector<std::uint8_t> bytes) {
    if (bytes.empty()) return {};
    // Judged as the reply it is: a late answer the rules allow (a gateway's exception 0B) is no finding.
    auto frame = modbus::decode_adu(framing, bytes);
    std::optional<modbus::Frame> response;
    if (frame) response = std::move(frame).value();
    return judge_late(oracle, previous, std::move(bytes), std::move(response),
                      "after the request was given up: ");
}

std::vector<conformance::OracleViolation> judge_late_frame(conformance::ExchangeOracle& oracle,
                                                           const modbus::transport::Exchange& request,
                                                           const modbus::Frame& reply,
                                                           std::string_view when) {
    return judge_late(oracle, request, std::vector<std::uint8_t>(reply.adu().begin(), reply.adu().end()),
                      reply, when);
}

std::vector<conformance::OracleViolation> repeated_reply(const modbus::transport::Exchange& previous,
                                                         std::span<const std::uint8_t> later,
                                                         std::string_view when) {
    if (!previous.response || !modbus::transport::repeats_reply(*previous.response, later)) return {};
    return {{"reply.duplicate", "SL §2.1, AP §4.1", "one reply to one request",
             std::string(when) + "the reply again, " + modbus::hex_bytes(previous.response->adu())}};
}

bool reply_may_come(const modbus::transport::Exchange& ex) {
    return ex.own_received().empty() || ex.timed_out || !ex.response || !ex.response->checksum_ok;
}

std::vector<ReplayedStep> replay(modbus::transport::Client& client, conformance::ExchangeOracle& oracle,
                                 const std::vector<Step>& steps, const ReplayOptions& options) {
    std::vector<ReplayedStep> out;
    const auto framing = client.framing();
    modbus::transport::OwedRequests owed;  // RTU and ASCII: steps given up, whose replies may still come
    std::vector<modbus::transport::SettledRequest> settled;
    Unanswered unanswered;  // Modbus/TCP: the same, told apart by their transaction ids (unanswered.hpp)
    Unanswered::Claims claimed;
    // A late reply judged as the reply of the step it answers: the latest step that sent its request.
    const auto judge_as_step = [&](const auto& sent, const modbus::Frame& reply, std::string_view when) {
        const auto step = std::find_if(out.rbegin(), out.rend(),
                                       [&](const ReplayedStep& r) { return r.exchange.sent == sent; });
        if (step == out.rend()) return;
        step->late_replies.push_back(reply);
        const auto found = judge_late_frame(oracle, step->exchange, reply, when);
        step->violations.insert(step->violations.end(), found.begin(), found.end());
    };
    // Every late reply matched to its request so far: settled (RTU, ASCII) or claimed (Modbus/TCP).
    const auto judge_settled = [&](std::string_view when) {
        for (const auto& s : std::exchange(settled, {}))
            judge_as_step(s.request.sent, s.reply, when);
        for (const auto& c : std::exchange(claimed, {}))
            judge_as_step(c.first.exchange.sent, c.second, when);
    };
    // Bytes no owed step accounts for: the last step's reply, too late; after its reply, that reply again
    // (as the campaign judges them).
    const auto judge_rest = [&](std::vector<std::uint8_t> bytes) {
        auto& last = out.back();
        const auto found = reply_may_come(last.exchange)
                               ? late_bytes(oracle, framing, last.exchange, std::move(bytes))
                               : repeated_reply(last.exchange, bytes, "after the reply: ");
        last.violations.insert(last.violations.end(), found.begin(), found.end());
    };
    const auto late = [&] {
        if (out.empty()) return;
        auto bytes = client.drain(std::chrono::milliseconds(0));
        bytes = framing == modbus::Framing::Tcp ? unanswered.claim_frames(bytes, claimed)
                                                : owed.settle_frames(framing, bytes, settled);
        judge_settled("after the request was given up: ");
        judge_rest(std::move(bytes));
    };
    unsigned quiet_waits = 0;  // OwedRequests::quiet_waits_kept
    for (const auto& step : steps) {
        if (options.stop && options.stop->load()) break;
        late();
        const auto request = step_request(framing, step);
        // RTU and ASCII: a late reply that this step's request could draw too is waited out first, as the
        // campaign does: only its timing would tell it from the step's own.
        if (request && quiet_waits < modbus::transport::OwedRequests::quiet_waits_kept &&
            owed.owes_reply_like(request->unit_id(), request->pdu())) {
            auto rest = await_owed(client, owed, owed.newest_given_up() + options.timeout, settled);
            quiet_waits = settled.empty() && rest.empty() ? quiet_waits + 1 : 0;
            judge_settled("after the request was given up: ");
            judge_rest(std::move(rest));
        }
        const auto sent = std::chrono::steady_clock::now();
        auto done = send_step(client, oracle, step, options, owed.list());
        if (done.interrupted) {
            // Stopped between the step's pieces. Over Modbus/TCP the piece sent would run into the next
            // request on the connection (the restore's): a new connection drops it. A serial device drops it
            // at the silence that follows.
            if (framing == modbus::Framing::Tcp) (void)client.reconnect();
            break;
        }
        out.push_back(std::move(done));
        const auto& ex = out.back().exchange;
        // As the campaign judges a slow target: the first byte of the step's own reply past the limit.
        if (options.slow.count() && !ex.own_received().empty() && ex.first_byte > options.slow)
            out.back().violations.push_back(
                {"timing.slow_reply", options.slow_source,
                 "a reply within " + std::to_string(options.slow.count()) + " ms",
                 "a reply after " + std::to_string(ex.first_byte.count() / 1'000'000) + " ms"});
        if (framing == modbus::Framing::Tcp) {
            for (const auto& frame : ex.stale_replies) {
                if (unanswered.claim(frame, claimed) || out.size() < 2) continue;
                auto& previous = out[out.size() - 2];
                const auto found = repeated_reply(previous.exchange, frame.adu(), "during a later request: ");
                previous.violations.insert(previous.violations.end(), found.begin(), found.end());
            }
            if (ex.closed || step.reconnect_after)
                unanswered.clear();  // no reply can come over a connection that is gone
            else if (!ex.response)
                unanswered.add(ex, sent, std::chrono::steady_clock::now(), out.back().reply_due);
        } else {
            (void)owed.after(ex, request ? request->unit_id() : 0,
                             request ? request->pdu() : std::span<const std::uint8_t>{}, &settled,
                             out.back().reply_due);
        }
        judge_settled("during a later request: ");
        if (step.reconnect_after) (void)client.reconnect();
    }
    std::this_thread::sleep_for(std::min(options.timeout, std::chrono::milliseconds(50)));
    late();
    // Replies still due are waited for (up to a timeout), so that none comes during what follows (the
    // campaign's next request, the next replay while minimising), where nothing could tell it: over RTU and
    // ASCII nothing tells whose reply a frame is, and over Modbus/TCP the next replay resends the same
    // transaction ids.
    if (!out.empty()) {
        auto rest =
            framing == modbus::Framing::Tcp
                ? unanswered.await_due(client, options.timeout, claimed)
                : await_owed(client, owed, std::chrono::steady_clock::now() + options.timeout, settled);
        judge_settled("after the request was given up: ");
        judge_rest(std::move(rest));
    }
    return out;
}

bool breaks(const std::vector<ReplayedStep>& replayed, const std::string& rule) {
    return std::any_of(replayed.begin(), replayed.end(), [&](const ReplayedStep& s) {
        return std::any_of(s.violations.begin(), s.violations.end(),
                           [&](const auto& v) { return v.rule == rule; });
    });
}

}  // namespace mbscope::fuzz::network
