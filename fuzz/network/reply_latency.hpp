#pragma once
// How long the network fuzzer waits where the rules demand silence, learnt from the target's own replies:
// TCP's retransmission-timeout estimator (RFC 6298: a smoothed latency and a smoothed deviation from it,
// the timeout their sum with the deviation four times), doubled. About a tenth of the probes must go
// unanswered (broadcasts, foreign units, bad checksums, protocol ids other than 0); waiting the full reply
// timeout for each made a run with the defaults spend over nine tenths of its time waiting (8 requests a
// second against a slave that answers in 50 us, 4,300 with the wait in whole milliseconds). A reply that
// comes after the shorter wait is still judged as that request's when it has arrived by the next request
// (late_bytes). Over Modbus/TCP a campaign's probes do not wait at all (unanswered.hpp); the learnt wait is
// then that of the replays that minimise a reproducer, and of the last request before the connection is
// dropped or the campaign ends.

#include <chrono>

namespace mbscope::fuzz::network {

class ReplyLatency {
  public:
    // The time from a request to the first byte of its reply.
    void add(std::chrono::nanoseconds sample) noexcept;
    // Twice the estimator's timeout, within [floor, cap]; `cap` until a reply was seen.
    std::chrono::microseconds silence_wait(std::chrono::microseconds floor,
                                           std::chrono::microseconds cap) const noexcept;

  private:
    double smoothed_us_ = 0, deviation_us_ = 0;
    bool any_ = false;
};

}  // namespace mbscope::fuzz::network
