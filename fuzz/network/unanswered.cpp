#include "fuzz/network/unanswered.hpp"

namespace mbscope::fuzz::network {

namespace {

std::uint16_t transaction_id_of(const modbus::transport::Exchange& ex) {
    return static_cast<std::uint16_t>((ex.sent[0] << 8) | ex.sent[1]);
}

}  // namespace

void Unanswered::add(const modbus::transport::Exchange& exchange, Clock::time_point sent) {
    if (exchange.sent.size() < 7) return;  // no MBAP header: no id a reply could carry
    expire(sent);
    if (requests_.size() == capacity) requests_.pop_front();
    requests_.push_back({exchange, sent});
}

std::optional<Unanswered::Request> Unanswered::take(std::uint16_t transaction_id, Clock::time_point now) {
    expire(now);
    for (auto it = requests_.rbegin(); it != requests_.rend(); ++it) {
        if (transaction_id_of(it->exchange) != transaction_id) continue;
        Request r = std::move(*it);
        requests_.erase(std::next(it).base());
        return r;
    }
    return std::nullopt;
}

void Unanswered::expire(Clock::time_point now) {
    while (!requests_.empty() && now - requests_.front().sent > keep_)
        requests_.pop_front();
}

}  // namespace mbscope::fuzz::network
