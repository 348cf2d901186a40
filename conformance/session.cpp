#include "conformance/session.hpp"

#include <algorithm>
#include <functional>
#include <memory>
#include <thread>
#include <utility>

#include "conformance/context.hpp"
#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::conformance {

using modbus::Table;
namespace tp = modbus::transport;

namespace {

bool is_exception(const tp::Exchange& ex) {
    if (!ex.response || !ex.response->checksum_ok) return false;
    const auto pdu = ex.response->pdu();
    return !pdu.empty() && (pdu[0] & 0x80) != 0;
}

// "exception 04 (Server Device Failure)" when the device answered the exchange's request with an exception,
// "" otherwise.
std::string refusal(const tp::Exchange& ex) {
    const auto pdu = response_pdu(ex);
    if (!pdu || !pdu->is_exception()) return {};
    return exception_text(std::get<modbus::ExceptionResponse>(pdu->body).exception_code);
}

// The read's answer as the rules accept it (response_pdu: framed, its checksum right, the request's
// transaction, protocol and unit identifiers) and of the read's function. The values remembered for
// restoring and the read-backs that call a point restored come from here: a reply to another transaction or
// unit, or another function's of the same shape, holds no value of these points.
// The read's answer when it is a normal one; `refused` tells an exception 01 or 02 (no such function or
// point) from no answer, a damaged one or another exception.
std::optional<modbus::Pdu> read_answer(const tp::Exchange& ex, modbus::FunctionCode fc, bool& refused) {
    auto pdu = response_pdu(ex);
    refused = false;
    if (pdu && pdu->is_exception() && pdu->function_code() == static_cast<std::uint8_t>(fc)) {
        const auto code = std::get<modbus::ExceptionResponse>(pdu->body).exception_code;
        refused = code == 0x01 || code == 0x02;
    }
    if (!pdu || pdu->is_exception() || pdu->function_code() != static_cast<std::uint8_t>(fc))
        return std::nullopt;
    return pdu;
}

// The points a write request sets and the value each gets (nullopt: one that cannot be known), read from
// the request's bytes as the device would (a deliberately inconsistent byte count included: a device that
// executes it writes what the bytes carry). `current`: a register's value before the write (FC22 masks it).
struct WrittenPoint {
    Table table;
    std::uint16_t address;
    std::optional<std::uint16_t> value;
};
std::vector<WrittenPoint> points_written(
    std::span<const std::uint8_t> pdu,
    const std::function<std::optional<std::uint16_t>(std::uint16_t)>& current) {
    std::vector<WrittenPoint> out;
    if (pdu.size() < 5) return out;
    const auto word = [&](std::size_t at) {
        return static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]);
    };
    const std::uint16_t address = word(1);
    const auto at = [&](std::uint32_t i) { return static_cast<std::uint16_t>(address + i); };
    switch (pdu[0]) {
        case 5: {
            const std::uint16_t v = word(3);
            out.push_back({Table::Coils, address,
                           v == 0xFF00 ? std::optional<std::uint16_t>(1)
                           : v == 0    ? std::optional<std::uint16_t>(0)
                                       : std::nullopt});
            break;
        }
        case 6:
            out.push_back({Table::HoldingRegisters, address, word(3)});
            break;
        case 15:
            if (pdu.size() < 6) break;
            for (std::uint32_t i = 0; i < word(3) && 6 + i / 8 < pdu.size(); ++i)
                out.push_back(
                    {Table::Coils, at(i), static_cast<std::uint16_t>((pdu[6 + i / 8] >> (i % 8)) & 1)});
            break;
        case 16:
            if (pdu.size() < 6) break;
            for (std::uint32_t i = 0; i < word(3) && 6 + 2 * i + 1 < pdu.size(); ++i)
                out.push_back({Table::HoldingRegisters, at(i), word(6 + 2 * i)});
            break;
        case 22: {
            if (pdu.size() < 7) break;
            const auto before = current(address);
            std::optional<std::uint16_t> v;
            if (before) v = static_cast<std::uint16_t>((*before & word(3)) | (word(5) & ~word(3) & 0xFFFF));
            out.push_back({Table::HoldingRegisters, address, v});
            break;
        }
        case 23: {
            if (pdu.size() < 10) break;
            const std::uint16_t start = word(5);
            for (std::uint32_t i = 0; i < word(7) && 10 + 2 * i + 1 < pdu.size(); ++i)
                out.push_back(
                    {Table::HoldingRegisters, static_cast<std::uint16_t>(start + i), word(10 + 2 * i)});
            break;
        }
        default:
            break;
    }
    return out;
}

}  // namespace

void Session::note_point(Table table, std::uint16_t address, std::optional<std::uint16_t> value, bool acked,
                         bool late) {
    const auto it = touched_.find({table, address});
    if (it == touched_.end()) return;  // not kept: nothing a rule means to restore
    Touched& t = it->second;
    // A late acknowledgement is of a write kept before, perhaps not the point's last one since: the last
    // value written stays, acknowledged only when it is that write's.
    if (!late) {
        t.written = value;
        t.acknowledged = acked;
    } else if (t.written == value) {
        t.acknowledged = true;
    }
    if (!value || *value != t.original) t.changed = true;
    if (!value)
        t.unknown_value = true;
    else if (std::find(t.run_values.begin(), t.run_values.end(), *value) == t.run_values.end())
        t.run_values.push_back(*value);
    if (acked && (!value || *value != t.original)) t.acknowledged_change = true;
}

void Session::note_write(std::span<const std::uint8_t> pdu, const std::optional<modbus::Pdu>& reply,
                         bool late) {
    if (!watch_writes_ || restoring_ || pdu.empty()) return;
    const std::uint8_t fc = pdu[0];
    if (fc != 5 && fc != 6 && fc != 15 && fc != 16 && fc != 22 && fc != 23) return;
    // Exceptions 01, 02, 03 and 06 say the write was not executed (AP §7: a function, address or value
    // refused, or the device busy, "the request was not processed"): nothing changed. Not 04 (a failure
    // "while attempting to perform" it, which may have written part or all of it; the reference slave's
    // exception-for-valid answers 04 after writing), 05 (accepted, to be done) or a gateway's 0A/0B (what
    // the device behind it did is unknown): as for no reply, it may have been executed.
    if (reply && reply->is_exception() && reply->function_code() == fc) {
        const auto code = std::get<modbus::ExceptionResponse>(reply->body).exception_code;
        if (code == 1 || code == 2 || code == 3 || code == 6) return;
    }
    const bool acked = reply && !reply->is_exception() && reply->function_code() == fc;
    if (late && !acked) return;
    const auto current = [&](std::uint16_t address) -> std::optional<std::uint16_t> {
        const auto it = touched_.find({Table::HoldingRegisters, address});
        if (it == touched_.end()) return std::nullopt;
        return it->second.changed ? it->second.written : std::optional<std::uint16_t>(it->second.original);
    };
    for (const auto& w : points_written(pdu, current)) {
        note_point(w.table, w.address, w.value, acked, late);
        // Where coils are views of the holding registers at their addresses (Walchem), a coil write leaves
        // 0 or 1 in the register (002:244, 493).
        if (w.table == Table::Coils && profile_ && profile_->coils_view_registers)
            note_point(Table::HoldingRegisters, w.address, w.value, acked, late);
    }
}

bool Session::connected(std::chrono::milliseconds wait) {
    if (!connection_lost_) return true;
    const auto until = std::chrono::steady_clock::now() + wait;
    for (;;) {
        if (const auto r = client_.reconnect(); r) {
            connection_lost_ = false;
            connect_error_.clear();
            return true;
        } else {
            connect_error_ = r.error();
        }
        const auto now = std::chrono::steady_clock::now();
        if (now >= until) return false;
        // A refused connection is answered at once: a short pause between tries, not a busy loop.
        std::this_thread::sleep_for(
            std::min<std::chrono::steady_clock::duration>(until - now, std::chrono::milliseconds(20)));
    }
}

tp::Exchange Session::not_sent(std::span<const std::uint8_t> bytes, const std::string& note,
                               std::chrono::nanoseconds waited) {
    tp::Exchange ex;
    ex.sent.assign(bytes.begin(), bytes.end());
    ex.closed = true;
    ex.elapsed = waited;
    ++unsent_;
    // No request went out: nothing timed out and no reply is owed, but for the restore it is one more
    // request the device did not take (device_gone).
    ++unanswered_in_a_row_;
    last_reply_.reset();
    evidence_.push_back(
        {note + " (not sent: could not connect: " + connect_error_ + ")", ex.sent, {}, waited, false});
    return ex;
}

void Session::pace() {
    if (options_.interval.count() > 0 && last_ != std::chrono::steady_clock::time_point{}) {
        const auto next = last_ + options_.interval;
        std::this_thread::sleep_until(next);
    }
    last_ = std::chrono::steady_clock::now();
    ++requests_;
}

void Session::log(const tp::Exchange& ex, const std::string& note, bool one_request) {
    if (one_request && tp::repeats_response(ex))
        repeated_.push_back({note + ": the reply came twice", ex.sent, ex.received, ex.elapsed, false});
    // Over Modbus/TCP a copy of the last reply carries its transaction id: the scanner sets it aside as a
    // late reply, which it is not. (Over RTU and ASCII a frame is set aside only for an owed request: none
    // is owed once a reply came.)
    std::size_t copies = 0;
    if (last_reply_ && client_.framing() == modbus::Framing::Tcp)
        for (const auto& f : ex.stale_replies)
            if (tp::repeats_reply(*last_reply_, f.adu()) && copies++ == 0)
                repeated_.push_back({"the previous request's reply again, during: " + note,
                                     last_reply_request_,
                                     {f.adu().begin(), f.adu().end()},
                                     ex.elapsed,
                                     false});
    last_reply_.reset();
    if (one_request && ex.response && ex.response->checksum_ok) {
        last_reply_ = ex.response;
        last_reply_request_ = ex.sent;
    }
    late_replies_ += ex.stale_replies.size() - copies;
    bytes_received_ += ex.received.size();
    // A connection the peer closed ended the wait, no timeout did: "timed out" after 0.003 ms misled.
    evidence_.push_back({ex.closed ? note + " (the connection closed)" : note, ex.sent, ex.received,
                         ex.elapsed, ex.timed_out && !ex.closed});
    if (!ex.timed_out) {
        times_.push_back(ex.elapsed);
        if (ex.response && ex.response->checksum_ok && envelope_fault(ex).empty())
            reply_times_.push_back(ex.elapsed);
    }
    unanswered_in_a_row_ = ex.received.empty() ? unanswered_in_a_row_ + 1 : 0;
}

void Session::log_late(std::vector<std::uint8_t> bytes, const char* when) {
    if (bytes.empty()) return;
    bytes_received_ += bytes.size();
    // The last reply again is that request answered twice, not a late reply.
    const bool again = last_reply_ && tp::repeats_reply(*last_reply_, bytes);
    if (again)
        repeated_.push_back(
            {"the last request's reply again, after it was answered", last_reply_request_, bytes, {}, false});
    // Each owed request a frame among them answers is settled; the others may still be answered.
    const auto frames = tp::frames_in(client_.framing(), bytes);
    for (const auto& frame : frames)
        if (owed().settle(frame)) ++answered_late_;
    late_replies_ += again ? frames.size() - std::min<std::size_t>(frames.size(), 1)
                           : std::max<std::size_t>(frames.size(), 1);
    evidence_.push_back({(again ? "the last reply again: arrived " : "late: arrived ") + std::string(when),
                         {},
                         std::move(bytes),
                         {},
                         false});
    quiet_waits_ = 0;
}

Evidence Session::listen_idle(std::chrono::milliseconds quiet) {
    // A reply still owed would come while listening and pass for one nobody asked for. (Over Modbus/TCP
    // only one due: requests the rules want unanswered, such as protocol id 1, are owed until the end.)
    const bool owing = client_.framing() == modbus::Framing::Tcp ? owed().owes_reply() : !owed().empty();
    if (unanswered_in_a_row_ > 0 || owing) log_late(client_.drain(options_.timeout));
    const auto start = std::chrono::steady_clock::now();
    Evidence e{"listening for " + std::to_string(quiet.count()) + " ms with no request out",
               {},
               client_.drain(quiet),
               {},
               false};
    e.elapsed = std::chrono::steady_clock::now() - start;
    e.timed_out = e.received.empty();
    bytes_received_ += e.received.size();
    evidence_.push_back(e);
    return e;
}

void Session::listen_for_late(std::chrono::milliseconds quiet) {
    const auto start = std::chrono::steady_clock::now();
    auto bytes = client_.drain(quiet);
    if (bytes.empty()) {
        Evidence e{
            "listening " + std::to_string(quiet.count()) + " ms more for late replies", {}, {}, {}, true};
        e.elapsed = std::chrono::steady_clock::now() - start;
        evidence_.push_back(std::move(e));
        return;
    }
    log_late(std::move(bytes), "after the run had given its requests up");
}

void Session::cite(const std::vector<Evidence>& evidence) {
    evidence_.insert(evidence_.end(), evidence.begin(), evidence.end());
}

void Session::settle_late(std::uint8_t unit, std::span<const std::uint8_t> pdu, bool several) {
    if (client_.framing() == modbus::Framing::Tcp) {
        // Over UDP what waits before a request, after one answered in full, is whole datagrams that answer
        // nothing (the second copy of a reply sent twice): read now, each is logged for what it is. Left
        // queued, the next exchange took it for its own reply whenever its transaction id was not just
        // behind the request's (the envelope rules send ids 0, 4660 and 65535), and blamed the device's
        // transaction id echo. After bytes sent without waiting (a rule's pipelined requests) the replies
        // waiting are the next exchange's. Over TCP a read now could cut an ADU still arriving; the scanner
        // sets late ones aside there.
        if (client_.endpoint().scheme == tp::Scheme::Udp && last_reply_)
            log_late(client_.drain(std::chrono::milliseconds(0)));
        return;
    }
    log_late(client_.drain(std::chrono::milliseconds(0)));
    if (quiet_waits_ >= tp::OwedRequests::quiet_waits_kept) return;
    // A late reply to an owed request is told from this one's by its content, unless they look alike; from
    // the replies to several requests in one write, by nothing (the client sets nothing aside there).
    if (several ? !owed().owes_reply() : !owed().owes_reply_like(unit, pdu)) return;
    // Another timeout after the owed request was given up: what has not come by then is taken as never.
    const auto until = owed().newest_given_up() + options_.timeout;
    const auto now = std::chrono::steady_clock::now();
    if (now >= until) return;
    auto late = client_.drain(std::chrono::ceil<std::chrono::milliseconds>(until - now));
    if (late.empty()) ++quiet_waits_;
    log_late(std::move(late));
}

void Session::account(const tp::Exchange& ex, std::uint8_t unit, std::span<const std::uint8_t> pdu) {
    std::vector<tp::SettledRequest> settled;
    if (client_.framing() == modbus::Framing::Tcp) {
        (void)owed().after_tcp(ex, &settled);
    } else {
        if (!ex.stale_replies.empty()) quiet_waits_ = 0;
        (void)owed().after(ex, unit, pdu, &settled);
    }
    answered_late_ += settled.size();
}

tp::Exchange Session::request(std::span<const std::uint8_t> pdu, const std::string& note,
                              std::optional<std::uint8_t> unit,
                              std::optional<std::chrono::milliseconds> timeout) {
    pace();
    const std::uint8_t to = unit.value_or(options_.unit);
    const auto wait = timeout.value_or(options_.timeout);
    const auto start = std::chrono::steady_clock::now();
    if (!connected(wait))
        return not_sent(client_.frame(to, pdu), note, std::chrono::steady_clock::now() - start);
    if (to != 0 || client_.framing() == modbus::Framing::Tcp) ++owed_reply_;
    settle_late(to, pdu);
    auto ex = client_.transact(to, pdu, wait, owed().list());
    if (ex.closed && ex.elapsed.count() == 0) {
        // The write itself failed (the peer went away since the last exchange): nothing was sent. Once
        // connected again, the request goes out; else it is reported not sent, never as timed out.
        connection_lost_ = true;
        if (!connected(wait)) return not_sent(ex.sent, note, std::chrono::steady_clock::now() - start);
        ex = client_.transact(to, pdu, wait, owed().list());
    }
    if (ex.closed) {
        // The device closed the connection (allowed after some malformed requests): the next request gets a
        // fresh one, trying until its timeout if the device refuses it for now.
        connection_lost_ = !client_.reconnect();
    }
    log(ex, note, true);
    account(ex, to, pdu);
    note_write(pdu, response_pdu(ex));
    return ex;
}

modbus::Result<void, std::string> Session::send_part(std::span<const std::uint8_t> bytes) {
    pace();  // the request starts here: no pacing between its parts
    if (!connected(options_.timeout)) return "not sent: could not connect: " + connect_error_;
    settle_late(0, {});
    part_sent_ = true;
    part_.assign(bytes.begin(), bytes.end());
    return client_.write(bytes);
}

tp::Exchange Session::raw(std::span<const std::uint8_t> bytes, const std::string& note, std::size_t frames,
                          std::optional<std::chrono::milliseconds> timeout) {
    // The rest of a request send_part() began is paced and settled there, and what arrives now is its
    // reply, whoever it answers: its last part alone does not say what it asks.
    const bool rest = std::exchange(part_sent_, false);
    // What the bytes are, decoded once (the rest of a split request is nothing on its own).
    std::optional<modbus::Frame> decoded;
    if (!rest)
        if (auto f = modbus::decode_adu(client_.framing(), bytes)) decoded = std::move(f).value();
    // Bytes that decode as one request (whatever their checksum: a device that skips the check answers
    // them) are owed a reply like any other; others are no request anyone could answer.
    const bool tcp = client_.framing() == modbus::Framing::Tcp;
    const modbus::Frame* request = decoded && !tcp && frames == 1 ? &*decoded : nullptr;
    const std::uint8_t unit = request ? request->unit_id() : 0;
    const auto pdu = request ? request->pdu() : std::span<const std::uint8_t>{};
    const auto wait = timeout.value_or(options_.timeout);
    if (!rest) {
        pace();
        const auto start = std::chrono::steady_clock::now();
        if (!connected(std::chrono::ceil<std::chrono::milliseconds>(wait)))
            return not_sent(bytes, note, std::chrono::steady_clock::now() - start);
        settle_late(unit, pdu, frames > 1);
    }
    const bool whole = decoded && decoded->wire_length == bytes.size();
    // One whole request with a good checksum to a unit is owed a reply as request()'s are.
    if (whole && frames > 0 && decoded->checksum_ok && (decoded->unit_id() != 0 || tcp)) ++owed_reply_;
    // Over Modbus/TCP the rest of a split request is awaited as the whole request (its transaction id tells
    // its reply from a late one); over RTU and ASCII what arrives is its reply, whoever it answers.
    std::vector<std::uint8_t> whole_request;
    if (rest && tcp) {
        whole_request = part_;
        whole_request.insert(whole_request.end(), bytes.begin(), bytes.end());
    }
    const auto owed_now = rest && !tcp ? std::span<const tp::OwedRequest>{} : owed().list();
    auto ex = client_.raw(bytes, wait, frames, whole_request, owed_now);
    if (!rest && ex.closed && ex.elapsed.count() == 0) {
        // The write itself failed: nothing was sent (see request()).
        const auto start = std::chrono::steady_clock::now();
        connection_lost_ = true;
        if (!connected(std::chrono::ceil<std::chrono::milliseconds>(wait)))
            return not_sent(bytes, note, std::chrono::steady_clock::now() - start);
        ex = client_.raw(bytes, wait, frames, {}, owed().list());
    }
    if (ex.closed) connection_lost_ = !client_.reconnect();
    const bool one_request = whole && frames == 1;
    log(ex, note, one_request);
    account(ex, unit, pdu);
    // What a write sent here did (a rule's deliberately inconsistent frame that a device may execute), the
    // rest of a split request read together with its first part.
    if (rest) {
        part_.insert(part_.end(), bytes.begin(), bytes.end());
        if (auto f = modbus::decode_adu(client_.framing(), part_))
            note_write(f.value().pdu(), response_pdu(ex));
    } else if (whole && frames == 1) {
        note_write(decoded->pdu(), response_pdu(ex));
    }
    return ex;
}

std::optional<std::vector<std::uint16_t>> Session::read_registers(Table table, std::uint16_t start,
                                                                  std::uint16_t quantity,
                                                                  const std::string& note) {
    const auto fc = modbus::read_function(table);
    const auto pdu = modbus::encode_pdu(modbus::make_read_request(fc, start, quantity));
    const auto rsp = read_answer(request(pdu, note), fc, last_read_refused_);
    if (!rsp) return std::nullopt;
    const auto* regs = std::get_if<modbus::ReadRegistersResponse>(&rsp->body);
    if (!regs || regs->values.size() != quantity) return std::nullopt;
    return regs->values;
}

std::optional<std::vector<bool>> Session::read_bits(Table table, std::uint16_t start, std::uint16_t quantity,
                                                    const std::string& note) {
    const auto fc = modbus::read_function(table);
    const auto pdu = modbus::encode_pdu(modbus::make_read_request(fc, start, quantity));
    const auto rsp = read_answer(request(pdu, note), fc, last_read_refused_);
    if (!rsp) return std::nullopt;
    const auto* bits = std::get_if<modbus::ReadBitsResponse>(&rsp->body);
    if (!bits || bits->values.size() * 8 < quantity) return std::nullopt;
    std::vector<bool> out(quantity);
    for (std::size_t i = 0; i < quantity; ++i)
        out[i] = modbus::bit_at(bits->values, i);
    return out;
}

bool Session::remember(Table table, std::uint16_t start, std::uint16_t count, std::uint16_t chunk) {
    if (chunk == 0) chunk = 1;
    for (std::uint32_t done = 0; done < count;) {
        const auto at = static_cast<std::uint16_t>(start + done);
        const auto n = static_cast<std::uint16_t>(std::min<std::uint32_t>(chunk, count - done));
        bool known = true;
        for (std::uint16_t i = 0; i < n; ++i)
            known &= touched_.count({table, static_cast<std::uint16_t>(at + i)}) != 0;
        if (!known) {
            std::vector<std::uint16_t> values;
            if (modbus::is_bit_table(table)) {
                auto bits = read_bits(table, at, n, "read original values before writing");
                if (!bits) return false;
                for (bool b : *bits)
                    values.push_back(b ? 1 : 0);
            } else {
                auto regs = read_registers(table, at, n, "read original values before writing");
                if (!regs) return false;
                values = *regs;
            }
            for (std::uint16_t i = 0; i < n; ++i) {
                const auto address = static_cast<std::uint16_t>(at + i);
                Touched t;
                t.table = table;
                t.address = address;
                t.original = values[i];
                touched_.try_emplace({table, address}, std::move(t));
            }
        }
        done += n;
    }
    // Where a coil is a view of the holding register at its address (Walchem), writing the coil writes the
    // register: its full value is remembered too. Restoring takes coils first and registers last, so the
    // register ends with its original value, not the 0 or 1 a coil write leaves.
    if (table == Table::Coils && profile_ && profile_->coils_view_registers)
        return remember(Table::HoldingRegisters, start, count, chunk);
    return true;
}

std::optional<std::uint16_t> Session::read_point(Table table, std::uint16_t address,
                                                 const std::string& note) {
    if (modbus::is_bit_table(table)) {
        if (auto b = read_bits(table, address, 1, note)) return (*b)[0] ? 1 : 0;
        return std::nullopt;
    }
    if (auto r = read_registers(table, address, 1, note)) return (*r)[0];
    return std::nullopt;
}

void Session::restore_blocks(Ledger::iterator first, Ledger::iterator last) {
    if (first == last) return;
    const Table table = first->first.first;
    if (table != Table::Coils && table != Table::HoldingRegisters) return;
    const bool coils = table == Table::Coils;
    const std::uint8_t write_fc = coils ? 15 : 16;
    const std::uint8_t read_fc = coils ? 1 : 3;
    int limit = coils ? 1968 : 123;  // AP §6.11, §6.12 without a profile
    if (profile_) {
        if (!profile_->functions.supports(write_fc) || !profile_->functions.supports(read_fc)) return;
        limit = std::min(profile_->functions.max_for(write_fc), profile_->functions.max_for(read_fc));
    }
    if (limit < 2) return;

    std::vector<Touched*> run;  // consecutive addresses, each one the map lets be written
    // After a block write the device answered, a read-back that got nothing usable is read once more before
    // the block is given up: one by one its points cost two requests each (minutes on a serial line for a
    // long block), and a read lost once on a busy line or answered late (the second read waits a late reply
    // out, see settle_late) is common. After a write nothing came back for, the device may be gone: the
    // one-by-one path finds out, and stops.
    const auto read_back = [&](auto read, bool write_answered, std::uint16_t start, std::size_t n,
                               const std::string& span) {
        const auto count = static_cast<std::uint16_t>(n);
        auto now = read(table, start, count, "verify the restored values, " + span);
        if (!now && write_answered)
            now = read(table, start, count, "verify the restored values again, " + span);
        return now;
    };
    // What the block's write left as far as known, before it is read back: the originals when the device
    // acknowledged it; the exception it answered with, for the one-by-one path's report.
    const auto written_back = [&](const tp::Exchange& ex, std::size_t from, std::size_t n) {
        const auto pdu = response_pdu(ex);
        for (std::size_t k = 0; k < n; ++k) {
            Touched& t = *run[from + k];
            if (pdu && !pdu->is_exception()) {
                t.left = t.original;
                t.left_from = "restore";
            }
            t.restore_refused = refusal(ex);
        }
    };
    const auto write_back = [&] {
        for (std::size_t i = 0; i < run.size();) {
            std::size_t n = std::min<std::size_t>(static_cast<std::size_t>(limit), run.size() - i);
            // A 32-bit value is not cut in two between blocks (some devices refuse a lone half).
            if (!coils && i + n < run.size() && profile_) {
                const modbus::Point* p = profile_->find(table, run[i + n - 1]->address);
                if (p && p->encoding.words == 2 && p->address == run[i + n - 1]->address) --n;
            }
            if (device_gone()) break;  // the points left go to the one-by-one path, which says why
            if (n < 2) {               // a lone point goes back on its own, below
                i += std::max<std::size_t>(n, 1);
                continue;
            }
            const std::uint16_t start = run[i]->address;
            const std::string span = std::to_string(n) + " from " + std::to_string(start);
            if (coils) {
                std::unique_ptr<bool[]> bits(new bool[n]);
                for (std::size_t k = 0; k < n; ++k)
                    bits[k] = run[i + k]->original != 0;
                const auto written =
                    request(modbus::encode_pdu(modbus::make_write_multiple_coils(start, {bits.get(), n})),
                            "restore the original values, " + span);
                written_back(written, i, n);
                if (const auto now = read_back([&](auto... a) { return read_bits(a...); },
                                               !written.own_received().empty(), start, n, span))
                    for (std::size_t k = 0; k < n; ++k) {
                        run[i + k]->left = (*now)[k] ? 1 : 0;
                        run[i + k]->left_from = "read";
                        run[i + k]->restored = *run[i + k]->left == run[i + k]->original;
                    }
            } else {
                std::vector<std::uint16_t> words;
                for (std::size_t k = 0; k < n; ++k)
                    words.push_back(run[i + k]->original);
                const auto written =
                    request(modbus::encode_pdu(modbus::make_write_multiple_registers(start, words)),
                            "restore the original values, " + span);
                written_back(written, i, n);
                if (const auto now = read_back([&](auto... a) { return read_registers(a...); },
                                               !written.own_received().empty(), start, n, span))
                    for (std::size_t k = 0; k < n; ++k) {
                        run[i + k]->left = (*now)[k];
                        run[i + k]->left_from = "read";
                        run[i + k]->restored = (*now)[k] == run[i + k]->original;
                    }
            }
            i += n;
        }
        run.clear();
    };
    for (auto it = first; it != last; ++it) {
        Touched& t = it->second;
        const modbus::Point* own = profile_ ? profile_->find(table, t.address) : nullptr;
        if (t.restored || t.device_changed || (own && own->access == modbus::Access::Read)) {
            write_back();
            continue;
        }
        if (!run.empty() && run.back()->address + 1 != t.address) write_back();
        run.push_back(&t);
    }
    write_back();
}

const modbus::Point* Session::pair_of(const Touched& t) const {
    if (t.table != Table::HoldingRegisters || !profile_) return nullptr;
    const modbus::Point* point = profile_->find(t.table, t.address);
    if (!point || point->encoding.words != 2) return nullptr;
    const bool both_kept = touched_.count({t.table, point->address}) != 0 &&
                           touched_.count({t.table, static_cast<std::uint16_t>(point->address + 1)}) != 0;
    return both_kept ? point : nullptr;
}

bool Session::restore_pair_first(const Touched& t) const {
    const modbus::Point* point = pair_of(t);
    return point && point->address == t.address;
}

std::vector<std::uint8_t> Session::restore_pdu(const Touched& t) const {
    if (t.table == Table::Coils)
        return modbus::encode_pdu(modbus::make_write_single_coil(t.address, t.original != 0));
    if (const modbus::Point* point = pair_of(t)) {
        const std::uint16_t pair[2] = {
            touched_.at({t.table, point->address}).original,
            touched_.at({t.table, static_cast<std::uint16_t>(point->address + 1)}).original};
        return modbus::encode_pdu(modbus::make_write_multiple_registers(point->address, pair));
    }
    return modbus::encode_pdu(modbus::make_write_single_register(t.address, t.original));
}

std::string Session::restore_announcement() const {
    if (options_.interval.count() <= 0 || touched_.empty()) return {};
    // What the run did not change is not written back (watch_writes()).
    const std::size_t n =
        watch_writes_
            ? static_cast<std::size_t>(std::count_if(touched_.begin(), touched_.end(),
                                                     [](const auto& kept) { return kept.second.changed; }))
            : touched_.size();
    if (n == 0) return {};
    return "restoring the " + std::to_string(n) + (n == 1 ? " point" : " points") +
           " written, a request every " + std::to_string(options_.interval.count()) +
           " ms (the polling interval)";
}

std::vector<Touched> Session::restore_and_forget() {
    if (touched_.empty()) return {};
    auto ledger = restore();
    // What went back is forgotten; what did not stays, to be tried again by the next call (a device that
    // did not answer then may answer later), from the state before any try.
    // So is what the run did not change (watch_writes()): a later write keeps the value then.
    std::erase_if(touched_, [&](const auto& kept) {
        return kept.second.restored || (watch_writes_ && !kept.second.changed);
    });
    for (auto& [point, t] : touched_)
        t.problem.clear();
    return ledger;
}

void Session::classify_for_restore(Ledger& ledger) {
    for (auto it = ledger.begin(); it != ledger.end();) {
        const Table table = it->first.first;
        const auto read_fc = static_cast<std::uint8_t>(modbus::read_function(table));
        std::size_t limit = modbus::is_bit_table(table) ? 2000 : 125;  // AP §6.1-6.4 without a profile
        if (profile_) limit = static_cast<std::size_t>(std::max(1, profile_->functions.max_for(read_fc)));
        // Consecutive points, as many as one read may ask: read together, else one by one.
        std::vector<Touched*> run;
        auto end = it;
        for (; end != ledger.end() && end->first.first == table && run.size() < limit; ++end) {
            const modbus::Point* own = profile_ ? profile_->find(table, end->first.second) : nullptr;
            if (own && own->access == modbus::Access::Read) break;  // the read-only path reads it itself
            if (!run.empty() && end->first.second != run.back()->address + 1) break;
            run.push_back(&end->second);
        }
        if (run.empty()) {  // a read-only point: left to restore()'s own path
            ++it;
            continue;
        }
        it = end;
        if (device_gone()) continue;  // the restore says why they are not back
        std::optional<std::vector<std::uint16_t>> values;
        const auto start = run.front()->address;
        const auto n = static_cast<std::uint16_t>(run.size());
        const std::string what = "read what the run left, before restoring";
        if (modbus::is_bit_table(table)) {
            if (const auto bits = read_bits(table, start, n, what)) {
                values.emplace();
                for (bool b : *bits)
                    values->push_back(b ? 1 : 0);
            }
        } else {
            values = read_registers(table, start, n, what);
        }
        for (std::size_t k = 0; k < run.size(); ++k) {
            Touched& t = *run[k];
            std::optional<std::uint16_t> now;
            if (values)
                now = (*values)[k];
            else if (n > 1 && !device_gone())
                now = read_point(table, t.address, what);
            if (!now) continue;  // unknown: written back, as a point whose value cannot be read was always
            t.left = now;
            t.left_from = "read";
            if (*now == t.original) {
                t.restored = true;  // back already (a rule set it back, or the device did)
                continue;
            }
            // A value the run wrote is there (or one it wrote is unknown), or the device acknowledged a
            // write of another value than the original and holds something else still (it took the run's
            // value its own way): the run changed it, and it goes back.
            const bool holds_run_value =
                t.unknown_value ||
                std::find(t.run_values.begin(), t.run_values.end(), *now) != t.run_values.end();
            if (holds_run_value || t.acknowledged_change) continue;
            // Neither the original nor a value the run wrote, and no write of another value acknowledged:
            // the device moved it itself. Writing the original would undo the device's own change and call it
            // restored.
            t.device_changed = true;
            t.problem = "not written back: it reads " + std::to_string(*now) +
                        ", neither its original nor a value the run wrote (last " +
                        (t.written ? std::to_string(*t.written) : std::string("unknown")) +
                        ", and no write of another value acknowledged): the device changed it itself";
        }
    }
}

std::vector<Touched> Session::restore() {
    // The restore's own writes are not the run's (note_write), whatever happens.
    restoring_ = true;
    struct Done {
        bool& restoring;
        ~Done() { restoring = false; }
    } done{restoring_};
    unanswered_in_a_row_ = 0;  // the rules before may have asked for silence on purpose
    for (auto& [point, t] : touched_) {
        t.restored = t.device_changed = false;
        t.left.reset();
        t.left_from.clear();
        t.problem.clear();
        t.restore_refused.clear();
    }
    // watch_writes(): only the points the run changed are restored and reported; the others (their write
    // refused, or of the value they held) wait aside, untouched: a device's own change to one (a latch set by
    // its process) was written back and called restored. The other half of a 32-bit value the run changed
    // goes back with it, whole (restore_pdu).
    Ledger aside;
    if (watch_writes_) {
        const auto partner_changed = [&](const Touched& t) {
            if (t.table != Table::HoldingRegisters || !profile_) return false;
            const modbus::Point* p = profile_->find(t.table, t.address);
            if (!p || p->encoding.words != 2) return false;
            const auto other =
                static_cast<std::uint16_t>(p->address == t.address ? t.address + 1 : p->address);
            const auto o = touched_.find({t.table, other});
            return o != touched_.end() && o->second.changed;
        };
        for (auto it = touched_.begin(); it != touched_.end();) {
            if (it->second.changed || partner_changed(it->second))
                ++it;
            else
                aside.insert(touched_.extract(it++));
        }
        classify_for_restore(touched_);
    }
    std::vector<Touched> out;
    std::vector<bool> refused;  // out[i]'s write was answered with an exception
    bool pair_written = false;  // the previous register was restored together with this one
    // Table by table, in the ledger's order (coils before registers: where coils are views of registers, the
    // register must be written last). Consecutive points go back in blocks first; what a block did not
    // bring back, and every other point, one by one.
    for (auto table_begin = touched_.begin(); table_begin != touched_.end();) {
        auto table_end = table_begin;
        while (table_end != touched_.end() && table_end->first.first == table_begin->first.first)
            ++table_end;
        restore_blocks(table_begin, table_end);
        for (auto it = std::exchange(table_begin, table_end); it != table_end; ++it) {
            auto& t = it->second;
            if (t.restored || t.device_changed) {  // by a block, back already, or the device's own value
                out.push_back(t);
                refused.push_back(false);
                pair_written = false;
                continue;
            }
            if (device_gone()) {
                t.problem = connection_lost_ ? "not restored: could not connect (" + connect_error_ + ")"
                                             : "not restored: no reply to " + std::to_string(gone_after) +
                                                   " requests in a row";
                out.push_back(t);
                refused.push_back(false);
                continue;
            }
            // A point the map makes read-only (a block write can span one, a function the device should not
            // have executed can write one) is written back only when it changed: a device that follows its
            // map refuses the write, and its value may move on its own (a process value, a relay state),
            // while a device that took a write there (it failed the rule that made it) takes the original
            // back as well; it used to keep the rule's value. It is reported with what it reads, not judged.
            const modbus::Point* own = profile_ ? profile_->find(t.table, t.address) : nullptr;
            if (own && own->access == modbus::Access::Read) {
                auto now = read_point(t.table, t.address, "read the read-only point");
                if (now && *now != t.original &&
                    !is_exception(request(restore_pdu(t), "write back the read-only point, changed")))
                    now = read_point(t.table, t.address, "verify the restored value");
                t.restored = true;
                if (!now || *now != t.original)
                    t.problem = "read-only in the map, not written back; reads " +
                                (now ? std::to_string(*now) : std::string("nothing")) + ", was " +
                                std::to_string(t.original);
                out.push_back(t);
                refused.push_back(false);
                continue;
            }
            // The second register of a pair written just before is not written again.
            const bool skip_write = std::exchange(pair_written, false);
            const auto pdu = restore_pdu(t);
            pair_written = !skip_write && restore_pair_first(t);  // restore_pdu wrote the pair
            modbus::transport::Exchange ex;
            if (!skip_write) {
                ex = request(pdu, "restore the original value");
                t.restore_refused = refusal(ex);
                if (const auto r = response_pdu(ex); r && !r->is_exception()) {
                    t.left = t.original;
                    t.left_from = "restore";
                }
            }
            const auto now = read_point(t.table, t.address, "verify the restored value");
            if (now) {
                t.left = now;
                t.left_from = "read";
            }
            t.restored = now && *now == t.original;
            if (!t.restored)
                t.problem =
                    now ? "reads " + std::to_string(*now) + " after restoring " + std::to_string(t.original)
                        : std::string(ex.timed_out ? "no reply while restoring" : "could not read it back");
            out.push_back(t);
            refused.push_back(!skip_write && is_exception(ex));
        }
    }
    // Points whose ranges depend on each other (a lower limit that must not exceed its upper limit,
    // MK-RNG-02) refuse their original value until a later point is back: those the device refused are
    // tried again, as long as a pass brings one more back. Only those, and a few passes at most: a chain of
    // limits is short, and a device that answers erratically (a reply now and then that reads as the
    // original) kept a pass over every unrestored point going once per point brought back, hours for the
    // 2,000 coils of the generic profile's quantity rules.
    constexpr int most_passes = 8;
    for (int pass = 0; pass < most_passes && !device_gone(); ++pass) {
        bool progress = false;
        for (std::size_t i = 0; i < out.size(); ++i) {
            auto& t = out[i];
            if (t.restored || !refused[i]) continue;
            auto& kept = touched_.at({t.table, t.address});
            const auto pdu = restore_pdu(t);
            const auto ex = request(pdu, "restore the original value again");
            refused[i] = is_exception(ex);
            t.restore_refused = refusal(ex);
            const auto now = read_point(t.table, t.address, "verify the restored value");
            if (now) {
                t.left = now;
                t.left_from = "read";
            }
            if (now && *now == t.original) {
                t.restored = kept.restored = progress = true;
                t.problem.clear();
                t.restore_refused.clear();
            }
        }
        if (!progress) break;
    }
    // What was not brought back says what it was left holding as far as known (read back, else the last
    // value written to it) and whether the device refused the restore's write: "no reply" alone hid that
    // the run's 20019 stayed, and "reads 0" that the device had answered exception 04.
    for (auto& t : out) {
        if (t.restored) continue;
        if (!t.left && t.written) {
            t.left = t.written;
            t.left_from = "run";
        }
        if (t.device_changed) continue;  // its problem says what it holds
        if (t.left)
            t.problem +=
                "; left holding " + std::to_string(*t.left) +
                (t.left_from == "read"      ? " (read back)"
                 : t.left_from == "restore" ? " as far as known (the restore's write acknowledged, not "
                                              "read back)"
                 : t.acknowledged           ? " as far as known (the last value the run wrote, acknowledged)"
                                  : " as far as known (the last value the run wrote, unacknowledged)");
        else
            t.problem += "; what it holds is unknown";
        if (!t.restore_refused.empty())
            t.problem += "; the device refused the restore's write: " + t.restore_refused;
    }
    // Listed: what the run changed (watch_writes()); the unchanged half of a 32-bit value written back with
    // its other half only when it did not come back.
    if (watch_writes_) std::erase_if(out, [](const Touched& t) { return !t.changed && t.restored; });
    touched_.merge(aside);
    take_evidence();
    return out;
}

}  // namespace mbscope::conformance
