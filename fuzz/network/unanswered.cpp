#include "fuzz/network/unanswered.hpp"

#include <algorithm>

#include "modbus/adu.hpp"
#include "modbus/tcp_deframer.hpp"

namespace mbscope::fuzz::network {

namespace {

std::uint16_t transaction_id_of(const modbus::transport::Exchange& ex) {
    return static_cast<std::uint16_t>((ex.sent[0] << 8) | ex.sent[1]);
}

}  // namespace

void Unanswered::add(const modbus::transport::Exchange& exchange, Clock::time_point sent,
                     Clock::time_point given_up, bool reply_due) {
    if (exchange.sent.size() < 7) return;  // no MBAP header: no id a reply could carry
    const std::uint16_t newest = transaction_id_of(exchange);
    // Out of the window: the id repeats every 65,536 requests. The campaign's ids go up by one per request,
    // so the oldest are at the front (and no more than the window's worth are kept, whatever the ids).
    while (!requests_.empty() &&
           (static_cast<std::uint16_t>(newest - transaction_id_of(requests_.front().exchange)) > window ||
            requests_.size() > window))
        requests_.pop_front();
    requests_.push_back({exchange, sent, given_up, reply_due});
}

std::optional<Unanswered::Request> Unanswered::take(std::uint16_t transaction_id) {
    for (auto it = requests_.rbegin(); it != requests_.rend(); ++it) {
        if (transaction_id_of(it->exchange) != transaction_id) continue;
        Request r = std::move(*it);
        requests_.erase(std::next(it).base());
        return r;
    }
    return std::nullopt;
}

const Unanswered::Request* Unanswered::newest_due() const noexcept {
    const auto it =
        std::find_if(requests_.rbegin(), requests_.rend(), [](const Request& r) { return r.reply_due; });
    return it == requests_.rend() ? nullptr : &*it;
}

bool Unanswered::claim(const modbus::Frame& reply, Claims& claims) {
    auto request = take(reply.transaction_id());
    if (!request) return false;
    claims.emplace_back(std::move(*request), reply);
    return true;
}

std::vector<std::uint8_t> Unanswered::claim_frames(std::span<const std::uint8_t> bytes, Claims& claims) {
    std::vector<std::uint8_t> rest;
    std::size_t used = 0;
    while (used < bytes.size()) {
        const auto tail = bytes.subspan(used);
        const auto step = modbus::tcp_step(tail, true, true);
        if (step.kind != modbus::DeframeStep::Kind::Complete) break;
        const auto frame = modbus::decode_adu(modbus::Framing::Tcp, tail.first(step.length));
        if (!frame || !claim(*frame, claims))
            rest.insert(rest.end(), tail.begin(), tail.begin() + step.length);
        used += step.length;
    }
    rest.insert(rest.end(), bytes.begin() + static_cast<std::ptrdiff_t>(used), bytes.end());
    return rest;
}

std::vector<std::uint8_t> Unanswered::await_due(modbus::transport::Client& client,
                                                std::chrono::milliseconds timeout, Claims& claims) {
    std::vector<std::uint8_t> rest;
    while (const Request* due = newest_due()) {
        const auto now = Clock::now();
        const auto until = due->given_up + timeout;
        if (now >= until) break;
        // Listens as for that request's reply: replies to the kept requests before it are set aside on the
        // way.
        const auto heard = client.raw({}, std::chrono::duration_cast<std::chrono::microseconds>(until - now),
                                      1, due->exchange.sent);
        const auto kept = size();
        auto unclaimed = claim_frames(heard.received, claims);
        rest.insert(rest.end(), unclaimed.begin(), unclaimed.end());
        if (heard.closed) clear();
        if (heard.received.empty() || size() == kept) break;  // nothing kept was answered
    }
    return rest;
}

}  // namespace mbscope::fuzz::network
