#include "fuzz/network/written_points.hpp"

#include <algorithm>
#include <variant>

#include "conformance/context.hpp"
#include "modbus/ascii_deframer.hpp"
#include "modbus/pdu.hpp"
#include "modbus/rtu_deframer.hpp"
#include "modbus/transport/exchange.hpp"

namespace mbscope::fuzz::network {
namespace {

std::uint16_t word(std::span<const std::uint8_t> pdu, std::size_t at) {
    return at + 1 < pdu.size() ? static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]) : 0;
}

struct LooseRequest {
    std::uint8_t unit = 0;
    std::vector<std::uint8_t> pdu;
    std::uint16_t transaction_id = 0;  // Modbus/TCP: its MBAP header's
};

// The requests a step's bytes carry as a device may read them, well formed or not. Over Modbus/TCP the ADUs
// its MBAP length fields delimit, and, where a length field is out of range or promises more than there
// is, everything after that header as one PDU: a device that sizes a request by its function code never
// reads the field (libmodbus does so, fuzz/README.md "Differences from libmodbus") and executes it. Over
// RTU and ASCII every frame the deframer finds, whatever its checksum (a device that skips the check
// executes it); unparsed bytes carry no request.
std::vector<LooseRequest> loose_requests(modbus::Framing framing, std::span<const std::uint8_t> bytes) {
    std::vector<LooseRequest> out;
    if (framing == modbus::Framing::Tcp) {
        constexpr std::size_t header = 7;  // MBAP: transaction, protocol, length, unit
        for (std::size_t at = 0; at + header < bytes.size();) {
            const std::size_t length = word(bytes, at + 4);
            const bool delimited = length >= 2 && length <= 254 && at + 6 + length <= bytes.size();
            const std::size_t end = delimited ? at + 6 + length : bytes.size();
            out.push_back({bytes[at + 6],
                           {bytes.begin() + static_cast<std::ptrdiff_t>(at + header),
                            bytes.begin() + static_cast<std::ptrdiff_t>(end)},
                           word(bytes, at)});
            at = end;
        }
        return out;
    }
    modbus::DeframeEvents events;
    if (framing == modbus::Framing::Rtu) {
        modbus::RtuDeframer deframer;
        deframer.feed(bytes, events);
        deframer.finish(events);
    } else {
        modbus::AsciiDeframer deframer;
        deframer.feed(bytes, events);
        deframer.finish(events);
    }
    for (const auto& e : events)
        if (const auto* frame = std::get_if<modbus::Frame>(&e)) {
            const auto pdu = frame->pdu();
            out.push_back({frame->unit_id(), {pdu.begin(), pdu.end()}});
        }
    return out;
}

// Whether a request to `unit` can land on the session's device: addressed to it or broadcast, or to any unit
// over Modbus/TCP, where devices that ignore the unit id are common.
bool lands(conformance::Session& session, std::uint8_t unit) {
    return session.client().framing() == modbus::Framing::Tcp || unit == session.options().unit || unit == 0;
}

// The device's answer to `request` among `replies` (what came for its step, then its late replies), each
// reply the answer to one request at most (`used`): over Modbus/TCP the one with its transaction id, unit
// and protocol id 0, over RTU and ASCII the first one with a good checksum that could answer it (a device
// answers in order). nullopt: none, or one no PDU decodes from, which tells nothing of what was done.
std::optional<modbus::Pdu> reply_to(modbus::Framing framing, const LooseRequest& request,
                                    const std::vector<modbus::Frame>& replies, std::vector<bool>& used) {
    // A broadcast on a serial line draws no reply (SL §2.1), and could_answer() takes any unit's for unit 0:
    // the exception refusing the write after it in the same step made the executed broadcast "refused",
    // and the point it wrote was neither restored nor listed. It is kept as a write that may have run.
    if (framing != modbus::Framing::Tcp && request.unit == 0) return std::nullopt;
    for (std::size_t i = 0; i < replies.size(); ++i) {
        const modbus::Frame& f = replies[i];
        const bool answers =
            framing == modbus::Framing::Tcp
                ? f.transaction_id() == request.transaction_id && f.protocol_id() == 0 &&
                      (request.unit == 0 || f.unit_id() == request.unit)
                : f.checksum_ok && modbus::transport::could_answer(request.unit, request.pdu, f);
        if (used[i] || !answers) continue;
        used[i] = true;
        auto pdu = modbus::decode_response(f.pdu());
        if (!pdu) return std::nullopt;
        return std::move(pdu).value();
    }
    return std::nullopt;
}

}  // namespace

std::optional<WriteRange> write_range(std::span<const std::uint8_t> pdu) {
    using modbus::Table;
    if (pdu.size() < 3) return std::nullopt;
    const std::uint16_t a = word(pdu, 1);
    switch (pdu[0]) {
        case 5:
            return WriteRange{Table::Coils, a, 1};
        case 6:
        case 22:
            return WriteRange{Table::HoldingRegisters, a, 1};
        case 15:
            return WriteRange{Table::Coils, a, std::min<std::uint16_t>(word(pdu, 3), modbus::max_write_bits)};
        case 16:
            return WriteRange{Table::HoldingRegisters, a,
                              std::min<std::uint16_t>(word(pdu, 3), modbus::max_write_registers)};
        case 23:
            return WriteRange{Table::HoldingRegisters, word(pdu, 5),
                              std::min<std::uint16_t>(word(pdu, 7), modbus::max_rw_write_registers)};
        default:
            return std::nullopt;
    }
}

std::size_t keep_registers(std::vector<std::uint8_t>& pdu,
                           const std::function<std::optional<std::uint16_t>(std::uint16_t)>& held) {
    const auto range = write_range(pdu);
    if (!range || range->table != modbus::Table::HoldingRegisters) return 0;
    // Where the values lie in the PDU (AP §6.6, §6.12, §6.17): after the address; after the address,
    // quantity and byte count; after the read and write ranges and the byte count.
    const std::size_t values = pdu[0] == 6 ? 3 : pdu[0] == 16 ? 6 : pdu[0] == 23 ? 10 : 0;
    std::size_t kept = 0;
    for (std::uint32_t i = 0; range->start + i < range->end(); ++i) {
        const auto value = held(static_cast<std::uint16_t>(range->start + i));
        if (!value) continue;
        if (pdu[0] == 22) {  // AP §6.16: (current AND and_mask) OR (or_mask AND NOT and_mask)
            if (pdu.size() < 7) continue;
            pdu[3] = pdu[4] = 0xFF;
            pdu[5] = pdu[6] = 0x00;
            ++kept;
            continue;
        }
        const std::size_t at = values + 2 * i;
        if (values == 0 || at + 1 >= pdu.size()) continue;
        pdu[at] = static_cast<std::uint8_t>(*value >> 8);
        pdu[at + 1] = static_cast<std::uint8_t>(*value);
        ++kept;
    }
    return kept;
}

std::vector<WriteRange> ranges_of(const std::set<std::pair<modbus::Table, std::uint16_t>>& points) {
    std::vector<WriteRange> out;
    for (const auto& [table, address] : points) {
        if (!out.empty() && out.back().table == table &&
            std::uint32_t{out.back().start} + out.back().count == address) {
            ++out.back().count;
            continue;
        }
        out.push_back({table, address, 1});
    }
    return out;
}

nlohmann::json to_json(const std::vector<WriteRange>& ranges) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& w : ranges)
        out.push_back(
            {{"table", std::string(modbus::to_string(w.table))}, {"start", w.start}, {"count", w.count}});
    return out;
}

std::string to_string(const WriteRange& range) {
    return std::string(modbus::to_string(range.table)) + ' ' + std::to_string(range.start) + " (" +
           std::to_string(range.count) + (range.count == 1 ? " point)" : " points)");
}

std::vector<WriteRange> read_blocks(const modbus::Profile& profile, const WriteRange& range) {
    std::vector<WriteRange> out;
    const std::uint32_t end = range.end();
    if (profile.open_address_space) {
        for (std::uint32_t a = range.start; a < end; a += 100)
            out.push_back({range.table, static_cast<std::uint16_t>(a),
                           static_cast<std::uint16_t>(std::min<std::uint32_t>(100, end - a))});
        return out;
    }
    const std::uint8_t read_fc = range.table == modbus::Table::Coils              ? 1
                                 : range.table == modbus::Table::DiscreteInputs   ? 2
                                 : range.table == modbus::Table::HoldingRegisters ? 3
                                                                                  : 4;
    const auto limit = static_cast<std::uint32_t>(std::max(1, profile.functions.max_for(read_fc)));
    for (std::uint32_t a = range.start; a < end; ++a) {
        const auto* point = profile.find(range.table, static_cast<std::uint16_t>(a));
        if (!point || point->access == modbus::Access::Write) continue;
        if (!out.empty() && out.back().end() == a && out.back().count < limit) {
            ++out.back().count;
            continue;
        }
        out.push_back({range.table, static_cast<std::uint16_t>(a), 1});
    }
    return out;
}

bool remember_range(conformance::Session& session, const modbus::Profile& profile, const WriteRange& range) {
    for (const auto& block : read_blocks(profile, range)) {
        if (session.remember(block.table, block.start, block.count, block.count)) continue;
        // A block refused as a whole is read point by point: a device may refuse a range for one point in
        // it (a condition, a part of a value) and still let the others be read.
        if (profile.open_address_space || block.count == 1 || !session.last_read_refused() ||
            !session.remember(block.table, block.start, block.count, 1))
            return false;
    }
    return true;
}

std::size_t reads_to_remember(const conformance::Session& session, const modbus::Profile& profile,
                              const WriteRange& range) {
    std::size_t reads = 0;
    const auto count_unknown = [&](const WriteRange& r) {
        for (const auto& block : read_blocks(profile, r))
            for (std::uint32_t a = block.start; a < block.end(); ++a)
                if (!session.touched().count({block.table, static_cast<std::uint16_t>(a)})) {
                    ++reads;
                    break;
                }
    };
    count_unknown(range);
    if (range.table == modbus::Table::Coils && profile.coils_view_registers)  // Session::remember
        count_unknown({modbus::Table::HoldingRegisters, range.start, range.count});
    return reads;
}

std::vector<std::pair<modbus::Table, std::uint16_t>> points_not_read(const conformance::Session& session,
                                                                     const modbus::Profile& profile,
                                                                     const WriteRange& range) {
    std::vector<std::pair<modbus::Table, std::uint16_t>> out;
    for (std::uint32_t a = range.start; a < range.end(); ++a) {
        const std::pair<modbus::Table, std::uint16_t> point{range.table, static_cast<std::uint16_t>(a)};
        const auto* own = profile.open_address_space ? nullptr : profile.find(point.first, point.second);
        if (!session.touched().count(point) && !(own && own->access == modbus::Access::Write))
            out.push_back(point);
    }
    return out;
}

RememberedWrites remember_writes(conformance::Session& session, const modbus::Profile& profile,
                                 const std::vector<Step>& steps) {
    RememberedWrites out;
    const auto framing = session.client().framing();
    for (std::size_t i = 0; i < steps.size(); ++i)
        for (const auto& request : loose_requests(framing, steps[i].joined())) {
            if (!lands(session, request.unit)) continue;
            const auto range = write_range(request.pdu);
            if (!range || range->count == 0) continue;
            if (!remember_range(session, profile, *range)) {
                out.unread.push_back(*range);
                continue;
            }
            const auto missing = points_not_read(session, profile, *range);
            if (missing.empty()) continue;
            out.unchecked.push_back({i, request.pdu[0], ranges_of({missing.begin(), missing.end()})});
        }
    return out;
}

void note_step_writes(conformance::Session& session, const Step& step, const ReplayedStep& replayed) {
    if (session.touched().empty()) return;  // no point read first: none a write could be kept for
    const auto framing = session.client().framing();
    auto requests = loose_requests(framing, step.joined());
    std::erase_if(requests,
                  [&](const LooseRequest& r) { return !lands(session, r.unit) || !write_range(r.pdu); });
    if (requests.empty()) return;
    auto replies = modbus::transport::frames_in(framing, replayed.exchange.own_received());
    replies.insert(replies.end(), replayed.late_replies.begin(), replayed.late_replies.end());
    std::vector<bool> used(replies.size());
    for (const auto& request : requests)
        session.note_write(request.pdu, reply_to(framing, request, replies, used));
}

void note_late_answer(conformance::Session& session, std::span<const std::uint8_t> request_pdu,
                      const modbus::Frame& reply) {
    if (!reply.checksum_ok) return;
    auto pdu = modbus::decode_response(reply.pdu());
    if (pdu) session.note_write(request_pdu, std::move(pdu).value(), true);
}

namespace {

enum class Answer { Acknowledged, Refused, None };

// What the step of an unchecked write drew for the write's function.
Answer answer_to(const UncheckedWrite& w, modbus::Framing framing, const std::vector<ReplayedStep>& steps) {
    const auto replies = loose_requests(framing, steps[w.step].exchange.received);
    const std::uint8_t function[] = {w.function};
    if (std::any_of(replies.begin(), replies.end(),
                    [&](const LooseRequest& r) { return acknowledges(function, r.pdu); }))
        return Answer::Acknowledged;
    if (std::any_of(replies.begin(), replies.end(),
                    [&](const LooseRequest& r) { return !r.pdu.empty() && r.pdu[0] == (w.function | 0x80); }))
        return Answer::Refused;
    return Answer::None;
}

// The points of the unchecked writes of steps the replay reached that drew `answer`.
std::set<std::pair<modbus::Table, std::uint16_t>> unchecked_points(
    const std::vector<UncheckedWrite>& unchecked, modbus::Framing framing,
    const std::vector<ReplayedStep>& steps, Answer answer) {
    std::set<std::pair<modbus::Table, std::uint16_t>> points;
    for (const auto& w : unchecked) {
        if (w.step >= steps.size()) continue;  // the replay stopped before it
        if (answer_to(w, framing, steps) != answer) continue;
        for (const auto& range : w.points)
            for (std::uint32_t a = range.start; a < range.end(); ++a)
                points.insert({range.table, static_cast<std::uint16_t>(a)});
    }
    return points;
}

}  // namespace

std::vector<WriteRange> acknowledged_unchecked(const std::vector<UncheckedWrite>& unchecked,
                                               modbus::Framing framing,
                                               const std::vector<ReplayedStep>& steps) {
    return ranges_of(unchecked_points(unchecked, framing, steps, Answer::Acknowledged));
}

std::set<std::pair<modbus::Table, std::uint16_t>> unanswered_unchecked(
    const std::vector<UncheckedWrite>& unchecked, modbus::Framing framing,
    const std::vector<ReplayedStep>& steps) {
    return unchecked_points(unchecked, framing, steps, Answer::None);
}

namespace {

enum class ReadAnswer { Values, Refused, Unusable, Silence };

// One read of [start, start + count) of `table`, its values appended to `held` when the device gives them.
// Refused: an exception of the read's function. Unusable: a reply came before the timeout and tells nothing
// about the points (a malformed one, another function's or transaction's). Silence: the read waited the whole
// timeout for nothing it could use (no reply, a reply cut short, a closed connection).
ReadAnswer read_piece(conformance::Session& session, modbus::Table table, std::uint16_t start,
                      std::uint16_t count, std::vector<HeldPoint>& held) {
    const bool bits = modbus::is_bit_table(table);
    const auto fc = modbus::read_function(table);
    const auto request = modbus::encode_pdu(modbus::make_read_request(fc, start, count));
    const auto exchange = session.request(request, "read after a write that drew no reply");
    const auto reply = conformance::response_pdu(exchange);
    if (!reply) return exchange.timed_out || exchange.closed ? ReadAnswer::Silence : ReadAnswer::Unusable;
    if (reply->function_code() != static_cast<std::uint8_t>(fc)) return ReadAnswer::Unusable;
    if (reply->is_exception()) return ReadAnswer::Refused;
    const auto at = [&](std::size_t i) { return static_cast<std::uint16_t>(start + i); };
    if (const auto* r = std::get_if<modbus::ReadRegistersResponse>(&reply->body); r && !bits) {
        if (r->values.size() != count) return ReadAnswer::Unusable;
        for (std::size_t i = 0; i < count; ++i)
            held.push_back({table, at(i), r->values[i]});
        return ReadAnswer::Values;
    }
    if (const auto* r = std::get_if<modbus::ReadBitsResponse>(&reply->body); r && bits) {
        if (r->values.size() * 8 < count) return ReadAnswer::Unusable;
        for (std::size_t i = 0; i < count; ++i)
            held.push_back({table, at(i), static_cast<std::uint16_t>(modbus::bit_at(r->values, i) ? 1 : 0)});
        return ReadAnswer::Values;
    }
    return ReadAnswer::Unusable;
}

}  // namespace

unsigned single_reads_within_a_minute(std::chrono::milliseconds interval) {
    if (interval.count() <= 0) return ReadHeldLimits{}.single_reads;
    const auto fit = std::chrono::milliseconds(60'000) / interval;
    return static_cast<unsigned>(std::clamp<std::int64_t>(fit, 1, ReadHeldLimits{}.single_reads));
}

HeldReading read_held(conformance::Session& session,
                      const std::set<std::pair<modbus::Table, std::uint16_t>>& points,
                      const ReadHeldLimits& limits) {
    HeldReading out;
    std::set<std::pair<modbus::Table, std::uint16_t>> unread;
    unsigned silent = 0;  // reads in a row that waited the whole timeout
    unsigned singles_left = limits.single_reads;
    // Reads one piece (none once the device is taken to be gone, or the reading is interrupted); the points
    // of one that drew neither values nor an exception are unread. A device that answers, however wrongly,
    // is not gone: only silence counts.
    const auto read = [&](modbus::Table table, std::uint16_t start, std::uint16_t count) {
        ReadAnswer answer = ReadAnswer::Silence;
        out.interrupted = out.interrupted || (limits.interrupted && limits.interrupted());
        if (silent < silent_reads_before_giving_up && !out.interrupted)
            answer = read_piece(session, table, start, count, out.held);
        silent = answer == ReadAnswer::Silence ? silent + 1 : 0;
        if (answer == ReadAnswer::Silence || answer == ReadAnswer::Unusable)
            for (std::uint32_t a = start; a < std::uint32_t{start} + count; ++a)
                unread.insert({table, static_cast<std::uint16_t>(a)});
        return answer;
    };
    for (const auto& range : ranges_of(points)) {
        const std::uint32_t chunk =
            modbus::is_bit_table(range.table) ? modbus::max_read_bits : modbus::max_read_registers;
        for (std::uint32_t start = range.start; start < range.end(); start += chunk) {
            const auto count = static_cast<std::uint16_t>(std::min(chunk, range.end() - start));
            if (read(range.table, static_cast<std::uint16_t>(start), count) != ReadAnswer::Refused ||
                count == 1)
                continue;
            if (count > singles_left) {
                out.refused.push_back({range.table, static_cast<std::uint16_t>(start), count});
                continue;
            }
            singles_left -= count;
            for (std::uint32_t a = start; a < start + count; ++a)
                (void)read(range.table, static_cast<std::uint16_t>(a), 1);
        }
    }
    (void)session.take_evidence();
    out.unread = ranges_of(unread);
    return out;
}

nlohmann::json to_json(const std::vector<HeldPoint>& points) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& p : points)
        out.push_back(
            {{"table", std::string(modbus::to_string(p.table))}, {"address", p.address}, {"value", p.value}});
    return out;
}

}  // namespace mbscope::fuzz::network
