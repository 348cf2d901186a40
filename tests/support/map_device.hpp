#pragma once
// A Modbus/TCP device whose map a test can see and whose own process a test can play: the restore tests of
// `mbscope check` and of `mbscope fuzz` / `mbscope replay` use it to show what a restore must leave alone (a
// point the device changed itself) and what it must put back.

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "modbus/transport/socket.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::test {

// A Modbus/TCP device on 127.0.0.1 with 200 points in each table (coil i is i % 3 == 0, holding register i
// is 1000 + i, so a value left behind shows), serving one connection at a time. `hook` sees each request's
// PDU first: it may change the map (the device's own process), answer otherwise (nullopt inside: silence),
// or ask for a reboot after the reply (reboot_for()).
class MapDevice {
  public:
    static constexpr unsigned points = 200;
    using Reply = std::optional<std::vector<std::uint8_t>>;
    using Hook = std::function<std::optional<Reply>(MapDevice&, const std::vector<std::uint8_t>&)>;

    explicit MapDevice(Hook hook, std::uint16_t port = 0) : hook_(std::move(hook)), port_(port) {
        for (unsigned i = 0; i < points; ++i) {
            hr[i] = static_cast<std::uint16_t>(1000 + i);
            co[i] = i % 3 == 0;
        }
        listen();
        thread_ = std::thread([this] { serve(); });
    }
    ~MapDevice() { stop(); }
    MapDevice(const MapDevice&) = delete;
    MapDevice& operator=(const MapDevice&) = delete;
    void stop() {
        done_ = true;
        if (thread_.joinable()) thread_.join();
    }
    std::uint16_t port() const { return port_; }
    // After this reply, the connection closes and connections are refused for `down` (a reboot).
    void reboot_for(std::chrono::milliseconds down) { reboot_ = down; }

    std::array<std::uint16_t, points> hr{};
    std::array<bool, points> co{};

  private:
    void listen() {
        auto l = modbus::transport::listen_tcp("127.0.0.1", port_);
        EXPECT_TRUE(l.has_value()) << (l ? "" : l.error());
        if (!l) return;
        listener_ = std::move(l).value();
        port_ = modbus::transport::bound_port(listener_.get());
    }
    static std::vector<std::uint8_t> exception(std::uint8_t fc, std::uint8_t code) {
        return {static_cast<std::uint8_t>(fc | 0x80), code};
    }
    std::vector<std::uint8_t> answer(const std::vector<std::uint8_t>& pdu) {
        if (pdu.size() < 5) return exception(pdu.empty() ? 0 : pdu[0], 0x03);
        const std::uint8_t fc = pdu[0];
        const unsigned a = (pdu[1] << 8) | pdu[2];
        const unsigned q = (pdu[3] << 8) | pdu[4];
        switch (fc) {
            case 1:
            case 2: {
                if (q < 1 || q > 2000) return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>((q + 7) / 8)};
                r.resize(2 + r[1], 0);
                for (unsigned i = 0; i < q; ++i)
                    if (fc == 1 && co[a + i]) r[2 + i / 8] |= static_cast<std::uint8_t>(1u << (i % 8));
                return r;
            }
            case 3:
            case 4: {
                if (q < 1 || q > 125) return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                std::vector<std::uint8_t> r{fc, static_cast<std::uint8_t>(2 * q)};
                for (unsigned i = 0; i < q; ++i) {
                    const std::uint16_t v = fc == 3 ? hr[a + i] : 0;
                    r.push_back(static_cast<std::uint8_t>(v >> 8));
                    r.push_back(static_cast<std::uint8_t>(v));
                }
                return r;
            }
            case 5:
                if (q != 0 && q != 0xFF00) return exception(fc, 0x03);
                if (a >= points) return exception(fc, 0x02);
                co[a] = q != 0;
                return pdu;
            case 6:
                if (a >= points) return exception(fc, 0x02);
                hr[a] = static_cast<std::uint16_t>(q);
                return pdu;
            case 15:
            case 16: {
                const unsigned max = fc == 15 ? 1968 : 123;
                const std::size_t bytes = fc == 15 ? (q + 7) / 8 : 2 * q;
                if (q < 1 || q > max || pdu.size() < 6 || pdu[5] != bytes || pdu.size() != 6 + bytes)
                    return exception(fc, 0x03);
                if (a + q > points) return exception(fc, 0x02);
                for (unsigned i = 0; i < q; ++i) {
                    if (fc == 15)
                        co[a + i] = (pdu[6 + i / 8] >> (i % 8)) & 1;
                    else
                        hr[a + i] = static_cast<std::uint16_t>((pdu[6 + 2 * i] << 8) | pdu[7 + 2 * i]);
                }
                return {pdu.begin(), pdu.begin() + 5};
            }
            default:
                return exception(fc, 0x01);
        }
    }
    void serve() {
        while (!done_) {
            pollfd incoming{listener_.get(), POLLIN, 0};
            if (::poll(&incoming, 1, 50) != 1) continue;
            serve_connection(modbus::transport::UniqueFd(::accept(listener_.get(), nullptr, nullptr)));
            if (reboot_.count() > 0) {
                // Closed and not listening: connections are refused until the device is back.
                listener_.reset();
                std::this_thread::sleep_for(std::exchange(reboot_, std::chrono::milliseconds(0)));
                listen();
            }
        }
    }
    void serve_connection(modbus::transport::UniqueFd fd) {
        if (!fd) return;
        std::uint8_t header[7];
        for (;;) {
            pollfd p{fd.get(), POLLIN, 0};
            if (::poll(&p, 1, 50) != 1) {
                if (done_) return;
                continue;
            }
            if (::recv(fd.get(), header, 7, MSG_WAITALL) != 7) break;
            const std::size_t length = (header[4] << 8) | header[5];
            std::vector<std::uint8_t> pdu(length > 1 ? length - 1 : 0);
            if (!pdu.empty() && ::recv(fd.get(), pdu.data(), pdu.size(), MSG_WAITALL) != ssize_t(pdu.size()))
                break;
            Reply reply;
            if (auto hooked = hook_(*this, pdu))
                reply = *hooked;
            else
                reply = answer(pdu);
            if (reply) {
                std::vector<std::uint8_t> adu(header, header + 7);
                adu[4] = static_cast<std::uint8_t>((reply->size() + 1) >> 8);
                adu[5] = static_cast<std::uint8_t>(reply->size() + 1);
                adu.insert(adu.end(), reply->begin(), reply->end());
                (void)::send(fd.get(), adu.data(), adu.size(), MSG_NOSIGNAL);
            }
            if (reboot_.count() > 0) break;
        }
    }

  public:
    // Serves a request as the device's map says (for hooks that change only part of the answer).
    std::vector<std::uint8_t> serve_normally(const std::vector<std::uint8_t>& pdu) { return answer(pdu); }

  private:
    Hook hook_;
    std::uint16_t port_;
    modbus::transport::UniqueFd listener_;
    std::atomic<bool> done_{false};
    std::chrono::milliseconds reboot_{0};
    std::thread thread_;
};

}  // namespace mbscope::test
