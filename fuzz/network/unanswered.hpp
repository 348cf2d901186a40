#pragma once
// Modbus/TCP requests that no reply has come for yet, kept for the network fuzzer. A Modbus/TCP reply
// carries its request's transaction id, so where the rules demand silence the fuzzer need not wait to see
// whether the target keeps it: it goes on with the next request, and a reply that comes later (between two
// exchanges, or during one, where the client sets it aside as stale) is matched by its id to the request it
// answers and judged as that request's reply. The same holds for a reply that was due and came after the
// timeout (a slow target): it is judged, and counted as late. A request is kept while its transaction id is
// within the window the client sets stale replies aside in (stale_transaction_window,
// exchange.hpp): a reply further behind would be taken for the current request's anyway.

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "modbus/transport/client.hpp"

namespace mbscope::fuzz::network {

class Unanswered {
  public:
    using Clock = std::chrono::steady_clock;

    struct Request {
        modbus::transport::Exchange exchange;  // `sent` is the request's MBAP frame; nothing received
        Clock::time_point sent;                // when it was written
        Clock::time_point given_up;            // when its exchange ended
        bool reply_due = false;                // false where the rules want no reply
    };

    // A request whose exchange ended without its reply; ignored unless `sent` holds an MBAP header. Requests
    // whose transaction ids are more than `window` behind this one's are dropped.
    void add(const modbus::transport::Exchange& exchange, Clock::time_point sent, Clock::time_point given_up,
             bool reply_due);
    // The request a reply with this transaction id answers, taken off the list (a request has one reply);
    // none when no kept request has that id.
    std::optional<Request> take(std::uint16_t transaction_id);
    // Late replies matched to their requests (taken off the list), to be judged as theirs.
    using Claims = std::vector<std::pair<Request, modbus::Frame>>;
    // A Modbus/TCP frame that came after its request was given up, matched to that request while it is
    // kept (appended to `claims`); false when no kept request has its transaction id.
    bool claim(const modbus::Frame& reply, Claims& claims);
    // Each whole frame in `bytes` (from their front) that a kept request's transaction id claims; returns
    // the other bytes, in order.
    std::vector<std::uint8_t> claim_frames(std::span<const std::uint8_t> bytes, Claims& claims);
    // Listens (nothing is written) until every kept request due a reply has had it, or until `timeout`
    // after the newest such request was given up, claiming the replies as they come. Returns the bytes
    // heard that no kept request claims. A connection closed meanwhile gives up every kept request.
    std::vector<std::uint8_t> await_due(modbus::transport::Client& client, std::chrono::milliseconds timeout,
                                        Claims& claims);
    // The connection the requests went over is gone: no reply to them can come.
    void clear() noexcept { requests_.clear(); }
    bool empty() const noexcept { return requests_.empty(); }
    std::size_t size() const noexcept { return requests_.size(); }
    // When the newest kept request was sent; only when not empty.
    Clock::time_point newest() const { return requests_.back().sent; }
    // The newest kept request that was due a reply; none when no such request is kept.
    const Request* newest_due() const noexcept;

    static constexpr std::uint16_t window = modbus::transport::stale_transaction_window;

  private:
    std::deque<Request> requests_;  // oldest first
};

}  // namespace mbscope::fuzz::network
