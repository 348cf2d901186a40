#pragma once
// Modbus/TCP requests that no reply has come for yet, kept for the network fuzzer. A Modbus/TCP reply
// carries its request's transaction id, so where the rules demand silence the fuzzer need not wait to see
// whether the target keeps it: it goes on with the next request, and a reply that comes later (between two
// exchanges, or during one, where the client sets it aside as stale) is matched by its id to the request it
// answers and judged as that request's reply. A request is kept for as long as a due reply is waited for
// (the reply timeout); a reply later than that is not attributed, as it would not be to a due request.

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>

#include "modbus/transport/client.hpp"

namespace mbscope::fuzz::network {

class Unanswered {
  public:
    using Clock = std::chrono::steady_clock;

    struct Request {
        modbus::transport::Exchange exchange;  // `sent` is the request's MBAP frame; nothing received
        Clock::time_point sent;
    };

    explicit Unanswered(std::chrono::nanoseconds keep) : keep_(keep) {}

    // A request whose exchange ended without its reply; ignored unless `sent` holds an MBAP header.
    void add(const modbus::transport::Exchange& exchange, Clock::time_point sent);
    // The request a reply with this transaction id answers, taken off the list (a request has one reply):
    // the newest one kept with that id, none when every such request was answered or given up by `now`.
    std::optional<Request> take(std::uint16_t transaction_id, Clock::time_point now);
    // The connection the requests went over is gone: no reply to them can come.
    void clear() noexcept { requests_.clear(); }
    bool empty() const noexcept { return requests_.empty(); }
    std::size_t size() const noexcept { return requests_.size(); }
    // When the newest kept request was sent; only when not empty.
    Clock::time_point newest() const { return requests_.back().sent; }

    // At most this many are kept, whatever the timeout: transaction ids repeat every 65,536 requests, and a
    // campaign at 30,000 requests a second with a long timeout must not grow without bound.
    static constexpr std::size_t capacity = 4096;

  private:
    void expire(Clock::time_point now);

    std::chrono::nanoseconds keep_;
    std::deque<Request> requests_;  // oldest first
};

}  // namespace mbscope::fuzz::network
