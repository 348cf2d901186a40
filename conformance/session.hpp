#pragma once
// The runner's hold on the device: every request goes through here, so pacing (the manual's minimum
// polling interval), the evidence of the rule being run and the ledger of touched points are never
// forgotten. Before the first write to a point its original value is read and kept; restore() writes every
// kept value back and reads it again to verify.

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "conformance/rule.hpp"
#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"
#include "modbus/result.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance {

struct SessionOptions {
    std::uint8_t unit = 1;
    std::chrono::milliseconds timeout{1000};
    std::chrono::milliseconds interval{0};
};

// A pause inside a request is made on this host, whose scheduler, tty buffers or USB adapter can close it
// before it reaches the line; a device that then answers one whole request is right. Before it is blamed for
// answering a request paused `pause` inside, the request is sent again paused this long: ten times as long,
// 50 ms at least (the fuzzer's silence.gap_inside_request, check's framing.gap_inside).
inline std::chrono::microseconds confirming_pause(std::chrono::microseconds pause) noexcept {
    return std::max<std::chrono::microseconds>(pause * 10, std::chrono::milliseconds(50));
}

struct Touched {
    modbus::Table table = modbus::Table::HoldingRegisters;
    std::uint16_t address = 0;
    std::uint16_t original = 0;
    // Written back and read back equal, or found holding the original again; or a point the map makes
    // read-only, which the device refused to take back (its value may move on its own), with what it reads
    // now in `problem`.
    bool restored = false;
    // Why not, with the value left and the exception the device answered the restore's write with; for a
    // read-only point counted restored, what it reads now.
    std::string problem;
    // What the run did to the point, in a session that sees every write (Session::watch_writes): the value
    // of its last write the device did not refuse (nullopt: none, or one whose value cannot be known, FC5
    // with a value other than FF00 or 0000), and whether that write was acknowledged (a normal reply; else
    // it went unanswered or came back damaged, and may or may not have been executed).
    std::optional<std::uint16_t> written{};
    bool acknowledged = false;
    // Every value the run's writes there carried (not refused), whether one was of a value unknown, and
    // whether a write of a value other than the original was acknowledged: a device holding any of them, or
    // anything but its original after such an acknowledged write, holds what the run did.
    std::vector<std::uint16_t> run_values{};
    bool unknown_value = false;
    bool acknowledged_change = false;
    // A write the device did not refuse carried a value other than the original (or one unknown): only such
    // points are restored and reported. A write refused with an exception wrote nothing (AP §7), and one of
    // the value the point held changed nothing.
    bool changed = false;
    // At the restore the point held neither its original nor what the run last wrote, and the run's write
    // was not acknowledged: the device changed it itself (a process, a latch), and it is not overwritten.
    bool device_changed = false;
    // After the restore, what the point holds as far as known (nullopt: nothing is), and how it is known:
    // "read" (read back), "restore" (the restore's write of the original, acknowledged, not read back) or
    // "run" (the last value the run wrote).
    std::optional<std::uint16_t> left{};
    std::string left_from{};
    // The exception the device answered the restore's last write with ("exception 04 (Server Device
    // Failure)"), "" when none.
    std::string restore_refused{};
};

class Session {
  public:
    Session(modbus::transport::Client& client, SessionOptions options,
            const modbus::Profile* profile = nullptr)
        : client_(client), options_(options), profile_(profile) {}

    // One request to `unit` (the session's unit when nullopt); the exchange joins the current evidence.
    modbus::transport::Exchange request(std::span<const std::uint8_t> pdu, const std::string& note,
                                        std::optional<std::uint8_t> unit = std::nullopt,
                                        std::optional<std::chrono::milliseconds> timeout = std::nullopt);
    // The first part of a request whose rest goes with raw() (a request with a pause inside it): late
    // bytes are looked for before it, not between it and the rest, where a reply is the request's.
    modbus::Result<void, std::string> send_part(std::span<const std::uint8_t> bytes);
    // Bytes as given (framing and MBAP rules); `frames` replies awaited.
    modbus::transport::Exchange raw(std::span<const std::uint8_t> bytes, const std::string& note,
                                    std::size_t frames = 1,
                                    std::optional<std::chrono::milliseconds> timeout = std::nullopt);

    // Reads that must work for a rule to be judged; nullopt when the device did not answer normally.
    std::optional<std::vector<std::uint16_t>> read_registers(modbus::Table table, std::uint16_t start,
                                                             std::uint16_t quantity, const std::string& note);
    // One point's value (a bit as 0/1); nullopt when the device did not answer normally.
    std::optional<std::uint16_t> read_point(modbus::Table table, std::uint16_t address,
                                            const std::string& note);
    std::optional<std::vector<bool>> read_bits(modbus::Table table, std::uint16_t start,
                                               std::uint16_t quantity, const std::string& note);

    // The session sees every write made to the device: the conformance runner's rules all go through it,
    // and the network fuzzer and a replay, which send their own requests over the session's client, tell it
    // of theirs (note_write). restore() then reads the points first and writes back only those the run
    // changed, leaving alone a point whose write was refused, or carried the value it held, or that the
    // device changed itself. Off, every remembered point is written back.
    void watch_writes() noexcept { watch_writes_ = true; }
    // watch_writes(): a write request the caller sent over the session's client itself, and the device's
    // answer to it (nullopt: none came, or a damaged one or another request's), kept as the session keeps
    // its own (a write refused with 01, 02, 03 or 06 wrote nothing). `late`: the answer came after the
    // write was kept as unanswered; an acknowledgement then makes it acknowledged (a late exception changes
    // nothing: the write was kept as perhaps executed, which the restore's read settles).
    void note_write(std::span<const std::uint8_t> request_pdu, const std::optional<modbus::Pdu>& reply,
                    bool late = false);
    // Keep the original values of [start, start+count) before writing them. False: they could not be read,
    // and the rule must not write.
    bool remember(modbus::Table table, std::uint16_t start, std::uint16_t count, std::uint16_t chunk = 1);
    // Whether the last read (of remember(), read_registers(), read_bits(), read_point()) was refused with
    // exception 01 or 02: the device has no such table or point, so a write there changes nothing to
    // restore. False after no answer, a damaged one or another exception: then the values may well be there,
    // and nothing may be written before they are kept.
    bool last_read_refused() const noexcept { return last_read_refused_; }
    // Write back every remembered value, verify, and return the ledger.
    std::vector<Touched> restore();
    // restore(), then forget the points restored: a later write remembers its point's value again, and a
    // later call restores what was written since and tries again what did not go back.
    std::vector<Touched> restore_and_forget();
    // What a person at a terminal is told before restore() at a polling interval, where it can take minutes
    // (Walchem's 5 s: a minute for every 12 points); empty without an interval or a point to restore.
    std::string restore_announcement() const;
    const std::map<std::pair<modbus::Table, std::uint16_t>, Touched>& touched() const noexcept {
        return touched_;
    }

    std::vector<Evidence> take_evidence() { return std::exchange(evidence_, {}); }
    const SessionOptions& options() const noexcept { return options_; }
    modbus::transport::Client& client() noexcept { return client_; }
    // How long each reply that came in time took, whatever it was (a target that answers nothing is told
    // by this list being empty); reply_times() only those of replies to their request: a good checksum and
    // the request's unit and transaction id (what a manual's response time limit is about).
    const std::vector<std::chrono::nanoseconds>& response_times() const noexcept { return times_; }
    const std::vector<std::chrono::nanoseconds>& reply_times() const noexcept { return reply_times_; }
    void forget_times() noexcept {
        times_.clear();
        reply_times_.clear();
    }
    std::uint64_t requests() const noexcept { return requests_; }
    // Requests that could not be sent: the connection was lost and could not be made again within the
    // request's timeout (a device rebooting refuses connections for a while). A rule with one is not
    // judged; why the last connection failed.
    std::uint64_t unsent_requests() const noexcept { return unsent_; }
    const std::string& connect_error() const noexcept { return connect_error_; }
    // Of those, the ones a slave owes a reply: whole requests with a good checksum to a unit (not a
    // broadcast on a serial framing). A target that answered none of these is silent; one sent only requests
    // every slave must ignore (a bad CRC, a broadcast, half a request) got the silence it asked for.
    std::uint64_t requests_owed_reply() const noexcept { return owed_reply_; }
    // Replies (or bytes) that came after their request was given up: set aside during a later request, or
    // found waiting before one.
    std::uint64_t late_replies() const noexcept { return late_replies_; }
    // Requests a late reply answered: given up with nothing back, then settled by a reply that came later
    // (over Modbus/TCP one carrying the request's transaction id, over RTU and ASCII one that answers what
    // it asked). The device answered them, only after the timeout.
    std::uint64_t answered_late() const noexcept { return answered_late_; }
    // Every byte the target sent in the run, replies or not, the address space's probing included: a target
    // whose bytes form no reply is not a silent one.
    std::uint64_t bytes_received() const noexcept { return bytes_received_; }
    // Requests answered twice (modbus::transport::repeats_reply): the reply again in the same read, before
    // the next request, or (Modbus/TCP) set aside by a later one; each with the request's bytes. Counted
    // for every exchange of one request (request(), and raw() of bytes that are one whole ADU awaiting one
    // frame): where a rule sends two requests at once, identical replies are both owed.
    const std::vector<Evidence>& repeated_replies() const noexcept { return repeated_; }
    // With no request out, listens until `quiet` passes without a byte (replies still owed are waited out
    // first, up to the timeout, and logged as late); the listening joins the evidence and is returned.
    Evidence listen_idle(std::chrono::milliseconds quiet);
    // With requests given up and no request out, reads for `quiet` more (until that long passes without a
    // byte): replies that come even later are logged as late ones (late_replies(), answered_late()), and the
    // listening joins the evidence. A run stopped for silence is then told apart from one too impatient.
    void listen_for_late(std::chrono::milliseconds quiet);
    // Adds to the current rule's evidence (what the session kept for a judgement over the whole run).
    void cite(const std::vector<Evidence>& evidence);
    // RTU and ASCII: keep the owed requests in `list` instead of the session's own, so that a caller that
    // sends its own requests over the same client (the network fuzzer) and the session each set aside the
    // other's late replies instead of taking them for their own (a value remembered for restoring among
    // them). `list` must outlive the session's use of it. (Over Modbus/TCP the session keeps its own: a
    // transaction id tells whose reply a frame is.)
    void share_owed(modbus::transport::OwedRequests& list) noexcept { shared_owed_ = &list; }

  private:
    using Ledger = std::map<std::pair<modbus::Table, std::uint16_t>, Touched>;
    void pace();
    // Writes the remembered values of [first, last) (one table) back in blocks, FC15 or FC16 as long as the
    // profile's limit and its read allows, and reads each block back: what reads as it was is restored.
    void restore_blocks(Ledger::iterator first, Ledger::iterator last);
    // The write that brings one point back: FC5 for a coil; for either register of a 32-bit point whose
    // two registers are both in the ledger, FC16 of the pair (some devices refuse a lone half; Walchem's
    // manual wants a 32-bit value written whole, 002:452-459, 499); any other register alone with FC6, so a
    // read-only neighbour cannot spoil its write.
    std::vector<std::uint8_t> restore_pdu(const Touched& t) const;
    const modbus::Point* pair_of(
        const Touched& t) const;                      // t's 32-bit point when both its registers are kept
    bool restore_pair_first(const Touched& t) const;  // t is the first register of such a point
    // `one_request`: the exchange sent one request and awaited one reply (repeated_replies()).
    void log(const modbus::transport::Exchange& ex, const std::string& note, bool one_request);
    // RTU and ASCII, before a request to `unit` of `pdu` (empty: bytes that are no request) goes out: what
    // has arrived since the last exchange is a late reply, logged as such; when the request could draw the
    // same reply as an owed one, the owed reply is waited for (content could not tell them apart). `several`:
    // the bytes hold several requests, several replies are awaited, and any owed reply due is waited for.
    void settle_late(std::uint8_t unit, std::span<const std::uint8_t> pdu, bool several = false);
    void log_late(std::vector<std::uint8_t> bytes,
                  const char* when = "after the last exchange ended, before this request");
    // After an exchange: a request that got nothing back joins the owed ones (OwedRequests; over Modbus/TCP
    // each request of the exchange by its transaction id), and the owed ones its late replies answer are
    // counted (answered_late()).
    void account(const modbus::transport::Exchange& ex, std::uint8_t unit, std::span<const std::uint8_t> pdu);
    // What a write did to one point kept: its value and whether it was acknowledged (note_write).
    void note_point(modbus::Table table, std::uint16_t address, std::optional<std::uint16_t> value,
                    bool acked, bool late);
    // watch_writes(): before restoring, reads the points the run changed and decides each one: back already
    // (restored), the device's own change (left alone), or to be written back.
    void classify_for_restore(Ledger& ledger);
    // Connects again after the connection was lost, trying until `wait` passes (a refused connection is
    // answered at once, and a device that reboots refuses them for a while); false when it could not.
    bool connected(std::chrono::milliseconds wait);
    // The exchange of a request that could not be sent (connected() failed), logged as such.
    modbus::transport::Exchange not_sent(std::span<const std::uint8_t> bytes, const std::string& note,
                                         std::chrono::nanoseconds waited);

    modbus::transport::Client& client_;
    SessionOptions options_;
    const modbus::Profile* profile_;  // tells which registers are halves of one 32-bit value
    std::vector<Evidence> evidence_;
    Ledger touched_;
    std::chrono::steady_clock::time_point last_{};
    std::vector<std::chrono::nanoseconds> times_;
    std::vector<std::chrono::nanoseconds> reply_times_;
    bool last_read_refused_ = false;
    std::uint64_t requests_ = 0;
    std::uint64_t owed_reply_ = 0;
    std::uint64_t late_replies_ = 0;
    std::uint64_t answered_late_ = 0;
    std::uint64_t bytes_received_ = 0;
    std::vector<Evidence> repeated_;
    // The reply to the last exchange of one request, when it came whole, and that request: a copy of it
    // arriving later is the request answered twice.
    std::optional<modbus::Frame> last_reply_;
    std::vector<std::uint8_t> last_reply_request_;
    bool part_sent_ = false;          // send_part() began a request that raw() completes
    std::vector<std::uint8_t> part_;  // its bytes (what raw() completes is one request with them)
    bool watch_writes_ = false;       // watch_writes()
    bool restoring_ = false;          // restore()'s own writes are not the run's
    bool connection_lost_ = false;    // the last attempt to connect again failed
    std::string connect_error_;
    std::uint64_t unsent_ = 0;
    std::uint32_t unanswered_in_a_row_ = 0;  // requests that got not a byte back, since the last that did
    // The last requests given up without a reply, each with when it was (OwedRequests).
    modbus::transport::OwedRequests owed_;
    modbus::transport::OwedRequests* shared_owed_ = nullptr;  // share_owed(), RTU and ASCII only
    modbus::transport::OwedRequests& owed() noexcept {
        return shared_owed_ && client_.framing() != modbus::Framing::Tcp ? *shared_owed_ : owed_;
    }
    // Waits for an owed reply that came to nothing, since one came (OwedRequests::quiet_waits_kept).
    unsigned quiet_waits_ = 0;
    // Restoring stops writing to a device that answered none of this many requests in a row (a device
    // that crashed mid-run would otherwise hold the run for the timeout twice per point: over an hour for
    // the generic profile's 2,000 coils at 1 s); the points left are listed as not restored, with why.
    static constexpr std::uint32_t gone_after = 8;
    bool device_gone() const noexcept { return unanswered_in_a_row_ >= gone_after; }
};

}  // namespace mbscope::conformance
