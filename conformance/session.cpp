#include "conformance/session.hpp"

#include <algorithm>
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

}  // namespace

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
    evidence_.push_back({note, ex.sent, ex.received, ex.elapsed, ex.timed_out});
    if (!ex.timed_out) {
        times_.push_back(ex.elapsed);
        if (ex.response && ex.response->checksum_ok && envelope_fault(ex).empty())
            reply_times_.push_back(ex.elapsed);
    }
    unanswered_in_a_row_ = ex.received.empty() ? unanswered_in_a_row_ + 1 : 0;
}

void Session::log_late(std::vector<std::uint8_t> bytes) {
    if (bytes.empty()) return;
    // The last reply again is that request answered twice, not a late reply.
    const bool again = last_reply_ && tp::repeats_reply(*last_reply_, bytes);
    if (again)
        repeated_.push_back(
            {"the last request's reply again, after it was answered", last_reply_request_, bytes, {}, false});
    // Each owed request a frame among them answers is settled; the others may still be answered.
    const auto frames = tp::frames_in(client_.framing(), bytes);
    for (const auto& frame : frames)
        (void)owed().settle(frame);
    late_replies_ += again ? frames.size() - std::min<std::size_t>(frames.size(), 1)
                           : std::max<std::size_t>(frames.size(), 1);
    evidence_.push_back(
        {again ? "the last reply again: arrived after the last exchange ended, before this request"
               : "late: arrived after the last exchange ended, before this request",
         {},
         std::move(bytes),
         {},
         false});
    quiet_waits_ = 0;
}

Evidence Session::listen_idle(std::chrono::milliseconds quiet) {
    // A reply still owed would come while listening and pass for one nobody asked for.
    if (unanswered_in_a_row_ > 0 || !owed().empty()) log_late(client_.drain(options_.timeout));
    const auto start = std::chrono::steady_clock::now();
    Evidence e{"listening for " + std::to_string(quiet.count()) + " ms with no request out",
               {},
               client_.drain(quiet),
               {},
               false};
    e.elapsed = std::chrono::steady_clock::now() - start;
    e.timed_out = e.received.empty();
    evidence_.push_back(e);
    return e;
}

void Session::cite(const std::vector<Evidence>& evidence) {
    evidence_.insert(evidence_.end(), evidence.begin(), evidence.end());
}

void Session::settle_late(std::uint8_t unit, std::span<const std::uint8_t> pdu) {
    if (client_.framing() == modbus::Framing::Tcp) return;
    log_late(client_.drain(std::chrono::milliseconds(0)));
    if (quiet_waits_ >= tp::OwedRequests::quiet_waits_kept) return;
    // A late reply to an owed request is told from this one's by its content, unless they look alike.
    if (!owed().owes_reply_like(unit, pdu)) return;
    // Another timeout after the owed request was given up: what has not come by then is taken as never.
    const auto until = owed().newest_given_up() + options_.timeout;
    const auto now = std::chrono::steady_clock::now();
    if (now >= until) return;
    auto late = client_.drain(std::chrono::ceil<std::chrono::milliseconds>(until - now));
    if (late.empty()) ++quiet_waits_;
    log_late(std::move(late));
}

void Session::account(const tp::Exchange& ex, std::uint8_t unit, std::span<const std::uint8_t> pdu) {
    if (client_.framing() == modbus::Framing::Tcp) return;
    if (!ex.stale_replies.empty()) quiet_waits_ = 0;
    (void)owed().after(ex, unit, pdu);
}

tp::Exchange Session::request(std::span<const std::uint8_t> pdu, const std::string& note,
                              std::optional<std::uint8_t> unit,
                              std::optional<std::chrono::milliseconds> timeout) {
    pace();
    const std::uint8_t to = unit.value_or(options_.unit);
    if (to != 0 || client_.framing() == modbus::Framing::Tcp) ++owed_reply_;
    settle_late(to, pdu);
    auto ex = client_.transact(to, pdu, timeout.value_or(options_.timeout), owed().list());
    if (ex.closed) {
        // The device closed the connection (allowed after some malformed requests): the next rule gets a
        // fresh one.
        (void)client_.reconnect();
    }
    log(ex, note, true);
    account(ex, to, pdu);
    return ex;
}

modbus::Result<void, std::string> Session::send_part(std::span<const std::uint8_t> bytes) {
    pace();  // the request starts here: no pacing between its parts
    settle_late(0, {});
    part_sent_ = true;
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
    const modbus::Frame* request =
        decoded && client_.framing() != modbus::Framing::Tcp && frames == 1 ? &*decoded : nullptr;
    const std::uint8_t unit = request ? request->unit_id() : 0;
    const auto pdu = request ? request->pdu() : std::span<const std::uint8_t>{};
    if (!rest) {
        pace();
        settle_late(unit, pdu);
    }
    const bool whole = decoded && decoded->wire_length == bytes.size();
    // One whole request with a good checksum to a unit is owed a reply as request()'s are.
    if (whole && frames > 0 && decoded->checksum_ok &&
        (decoded->unit_id() != 0 || client_.framing() == modbus::Framing::Tcp))
        ++owed_reply_;
    auto ex = client_.raw(bytes, timeout.value_or(options_.timeout), frames, {},
                          rest ? std::span<const tp::OwedRequest>{} : owed().list());
    if (ex.closed) (void)client_.reconnect();
    const bool one_request = whole && frames == 1;
    log(ex, note, one_request);
    account(ex, unit, pdu);
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
                touched_.try_emplace({table, address}, Touched{table, address, values[i], false, {}});
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
                if (const auto now = read_back([&](auto... a) { return read_bits(a...); },
                                               !written.own_received().empty(), start, n, span))
                    for (std::size_t k = 0; k < n; ++k)
                        run[i + k]->restored = ((*now)[k] ? 1 : 0) == run[i + k]->original;
            } else {
                std::vector<std::uint16_t> words;
                for (std::size_t k = 0; k < n; ++k)
                    words.push_back(run[i + k]->original);
                const auto written =
                    request(modbus::encode_pdu(modbus::make_write_multiple_registers(start, words)),
                            "restore the original values, " + span);
                if (const auto now = read_back([&](auto... a) { return read_registers(a...); },
                                               !written.own_received().empty(), start, n, span))
                    for (std::size_t k = 0; k < n; ++k)
                        run[i + k]->restored = (*now)[k] == run[i + k]->original;
            }
            i += n;
        }
        run.clear();
    };
    for (auto it = first; it != last; ++it) {
        Touched& t = it->second;
        const modbus::Point* own = profile_ ? profile_->find(table, t.address) : nullptr;
        if (t.restored || (own && own->access == modbus::Access::Read)) {
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
    const std::size_t n = touched_.size();
    return "restoring the " + std::to_string(n) + (n == 1 ? " point" : " points") +
           " written, a request every " + std::to_string(options_.interval.count()) +
           " ms (the polling interval)";
}

std::vector<Touched> Session::restore_and_forget() {
    if (touched_.empty()) return {};
    auto ledger = restore();
    // What went back is forgotten; what did not stays, to be tried again by the next call (a device that
    // did not answer then may answer later), from the state before any try.
    std::erase_if(touched_, [](const auto& kept) { return kept.second.restored; });
    for (auto& [point, t] : touched_)
        t.problem.clear();
    return ledger;
}

std::vector<Touched> Session::restore() {
    unanswered_in_a_row_ = 0;  // the rules before may have asked for silence on purpose
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
            if (t.restored) {  // by a block
                out.push_back(t);
                refused.push_back(false);
                pair_written = false;
                continue;
            }
            if (device_gone()) {
                t.problem = "not restored: no reply to " + std::to_string(gone_after) + " requests in a row";
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
            if (!skip_write) ex = request(pdu, "restore the original value");
            const auto now = read_point(t.table, t.address, "verify the restored value");
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
            refused[i] = is_exception(request(pdu, "restore the original value again"));
            const auto now = read_point(t.table, t.address, "verify the restored value");
            if (now && *now == t.original) {
                t.restored = kept.restored = progress = true;
                t.problem.clear();
            }
        }
        if (!progress) break;
    }
    take_evidence();
    return out;
}

}  // namespace mbscope::conformance
