#include "analyzer/live_capture.hpp"

#include <pcap/pcap.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "analyzer/pcapng_writer.hpp"
#include "analyzer/timestamps.hpp"
#include "modbus/transport/serial_port.hpp"

namespace mbscope::analyzer {

using modbus::Direction;
using modbus::Timestamp;
using modbus::transport::UniqueFd;

namespace {

constexpr int snap_length = 65535;
constexpr int read_timeout_ms = 100;  // how often the loop looks at the clock and the stop flag
constexpr int drain_timeout_ms = 20;  // after a stop, the silence that ends the capture
// After a stop, what is still coming is read for at most this long: a busy network or line is never quiet
// for drain_timeout_ms, and a stop must stop.
constexpr auto drain_at_most = std::chrono::milliseconds(500);

// pcap_datalink() gives DLT_ values, capture files hold LINKTYPE_ values: they differ for the few link
// types whose DLT_ number varies by platform. pcap_dump maps them itself; libpcap exports no mapping.
int linktype_of(int dlt) {
    if (dlt == DLT_RAW) return 101;
#if DLT_LOOP != 108
    if (dlt == DLT_LOOP) return 108;
#endif
    return dlt;
}

Timestamp wall_clock() {
    return std::chrono::duration_cast<Timestamp>(std::chrono::system_clock::now().time_since_epoch());
}

// The time up to which nothing more can come: a packet or a read waiting in a buffer is stamped when it was
// captured, so the quiet time handed to the analyzer stops short of the clock by twice the loop's wait.
Timestamp quiet_until() {
    return wall_clock() - std::chrono::milliseconds(2 * read_timeout_ms);
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
    // A port test matches a datagram's first fragment only: the others carry no UDP or TCP header. Every
    // later fragment passes (IPv4 with a fragment offset; IPv6 whose first extension header is a fragment
    // header, whose first fragment a port test misses too); the analyzer reassembles what belongs to a
    // datagram it decodes and leaves the rest.
    if (!filter.empty()) filter += " or (ip and ip[6:2] & 0x1fff != 0) or (ip6 and ip6[6] == 44)";
    return filter;
}

bool writes_pcapng(std::string_view path) {
    constexpr std::string_view ng = ".pcapng";
    if (path.size() < ng.size()) return false;
    return std::equal(ng.begin(), ng.end(), path.end() - static_cast<std::ptrdiff_t>(ng.size()),
                      [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); });
}

struct LiveCapture::Impl {
    pcap_t* pcap = nullptr;  // network capture
    pcap_t* dead = nullptr;  // serial capture's classic pcap output: a USER0 "capture" for pcap_dump_open
    pcap_dumper_t* dumper = nullptr;  // classic pcap output
    PcapngWriter pcapng;              // pcapng output: one interface per network interface or serial port
    UniqueFd serial[2];
    ~Impl() {
        if (dumper) pcap_dump_close(dumper);
        if (pcap) pcap_close(pcap);
        if (dead) pcap_close(dead);
    }
    bool direction_header = false;  // two serial taps: one byte of UserDltDirection ahead of each record
    std::vector<std::uint8_t> record;
    std::uint32_t drops_seen = 0;  // pcap_stats' ps_drop at the last look (an unsigned count that wraps)
    std::uint64_t dropped = 0;
    Timestamp drops_looked{};  // when they were last looked at

    // Packets the kernel dropped since the last look, said as an input error with the time they were lost
    // in: its buffer was full, the reader behind (a slow reader of the output, a stopped process, a burst).
    void count_drops(Analyzer& a, const std::string& name) {
        if (!pcap) return;
        pcap_stat st{};
        const Timestamp now = wall_clock();
        if (pcap_stats(pcap, &st) != 0) return;
        const std::uint32_t fresh = static_cast<std::uint32_t>(st.ps_drop) - drops_seen;
        drops_seen = static_cast<std::uint32_t>(st.ps_drop);
        const Timestamp since = drops_looked;
        drops_looked = now;
        if (fresh == 0) return;
        dropped += fresh;
        a.input_error(name + ": the kernel dropped " + std::to_string(fresh) +
                      (fresh == 1 ? " packet" : " packets") + " between " + time_of_day_text(since) +
                      " and " + time_of_day_text(now) +
                      " UTC, its capture buffer full (the reader fell behind): the exchanges around then may "
                      "show as unanswered, cut or unsolicited; a larger --buffer-size, or an output read as "
                      "fast as it comes, keeps them");
    }

    // The capture file for `names` (the interface, or each serial port), all of `linktype` and `snaplen`.
    std::string open_output(const std::string& path, int linktype, int snaplen,
                            const std::vector<std::string>& names) {
        if (writes_pcapng(path)) {
            if (auto e = pcapng.open(path); !e.empty()) return e;
            for (const auto& name : names) {
                if (auto e = pcapng.add_interface(static_cast<std::uint16_t>(linktype),
                                                  static_cast<std::uint32_t>(snaplen), name);
                    !e.empty())
                    return e;
            }
            return pcapng.flush();  // a reader opening the file before the first packet finds it whole
        }
        pcap_t* source = pcap ? pcap : (dead = pcap_open_dead(linktype, snap_length));
        if (!source) return path + ": " + std::strerror(ENOMEM);
        dumper = pcap_dump_open(source, path.c_str());
        if (!dumper) {
            // libpcap names the file itself ("x.pcap: No such file or directory"): not twice.
            const std::string e = pcap_geterr(source);
            return e.starts_with(path + ":") ? e : path + ": " + e;
        }
        return {};
    }

    // One record from `port` (the serial port's index, 0 for a network interface) to the capture file, if
    // any: classic pcap keeps microseconds, pcapng nanoseconds. An error naming the file when it fails.
    std::string dump(Timestamp t, std::span<const std::uint8_t> bytes, std::uint32_t original_length,
                     int port) {
        if (!dumper && !pcapng.is_open()) return {};
        if (direction_header) {
            record.assign(1, static_cast<std::uint8_t>(port == 0 ? UserDltDirection::MasterToSlave
                                                                 : UserDltDirection::SlaveToMaster));
            record.insert(record.end(), bytes.begin(), bytes.end());
            bytes = record;
            ++original_length;
        }
        if (pcapng.is_open())
            return pcapng.write_packet(static_cast<std::uint32_t>(port), t, bytes, original_length);
        pcap_pkthdr h{};
        h.ts.tv_sec = static_cast<time_t>(std::chrono::duration_cast<std::chrono::seconds>(t).count());
        h.ts.tv_usec = static_cast<suseconds_t>(
            std::chrono::duration_cast<std::chrono::microseconds>(t % std::chrono::seconds(1)).count());
        h.caplen = static_cast<bpf_u_int32>(bytes.size());
        h.len = original_length;
        pcap_dump(reinterpret_cast<u_char*>(dumper), &h, bytes.data());
        return {};
    }

    std::string flush(const std::string& path) {
        if (pcapng.is_open()) return pcapng.flush();
        if (!dumper) return {};
        errno = 0;
        // pcap_dump reports nothing: a write that failed before shows in the stream's error flag.
        if (pcap_dump_flush(dumper) != 0 || std::ferror(pcap_dump_file(dumper)))
            return path + ": " + (errno ? std::strerror(errno) : "write error");
        return {};
    }
};

std::unique_ptr<LiveCapture> LiveCapture::open(const SniffOptions& o, std::string& error,
                                               bool& permission_denied) {
    permission_denied = false;
    std::unique_ptr<LiveCapture> c(new LiveCapture);
    c->impl_ = std::make_unique<Impl>();
    c->options_ = o;
    Impl& m = *c->impl_;
    int linktype = link_user0, snaplen = snap_length;
    std::vector<std::string> interfaces;  // as the capture file names them
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
        pcap_set_buffer_size(m.pcap, std::max(o.buffer_mib, 1) * 1024 * 1024);
        if (const int status = pcap_activate(m.pcap); status < 0) {
            permission_denied = status == PCAP_ERROR_PERM_DENIED;
            const std::string detail = pcap_geterr(m.pcap), reason = pcap_statustostr(status);
            // libpcap's detail is often the status again ("No such device exists (No such device exists)").
            error =
                o.interface + ": " + reason + (detail.empty() || detail == reason ? "" : " (" + detail + ")");
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
        linktype = linktype_of(pcap_datalink(m.pcap));
        snaplen = pcap_snapshot(m.pcap);
        interfaces = {o.interface};
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
            interfaces.push_back(*devices[i]);
        }
        // USER0 records hold the line's bytes. Two ports are two interfaces of the pcapng file, but libpcap
        // does not tell which a record came from: the direction byte does, for mbscope decode.
        m.direction_header = !o.serial2.empty();
    } else {
        error = "nothing to capture: give --interface or --serial";
        return nullptr;
    }
    if (!o.write.empty()) {
        if (auto e = m.open_output(o.write, linktype, snaplen, interfaces); !e.empty()) {
            error = e;
            return nullptr;
        }
    }
    return c;
}

LiveCapture::~LiveCapture() = default;

bool LiveCapture::direction_header() const noexcept {
    return impl_->direction_header;
}

std::uint64_t LiveCapture::dropped() const noexcept {
    return impl_->dropped;
}

bool LiveCapture::run(Analyzer& a, const std::atomic<bool>& stop) {
    Impl& m = *impl_;
    const auto start = std::chrono::steady_clock::now();
    const auto done = [&] {
        if (options_.count && captured_ >= *options_.count) return true;
        return options_.duration && std::chrono::steady_clock::now() - start >= *options_.duration;
    };
    // A capture file that cannot be written ends the capture: what was asked for can no longer be kept.
    const auto write_failed = [&](const std::string& error) {
        a.input_error(error);
        return false;
    };
    // Time passes for the analyzer at least every read_timeout_ms, busy or quiet: requests time out, frames
    // a silence ended come out, and what was decoded is written out, while the capture runs.
    auto last_pass = std::chrono::steady_clock::now();
    // The capture file is flushed at the same pace: a process killed, or stopped by a reader of its output
    // that went away, leaves what it captured in the file (pcap_dump buffers, and a network --write file
    // held no packet after ten transactions were printed). The write's error, or empty.
    // `up_to`: the time up to which nothing more can come. Quiet (nothing to read), that is the clock less
    // the loop's wait; busy, only the last packet's time: packets still waiting in the kernel's buffer were
    // captured earlier than the clock says, and a reader that fell behind (a slow reader of its output, a
    // process stopped and continued) timed out requests whose replies were waiting there, then read them
    // as late, and the capture's clock went back.
    const auto pass_time = [&](Timestamp up_to, bool quiet) -> std::string {
        const auto t = std::chrono::steady_clock::now();
        if (!quiet && t - last_pass < std::chrono::milliseconds(read_timeout_ms)) return {};
        last_pass = t;
        a.idle(up_to);
        m.count_drops(a, name_);
        return m.flush(options_.write);
    };
    m.drops_looked = wall_clock();
    const auto finished = [&] {
        const Timestamp end = quiet_until();
        a.idle(end);  // what timed out while the capture ran is a timeout, not cut off by its end
        m.count_drops(a, name_);
        // pcapng says when the capture ended, so that its decode times out what this run did.
        if (m.pcapng.is_open())
            if (const auto e = m.pcapng.end_statistics(end, m.dropped); !e.empty()) return write_failed(e);
        const std::string written = m.flush(options_.write);
        return written.empty() || write_failed(written);
    };
    bool draining = false;
    std::chrono::steady_clock::time_point drain_end{};
    // Stopped: what the kernel or the tty still passes on is read until a short silence, for a moment at
    // most.
    const auto drained = [&] {
        if (stop && !draining) {
            draining = true;
            drain_end = std::chrono::steady_clock::now() + drain_at_most;
        }
        return draining && std::chrono::steady_clock::now() >= drain_end;
    };
    if (m.pcap) {
        const int linktype = pcap_datalink(m.pcap);
        while (!done() && !drained()) {
            pcap_pkthdr* h = nullptr;
            const u_char* data = nullptr;
            const int status = pcap_next_ex(m.pcap, &h, &data);
            if (status == 0) {
                // Non-blocking reads and our own wait: in immediate mode libpcap's timeout may never fire.
                // Stopped, the wait is a short one (the packets of an exchange that ended just before the
                // stop were lost on a busy machine when the first empty read ended the capture).
                pollfd wait{pcap_get_selectable_fd(m.pcap), POLLIN, 0};
                const int ready = ::poll(&wait, 1, draining ? drain_timeout_ms : read_timeout_ms);
                if (ready == 0 && draining) break;
                if (ready == 0)
                    if (const auto written = pass_time(quiet_until(), true); !written.empty())
                        return write_failed(written);
                continue;
            }
            if (status < 0) {
                a.input_error(name_ + ": " + pcap_geterr(m.pcap));
                return false;
            }
            Packet p;
            p.number = ++captured_;
            const auto time = timestamp_from(h->ts.tv_sec, std::int64_t{h->ts.tv_usec} * 1000);
            p.time_out_of_range = !time;
            p.time = time.value_or(wall_clock());
            p.linktype = linktype;
            p.data = {data, h->caplen};
            p.original_length = h->len;
            const std::string written = m.dump(p.time, p.data, h->len, 0);
            a.packet(name_, p);
            if (!written.empty()) return write_failed(written);
            if (const auto flushed = pass_time(p.time, false); !flushed.empty()) return write_failed(flushed);
        }
        return finished();
    }
    // Serial: each read is a chunk stamped when it returned. With two taps the first carries the master's
    // requests and the second the slaves' responses.
    const bool two = static_cast<bool>(m.serial[1]);
    // The devices on the line acknowledged other settings (MK BAUD, PARID, PROT with a profile) and the
    // analysis follows them: so do the ports, or every byte from then on is read at the old speed, garbled.
    modbus::SerialLine port_line = options_.line;
    const auto follow_line = [&] {
        const auto line = a.serial_line(name_);
        if (!line || *line == port_line) return;
        for (int i = 0; i < 2; ++i) {
            if (!m.serial[i]) continue;
            const std::string& device = i == 0 ? options_.serial : options_.serial2;
            if (auto set =
                    modbus::transport::set_line(m.serial[i].get(), *line, modbus::transport::is_pty(device));
                !set)
                a.input_error(device + ": cannot follow the line to " + modbus::character_text(*line) + ": " +
                              set.error() + "; what follows is read at the old settings");
        }
        port_line = *line;
    };
    std::uint8_t buf[4096];
    // One read of `got` bytes in buf from serial port `port`: to the file and the analyzer, stamped now.
    const auto take_read = [&](int port, std::size_t got) {
        const Timestamp t = wall_clock();
        const std::span<const std::uint8_t> bytes(buf, got);
        ++captured_;
        std::string written = m.dump(t, bytes, static_cast<std::uint32_t>(bytes.size()), port);
        // A serial read is rare: flushed at once, the file is whole even if the process is killed.
        if (written.empty()) written = m.flush(options_.write);
        a.serial(name_, bytes, t,
                 two ? (port == 0 ? Direction::Request : Direction::Response) : Direction::Unknown);
        return written;
    };
    while (!done() && !drained()) {
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
            if (const auto written = pass_time(quiet_until(), true); !written.empty())
                return write_failed(written);
            follow_line();
            continue;
        }
        int hung = -1;  // the port that went away this round
        std::string how;
        for (nfds_t k = 0; k < n && !done(); ++k) {  // --count 1 with both ports ready read two
            const bool hung_up = fds[k].revents & (POLLHUP | POLLERR | POLLNVAL);
            ssize_t got = 0;
            if (fds[k].revents & POLLIN) {
                got = ::read(fds[k].fd, buf, sizeof buf);
                if (got < 0 && (errno == EAGAIN || errno == EINTR)) continue;
            } else if (!hung_up) {
                continue;
            }
            if (got <= 0 && (hung_up || got < 0)) {
                hung = which[k];
                how = got < 0 ? "failed (" + std::string(std::strerror(errno)) + ")" : std::string("hung up");
                continue;  // the other port's bytes of this round are still read
            }
            if (got == 0) continue;
            if (auto written = take_read(which[k], static_cast<std::size_t>(got)); !written.empty())
                return write_failed(written);
        }
        if (hung >= 0) {
            // The port went away (a USB adapter unplugged, a pseudo-terminal's other end closed): poll says
            // so at once, forever, and the capture would spin in silence. What was read is kept, and so is
            // what the other port holds already (a reply waiting there when the request's port hung up was
            // lost).
            for (int i = 0; i < 2 && !done(); ++i) {
                if (i == hung || !m.serial[i]) continue;
                for (ssize_t got; !done() && (got = ::read(m.serial[i].get(), buf, sizeof buf)) > 0;)
                    if (auto written = take_read(i, static_cast<std::size_t>(got)); !written.empty())
                        return write_failed(written);
            }
            const std::string& device = hung == 0 ? options_.serial : options_.serial2;
            a.input_error(device + ": the port " + how + "; the capture ends here");
            finished();
            return false;
        }
        if (const auto written = pass_time(quiet_until(), false); !written.empty())
            return write_failed(written);
        follow_line();
    }
    return finished();
}

}  // namespace mbscope::analyzer
