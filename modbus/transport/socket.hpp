#pragma once
// Sockets for the network schemes of endpoint.hpp. All are non-blocking and close-on-exec.

#include <chrono>
#include <cstdint>
#include <string>

#include "modbus/result.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::modbus::transport {

// A listening TCP socket (SO_REUSEADDR). Port 0 picks a free port; bound_port tells which.
Result<UniqueFd, std::string> listen_tcp(const std::string& host, std::uint16_t port, int backlog = 128);
// A bound UDP socket.
Result<UniqueFd, std::string> bind_udp(const std::string& host, std::uint16_t port);
// A connected TCP socket, waiting at most `timeout` for the connection (TCP_NODELAY set).
Result<UniqueFd, std::string> connect_tcp(const std::string& host, std::uint16_t port,
                                          std::chrono::milliseconds timeout);
// A connected UDP socket: send() reaches the server, recv() returns only its datagrams.
Result<UniqueFd, std::string> connect_udp(const std::string& host, std::uint16_t port);
std::uint16_t bound_port(int fd) noexcept;

}  // namespace mbscope::modbus::transport
