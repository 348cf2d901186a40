#include "fuzz/network/unanswered.hpp"

#include <algorithm>

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

}  // namespace mbscope::fuzz::network
