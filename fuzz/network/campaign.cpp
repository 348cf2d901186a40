#include "fuzz/network/campaign.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <ranges>
#include <set>
#include <span>
#include <thread>

#include "conformance/report.hpp"
#include "fuzz/network/generator.hpp"
#include "fuzz/network/reply_latency.hpp"
#include "fuzz/network/unanswered.hpp"
#include "fuzz/network/written_points.hpp"
#include "modbus/addressing.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::fuzz::network {

namespace {

using Clock = std::chrono::steady_clock;
using Location = std::pair<modbus::Table, std::uint16_t>;  // a table and an address
using modbus::Table;
using modbus::transport::Exchange;

constexpr std::size_t trace_capacity = 32;  // steps kept since the last known-good state
constexpr int health_attempts = 3;          // health checks before a target counts as unresponsive

// FNV-1a (64 bits) over a request as written: each piece's length, then its bytes, so that a split request
// differs from the same bytes written whole.
std::uint64_t fnv1a(std::uint64_t h, std::span<const std::uint8_t> piece) {
    const auto mix = [&h](std::uint8_t b) {
        h ^= b;
        h *= 0x100000001B3ull;
    };
    mix(static_cast<std::uint8_t>(piece.size() >> 8));
    mix(static_cast<std::uint8_t>(piece.size()));
    for (const std::uint8_t b : piece)
        mix(b);
    return h;
}

// The reply's PDU, when a frame came back.
std::optional<std::vector<std::uint8_t>> reply_pdu(const Exchange& ex) {
    if (!ex.response) return std::nullopt;
    const auto p = ex.response->pdu();
    return std::vector<std::uint8_t>(p.begin(), p.end());
}

class Campaign {
  public:
    Campaign(const modbus::Profile& profile, const CampaignOptions& options,
             modbus::transport::Client& client)
        : profile_(profile),
          options_(options),
          client_(client),
          framing_(modbus::transport::framing_of(options.endpoint.scheme)),
          serial_line_(modbus::transport::is_serial(options.endpoint.scheme)),
          ip_network_(options.endpoint.scheme == modbus::transport::Scheme::Tcp ||
                      options.endpoint.scheme == modbus::transport::Scheme::Udp),
          oracle_(framing_, {{options.unit, &profile}}, ip_network_),
          session_(client, conformance::SessionOptions{options.unit, options.timeout, options.interval},
                   &profile),
          generator_(profile, GeneratorOptions{framing_, serial_line_, options.endpoint.line.t1_5(),
                                               options.unit, options.read_only, options.seed,
                                               options.endpoint.scheme == modbus::transport::Scheme::Udp}) {
        slow_ = options.slow.count()
                    ? options.slow
                    : std::chrono::milliseconds(profile.line.response_timeout_ms.value_or(250));
        if (serial_line_)  // the longest frame's transmission on top
            slow_ += std::chrono::duration_cast<std::chrono::milliseconds>(
                options.endpoint.line.character_time() * 2 * modbus::max_rtu_adu_length);
        health_ = health_request();
        rng_.seed(options.seed ^ 0x9E3779B97F4A7C15ull);
        for (const auto& p : profile.table(Table::HoldingRegisters))
            if (p.access == modbus::Access::ReadWrite && !p.reserved && !p.momentary && !p.fixed_value)
                rewritable_.push_back(&p);
        std::shuffle(rewritable_.begin(), rewritable_.end(), rng_);
        session_.share_owed(owed_);
        // The probes go out over the session's client, not through it: each is told to it
        // (note_step_writes), so that the restore puts back only what the run changed.
        session_.watch_writes();
        replay_.timeout = options.timeout;
        // A serial device may keep the line quiet for t3.5 before it answers.
        if (serial_line_)
            silence_floor_ += std::chrono::ceil<std::chrono::microseconds>(options.endpoint.line.t3_5());
    }

    CampaignSummary run();

  private:
    std::vector<std::uint8_t> health_request() const;
    Step frame(const Probe& p);
    ReplayedStep send(const Step& step, std::chrono::milliseconds timeout);
    std::chrono::microseconds silence_wait() const;
    std::chrono::microseconds probe_silence_wait(const Step& step) const;
    void judge_claimed(std::string_view when);
    void judge_settled(std::vector<modbus::transport::SettledRequest> settled, std::string_view when);
    void wait_out_owed(const modbus::Frame& request, std::chrono::milliseconds timeout);
    bool await_due_replies(std::chrono::milliseconds timeout);
    void judge_arrivals();
    bool last_unanswered() const;
    // `strict`: only a frame counts (the run's first check: a target that answers bytes that form no
    // frame was never shown to be a Modbus slave at all).
    bool healthy(std::chrono::nanoseconds* latency = nullptr, bool strict = false);
    // Whether a write in `p` can land: addressed to the unit, broadcast, or to any unit over Modbus/TCP
    // (devices that ignore the unit id are common there).
    bool lands(const Probe& p) const { return lands(p.unit); }
    bool lands(std::uint8_t unit) const {
        return framing_ == modbus::Framing::Tcp || unit == options_.unit || unit == 0;
    }
    bool prepare_writes(const Probe& p);
    // The reads prepare_writes would send before `p` (none unless it writes where a write can land).
    std::size_t reads_before(const Probe& p) const;
    // With a polling interval every request is paced: whether `reads` reads and then the step itself would
    // all go out before --duration ends.
    bool fits_before_deadline(std::size_t reads) const;
    bool keep_line_settings(Probe& p);
    bool remember_before_write(const WriteRange& range, const std::function<bool()>& read);
    void note_unread(const modbus::transport::Exchange& ex);
    void read_unanswered_writes();
    void note_late_acknowledgement(std::uint8_t unit, std::span<const std::uint8_t> request_pdu,
                                   const modbus::Frame& reply);
    // Replays `steps` (a minimisation's) with `oracle`; what their writes did goes into the session's ledger
    // as the probes' does (note_step_writes): the device may answer them otherwise than it did the probes.
    std::vector<ReplayedStep> replay_steps(const std::vector<Step>& steps,
                                           conformance::ExchangeOracle& oracle);
    // The ledger after the run: what the restore did, and the points it could not vouch for (doubtful_).
    void list_restored();
    std::optional<Probe> round_trip();
    void pace();
    void classify(const Probe& p, const ReplayedStep& r);
    // `before`: steps from before the trace the finding needs (the write a lost write was made by);
    // `kept`: steps the minimisation may not drop (every write that set a point the read reads).
    void record(const conformance::OracleViolation& v, std::uint8_t fc, bool replayable,
                const std::vector<Step>& before = {}, const std::vector<Step>& kept = {});
    std::vector<Step> minimise(const std::string& rule, std::vector<Step> window,
                               const std::vector<Step>& kept, bool& reproduced,
                               std::optional<bool>& on_new_connection);
    struct WrittenBy;
    // The acknowledged writes that last set the points a read reads, in the order they were sent.
    std::vector<const WrittenBy*> writers_of(std::span<const std::uint8_t> read_pdu) const;
    // Those of them no longer in the trace.
    std::vector<Step> writes_before_trace(std::span<const std::uint8_t> read_pdu) const;
    conformance::OracleViolation slow_reply(std::chrono::nanoseconds first,
                                            std::chrono::nanoseconds second) const;
    void progress(bool force = false);
    bool done() const;

    const modbus::Profile& profile_;
    const CampaignOptions& options_;
    modbus::transport::Client& client_;
    modbus::Framing framing_;
    bool serial_line_;
    bool ip_network_;
    conformance::ExchangeOracle oracle_;
    conformance::Session session_;
    Generator generator_;
    Unanswered unanswered_;  // Modbus/TCP: requests whose reply, if any comes, is still to be judged
    // Late replies matched to their kept requests, to be judged; all are claimed before any is judged, as
    // judging may minimise a reproducer, which gives up every kept request.
    Unanswered::Claims claimed_;
    std::uint64_t minimised_ = 0;  // reproducers minimised (their replays resend old transaction ids)
    // RTU and ASCII: no transaction id says which request a reply answers. Requests given up with nothing
    // back are owed (exchange.hpp): a reply that comes later, between exchanges or during one (the client
    // sets it aside when it could answer an owed request and not the current one), is judged as the owed
    // request's. A request that could draw the same reply as an owed one that was due first waits that
    // reply out, as the conformance session does.
    modbus::transport::OwedRequests owed_;
    unsigned quiet_waits_ = 0;  // OwedRequests::quiet_waits_kept
    // Late replies with their owed requests, to be judged (as claimed_: judging may minimise a reproducer,
    // which waits out the owed replies first and leaves what it heard here), each with when it came.
    std::vector<std::pair<modbus::transport::SettledRequest, std::string_view>> settled_;
    // Bytes heard while waiting out due replies before a minimisation that answer no request given up: the
    // last exchange's reply, too late, judged with the next arrivals (judging them there could minimise).
    std::vector<std::uint8_t> heard_unexplained_;
    ReplayOptions replay_;
    std::chrono::milliseconds slow_{250};
    ReplyLatency latency_;  // of the target's replies: the silence wait when none was given
    // At least this: the scheduler's wake-up and a loaded machine's delays are in the tens of microseconds.
    std::chrono::microseconds silence_floor_{200};
    std::vector<std::uint8_t> health_;
    CampaignSummary s_;
    std::deque<Step> trace_;
    // The step of the last acknowledged write to each point, with its request's number: a lost write shows
    // on a read after a health check cleared the trace, and its reproducer needs the write.
    struct WrittenBy {
        std::uint64_t request = 0;
        Step step;
    };
    std::map<std::pair<Table, std::uint16_t>, std::shared_ptr<const WrittenBy>> written_by_;
    std::set<std::string> classes_;
    std::map<std::string, std::size_t> finding_index_;  // rule + function -> index in s_.findings
    Clock::time_point start_{}, last_send_{}, last_progress_{};
    std::optional<Probe> follow_up_;
    std::mt19937_64 rng_;
    std::vector<const modbus::Point*> rewritable_;  // holding registers a master may read and write
    // Points the probe about to be sent may write that were not read first (outside the map, a read that
    // failed); write-only points are not among them (written_points.hpp, remember_range).
    std::vector<Location> unread_;
    // Points a write not refused may have changed before they were read: a value read there later may be
    // one the fuzzer wrote, not the device's own, so restoring it would not put the device back.
    std::set<Location> unknown_;
    std::set<Location> doubtful_;  // read for the first time after such a write
    std::set<Location> not_read_;  // reached by writes the device acknowledged (CampaignSummary::not_read)
    std::size_t next_round_trip_ = 0;
    std::uint8_t last_function_ = 0;
    std::optional<modbus::transport::Exchange> last_;  // the previous probe's exchange
    bool health_passed_ = false;                       // a health check passed since the trace was cleared
};

std::vector<std::uint8_t> Campaign::health_request() const {
    // A read of one point the map says exists and is readable: any device following its manual answers it
    // normally, whatever the fuzzer sent before.
    for (const Table t :
         {Table::HoldingRegisters, Table::InputRegisters, Table::Coils, Table::DiscreteInputs}) {
        const std::uint8_t fc = t == Table::HoldingRegisters ? 3
                                : t == Table::InputRegisters ? 4
                                : t == Table::Coils          ? 1
                                                             : 2;
        if (!profile_.functions.supports(fc) || !profile_.implements(t)) continue;
        for (const auto& p : profile_.table(t))
            if (p.access != modbus::Access::Write && !modbus::check_read(profile_, t, p.address, 1))
                return modbus::encode_pdu(
                    modbus::make_read_request(static_cast<modbus::FunctionCode>(fc), p.address, 1));
    }
    return modbus::encode_pdu(modbus::make_read_request(modbus::FunctionCode::ReadHoldingRegisters, 0, 1));
}

Step Campaign::frame(const Probe& p) {
    const std::uint16_t tid = client_.next_transaction_id();
    client_.set_transaction_id(static_cast<std::uint16_t>(tid + 1));
    const Wire w = frame_probe(p, framing_, tid);
    Step step;
    step.parts = w.parts;
    step.pause = w.pause;
    step.reconnect_after = p.envelope == Envelope::MbapLength && !serial_line_ &&
                           options_.endpoint.scheme != modbus::transport::Scheme::Udp;
    // Only RTU delimits frames by silence (SL §2.5.1.1): an ASCII frame may pause up to a second between
    // characters (SL §2.5.2.1), so a split one is a request the device must answer.
    step.void_by_gap = serial_line_ && framing_ == modbus::Framing::Rtu && w.parts.size() > 1 &&
                       w.pause > options_.endpoint.line.t1_5();
    step.recipe = p.recipe;
    return step;
}

ReplayedStep Campaign::send(const Step& step, std::chrono::milliseconds timeout) {
    ReplayOptions o = replay_;
    o.timeout = timeout;
    o.silence_wait = probe_silence_wait(step);
    const auto request = step_request(framing_, step);
    if (request) wait_out_owed(*request, timeout);
    const auto sent = Clock::now();
    const auto minimised = minimised_;
    auto r = send_step(client_, oracle_, step, o, owed_.list());
    last_send_ = Clock::now();
    note_step_writes(session_, step, r);
    // The latency of this request's own reply: late replies to earlier ones are not its.
    if (!r.exchange.own_received().empty()) latency_.add(r.exchange.first_byte);
    if (framing_ != modbus::Framing::Tcp) {
        std::vector<modbus::transport::SettledRequest> settled;
        (void)owed_.after(r.exchange, request ? request->unit_id() : 0,
                          request ? request->pdu() : std::span<const std::uint8_t>{}, &settled, r.reply_due);
        judge_settled(std::move(settled), "during a later request: ");
    } else {
        for (const auto& frame : r.exchange.stale_replies)
            if (!unanswered_.claim(frame, claimed_) && last_)
                for (const auto& v : repeated_reply(*last_, frame.adu(), "during a later request: "))
                    record(v, last_function_, true);
        judge_claimed("during a later request: ");
        if (r.exchange.closed)
            unanswered_.clear();
        else if (!r.exchange.response && minimised_ == minimised)
            unanswered_.add(r.exchange, sent, Clock::now(), r.reply_due);
    }
    return r;
}

std::chrono::microseconds Campaign::silence_wait() const {
    if (options_.silence_wait) return *options_.silence_wait;
    return latency_.silence_wait(silence_floor_, options_.timeout);
}

// Where the rules demand silence: the wait given; else, over Modbus/TCP, none: a reply that comes anyway is
// matched to its request by its transaction id when it arrives (unanswered.hpp), unless the connection is
// dropped after the step; else the wait learnt from the replies.
std::chrono::microseconds Campaign::probe_silence_wait(const Step& step) const {
    if (options_.silence_wait) return *options_.silence_wait;
    if (framing_ == modbus::Framing::Tcp && !step.reconnect_after) return std::chrono::microseconds(0);
    return silence_wait();
}

// Each claimed reply judged as its request's.
void Campaign::judge_claimed(std::string_view when) {
    for (const auto& [request, reply] : std::exchange(claimed_, {})) {
        ++s_.late_replies;
        if (request.reply_due) ++s_.replies_after_timeout;
        const std::uint8_t fc = request.exchange.sent.size() > 7 ? request.exchange.sent[7] : 0;
        if (request.exchange.sent.size() > 7)
            note_late_acknowledgement(request.exchange.sent[6],
                                      std::span<const std::uint8_t>(request.exchange.sent).subspan(7), reply);
        for (const auto& v : judge_late_frame(oracle_, request.exchange, reply, when))
            record(v, fc, true);
    }
}

// RTU and ASCII: each late reply judged as the reply of the owed request it answers (`settled`, and any
// left by a minimisation); `when` says when these came.
void Campaign::judge_settled(std::vector<modbus::transport::SettledRequest> settled, std::string_view when) {
    if (!settled.empty()) quiet_waits_ = 0;
    for (auto& s : settled)
        settled_.emplace_back(std::move(s), when);
    for (const auto& [s, came] : std::exchange(settled_, {})) {
        ++s_.late_replies;
        if (s.request.reply_due) ++s_.replies_after_timeout;
        modbus::transport::Exchange request;
        request.sent = s.request.sent;
        note_late_acknowledgement(s.request.unit, s.request.pdu, s.reply);
        for (const auto& v : judge_late_frame(oracle_, request, s.reply, came))
            record(v, s.request.pdu.empty() ? 0 : s.request.pdu[0], true);
    }
}

// RTU and ASCII: before a request that could draw the same reply as an owed one that was due (the same
// function, or one whose exception shares its code, as 0x84 does with 04; the same unit or a broadcast),
// that reply is waited for, up to `timeout` after the owed request was given up:
// it is told from this request's own only by its timing. After quiet_waits_kept waits that saw nothing in a
// row the target is taken to drop replies, and this waits no more until a late reply shows again.
void Campaign::wait_out_owed(const modbus::Frame& request, std::chrono::milliseconds timeout) {
    if (quiet_waits_ >= modbus::transport::OwedRequests::quiet_waits_kept) return;
    if (!owed_.owes_reply_like(request.unit_id(), request.pdu())) return;
    if (!await_due_replies(timeout)) ++quiet_waits_;
}

// RTU and ASCII: the replies still due are waited for, up to `timeout` after the newest owed request was
// given up, and judged as their requests'. Before a request that could draw the same reply (above), and
// before the session reads a point's original value for restoring (a late FC3 reply and the session's
// FC3 read of one register have the same shape). Whether anything was heard.
bool Campaign::await_due_replies(std::chrono::milliseconds timeout) {
    if (framing_ == modbus::Framing::Tcp || owed_.empty()) return false;
    std::vector<modbus::transport::SettledRequest> settled;
    auto rest = await_owed(client_, owed_, owed_.newest_given_up() + timeout, settled);
    const bool heard = !settled.empty() || !rest.empty();
    judge_settled(std::move(settled), "after the request was given up: ");
    // Bytes no owed request accounts for (no whole frame, a bad checksum): the last exchange's, too late.
    if (!rest.empty() && last_unanswered())
        for (const auto& v : late_bytes(oracle_, framing_, *last_, std::move(rest)))
            record(v, last_function_, true);
    return heard;
}

// Whether a reply to the last request may still come: no whole, valid one came.
bool Campaign::last_unanswered() const {
    return last_ && reply_may_come(*last_);
}

// Whatever arrived since the last exchange ended (nothing is waited for). Over Modbus/TCP each whole frame
// is the reply of the kept request whose transaction id it carries, over RTU and ASCII of the owed request
// it could answer; what is left is the last exchange's reply, too late.
void Campaign::judge_arrivals() {
    auto bytes = std::exchange(heard_unexplained_, {});
    const auto drained = client_.drain(std::chrono::milliseconds(0));
    bytes.insert(bytes.end(), drained.begin(), drained.end());
    if (framing_ != modbus::Framing::Tcp && !owed_.empty()) {
        std::vector<modbus::transport::SettledRequest> settled;
        bytes = owed_.settle_frames(framing_, bytes, settled);
        judge_settled(std::move(settled), "after the request was given up: ");
    }
    if (framing_ == modbus::Framing::Tcp) bytes = unanswered_.claim_frames(bytes, claimed_);
    judge_claimed("after the request was given up: ");
    if (!last_) return;  // no exchange yet: nothing the bytes could be judged against
    if (!last_unanswered()) {
        // Answered: the same reply again is the request answered twice; any other rest is no one's reply
        // the rules can name (what a step holding more than one request may draw).
        for (const auto& v : repeated_reply(*last_, bytes, "after the reply: "))
            record(v, last_function_, true);
        return;
    }
    for (const auto& v : late_bytes(oracle_, framing_, *last_, std::move(bytes)))
        record(v, last_function_, true);
}

bool Campaign::healthy(std::chrono::nanoseconds* latency, bool strict) {
    const auto late_before = s_.late_replies;
    for (int attempt = 0; attempt < health_attempts; ++attempt) {
        ++s_.health_checks;
        Probe p;
        p.unit = options_.unit;
        p.pdu = health_;
        p.recipe = "health check";
        const auto r = send(frame(p), options_.timeout);
        if (r.exchange.closed) {
            if (!client_.reconnect()) return false;
            continue;
        }
        // Alive is answering at all, if late (the reply to an earlier attempt, heard while waiting it out
        // or during this one): whether the answer keeps the rules is the probes' business. A late reply's
        // latency is at least the timeout it missed. At the start, over Modbus/TCP, the answer must be a
        // frame its MBAP header delimits, whatever it holds (wrong unit, function, transaction or protocol
        // id are what the probes are for): bytes that form none were never shown to come from a Modbus
        // slave. On a serial framing the line's silence ends any bytes, and a faulty reply is told from
        // noise by no rule the probes do not apply themselves (extra bytes inside a valid CRC).
        const bool normal = framing_ != modbus::Framing::Tcp
                                ? !r.exchange.received.empty()
                                : r.exchange.response && !r.exchange.response->pdu().empty();
        const bool late = s_.late_replies > late_before;  // a frame, set aside as an earlier attempt's
        if (late || (strict ? normal : !r.exchange.received.empty())) {
            if (latency)
                *latency = !r.exchange.own_received().empty()
                               ? r.exchange.first_byte
                               : std::chrono::duration_cast<std::chrono::nanoseconds>(options_.timeout);
            health_passed_ = true;
            return true;
        }
        (void)client_.drain(std::chrono::milliseconds(10));
    }
    return false;
}

std::size_t Campaign::reads_before(const Probe& p) const {
    const auto range = write_range(p.pdu);
    if (!range || range->count == 0 || !lands(p)) return 0;
    return reads_to_remember(session_, profile_, *range);
}

bool Campaign::fits_before_deadline(std::size_t reads) const {
    if (!options_.duration || options_.interval.count() == 0) return true;
    // The first probe goes out whatever the budget when it needs no reads: a run sends at least one.
    if (s_.requests == 0 && reads == 0) return true;
    const auto first = std::max(Clock::now(), last_send_ + options_.interval);
    return first + options_.interval * static_cast<long>(reads) <= start_ + *options_.duration;
}

bool Campaign::prepare_writes(const Probe& p) {
    unread_.clear();
    const auto range = write_range(p.pdu);
    if (!range || range->count == 0 || !lands(p)) return true;
    // A write the device's own rules let through (a function it supports, a quantity within its limits) is
    // sent only once its points are read. One they forbid is sent whatever (the device must refuse it: that
    // is the test), its points read first all the same where the device lets them be read, so that a device
    // executing it anyway is put back too, not only reported.
    const std::uint8_t fc = p.pdu[0];
    const int max = profile_.functions.max_for(fc, fc == 23);
    const bool allowed = profile_.functions.supports(fc) && !(max > 0 && range->count > max);
    const bool ok = remember_before_write(*range, [&] { return remember_range(session_, profile_, *range); });
    if (!ok && allowed) return false;
    const auto missing = points_not_read(session_, profile_, *range);
    unread_.insert(unread_.end(), missing.begin(), missing.end());
    return true;
}

// A point mirroring a line setting (the unit address, the speed, the framing) given another value takes
// the device off the line, the fuzzer's and its real master's: a real MK device obeys a valid one at once.
// Like FC8 03 and 04 (Generator::allowed), such a value is never sent; the write goes out with the value
// the point holds, read just before (prepare_writes), so its shape is still tried.
bool Campaign::keep_line_settings(Probe& p) {
    if (profile_.open_address_space) return true;
    // A mirror whose value could not be read first: what to keep is unknown, and the write is not sent.
    if (const auto range = write_range(p.pdu); range && range->table == Table::HoldingRegisters)
        for (std::uint32_t a = range->start; a < range->end(); ++a) {
            const auto* point = profile_.find(Table::HoldingRegisters, static_cast<std::uint16_t>(a));
            if (point && point->mirrors &&
                !session_.touched().count({Table::HoldingRegisters, static_cast<std::uint16_t>(a)}))
                return false;
        }
    const auto kept = keep_registers(p.pdu, [&](std::uint16_t address) -> std::optional<std::uint16_t> {
        const auto* point = profile_.find(Table::HoldingRegisters, address);
        if (!point || !point->mirrors) return std::nullopt;
        const auto held = session_.touched().find({Table::HoldingRegisters, address});
        if (held == session_.touched().end()) return std::nullopt;
        return held->second.original;
    });
    if (kept) {
        p.recipe += " (line settings kept)";
        ++s_.line_settings_kept;
    }
    return true;
}

// Reads, with `read`, the original values of what a write to `range` may change, once no reply is due that
// the read could take for its own. A point first read now after an unread write may have reached it
// (unknown_) holds the fuzzer's value, not the device's: doubtful, never called restored.
bool Campaign::remember_before_write(const WriteRange& range, const std::function<bool()>& read) {
    (void)await_due_replies(options_.timeout);
    std::vector<Location> unknown;
    for (std::uint32_t a = range.start; a < range.end() && !unknown_.empty(); ++a) {
        const Location point{range.table, static_cast<std::uint16_t>(a)};
        if (unknown_.count(point) && !session_.touched().count(point)) unknown.push_back(point);
    }
    const bool ok = read();
    for (const auto& point : unknown)
        if (session_.touched().count(point)) doubtful_.insert(point);
    (void)session_.take_evidence();
    session_.forget_times();
    return ok;
}

// After a probe whose points were not all read first: unless the device refused it, those points may have
// changed; where it acknowledged it, they did, and the summary lists them.
void Campaign::note_unread(const modbus::transport::Exchange& ex) {
    if (unread_.empty()) return;
    const auto reply = reply_pdu(ex);
    const bool answered = reply && !reply->empty();
    if (answered && (reply->front() & 0x80)) return;
    for (const auto& point : unread_) {
        unknown_.insert(point);
        if (answered) not_read_.insert(point);
    }
}

// When the run ends: the points writes that drew no reply reached unread (unknown_, neither acknowledged nor
// read since), read to see which the device holds (CampaignSummary::unanswered_writes); those no read could
// tell about, and all of them when the target was lost (it is not sent anything more), are listed unread.
void Campaign::read_unanswered_writes() {
    std::set<Location> points;
    for (const auto& point : unknown_)
        if (!not_read_.count(point) && !session_.touched().count(point)) points.insert(point);
    if (s_.target_lost) {
        s_.unanswered_unread = ranges_of(points);
        return;
    }
    // An interrupt that stopped the fuzzing asks for the read-back too; one more ends it. After a run that
    // ended by its budget, the first ends it.
    const auto stop_set = [](const std::atomic<bool>* flag) { return flag && flag->load(); };
    const bool stopping = stop_set(options_.stop);
    ReadHeldLimits limits;
    limits.single_reads = single_reads_within_a_minute(options_.interval);
    limits.interrupted = [&] {
        return stop_set(options_.stop_again) || (!stopping && stop_set(options_.stop));
    };
    if (options_.note && !points.empty()) {
        const auto ranges = ranges_of(points).size();
        std::string text = "reading back " + std::to_string(points.size()) + " points in " +
                           std::to_string(ranges) + (ranges == 1 ? " range" : " ranges") +
                           " that writes without a reply reached";
        if (options_.interval.count() > 0)
            text += ", a request every " + std::to_string(options_.interval.count()) +
                    " ms (the polling interval)";
        if (options_.stop)
            text += std::string("; interrupt") + (stopping ? " again" : "") +
                    " to skip it (the restore after it still runs)";
        options_.note(text);
    }
    auto reading = read_held(session_, points, limits);
    s_.unanswered_writes = std::move(reading.held);
    s_.unanswered_unread = std::move(reading.unread);
    s_.unanswered_refused = std::move(reading.refused);
    s_.read_back_interrupted = reading.interrupted;
}

// A write's acknowledgement that came after its exchange ended (matched to it by transaction id, over RTU
// and ASCII by what it answers): a reply after --timeout, or over Modbus/TCP one to a request the rules want
// unanswered (another unit, which a device ignoring the unit id executes), which is not waited for at all.
// The points it reached that were not read first changed as surely as with a prompt acknowledgement.
void Campaign::note_late_acknowledgement(std::uint8_t unit, std::span<const std::uint8_t> request_pdu,
                                         const modbus::Frame& reply) {
    if (lands(unit)) note_late_answer(session_, request_pdu, reply);
    if (unknown_.empty() || !reply.checksum_ok) return;
    const auto range = write_range(request_pdu);
    if (!range || !acknowledges(request_pdu, reply.pdu())) return;
    for (std::uint32_t a = range->start; a < range->end(); ++a) {
        const Location point{range->table, static_cast<std::uint16_t>(a)};
        if (unknown_.count(point) && !session_.touched().count(point)) not_read_.insert(point);
    }
}

// A write to one point a master may read and write, read just before: either the value it holds (always
// in range, so it is acknowledged) or another value its map allows. The read-back that follows must return
// what was written: a swapped, misplaced, stuck or lost write shows there. The points are taken in turn (in
// an order drawn from the seed), so a fault at one address is reached in a bounded number of requests.
std::optional<Probe> Campaign::round_trip() {
    if (rewritable_.empty()) return std::nullopt;
    const modbus::Point& point = *rewritable_[next_round_trip_++ % rewritable_.size()];
    const std::uint16_t words = point.encoding.words == 2 ? 2 : 1;
    const bool ok = remember_before_write({Table::HoldingRegisters, point.address, words}, [&] {
        return session_.remember(Table::HoldingRegisters, point.address, words);
    });
    if (!ok) return std::nullopt;
    std::vector<std::uint16_t> values;
    for (std::uint16_t i = 0; i < words; ++i)
        values.push_back(session_.touched()
                             .at({Table::HoldingRegisters, static_cast<std::uint16_t>(point.address + i)})
                             .original);
    Probe p;
    p.unit = options_.unit;
    p.recipe = "write back the value read";
    if (words == 1 && rng_() % 2) {
        std::vector<std::int64_t> allowed;
        for (const auto& v : point.encoding.values)
            if (!v.forbidden) allowed.push_back(v.value);
        if (point.min && point.max && *point.max > *point.min)
            allowed.insert(allowed.end(), {*point.min, *point.max});
        std::erase(allowed, static_cast<std::int64_t>(values[0]));
        if (!allowed.empty()) {
            values[0] = static_cast<std::uint16_t>(allowed[rng_() % allowed.size()]);
            p.recipe = "write another value the map allows";
        }
    }
    p.pdu = words == 2 && profile_.functions.supports(16)
                ? modbus::encode_pdu(modbus::make_write_multiple_registers(point.address, values))
                : modbus::encode_pdu(modbus::make_write_single_register(point.address, values[0]));
    return p;
}

void Campaign::pace() {
    if (options_.interval.count() == 0) return;
    const auto next = last_send_ + options_.interval;
    if (Clock::now() < next) std::this_thread::sleep_until(next);
}

void Campaign::classify(const Probe& p, const ReplayedStep& r) {
    std::string outcome;
    const auto pdu = reply_pdu(r.exchange);
    // Late replies to earlier requests that came during this exchange are theirs (judge_settled,
    // Unanswered::claim).
    if (r.exchange.own_received().empty()) {
        outcome = "silence";
        ++s_.silences;
    } else if (!pdu || pdu->empty()) {
        outcome = "unframed reply";
        ++s_.replies;
    } else if (pdu->front() & 0x80) {
        char b[16];
        std::snprintf(b, sizeof b, "exception %02X", pdu->size() > 1 ? (*pdu)[1] : 0);
        outcome = b;
        ++s_.replies;
        ++s_.exceptions;
    } else {
        outcome = "normal";
        ++s_.replies;
    }
    ++s_.outcomes[outcome];
    std::string key = std::to_string(p.pdu.empty() ? 0 : p.pdu[0]);
    if (r.reply_due) {
        const std::size_t n = r.exchange.own_received().size();
        key += "|" + outcome + "|" + std::to_string(n < 8 ? n : 8 + n / 16);
        // Latency in two bands only: finer bands would make the feedback (and so the run) depend on the
        // machine's load rather than on the seed.
        key += r.exchange.elapsed > slow_ / 2 ? "|late" : "|prompt";
    } else {
        // No reply was due, so none was waited for in full (the silence wait: none over Modbus/TCP, a
        // fraction of a millisecond learnt on a fast network): whether a reply the target gives anyway is
        // seen within it is up to the machine's load. The class does not take it, or the same seed would
        // send other requests on a busier machine (a reply where the rules demand silence is a broken rule,
        // and the rule is in the class).
        key += "|unwaited";
    }
    for (const auto& v : r.violations) {
        ++s_.outcomes["rule " + v.rule];
        key += "|" + v.rule;
    }
    if (classes_.insert(key).second) generator_.keep(p);
    s_.response_classes = classes_.size();
}

std::vector<const Campaign::WrittenBy*> Campaign::writers_of(std::span<const std::uint8_t> pdu) const {
    if (pdu.size() < 5 || pdu[0] < 1 || pdu[0] > 4) return {};
    // The table the read reaches, as the oracle resolves it (a map whose input registers are its holding
    // registers: a write shows on FC4 too).
    const Table table = profile_.resolve(*modbus::table_of_function(pdu[0]));
    const std::uint32_t start = (pdu[1] << 8) | pdu[2];
    const std::uint32_t count = (pdu[3] << 8) | pdu[4];
    std::vector<const WrittenBy*> found;
    for (auto it = written_by_.lower_bound({table, static_cast<std::uint16_t>(start)});
         it != written_by_.end() && it->first.first == table && it->first.second < start + count; ++it)
        if (std::find(found.begin(), found.end(), it->second.get()) == found.end())
            found.push_back(it->second.get());
    std::sort(found.begin(), found.end(), [](auto* a, auto* b) { return a->request < b->request; });
    return found;
}

std::vector<Step> Campaign::writes_before_trace(std::span<const std::uint8_t> pdu) const {
    std::vector<Step> out;
    for (const WrittenBy* w : writers_of(pdu)) {
        const auto bytes = w->step.joined();
        const bool traced =
            std::any_of(trace_.begin(), trace_.end(), [&](const Step& s) { return s.joined() == bytes; });
        if (!traced) out.push_back(w->step);
    }
    return out;
}

std::vector<Step> Campaign::minimise(const std::string& rule, std::vector<Step> window,
                                     const std::vector<Step>& kept, bool& reproduced,
                                     std::optional<bool>& on_new_connection) {
    reproduced = false;
    on_new_connection.reset();
    std::size_t budget = options_.minimise_budget;
    replay_.silence_wait = silence_wait();
    // The replies still due are waited for first (up to a timeout after the last was given up), or they
    // would come during a replay and be taken for its requests'; they are judged after the minimisation
    // (judge_claimed, judge_settled), and the bytes heard that answer none with the next arrivals.
    // The replays resend requests with the transaction ids they had: their replies must not be taken for
    // those of requests kept unanswered.
    ++minimised_;
    std::vector<std::uint8_t> unexplained;
    if (framing_ == modbus::Framing::Tcp) {
        unexplained = unanswered_.await_due(client_, options_.timeout, claimed_);
        unanswered_.clear();
    } else {
        std::vector<modbus::transport::SettledRequest> settled;
        if (!owed_.empty())
            unexplained = await_owed(client_, owed_, owed_.newest_given_up() + options_.timeout, settled);
        for (auto& s : settled)
            settled_.emplace_back(std::move(s), "after the request was given up: ");
        owed_.clear();
    }
    heard_unexplained_.insert(heard_unexplained_.end(), unexplained.begin(), unexplained.end());
    const auto reproduces = [&](const std::vector<Step>& steps) {
        if (budget == 0) return false;
        --budget;
        (void)client_.drain(std::chrono::milliseconds(0));
        conformance::ExchangeOracle fresh(framing_, {{options_.unit, &profile_}}, ip_network_);
        return breaks(replay_steps(steps, fresh), rule);
    };
    // Steps are tried by their place in the window. A kept one is in every candidate: the device still
    // holds what the campaign wrote, so a candidate without the write that set a point the read reads may
    // break the rule here and not on a device that never saw that write (word-swap's lost write shows the
    // partner register's value: the write to the partner was dropped, and the reproducer broke nothing on
    // a fresh slave).
    const auto is_kept = [&](const Step& s) {
        const auto bytes = s.joined();
        return std::any_of(kept.begin(), kept.end(), [&](const Step& k) { return k.joined() == bytes; });
    };
    std::vector<bool> pinned(window.size());
    for (std::size_t i = 0; i < window.size(); ++i)
        pinned[i] = is_kept(window[i]);
    const auto steps_of = [&](const std::vector<std::size_t>& places) {
        std::vector<Step> out;
        for (std::size_t i : places)
            out.push_back(window[i]);
        return out;
    };
    std::vector<std::size_t> found;
    for (std::size_t n = 1; n <= window.size();
         n = n * 2 > window.size() && n < window.size() ? window.size() : n * 2) {
        std::vector<std::size_t> suffix;
        for (std::size_t i = 0; i < window.size(); ++i)
            if (i >= window.size() - n || pinned[i]) suffix.push_back(i);
        if (reproduces(steps_of(suffix))) {
            found = std::move(suffix);
            break;
        }
        if (budget == 0 || n == window.size()) break;
    }
    if (found.empty()) return window;
    reproduced = true;
    for (std::size_t i = 0; found.size() > 1 && i + 1 < found.size() && budget > 0;) {
        if (pinned[found[i]]) {
            ++i;
            continue;
        }
        auto shorter = found;
        shorter.erase(shorter.begin() + static_cast<std::ptrdiff_t>(i));
        if (reproduces(steps_of(shorter)))
            found = std::move(shorter);
        else
            ++i;
    }
    // `mbscope replay` sends the steps on a connection of its own, at once: tried so once more, outside the
    // budget. (pymodbus drops a connection whose first request comes split a moment after it opened, and not
    // one that carried requests before: a reproducer minimised on the campaign's connection did not
    // reproduce with replay, every time.)
    std::vector<Step> steps = steps_of(found);
    if (!serial_line_ && client_.reconnect()) {
        conformance::ExchangeOracle fresh(framing_, {{options_.unit, &profile_}}, ip_network_);
        on_new_connection = breaks(replay_steps(steps, fresh), rule);
    }
    return steps;
}

std::vector<ReplayedStep> Campaign::replay_steps(const std::vector<Step>& steps,
                                                 conformance::ExchangeOracle& oracle) {
    auto replayed = replay(client_, oracle, steps, replay_);
    for (std::size_t i = 0; i < replayed.size(); ++i)
        note_step_writes(session_, steps[i], replayed[i]);
    return replayed;
}

void Campaign::record(const conformance::OracleViolation& v, std::uint8_t fc, bool replayable,
                      const std::vector<Step>& before, const std::vector<Step>& kept) {
    const std::string key = v.rule + "|" + std::to_string(fc);
    if (auto it = finding_index_.find(key); it != finding_index_.end()) {
        ++s_.findings[it->second].count;
        return;
    }
    CampaignFinding f;
    f.rule = v.rule;
    f.source = v.source;
    f.expected = v.expected;
    f.observed = v.observed;
    f.function = fc;
    f.first_request = s_.requests;
    f.count = 1;
    Reproducer& r = f.reproducer;
    r.rule = v.rule;
    r.source = v.source;
    r.expected = v.expected;
    r.observed = v.observed;
    r.target = options_.target;
    r.profile = profile_.id;
    r.unit = options_.unit;
    r.framing = std::string(modbus::to_string(framing_));
    r.seed = options_.seed;
    r.request = s_.requests;
    std::vector<Step> window = before;
    window.insert(window.end(), trace_.begin(), trace_.end());
    r.original_steps = window.size();
    if (v.rule == "timing.slow_reply") r.slow_ms = static_cast<std::uint32_t>(slow_.count());
    if (replayable && options_.minimise_budget > 0)
        r.steps = minimise(v.rule, std::move(window), kept, r.minimised, r.replays_on_new_connection);
    else
        r.steps = std::move(window);
    if (!options_.artifacts.empty()) {
        std::error_code ec;
        std::filesystem::create_directories(options_.artifacts, ec);
        // A reproducer an earlier run left in the directory is kept: this one takes the next free name.
        const std::string stem = v.rule + "-fc" + std::to_string(fc);
        std::string path = (std::filesystem::path(options_.artifacts) / (stem + ".json")).string();
        for (int n = 2; std::filesystem::exists(path, ec) && n < 10'000; ++n)
            path = (std::filesystem::path(options_.artifacts) / (stem + "-" + std::to_string(n) + ".json"))
                       .string();
        if (auto saved = save_reproducer(r, path); saved)
            f.file = path;
        else
            f.file_error = saved.error();
    }
    finding_index_.emplace(key, s_.findings.size());
    s_.findings.push_back(std::move(f));
}

conformance::OracleViolation Campaign::slow_reply(std::chrono::nanoseconds first,
                                                  std::chrono::nanoseconds second) const {
    const auto ms = [](std::chrono::nanoseconds t) { return std::to_string(t.count() / 1'000'000) + " ms"; };
    return {"timing.slow_reply",
            options_.slow.count()               ? "--slow"
            : profile_.line.response_timeout_ms ? profile_.source
                                                : "SL §2.4.1",
            "a reply within " + std::to_string(slow_.count()) + " ms",
            "replies after " + ms(first) + " and " + ms(second)};
}

void Campaign::progress(bool force) {
    if (!options_.progress) return;
    const auto now = Clock::now();
    if (!force && now - last_progress_ < std::chrono::milliseconds(250)) return;
    last_progress_ = now;
    s_.elapsed = now - start_;
    options_.progress(s_);
}

bool Campaign::done() const {
    if (options_.stop && options_.stop->load()) return true;
    if (s_.target_lost) return true;
    if (options_.max_findings && s_.findings.size() >= options_.max_findings) return true;
    if (options_.requests && s_.requests >= *options_.requests) return true;
    if (options_.duration && Clock::now() - start_ >= *options_.duration) return true;
    return false;
}

CampaignSummary Campaign::run() {
    start_ = Clock::now();
    if (!healthy(nullptr, true)) {
        s_.error = "no normal reply to the health-check request " + modbus::hex_bytes(health_) + " (unit " +
                   std::to_string(options_.unit) + ")";
        s_.stopped = options_.stop && options_.stop->load();
        return s_;
    }
    s_.reachable = true;
    health_passed_ = false;  // the trace starts empty anyway
    while (!done()) {
        std::optional<Probe> chosen = std::exchange(follow_up_, std::nullopt);
        if (!chosen && !options_.read_only && rng_() % 100 < 5) chosen = round_trip();
        Probe p = chosen ? std::move(*chosen) : generator_.next();
        // A polling interval (Walchem's 5 s) makes the reads before a write cost seconds each: a step that
        // would run past --duration is not begun (a write's is skipped, another probe may fit).
        if (const std::size_t reads = reads_before(p); !fits_before_deadline(reads)) {
            if (reads == 0) break;
            ++s_.writes_past_deadline;
            continue;
        }
        if (!prepare_writes(p) || !keep_line_settings(p)) {
            ++s_.skipped_writes;
            continue;
        }
        pace();
        // Whatever arrived since the last exchange ended: late replies to kept requests, else that
        // exchange's reply, too late. Only looked for where the last one can be pending (no whole, valid
        // reply came): a poll per request costs speed, and over Modbus/TCP a later exchange reads the
        // others' anyway.
        if (last_unanswered() || !owed_.empty() || !heard_unexplained_.empty()) judge_arrivals();
        const Step step = frame(p);
        trace_.push_back(step);
        for (const auto& part : step.parts)
            s_.requests_digest = fnv1a(s_.requests_digest, part);
        if (trace_.size() > trace_capacity) trace_.pop_front();
        auto r = send(step, options_.timeout);
        note_unread(r.exchange);
        last_ = r.exchange;
        ++s_.requests;
        classify(p, r);
        const std::uint8_t fc = p.pdu.empty() ? 0 : p.pdu[0];
        last_function_ = fc;

        if (r.exchange.closed && client_.reconnect()) {
            if (!healthy()) s_.target_lost = true;
        } else if (r.exchange.closed) {
            s_.target_lost = true;
        }
        for (const auto& v : r.violations) {
            if (v.rule == "reply.missing") {
                // Missing twice, with four times the patience, before it counts.
                // Over RTU and ASCII the first request's reply, should it come late, is waited out first
                // (wait_out_owed), or the second would take it for its own and seem prompt.
                const auto again = send(frame(p), options_.timeout * 4);
                note_unread(again.exchange);
                if (!again.exchange.own_received().empty()) {
                    // Answered the second time: a slow target when it took longer than --slow, else chance.
                    if (again.exchange.first_byte > slow_)
                        record(slow_reply(again.exchange.first_byte, again.exchange.first_byte), fc, false);
                    else
                        ++s_.unconfirmed;
                    continue;
                }
                if (!healthy()) s_.target_lost = true;
            } else if (v.rule == "silence.gap_inside_request") {
                // Sent again with a pause the host cannot miss before it counts.
                auto again = frame(p);
                again.pause = conformance::confirming_pause(step.pause);
                const auto confirmed = send(again, options_.timeout);
                note_unread(confirmed.exchange);
                if (std::none_of(confirmed.violations.begin(), confirmed.violations.end(),
                                 [&](const auto& c) { return c.rule == v.rule; })) {
                    ++s_.unconfirmed;
                    continue;
                }
            }
            // A lost write's reproducer holds the writes that set the points the read reads, however long
            // ago the trace was cleared, and keeps them through its minimisation.
            if (v.rule == "state.lost_write") {
                std::vector<Step> writers;
                for (const WrittenBy* w : writers_of(p.pdu))
                    writers.push_back(w->step);
                record(v, fc, !s_.target_lost, writes_before_trace(p.pdu), writers);
            } else {
                record(v, fc, !s_.target_lost);
            }
        }
        if (step.reconnect_after) {
            (void)client_.reconnect();
            unanswered_.clear();
            if (!healthy()) s_.target_lost = true;
        }
        if (s_.target_lost) {
            record({"target.unresponsive", "AP §4.1",
                    "a normal reply to the health-check request " + modbus::hex_bytes(health_) +
                        " after a failure",
                    "no reply to " + std::to_string(health_attempts) + " health checks, connection " +
                        (r.exchange.closed ? "closed" : "open")},
                   fc, false);
            break;
        }
        if (!r.exchange.own_received().empty() && r.exchange.first_byte > slow_) {
            std::chrono::nanoseconds latency{0};
            if (healthy(&latency) && latency > slow_)
                record(slow_reply(r.exchange.first_byte, latency), fc, false);
        }
        // An acknowledged write is read back at once: a lost or misplaced write shows on the read.
        if (const auto range = write_range(p.pdu); range && range->count && r.violations.empty()) {
            const auto reply = reply_pdu(r.exchange);
            if (reply && !reply->empty() && !(reply->front() & 0x80) && p.unit == options_.unit) {
                const auto by = std::make_shared<const WrittenBy>(WrittenBy{s_.requests, step});
                for (std::uint32_t a = range->start;
                     a < std::uint32_t{range->start} + range->count && a <= 0xFFFF; ++a)
                    written_by_[{range->table, static_cast<std::uint16_t>(a)}] = by;
                const bool bits = range->table == Table::Coils;
                Probe back;
                back.unit = options_.unit;
                back.pdu = modbus::encode_pdu(modbus::make_read_request(
                    bits ? modbus::FunctionCode::ReadCoils : modbus::FunctionCode::ReadHoldingRegisters,
                    range->start,
                    std::min<std::uint16_t>(range->count,
                                            bits ? modbus::max_read_bits : modbus::max_read_registers)));
                back.recipe = "read back fc" + std::to_string(fc);
                if (generator_.allowed(back.pdu)) follow_up_ = back;
            }
        }
        // A health check passed in this round: the target is known to be good from here, and a later
        // reproducer starts here (its findings were saved above with the steps before).
        // Not while a read-back is due: the write it checks belongs in that reproducer.
        if (std::exchange(health_passed_, false) && !follow_up_) trace_.clear();
        progress();
    }
    // Replies still owed: over Modbus/TCP the learnt wait after the last request, and up to a timeout for
    // those due; over RTU and ASCII up to a timeout for those due; then judged.
    if (last_ && !s_.target_lost && (!unanswered_.empty() || !owed_.empty() || !heard_unexplained_.empty())) {
        if (framing_ == modbus::Framing::Tcp && !unanswered_.empty()) {
            std::this_thread::sleep_until(unanswered_.newest() + silence_wait());
            judge_arrivals();
            auto unexplained = unanswered_.await_due(client_, options_.timeout, claimed_);
            heard_unexplained_.insert(heard_unexplained_.end(), unexplained.begin(), unexplained.end());
        } else if (framing_ != modbus::Framing::Tcp) {
            (void)await_due_replies(options_.timeout);
        }
        judge_arrivals();
    }
    if (options_.stop && options_.stop->load()) s_.stopped = true;
    progress(true);
    s_.elapsed = Clock::now() - start_;  // the fuzzing, not the restore after it
    s_.silence_wait = silence_wait();
    read_unanswered_writes();
    list_restored();
    s_.not_read = ranges_of(not_read_);
    return s_;
}

void Campaign::list_restored() {
    const std::string doubt =
        "not restored: first read after a write that reached it unread, so the value read as its original "
        "may be one the fuzzer wrote";
    if (s_.target_lost) {
        // A target that stopped answering is not written to again (each point would wait out the timeout
        // twice, an hour for 2,000 points at 1 s): every point the run changed is listed as not restored, so
        // the summary and the exit code say what was left changed.
        for (const auto& [key, kept] : session_.touched()) {  // no std::views: clang 14 with libstdc++ 12
            if (!kept.changed && !doubtful_.count(key)) continue;  // its writes refused, or of its value
            conformance::Touched t = kept;
            t.restored = false;
            t.problem = kept.changed ? "not restored: the target stopped answering" : doubt;
            s_.restored.push_back(std::move(t));
        }
        return;
    }
    if (const auto text = session_.restore_announcement(); options_.note && !text.empty())
        options_.note(text);
    if (!session_.touched().empty()) s_.restored = session_.restore();
    for (auto& t : s_.restored)
        if (doubtful_.count({t.table, t.address})) {
            t.restored = false;
            t.problem = doubt;
        }
    // A doubtful point the run did not change after its read is neither put back nor listed by the restore:
    // what it held before the run is unknown all the same, and it is listed.
    const auto listed = [&](const Location& point) {
        return std::any_of(s_.restored.begin(), s_.restored.end(), [&](const auto& t) {
            return t.table == point.first && t.address == point.second;
        });
    };
    for (const auto& point : doubtful_) {
        const auto kept = session_.touched().find(point);
        if (kept == session_.touched().end() || listed(point)) continue;
        conformance::Touched t = kept->second;
        t.restored = false;
        t.problem = doubt;
        s_.restored.push_back(std::move(t));
    }
}

std::string digest_text(std::uint64_t digest) {
    char b[17];
    std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(digest));
    return b;
}

}  // namespace

double CampaignSummary::requests_per_second() const {
    const double seconds = std::chrono::duration<double>(elapsed).count();
    return seconds > 0 ? static_cast<double>(requests) / seconds : 0;
}

CampaignSummary run_campaign(const modbus::Profile& profile, const CampaignOptions& options) {
    const auto stopped = [&] { return options.stop && options.stop->load(); };
    // Stopped before it began (a signal while the profile loaded): the target is not even opened, and the
    // summary says the run was interrupted with nothing done. The same when the stop cut the opening short.
    if (stopped()) {
        CampaignSummary s;
        s.stopped = true;
        return s;
    }
    auto client = modbus::transport::Client::open(options.endpoint);
    if (!client) {
        CampaignSummary s;
        s.error = client.error();
        s.stopped = stopped();
        return s;
    }
    Campaign c(profile, options, *client);
    return c.run();
}

nlohmann::json to_json(const CampaignSummary& s) {
    nlohmann::json findings = nlohmann::json::array();
    for (const auto& f : s.findings) {
        findings.push_back({{"rule", f.rule},
                            {"source", f.source},
                            {"expected", f.expected},
                            {"observed", f.observed},
                            {"function", f.function},
                            {"first_request", f.first_request},
                            {"count", f.count},
                            {"reproducer", f.file.empty() ? nlohmann::json(nullptr) : nlohmann::json(f.file)},
                            {"steps", f.reproducer.steps.size()},
                            {"minimised", f.reproducer.minimised}});
        if (!f.file_error.empty()) findings.back()["reproducer_error"] = f.file_error;
        if (f.reproducer.replays_on_new_connection)
            findings.back()["replays_on_new_connection"] = *f.reproducer.replays_on_new_connection;
    }
    nlohmann::json j{{"reachable", s.reachable},
                     {"requests", s.requests},
                     {"replies", s.replies},
                     {"exceptions", s.exceptions},
                     {"silences", s.silences},
                     {"late_replies", s.late_replies},
                     {"replies_after_timeout", s.replies_after_timeout},
                     {"silence_wait_ms", std::chrono::duration<double, std::milli>(s.silence_wait).count()},
                     {"skipped_writes", s.skipped_writes},
                     {"writes_past_deadline", s.writes_past_deadline},
                     {"line_settings_kept", s.line_settings_kept},
                     {"unconfirmed", s.unconfirmed},
                     {"health_checks", s.health_checks},
                     {"seconds", std::chrono::duration<double>(s.elapsed).count()},
                     {"requests_per_second", s.requests_per_second()},
                     {"response_classes", s.response_classes},
                     {"requests_digest", digest_text(s.requests_digest)},
                     {"outcomes", s.outcomes},
                     {"findings", findings},
                     {"restored", conformance::to_json(s.restored)},
                     {"not_read", to_json(s.not_read)},
                     {"unanswered_writes", to_json(s.unanswered_writes)},
                     {"unanswered_unread", to_json(s.unanswered_unread)},
                     {"unanswered_refused", to_json(s.unanswered_refused)},
                     {"read_back_interrupted", s.read_back_interrupted},
                     {"stopped", s.stopped},
                     {"target_lost", s.target_lost}};
    if (!s.error.empty()) j["error"] = s.error;
    return j;
}

}  // namespace mbscope::fuzz::network
