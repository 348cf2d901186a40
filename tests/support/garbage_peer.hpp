#pragma once
// A TCP peer on a free loopback port that answers every read with bytes that form no Modbus frame
// ("DE AD BE EF" three times): something that is not a Modbus slave, for the tools that must say so.

#include <poll.h>
#include <sys/socket.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "modbus/transport/socket.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::test {

class GarbagePeer {
  public:
    GarbagePeer() : listener_(std::move(modbus::transport::listen_tcp("127.0.0.1", 0).value())) {
        port_ = modbus::transport::bound_port(listener_.get());
        thread_ = std::thread([this] { serve(); });
    }
    ~GarbagePeer() {
        stop_ = true;
        thread_.join();
    }
    GarbagePeer(const GarbagePeer&) = delete;
    GarbagePeer& operator=(const GarbagePeer&) = delete;
    std::uint16_t port() const { return port_; }

  private:
    void serve() {
        while (!stop_) {
            pollfd p{listener_.get(), POLLIN, 0};
            if (::poll(&p, 1, 50) != 1) continue;
            modbus::transport::UniqueFd c(::accept(listener_.get(), nullptr, nullptr));
            std::uint8_t buf[512];
            while (!stop_ && c.get() >= 0) {
                pollfd q{c.get(), POLLIN, 0};
                if (::poll(&q, 1, 50) != 1) continue;
                if (::recv(c.get(), buf, sizeof buf, 0) <= 0) break;
                static constexpr std::uint8_t garbage[] = {0xDE, 0xAD, 0xBE, 0xEF, 0xDE, 0xAD,
                                                           0xBE, 0xEF, 0xDE, 0xAD, 0xBE, 0xEF};
                (void)::send(c.get(), garbage, sizeof garbage, MSG_NOSIGNAL);
            }
        }
    }
    modbus::transport::UniqueFd listener_;
    std::uint16_t port_ = 0;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

}  // namespace mbscope::test
