#include "analyzer/live_capture.hpp"

#include <pcap/pcap.h>
#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "modbus/transport/serial_port.hpp"

namespace mbscope::analyzer {

using modbus::Direction;
using modbus::Timestamp;
using modbus::transport::UniqueFd;

namespace {

constexpr int snap_length = 65535;
constexpr int read_timeout_ms = 100;  // how often the loop looks at the clock and the stop flag
constexpr int drain_timeout_ms = 20;  // after a stop, the silence that ends the serial capture

Timestamp wall_clock() {
    return std::chrono::duration_cast<Timestamp>(std::chrono::system_clock::now().time_since_epoch());
}

}  // namespace

std::string capture_filter(const SniffOptions& o) {
    std::string filter;
    auto add = [&](const char* proto, std::uint16_t port) {
        filter += (filter.empty() ? "" : " or ") + std::string(proto) + " port " + std::to_string(port);
    };
    for (auto p : o.tcp_ports)
        add("tcp", p);
    for (auto p : o.udp_ports)
        add("udp", p);
    return filter;
}

std::string pcap_output_name(const std::string& requested) {
    constexpr std::string_view ng = ".pcapng";
    if (requested.size() > ng.size() && requested.ends_with(ng))
        return requested.substr(0, requested.size() - ng.size()) + ".pcap";
    return requested;
}

struct LiveCapture::Impl {
    pcap_t* pcap = nullptr;  // network capture
    pcap_t* dead = nullptr;  // serial capture's output: a USER0 "capture" for pcap_dump_open
    pcap_dumper_t* dumper = nullptr;
    UniqueFd serial[2];
    ~Impl() {
        if (dumper) pcap_dump_close(dumper);
        if (pcap) pcap_close(pcap);
        if (dead) pcap_close(dead);
    }
    bool direction_header = false;  // two serial taps: one byte of UserDltDirection ahead of each record
    std::vector<std::uint8_t> record;
    void dump(Timestamp t, std::span<const std::uint8_t> bytes, int port) {
        if (!dumper) return;
        if (direction_header) {
            record.assign(1, static_cast<std::uint8_t>(port == 0 ? UserDltDirection::MasterToSlave
                                                                 : UserDltDirection::SlaveToMaster));
            record.insert(record.end(), bytes.begin(), bytes.end());
            bytes = record;
        }
        pcap_pkthdr h{};
        h.ts.tv_sec = static_cast<time_t>(std::chrono::duration_cast<std::chrono::seconds>(t).count());
        h.ts.tv_usec = static_cast<suseconds_t>(
            std::chrono::duration_cast<std::chrono::microseconds>(t % std::chrono::seconds(1)).count());
        h.caplen = h.len = static_cast<bpf_u_int32>(bytes.size());
        pcap_dump(reinterpret_cast<u_char*>(dumper), &h, bytes.data());
        pcap_dump_flush(dumper);  // a serial read is rare: the file is complete even if the process is killed
    }
};

std::unique_ptr<LiveCapture> LiveCapture::open(const SniffOptions& o, std::string& error,
                                               bool& permission_denied) {
    permission_denied = false;
    std::unique_ptr<LiveCapture> c(new LiveCapture);
    c->impl_ = std::make_unique<Impl>();
    c->options_ = o;
    Impl& m = *c->impl_;
    pcap_t* writer = nullptr;
    if (!o.interface.empty()) {
        c->name_ = o.interface;
        char err[PCAP_ERRBUF_SIZE] = {};
        m.pcap = pcap_create(o.interface.c_str(), err);
        if (!m.pcap) {
            error = o.interface + ": " + err;
            return nullptr;
        }
        pcap_set_snaplen(m.pcap, snap_length);
        pcap_set_immediate_mode(m.pcap, 1);
        if (const int status = pcap_activate(m.pcap); status < 0) {
            permission_denied = status == PCAP_ERROR_PERM_DENIED;
            const std::string detail = pcap_geterr(m.pcap);
            error =
                o.interface + ": " + pcap_statustostr(status) + (detail.empty() ? "" : " (" + detail + ")");
            return nullptr;
        }
        bpf_program program{};
        const std::string filter = capture_filter(o);
        if (pcap_compile(m.pcap, &program, filter.c_str(), 1, PCAP_NETMASK_UNKNOWN) != 0 ||
            pcap_setfilter(m.pcap, &program) != 0) {
            error = o.interface + ": filter '" + filter + "': " + pcap_geterr(m.pcap);
            pcap_freecode(&program);
            return nullptr;
        }
        pcap_freecode(&program);
        if (pcap_setnonblock(m.pcap, 1, err) != 0) {
            error = o.interface + ": " + err;
            return nullptr;
        }
        writer = m.pcap;
    } else if (!o.serial.empty()) {
        c->name_ = o.serial2.empty() ? o.serial : o.serial + "+" + o.serial2;
        const std::string* devices[2] = {&o.serial, &o.serial2};
        for (int i = 0; i < 2; ++i) {
            if (devices[i]->empty()) continue;
            auto fd = modbus::transport::open_serial(*devices[i], o.line);
            if (!fd) {
                permission_denied = errno == EACCES;
                error = fd.error();
                return nullptr;
            }
            m.serial[i] = std::move(fd.value());
        }
        m.dead = pcap_open_dead(147, snap_length);  // LINKTYPE_USER0: the line's bytes
        m.direction_header = !o.serial2.empty();
        writer = m.dead;
    } else {
        error = "nothing to capture: give --interface or --serial";
        return nullptr;
    }
    if (!o.write.empty()) {
        c->written_ = pcap_output_name(o.write);
        m.dumper = pcap_dump_open(writer, c->written_.c_str());
        if (!m.dumper) {
            error = c->written_ + ": " + pcap_geterr(writer);
            return nullptr;
        }
    }
    return c;
}

LiveCapture::~LiveCapture() = default;

bool LiveCapture::direction_header() const noexcept {
    return impl_->direction_header;
}

bool LiveCapture::run(Analyzer& a, const std::atomic<bool>& stop) {
    Impl& m = *impl_;
    const auto start = std::chrono::steady_clock::now();
    const auto done = [&] {
        if (options_.count && captured_ >= *options_.count) return true;
        return options_.duration && std::chrono::steady_clock::now() - start >= *options_.duration;
    };
    bool draining = false;
    if (m.pcap) {
        const int linktype = pcap_datalink(m.pcap);
        while (!done()) {
            if (stop) draining = true;  // stopped: take what the kernel already holds, then return
            pcap_pkthdr* h = nullptr;
            const u_char* data = nullptr;
            const int status = pcap_next_ex(m.pcap, &h, &data);
            if (status == 0) {
                if (draining) break;
                // Non-blocking reads and our own wait: in immediate mode libpcap's timeout may never fire.
                pollfd wait{pcap_get_selectable_fd(m.pcap), POLLIN, 0};
                ::poll(&wait, 1, read_timeout_ms);
                continue;
            }
            if (status < 0) {
                a.input_error(name_ + ": " + pcap_geterr(m.pcap));
                return false;
            }
            Packet p;
            p.number = ++captured_;
            p.time = std::chrono::seconds(h->ts.tv_sec) + std::chrono::microseconds(h->ts.tv_usec);
            p.linktype = linktype;
            p.data = {data, h->caplen};
            p.original_length = h->len;
            if (m.dumper) pcap_dump(reinterpret_cast<u_char*>(m.dumper), h, data);
            a.packet(name_, p);
        }
        return true;
    }
    // Serial: each read is a chunk stamped when it returned. With two taps the first carries the master's
    // requests and the second the slaves' responses.
    const bool two = static_cast<bool>(m.serial[1]);
    std::uint8_t buf[4096];
    while (!done()) {
        if (stop) draining = true;
        pollfd fds[2];
        nfds_t n = 0;
        int which[2] = {0, 0};
        for (int i = 0; i < 2; ++i) {
            if (!m.serial[i]) continue;
            fds[n] = {m.serial[i].get(), POLLIN, 0};
            which[n++] = i;
        }
        // Stopped: what was written before is read, allowing the tty layer a moment to deliver it.
        const int ready = ::poll(fds, n, draining ? drain_timeout_ms : read_timeout_ms);
        if (ready < 0 && errno != EINTR) {
            a.input_error(name_ + ": poll: " + std::strerror(errno));
            return false;
        }
        if (ready <= 0) {
            if (draining) break;
            continue;
        }
        for (nfds_t k = 0; k < n; ++k) {
            if (!(fds[k].revents & POLLIN)) continue;
            const ssize_t got = ::read(fds[k].fd, buf, sizeof buf);
            if (got <= 0) continue;
            const Timestamp t = wall_clock();
            const std::span<const std::uint8_t> bytes(buf, static_cast<std::size_t>(got));
            ++captured_;
            m.dump(t, bytes, which[k]);
            a.serial(name_, bytes, t,
                     two ? (which[k] == 0 ? Direction::Request : Direction::Response) : Direction::Unknown);
        }
    }
    return true;
}

}  // namespace mbscope::analyzer
