#include "modbus/transport/socket.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>
#include <memory>

namespace mbscope::modbus::transport {

namespace {

struct AddrInfoFree {
    void operator()(addrinfo* a) const noexcept { freeaddrinfo(a); }
};
using AddrInfoPtr = std::unique_ptr<addrinfo, AddrInfoFree>;

Result<AddrInfoPtr, std::string> resolve(const std::string& host, std::uint16_t port, int socktype,
                                         bool passive) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = socktype;
    hints.ai_flags = passive ? AI_PASSIVE : 0;
    addrinfo* res = nullptr;
    const std::string service = std::to_string(port);
    const int rc = getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &res);
    if (rc != 0) return host + ":" + service + ": " + gai_strerror(rc);
    return AddrInfoPtr(res);
}

std::string where(const std::string& host, std::uint16_t port) {
    return host + ":" + std::to_string(port);
}

// Tries each resolved address in turn with `setup` (bind, connect) until one succeeds.
template <class Setup>
Result<UniqueFd, std::string> first_working(const std::string& host, std::uint16_t port, int socktype,
                                            bool passive, Setup setup) {
    auto ai = resolve(host, port, socktype, passive);
    if (!ai) return ai.error();
    std::string last = "no address";
    for (addrinfo* a = ai->get(); a; a = a->ai_next) {
        UniqueFd fd(::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol));
        if (!fd) {
            last = std::strerror(errno);
            continue;
        }
        if (std::string err = setup(fd.get(), a); !err.empty()) {
            last = err;
            continue;
        }
        return fd;
    }
    return where(host, port) + ": " + last;
}

Result<UniqueFd, std::string> bound_socket(const std::string& host, std::uint16_t port, int socktype) {
    return first_working(host, port, socktype, true, [socktype](int fd, const addrinfo* a) -> std::string {
        // TCP: a restarted server rebinds its port while old connections sit in TIME_WAIT. Not UDP, where
        // SO_REUSEADDR lets a second socket bind a port in use (even one picked for port 0), and the
        // datagrams meant for one server go to the other.
        const int one = 1;
        if (socktype == SOCK_STREAM) setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (::bind(fd, a->ai_addr, a->ai_addrlen) != 0) return std::strerror(errno);
        return {};
    });
}

}  // namespace

Result<UniqueFd, std::string> listen_tcp(const std::string& host, std::uint16_t port, int backlog) {
    auto fd = bound_socket(host, port, SOCK_STREAM);
    if (!fd) return fd.error();
    if (::listen(fd->get(), backlog) != 0) return where(host, port) + ": listen: " + std::strerror(errno);
    return std::move(fd).value();
}

Result<UniqueFd, std::string> bind_udp(const std::string& host, std::uint16_t port) {
    return bound_socket(host, port, SOCK_DGRAM);
}

Result<UniqueFd, std::string> connect_tcp(const std::string& host, std::uint16_t port,
                                          std::chrono::milliseconds timeout) {
    return first_working(host, port, SOCK_STREAM, false, [timeout](int fd, const addrinfo* a) -> std::string {
        if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
            if (errno != EINPROGRESS) return std::strerror(errno);
            pollfd p{fd, POLLOUT, 0};
            if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return "connection timed out";
            int err = 0;
            socklen_t len = sizeof err;
            getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
            if (err != 0) return std::strerror(err);
        }
        const int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        return {};
    });
}

Result<UniqueFd, std::string> connect_udp(const std::string& host, std::uint16_t port) {
    return first_working(host, port, SOCK_DGRAM, false, [](int fd, const addrinfo* a) -> std::string {
        if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0) return std::strerror(errno);
        return {};
    });
}

std::uint16_t bound_port(int fd) noexcept {
    sockaddr_storage ss{};
    socklen_t len = sizeof ss;
    if (getsockname(fd, reinterpret_cast<sockaddr*>(&ss), &len) != 0) return 0;
    if (ss.ss_family == AF_INET) return ntohs(reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
    if (ss.ss_family == AF_INET6) return ntohs(reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port);
    return 0;
}

}  // namespace mbscope::modbus::transport
