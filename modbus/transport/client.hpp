#pragma once
// The master side of every endpoint: send a request, collect what comes back, with the bytes and the time.
// Shared by the conformance runner and the network fuzzer (one implementation of "what did the slave
// answer"), and by tests that need a client which can also send malformed bytes.
// Where a response ends and which frame is the request's own: exchange.hpp.

#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/result.hpp"
#include "modbus/transport/endpoint.hpp"
#include "modbus/transport/exchange.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::modbus::transport {

struct ClientOptions {
    std::chrono::milliseconds connect_timeout{2000};
    // Serial over TCP has no line timing: a pause this long after the last byte ends an RTU response
    // whose length could not be predicted.
    std::chrono::milliseconds settle{20};
};

class Client {
  public:
    // Connects (TCP schemes), binds a UDP socket, or opens the serial device with the endpoint's line.
    static Result<Client, std::string> open(const Endpoint& endpoint, ClientOptions options = {});

    // Frames `pdu` for the endpoint (a fresh transaction id on MBAP schemes) and waits up to `timeout`.
    // `owed`: RTU and ASCII, earlier requests still unanswered, whose late replies are set aside
    // (exchange.hpp).
    Exchange transact(std::uint8_t unit, std::span<const std::uint8_t> pdu, std::chrono::milliseconds timeout,
                      std::span<const OwedRequest> owed = {});
    // Sends `bytes` exactly as given (malformed frames, split segments, pipelines) and collects replies for
    // up to `timeout` (to the microsecond: the network fuzzer waits less than a millisecond where a fast
    // target must stay silent); stops early after `frames` complete frames (0: wait the whole time).
    // `request`: the whole request when `bytes` is only its last piece (the rest went out with write()); its
    // transaction id tells this request's reply from late ones, and it is the exchange's `sent`. Empty
    // `bytes` write nothing: the exchange listens for the reply to `request`, sent earlier.
    Exchange raw(std::span<const std::uint8_t> bytes, std::chrono::microseconds timeout,
                 std::size_t frames = 1, std::span<const std::uint8_t> request = {},
                 std::span<const OwedRequest> owed = {});
    // Sends without waiting (the first part of a split request); errors when the peer is gone.
    Result<void, std::string> write(std::span<const std::uint8_t> bytes);
    // Reads whatever arrives until `quiet` passes without a byte (resynchronise between tests; a late reply
    // to the previous request); returns it. No longer than twice `quiet` and half a second in all: a device
    // that never falls silent (a chattering line, a flood of bytes) cannot hold the caller.
    std::vector<std::uint8_t> drain(std::chrono::milliseconds quiet);
    // Closes and connects again (after the slave closed the connection).
    Result<void, std::string> reconnect();

    const Endpoint& endpoint() const noexcept { return endpoint_; }
    Framing framing() const noexcept { return framing_of(endpoint_.scheme); }
    std::uint16_t next_transaction_id() const noexcept { return tid_; }
    void set_transaction_id(std::uint16_t tid) noexcept { tid_ = tid; }
    // The ADU `transact` would send.
    std::vector<std::uint8_t> frame(std::uint8_t unit, std::span<const std::uint8_t> pdu);

  private:
    Client(Endpoint endpoint, ClientOptions options) : endpoint_(std::move(endpoint)), options_(options) {}
    Result<void, std::string> connect();

    Endpoint endpoint_;
    ClientOptions options_;
    UniqueFd fd_;
    std::uint16_t tid_ = 1;
};

}  // namespace mbscope::modbus::transport
