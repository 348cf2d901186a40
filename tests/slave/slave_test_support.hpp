#pragma once
// Shared by the slave tests: the bundled profiles loaded once, PDUs written as hex, a Device driven with PDU
// bytes, and a Server run on 127.0.0.1 port 0 in a thread with a raw socket client beside it.

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "modbus/adu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/endpoint.hpp"
#include "slave/device.hpp"
#include "slave/faults.hpp"
#include "slave/server.hpp"

namespace mbscope::slave::test {

namespace mb = mbscope::modbus;

// The source tree's profiles/, where the bundled profiles live.
inline std::filesystem::path profiles_dir() {
    return std::filesystem::path(MBSCOPE_SOURCE_DIR) / "profiles";
}

inline const mb::storage::ProfileStore& store() {
    static const mb::storage::ProfileStore s({profiles_dir().string()});
    return s;
}

// The bundled devices by id, with the file under profiles/ that defines each, in the store's order. Tests
// name their cases from this list and load a profile from its own file: the store reads and resolves every
// file (about a second under the sanitizers), and ctest runs each test in a process of its own, so naming
// the cases from the store made that second the largest part of a few hundred tests. The list is checked
// against the store (EveryProfileList.IsTheStoresList in rules_test.cpp), so a profile added, removed or
// moved fails there until it is listed here.
struct BundledProfile {
    const char* id;
    const char* file;
};
inline constexpr BundledProfile bundled_profiles[] = {
    {"cth2265i", "cth2265i.json"},
    {"dcy-2050", "mk/3.09-dcy-2050.json"},
    {"dcy-2050-f", "mk/3.09-dcy-2050.json"},
    {"dcy-2050-light", "mk/3.12-dcy-2050-light.json"},
    {"dcy-2051", "mk/3.09-dcy-2050.json"},
    {"dcy-2051-f", "mk/3.09-dcy-2050.json"},
    {"dcy-2051-light", "mk/3.12-dcy-2050-light.json"},
    {"dcy-2058", "mk/3.10-dcy-2058.json"},
    {"dcy-2059", "mk/3.10-dcy-2058.json"},
    {"dmy-2011", "mk/3.15-dmy-2011.json"},
    {"dmy-2011-f", "mk/3.15-dmy-2011.json"},
    {"dmy-2017", "mk/3.14-dmy-2017.json"},
    {"dmy-2031-fcs", "mk/3.23-dmy-2031-fcs.json"},
    {"dmy-2035", "mk/3.15-dmy-2011.json"},
    {"dmy-2036", "mk/3.15-dmy-2011.json"},
    {"mmk-2015-ma", "mk/3.20-mmk-2015-ma.json"},
    {"mmk-2015-ma-v", "mk/3.20-mmk-2015-ma.json"},
    {"mmk-2015-rtd", "mk/3.17-mmk-2015-rtd.json"},
    {"mmk-2015-rtd-ma", "mk/3.21-mmk-2015-rtd-ma.json"},
    {"mmk-2015-rtd-v", "mk/3.21-mmk-2015-rtd-ma.json"},
    {"mmk-2015-tc", "mk/3.16-mmk-2015-tc.json"},
    {"mmk-2015-tc-ma", "mk/3.18-mmk-2015-tc-ma.json"},
    {"mmk-2015-tc-rtd", "mk/3.19-mmk-2015-tc-rtd.json"},
    {"mmk-2015-tc-v", "mk/3.18-mmk-2015-tc-ma.json"},
    {"mmk-2015-v", "mk/3.20-mmk-2015-ma.json"},
    {"mmk-2030", "mk/3.08-mmk-2030.json"},
    {"mmk-2030-f", "mk/3.08-mmk-2030.json"},
    {"mmk-2030-light", "mk/3.11-mmk-2030-light.json"},
    {"mmk-2030-tot", "mk/3.13-mmk-2030-tot.json"},
    {"mmk-2030-tot-f", "mk/3.13-mmk-2030-tot.json"},
    {"mmk-2030-tot-fcs", "mk/3.22-mmk-2030-tot-fcs.json"},
    {"mmk-2032", "mk/3.08-mmk-2030.json"},
    {"modbus", "modbus.json"},
    {"ty-2090", "mk/3.08-mmk-2030.json"},
    {"ty-2090-f", "mk/3.08-mmk-2030.json"},
    {"ty-2095-ma", "mk/3.20-mmk-2015-ma.json"},
    {"ty-2095-ma-v", "mk/3.20-mmk-2015-ma.json"},
    {"ty-2095-rtd", "mk/3.17-mmk-2015-rtd.json"},
    {"ty-2095-rtd-ma", "mk/3.21-mmk-2015-rtd-ma.json"},
    {"ty-2095-rtd-v", "mk/3.21-mmk-2015-rtd-ma.json"},
    {"ty-2095-tc", "mk/3.16-mmk-2015-tc.json"},
    {"ty-2095-tc-ma", "mk/3.18-mmk-2015-tc-ma.json"},
    {"ty-2095-tc-rtd", "mk/3.19-mmk-2015-tc-rtd.json"},
    {"ty-2095-tc-v", "mk/3.18-mmk-2015-tc-ma.json"},
    {"ty-2095-v", "mk/3.20-mmk-2015-ma.json"},
    {"walchem-intuition9", "walchem/walchem-intuition9.json"},
    {"walchem-w600", "walchem/walchem-w600.json"},
    {"walchem-w900", "walchem/walchem-w900.json"},
};

inline std::map<std::string, std::unique_ptr<mb::Profile>>& profile_cache() {
    static std::map<std::string, std::unique_ptr<mb::Profile>> cache;
    return cache;
}

// A bundled profile with its default configuration, loaded once and kept for the life of the test binary
// (a Device keeps a pointer to its profile). A file is read once for all the models it describes.
inline const mb::Profile& profile(const std::string& id) {
    auto& cache = profile_cache();
    auto it = cache.find(id);
    if (it == cache.end()) {
        for (const auto& b : bundled_profiles) {
            if (b.id != id) continue;
            auto loaded = mb::storage::load_profile_file((profiles_dir() / b.file).string());
            for (auto& p : loaded.profiles) {
                std::string key = p.id;  // copied: the profile is moved below
                if (!cache.contains(key))
                    cache.emplace(std::move(key), std::make_unique<mb::Profile>(std::move(p)));
            }
        }
        it = cache.find(id);
        if (it == cache.end()) {
            ADD_FAILURE() << "profile " << id << " is not in bundled_profiles or does not load";
            std::abort();
        }
    }
    return *it->second;
}

// A device that differs from a bundled one as `change` says (a manual's other edition, a firmware that
// behaves otherwise), kept under `id` like the bundled ones, so that profile(id) and RunningServer find it.
inline const mb::Profile& profile_variant(const std::string& id, const std::string& base,
                                          const std::function<void(mb::Profile&)>& change) {
    auto& cache = profile_cache();
    if (auto it = cache.find(id); it != cache.end()) return *it->second;
    auto variant = std::make_unique<mb::Profile>(profile(base));
    variant->id = id;
    change(*variant);
    return *cache.emplace(id, std::move(variant)).first->second;
}

// Every bundled device id, in the store's order.
inline std::vector<std::string> profile_ids() {
    std::vector<std::string> ids;
    for (const auto& b : bundled_profiles)
        ids.emplace_back(b.id);
    return ids;
}

// "03 00 60 00 03" → bytes; spaces are optional.
inline std::vector<std::uint8_t> bytes(std::string_view hex) {
    std::vector<std::uint8_t> out;
    int high = -1;
    for (char c : hex) {
        int v = -1;
        if (c >= '0' && c <= '9') v = c - '0';
        if (c >= 'A' && c <= 'F') v = c - 'A' + 10;
        if (c >= 'a' && c <= 'f') v = c - 'a' + 10;
        if (v < 0) continue;
        if (high < 0) {
            high = v;
        } else {
            out.push_back(static_cast<std::uint8_t>(high * 16 + v));
            high = -1;
        }
    }
    return out;
}

// Bytes → "03 06 02 2B", upper case, one space between bytes (the form expected values are written in).
inline std::string hex(std::span<const std::uint8_t> data) {
    std::string out;
    char buf[4];
    for (std::uint8_t b : data) {
        std::snprintf(buf, sizeof buf, "%02X", b);
        if (!out.empty()) out += ' ';
        out += buf;
    }
    return out;
}

// One request through the device: the reply PDU as hex, "" when the device does not answer.
inline std::string ask(Device& device, std::string_view request_hex, bool broadcast = false) {
    const auto pdu = bytes(request_hex);
    return hex(device.handle({pdu, broadcast}).pdu);
}

// A request PDU of `fc` with a quantity field (read requests, FC15/FC16 with zeroed values).
inline std::vector<std::uint8_t> quantity_request(std::uint8_t fc, std::uint16_t start,
                                                  std::uint32_t quantity) {
    std::vector<std::uint8_t> pdu{fc, static_cast<std::uint8_t>(start >> 8), static_cast<std::uint8_t>(start),
                                  static_cast<std::uint8_t>(quantity >> 8),
                                  static_cast<std::uint8_t>(quantity)};
    if (fc == 15 || fc == 16) {
        const std::size_t n = fc == 15 ? (quantity + 7) / 8 : 2 * quantity;
        pdu.push_back(static_cast<std::uint8_t>(n));
        pdu.insert(pdu.end(), n, 0);
    }
    return pdu;
}

// ---- peer clients: which profiles over which transports

// A profile served over a transport ("tcp", "udp", "rtu-tcp", "ascii-tcp"; "rtu" and "ascii" on a
// pseudo-terminal).
struct ClientCase {
    std::string profile;
    std::string transport;
};

inline std::ostream& operator<<(std::ostream& out, const ClientCase& c) {
    return out << c.profile << " over " << c.transport;
}

// "rtu_tcp": a transport as a test name GoogleTest accepts.
inline std::string transport_test_name(const ::testing::TestParamInfo<std::string>& info) {
    std::string n = info.param;
    for (auto& ch : n)
        if (ch == '-') ch = '_';
    return n;
}

// ---- a server in a thread

// A slave::Server on 127.0.0.1, port 0, serving one unit with the given faults; stopped and joined when the
// object goes away.
class RunningServer {
  public:
    explicit RunningServer(const std::vector<std::string>& faults, std::uint64_t seed = 1,
                           const std::string& profile_id = "modbus", std::uint8_t unit = 1)
        : faults_(specs(faults), seed), device_(profile(profile_id), unit, &faults_) {}

    ~RunningServer() { stop(); }

    Device& device() noexcept { return device_; }
    // Serve the image as the test made it, without the line's settings in the registers that mirror them.
    bool keep_image = false;

    // Opens the endpoint ("tcp://127.0.0.1:0", "rtu:pty?baud=38400" with options.create_pty, ...) and
    // starts serving.
    Server& serve(const std::string& uri, ServerOptions options = {}) {
        auto endpoint = mb::transport::parse_endpoint(uri);
        EXPECT_TRUE(endpoint.has_value()) << uri;
        // The registers mirroring the line read the line served, as mbscope slave makes them (MK-CFG-01),
        // unless the test has set the image itself.
        if (endpoint && !keep_image && device_.image().modifications() == 0)
            device_.image() =
                RegisterImage(device_.profile(), mb::transport::line_state(*endpoint, device_.unit()));
        server_ =
            std::make_unique<Server>(*endpoint, std::vector<Device*>{&device_}, faults_, std::move(options));
        auto opened = server_->open();
        EXPECT_TRUE(opened.has_value()) << uri << ": " << (opened ? "" : opened.error());
        thread_ = std::thread([this] { (void)server_->run(stop_); });
        return *server_;
    }

    // Serves over a transport as the peer-client tests name it: "tcp", "udp", "rtu-tcp", "ascii-tcp" on
    // 127.0.0.1 (a port the system picks), "rtu" and "ascii" on a pseudo-terminal at 38400 baud, 8N1.
    Server& serve_over(const std::string& transport) {
        const bool serial = transport == "rtu" || transport == "ascii";
        ServerOptions o;
        o.create_pty = serial;
        return serve(serial ? transport + ":pty?baud=38400&parity=N" : transport + "://127.0.0.1:0", o);
    }

    // Serves on 127.0.0.1, a port the system picks; the port clients connect to.
    std::uint16_t start(const std::string& scheme) { return serve(scheme + "://127.0.0.1:0").port(); }

    Server& server() noexcept { return *server_; }

    void stop() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
    }

  private:
    static std::vector<FaultSpec> specs(const std::vector<std::string>& texts) {
        std::vector<FaultSpec> out;
        for (const auto& t : texts) {
            auto spec = parse_fault(t);
            EXPECT_TRUE(spec.has_value()) << t;
            if (spec) out.push_back(*spec);
        }
        return out;
    }

    FaultSet faults_;
    Device device_;
    std::unique_ptr<Server> server_;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

// A raw TCP client: sends bytes, reads what arrives within a deadline.
class Client {
  public:
    explicit Client(std::uint16_t port) {
        fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_port = htons(port);
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        connected_ = ::connect(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0;
    }
    ~Client() {
        if (fd_ >= 0) ::close(fd_);
    }
    Client(const Client&) = delete;
    Client& operator=(const Client&) = delete;

    bool connected() const noexcept { return connected_; }

    void send(std::span<const std::uint8_t> data) {
        ASSERT_EQ(::send(fd_, data.data(), data.size(), MSG_NOSIGNAL), static_cast<ssize_t>(data.size()));
    }
    void send(std::string_view text) {
        send(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
    }

    // Whatever arrives in one read within `timeout` (empty when nothing does).
    std::vector<std::uint8_t> read_some(std::chrono::milliseconds timeout) {
        pollfd p{fd_, POLLIN, 0};
        if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return {};
        std::uint8_t buf[1024];
        const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
        return n > 0 ? std::vector<std::uint8_t>(buf, buf + n) : std::vector<std::uint8_t>{};
    }

    // Reads until `count` bytes arrived or `timeout` passed; returns what arrived.
    std::vector<std::uint8_t> read(std::size_t count,
                                   std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
        std::vector<std::uint8_t> out;
        const auto deadline = std::chrono::steady_clock::now() + timeout;
        while (out.size() < count) {
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                deadline - std::chrono::steady_clock::now());
            if (left.count() <= 0) break;
            pollfd p{fd_, POLLIN, 0};
            if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
            std::uint8_t buf[1024];
            const ssize_t n = ::recv(fd_, buf, std::min(sizeof buf, count - out.size()), 0);
            if (n <= 0) break;
            out.insert(out.end(), buf, buf + n);
        }
        return out;
    }

    // True when the server closes the connection (a read returns end of file, or a reset) within
    // `timeout`; what it sends before is read and dropped.
    bool closed_within(std::chrono::milliseconds timeout) {
        const auto deadline = std::chrono::steady_clock::now() + timeout;
        while (std::chrono::steady_clock::now() < deadline) {
            pollfd p{fd_, POLLIN, 0};
            if (::poll(&p, 1, 50) <= 0) continue;
            std::uint8_t buf[256];
            const ssize_t n = ::recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
            if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return true;
        }
        return false;
    }

    // Sends a request and returns the reply's hex: `count` bytes expected; "" when nothing arrives within
    // `timeout`.
    std::string exchange(std::string_view request_hex, std::size_t count,
                         std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
        send(bytes(request_hex));
        return hex(read(count, timeout));
    }

  private:
    int fd_ = -1;
    bool connected_ = false;
};

// The other side of a slave's pseudo-terminal, raw.
inline int open_terminal(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    EXPECT_GE(fd, 0) << path;
    if (fd < 0) return fd;
    termios t{};
    ::tcgetattr(fd, &t);
    ::cfmakeraw(&t);
    ::tcsetattr(fd, TCSANOW, &t);
    return fd;
}

// Reads from a terminal until `count` bytes arrived or `timeout` passed without one; returns what arrived.
inline std::vector<std::uint8_t> read_terminal(int fd, std::size_t count,
                                               std::chrono::milliseconds timeout = std::chrono::seconds(1)) {
    std::vector<std::uint8_t> out;
    while (out.size() < count) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) break;
        std::uint8_t buf[256];
        const ssize_t n = ::read(fd, buf, std::min(sizeof buf, count - out.size()));
        if (n <= 0) break;
        out.insert(out.end(), buf, buf + n);
    }
    return out;
}

// How long a test waits before it concludes that no answer is coming: far above a loopback round trip, also
// under the sanitizers.
inline constexpr std::chrono::milliseconds silence{400};

}  // namespace mbscope::slave::test
