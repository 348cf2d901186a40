#include "modbus/transport/client.hpp"

#include <poll.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>

#include "modbus/adu.hpp"
#include "modbus/transport/serial_port.hpp"
#include "modbus/transport/socket.hpp"

namespace mbscope::modbus::transport {

using Clock = std::chrono::steady_clock;

Result<Client, std::string> Client::open(const Endpoint& endpoint, ClientOptions options) {
    Client c(endpoint, options);
    if (auto r = c.connect(); !r) return r.error();
    return c;
}

Result<void, std::string> Client::connect() {
    fd_.reset();
    switch (endpoint_.scheme) {
        case Scheme::Tcp:
        case Scheme::RtuOverTcp:
        case Scheme::AsciiOverTcp: {
            auto fd = connect_tcp(endpoint_.host, endpoint_.port, options_.connect_timeout);
            if (!fd) return endpoint_.text() + ": " + fd.error();
            fd_ = std::move(fd).value();
            return {};
        }
        case Scheme::Udp: {
            auto fd = connect_udp(endpoint_.host, endpoint_.port);
            if (!fd) return endpoint_.text() + ": " + fd.error();
            fd_ = std::move(fd).value();
            return {};
        }
        case Scheme::RtuSerial:
        case Scheme::AsciiSerial: {
            auto fd = open_serial(endpoint_.device, endpoint_.line);
            if (!fd) return fd.error();
            fd_ = std::move(fd).value();
            return {};
        }
    }
    return std::string("unsupported endpoint");
}

Result<void, std::string> Client::reconnect() {
    return connect();
}

std::vector<std::uint8_t> Client::frame(std::uint8_t unit, std::span<const std::uint8_t> pdu) {
    return encode_adu(framing(), framing() == Framing::Tcp ? tid_++ : std::uint16_t{0}, unit, pdu);
}

Result<void, std::string> Client::write(std::span<const std::uint8_t> bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = is_serial(endpoint_.scheme)
                              ? ::write(fd_.get(), bytes.data() + done, bytes.size() - done)
                              : ::send(fd_.get(), bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
        if (n < 0) {
            if (errno == EINTR) continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK) {
                pollfd p{fd_.get(), POLLOUT, 0};
                ::poll(&p, 1, 1000);
                continue;
            }
            return endpoint_.text() + ": write: " + std::strerror(errno);
        }
        done += static_cast<std::size_t>(n);
    }
    // On a serial port write() returns once the bytes are in the kernel's buffer, while the line still
    // carries them for a character time each (4 ms for a request of 8 bytes at 19200): a reply timed from
    // then was timed from the request's first characters, and framing.reply_after_t3_5 could not fail. The
    // clock starts when the last character has left. (Not on a pseudo-terminal, whose bytes are at the
    // other side at once, and where tcdrain may wait for them to be read.)
    if (is_serial(endpoint_.scheme)) {
        struct stat st {};
        const bool pty = ::fstat(fd_.get(), &st) == 0 && S_ISCHR(st.st_mode) && major(st.st_rdev) >= 136 &&
                         major(st.st_rdev) <= 143;  // UNIX98 pseudo-terminal slaves
        if (!pty) ::tcdrain(fd_.get());
    }
    return {};
}

Exchange Client::transact(std::uint8_t unit, std::span<const std::uint8_t> pdu,
                          std::chrono::milliseconds timeout, std::span<const OwedRequest> owed) {
    const auto adu = frame(unit, pdu);
    return raw(adu, timeout, 1, {}, owed);
}

Exchange Client::raw(std::span<const std::uint8_t> bytes, std::chrono::microseconds timeout,
                     std::size_t frames, std::span<const std::uint8_t> request,
                     std::span<const OwedRequest> owed) {
    Exchange ex;
    if (request.empty()) request = bytes;
    ex.sent.assign(request.begin(), request.end());
    if (auto w = write(bytes); !w) {
        ex.closed = true;
        ex.timed_out = true;
        return ex;
    }
    const auto start = Clock::now();
    const auto deadline = start + timeout;
    const bool datagram = endpoint_.scheme == Scheme::Udp;
    const bool serial = is_serial(endpoint_.scheme);
    const std::chrono::microseconds silence_window =
        serial ? std::chrono::duration_cast<std::chrono::microseconds>(endpoint_.line.t3_5()) +
                     std::chrono::milliseconds(1)
               : std::chrono::microseconds(options_.settle);
    // A server on the same machine or a fast network answers within tens of microseconds: polling without
    // sleeping for that long first spares the wake-up of a sleeping thread, which costs about as much as
    // the exchange (the slave's server loop does the same after answering).
    const auto spin_until = start + std::chrono::microseconds(50);
    ReplyScanner frames_in(framing(), datagram, frames, owed);
    std::uint8_t buf[2048];
    std::chrono::nanoseconds read_at{0};  // when the last read came, and where its bytes begin
    std::size_t read_from = 0;
    for (;;) {
        const auto now = Clock::now();
        if (now >= deadline) break;
        auto wait = std::chrono::duration_cast<std::chrono::microseconds>(deadline - now);
        const bool timing_silence = framing() == Framing::Rtu && !ex.received.empty();
        if (timing_silence) wait = std::min(wait, silence_window);
        const bool spin = now < spin_until && ex.received.empty();
        pollfd p{fd_.get(), POLLIN, 0};
        const auto sleep = spin ? std::chrono::microseconds(0) : std::max(wait, std::chrono::microseconds(1));
        const timespec ts{static_cast<time_t>(sleep.count() / 1'000'000),
                          static_cast<long>(sleep.count() % 1'000'000) * 1000};
        const int rc = ::ppoll(&p, 1, &ts, nullptr);
        if (rc < 0 && errno == EINTR) continue;
        bool silence = false;
        if (rc == 0 && spin) {
            ::sched_yield();
            continue;
        }
        if (rc == 0) {
            if (!timing_silence) continue;
            silence = true;
        } else {
            const ssize_t n = ::read(fd_.get(), buf, sizeof buf);
            if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR && errno != EWOULDBLOCK)) {
                ex.closed = !is_serial(endpoint_.scheme);
                if (ex.closed) break;
                continue;
            }
            if (n < 0) continue;
            const auto previous_read = read_at;
            read_at = Clock::now() - start;
            if (serial && ex.received.size() > frames_in.framed() &&
                read_at - previous_read > ex.longest_pause) {
                ex.longest_pause = read_at - previous_read;
                ex.pause_after = ex.received.size() - frames_in.framed();
            }
            read_from = ex.received.size();
            if (read_from == 0) ex.first_byte = read_at;
            ex.received.insert(ex.received.end(), buf, buf + n);
        }
        if (frames_in.scan(ex, silence) > 0) ex.elapsed = Clock::now() - start;
        // first_byte is when this request's own reply began: late replies set aside come before it (a slow
        // device's reply to the request given up would otherwise make its second reply look prompt).
        if (!silence && ex.received.size() - ex.own_received().size() >= read_from &&
            !ex.own_received().empty())
            ex.first_byte = read_at;
        if (frames_in.complete()) return ex;
    }
    ex.timed_out = frames_in.found() == 0;
    if (frames_in.found() == 0) ex.elapsed = Clock::now() - start;
    return ex;
}

std::vector<std::uint8_t> Client::drain(std::chrono::milliseconds quiet) {
    std::vector<std::uint8_t> out;
    std::uint8_t buf[2048];
    const auto deadline = std::chrono::steady_clock::now() + 2 * quiet + std::chrono::milliseconds(500);
    for (;;) {
        const auto left =
            std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) return out;
        pollfd p{fd_.get(), POLLIN, 0};
        if (::poll(&p, 1, static_cast<int>(std::min(quiet, left).count())) <= 0) return out;
        const ssize_t n = ::read(fd_.get(), buf, sizeof buf);
        if (n <= 0) return out;
        out.insert(out.end(), buf, buf + n);
    }
}

}  // namespace mbscope::modbus::transport
