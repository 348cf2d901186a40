#include "slave/server.hpp"

#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <optional>
#include <string>

#include "modbus/adu.hpp"
#include "modbus/ascii_deframer.hpp"
#include "modbus/checksum.hpp"
#include "modbus/rtu_deframer.hpp"
#include "modbus/tcp_deframer.hpp"
#include "modbus/transport/serial_port.hpp"
#include "modbus/transport/socket.hpp"
#include "slave/responder.hpp"
#include "slave/state_file.hpp"

namespace mbscope::slave {

namespace tp = modbus::transport;
using Clock = std::chrono::steady_clock;
using modbus::Framing;

namespace {

// Replies a client has not taken yet, above which its requests are no longer read: a client that pipelines
// requests and never reads (a reply to a read of 125 registers is 21 times its request) grew the slave's
// memory by gigabytes in seconds and slowed every other client. Its requests wait in the kernel's buffers,
// and TCP holds the client back, until it reads.
constexpr std::size_t max_unsent = 64 * 1024;

modbus::Timestamp stamp(Clock::time_point t) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch());
}

struct Connection {
    tp::UniqueFd fd;
    bool serial = false;
    modbus::TcpStreamDeframer mbap;
    modbus::AsciiDeframer ascii;
    std::vector<std::uint8_t> rtu;  // RTU bytes since the last frame (serial: since the last t3.5 silence)
    Clock::time_point last_byte{};
    bool rtu_gap = false;  // serial RTU: a silence above t1.5 inside the bytes in `rtu`
    bool partial = false;  // some bytes of a frame are buffered
    Clock::time_point last_activity{};
    std::vector<std::uint8_t> out;  // bytes waiting for the socket to accept them
    std::size_t scheduled = 0;  // bytes of its replies waiting for their time (slow-reply, gap-inside-frame)
    std::size_t unsent() const noexcept { return out.size() + scheduled; }
};

// A serial line's settings, or a stream's framing, that a device was told to take: applied once the
// acknowledgement has left with the old ones.
struct LineChange {
    Framing framing = Framing::Rtu;
    modbus::SerialLine line;
};

using modbus::settings_text;

struct Scheduled {
    Clock::time_point due;
    std::uint64_t connection = 0;  // 0: the UDP socket
    sockaddr_storage peer{};
    socklen_t peer_len = 0;
    std::vector<std::uint8_t> bytes;
};

}  // namespace

struct Server::Impl {
    tp::Endpoint endpoint;
    std::vector<Device*> units;
    FaultSet& faults;
    ServerOptions options;
    ServerStats& stats;
    Framing framing = Framing::Tcp;

    tp::UniqueFd listener;
    // A descriptor held in reserve: out of descriptors, accept() fails and leaves the client queued, and
    // poll reports the listener ready at once, for ever (a core spun and new clients hung). Closed for a
    // moment, it lets the client be accepted and closed, as one over max_clients is.
    tp::UniqueFd spare;
    tp::UniqueFd udp;
    tp::Pty pty;
    std::uint64_t serial_id = 0;
    std::map<std::uint64_t, Connection> connections;
    std::uint64_t next_id = 1;
    std::deque<Scheduled> scheduled;  // kept sorted by due time
    Responder responder;
    Clock::time_point last_tick{};
    // Per unit, the framing, baud rate and parity its registers held when the line last followed them
    // (first: as the device was made); and a change of the line's waiting for its acknowledgement to leave.
    std::vector<modbus::LineState> followed;
    std::optional<LineChange> pending_line;
    // A framing, speed or parity some unit's map mirrors, on a wire that has them: only then can a write
    // move the line, and only then is a frame's effect on the images looked at.
    bool line_can_follow = false;

    Impl(tp::Endpoint e, std::vector<Device*> u, FaultSet& f, ServerOptions o, ServerStats& s)
        : endpoint(std::move(e)),
          units(std::move(u)),
          faults(f),
          options(std::move(o)),
          stats(s),
          framing(tp::framing_of(endpoint.scheme)),
          responder(units, faults, framing, framing == Framing::Tcp && !tp::is_serial(endpoint.scheme),
                    [this] { return save(); }) {
        for (const Device* d : units) {
            followed.push_back(d->made_line());
            for (const auto& p : d->profile().table(modbus::Table::HoldingRegisters))
                line_can_follow |=
                    framing != Framing::Tcp && p.mirrors && *p.mirrors != modbus::LineSetting::UnitId;
        }
    }

    // ---- the line's settings, as the devices hold them

    void say(const std::string& text) const {
        if (options.on_line_change) options.on_line_change(text);
    }

    // A device told another framing, speed or parity (a valid code written to MK's PROT, BAUD or PARID:
    // MK-CFG-01; the manual gives no delay, so at once) talks with them from then on. One UART serves every
    // unit on the line, so the line follows only when every unit on it holds the same new settings (a
    // device alone, a broadcast write, or the last of a line's devices told one by one); until then a unit
    // whose settings differ from the line's cannot read a frame on it and answers nothing. The line
    // switches once the acknowledgement, sent with the old settings, is out. Over Modbus/TCP the wire has
    // none of these settings, and over a TCP stream (a serial server's) only the framing is seen: the rest
    // are stored only.
    void follow_line(bool at_open = false) {
        if (!line_can_follow) return;
        const bool serial = tp::is_serial(endpoint.scheme);
        std::vector<modbus::LineState> held;
        std::vector<bool> differs;
        for (std::size_t i = 0; i < units.size(); ++i) {
            held.push_back(units[i]->held_line());
            const auto& h = held.back();
            const auto& was = followed[i];
            differs.push_back((h.framing && h.framing != was.framing) ||
                              (serial && h.baud && h.baud != was.baud) ||
                              (serial && h.parity && h.parity != was.parity));
        }
        const auto told = std::find(differs.begin(), differs.end(), true);
        if (told == differs.end()) return;
        const auto& first = held[static_cast<std::size_t>(told - differs.begin())];
        bool every = true;
        for (std::size_t i = 0; i < units.size(); ++i)
            every = every && differs[i] && held[i].framing == first.framing &&
                    (!serial || (held[i].baud == first.baud && held[i].parity == first.parity));
        const auto name = [](const Device* d) {
            return "unit " + std::to_string(d->unit()) + " (" + d->profile().id + ")";
        };
        if (!every) {
            for (std::size_t i = 0; i < units.size(); ++i) {
                if (!differs[i] || units[i]->off_line()) continue;
                units[i]->leave_line();
                modbus::SerialLine own = endpoint.line;
                if (held[i].baud) own.baud = *held[i].baud;
                if (held[i].parity) own.parity = *held[i].parity;
                say(name(units[i]) + (at_open ? " holds " : " was told ") +
                    settings_text(held[i].framing.value_or(framing), own, serial) +
                    (at_open ? " (the state file)" : "") +
                    ": it cannot read the line the other units keep and answers nothing until they are told "
                    "the same");
            }
            return;
        }
        LineChange change{pending_line ? pending_line->framing : framing,
                          pending_line ? pending_line->line : endpoint.line};
        const auto& was = followed[static_cast<std::size_t>(told - differs.begin())];
        if (first.framing && first.framing != was.framing) change.framing = *first.framing;
        if (serial && first.baud && first.baud != was.baud) change.line.baud = *first.baud;
        if (serial && first.parity && first.parity != was.parity) change.line.parity = *first.parity;
        // The character that goes with them (the manual's, else the specification's).
        const auto& rules = units[static_cast<std::size_t>(told - differs.begin())]->profile().line;
        change.line = rules.character_for(change.framing, change.line);
        for (std::size_t i = 0; i < units.size(); ++i) {
            followed[i] = held[i];
            units[i]->join_line();
        }
        const std::string who = units.size() == 1 ? name(units.front()) : "every unit on the line";
        const std::string now = settings_text(change.framing, change.line, serial);
        say(at_open ? who + " holds " + now + " (the state file): the line is served so"
                    : who + " was told " + now + ": the line follows once the acknowledgement is out");
        pending_line = change;
    }

    std::uint64_t modifications() const noexcept {
        std::uint64_t n = 0;
        for (const Device* d : units)
            n += d->image().modifications();
        return n;
    }

    void take_framing(Framing f) {
        framing = f;
        responder.set_framing(f);
        const bool serial = tp::is_serial(endpoint.scheme);
        if (f == Framing::Ascii)
            endpoint.scheme = serial ? tp::Scheme::AsciiSerial : tp::Scheme::AsciiOverTcp;
        else
            endpoint.scheme = serial ? tp::Scheme::RtuSerial : tp::Scheme::RtuOverTcp;
    }

    // The change waits for the reply that acknowledged it (queued, or not yet taken by the socket). Before
    // the port is opened (a state file's settings) it only sets what open() will use.
    void apply_line_change() {
        if (!pending_line || !scheduled.empty()) return;
        for (const auto& [id, c] : connections)
            if (!c.out.empty()) return;
        const LineChange change = *std::exchange(pending_line, std::nullopt);
        if (tp::is_serial(endpoint.scheme) && serial_id) {
            Connection& c = connections.at(serial_id);
            const bool pty = options.create_pty || tp::is_pty(endpoint.device);
            // The acknowledgement leaves at the old speed: wait for the UART (a pseudo-terminal has none,
            // and would wait for its reader).
            if (!pty) ::tcdrain(c.fd.get());
            if (auto set = tp::set_line(c.fd.get(), change.line, pty); !set) {
                say("cannot set " + endpoint.device + " to " +
                    settings_text(change.framing, change.line, true) + ": " + set.error());
                return;
            }
        }
        endpoint.line = change.line;
        if (change.framing != framing) {
            take_framing(change.framing);
            for (auto& [id, c] : connections) {
                c.rtu.clear();
                c.rtu_gap = false;
                c.ascii = c.serial ? modbus::AsciiDeframer({std::chrono::milliseconds(1000)})
                                   : modbus::AsciiDeframer{};
                c.partial = false;
            }
        }
    }

    // ---- request → response

    bool save() {
        if (options.state_file.empty()) return true;
        auto saved = save_state(options.state_file, units, options.state_others);
        if (!saved) std::fprintf(stderr, "mbscope slave: cannot save state: %s\n", saved.error().c_str());
        return bool(saved);
    }

    std::chrono::nanoseconds character_time() const { return endpoint.line.character_time(); }

    // Queue a response: now, later (slow-reply) or in two parts (gap-inside-frame).
    void send(std::uint64_t connection, const sockaddr_storage* peer, socklen_t peer_len,
              std::vector<std::uint8_t> bytes) {
        auto due = Clock::now();
        if (faults.enabled(Fault::SlowReply))
            due += std::chrono::milliseconds(static_cast<long>(faults.arg(Fault::SlowReply)));
        auto make = [&](Clock::time_point when, std::vector<std::uint8_t> b) {
            Scheduled s{when, connection, {}, peer_len, std::move(b)};
            if (peer) s.peer = *peer;
            return s;
        };
        std::vector<Scheduled> parts;
        if (faults.enabled(Fault::GapInsideFrame) && framing != Framing::Tcp && bytes.size() >= 2) {
            const std::size_t half = bytes.size() / 2;
            std::vector<std::uint8_t> second(bytes.begin() + static_cast<long>(half), bytes.end());
            bytes.resize(half);
            const auto gap = std::chrono::duration_cast<Clock::duration>(character_time() *
                                                                         faults.arg(Fault::GapInsideFrame));
            parts.push_back(make(due, std::move(bytes)));
            parts.push_back(make(due + gap, std::move(second)));
        } else {
            parts.push_back(make(due, std::move(bytes)));
        }
        for (auto& s : parts) {
            if (s.due <= Clock::now() && scheduled.empty()) {
                deliver(s);
                continue;
            }
            if (const auto c = connections.find(s.connection); s.connection != 0 && c != connections.end())
                c->second.scheduled += s.bytes.size();
            auto it = scheduled.end();
            while (it != scheduled.begin() && (it - 1)->due > s.due)
                --it;
            scheduled.insert(it, std::move(s));
        }
    }

    void deliver(const Scheduled& s) {
        ++stats.responses;
        if (s.connection == 0) {
            ::sendto(udp.get(), s.bytes.data(), s.bytes.size(), MSG_NOSIGNAL,
                     reinterpret_cast<const sockaddr*>(&s.peer), s.peer_len);
            return;
        }
        auto it = connections.find(s.connection);
        if (it == connections.end()) return;  // the client went away meanwhile
        Connection& c = it->second;
        c.out.insert(c.out.end(), s.bytes.begin(), s.bytes.end());
        flush(c);
    }

    void flush(Connection& c) {
        while (!c.out.empty()) {
            const ssize_t n = c.serial ? ::write(c.fd.get(), c.out.data(), c.out.size())
                                       : ::send(c.fd.get(), c.out.data(), c.out.size(), MSG_NOSIGNAL);
            if (n < 0) {
                if (errno == EINTR) continue;
                if (errno != EAGAIN && errno != EWOULDBLOCK)
                    c.out.clear();  // the peer is gone; close follows
                return;
            }
            c.out.erase(c.out.begin(), c.out.begin() + n);
        }
    }

    void on_frame(std::uint64_t id, const modbus::Frame& f) {
        if (!f.checksum_ok)
            ++stats.bad_frames;
        else if (f.framing != Framing::Tcp || f.protocol_id() == 0)
            ++stats.requests;
        const auto before = line_can_follow ? modifications() : 0;
        auto reply = responder.respond(f);
        if (!reply.empty()) send(id, nullptr, 0, std::move(reply));
        if (line_can_follow && modifications() != before) follow_line();
    }

    // ---- endpoints

    modbus::Result<void, std::string> open() {
        // Settings a state file restored (a device keeps what it was told) are the line's from the start.
        follow_line(true);
        apply_line_change();
        using S = tp::Scheme;
        switch (endpoint.scheme) {
            case S::Tcp:
            case S::RtuOverTcp:
            case S::AsciiOverTcp: {
                auto fd = tp::listen_tcp(endpoint.host, endpoint.port, 512);
                if (!fd) return endpoint.text() + ": " + fd.error();
                listener = std::move(fd).value();
                spare = tp::UniqueFd(::open("/dev/null", O_RDONLY | O_CLOEXEC));
                return {};
            }
            case S::Udp: {
                auto fd = tp::bind_udp(endpoint.host, endpoint.port);
                if (!fd) return endpoint.text() + ": " + fd.error();
                udp = std::move(fd).value();
                return {};
            }
            case S::RtuSerial:
            case S::AsciiSerial: {
                Connection c;
                c.serial = true;
                if (options.create_pty) {
                    auto p = tp::open_pty(endpoint.line);
                    if (!p) return p.error();
                    pty = std::move(p).value();
                    c.fd = tp::UniqueFd(::dup(pty.master.get()));
                    if (!c.fd) return std::string("pty: dup: ") + std::strerror(errno);
                } else {
                    auto fd = tp::open_serial(endpoint.device, endpoint.line);
                    if (!fd) return fd.error();
                    c.fd = std::move(fd).value();
                }
                c.ascii = modbus::AsciiDeframer({std::chrono::milliseconds(1000)});
                serial_id = next_id++;
                connections.emplace(serial_id, std::move(c));
                return {};
            }
        }
        return std::string("unsupported endpoint");
    }

    void accept_clients() {
        for (;;) {
            tp::UniqueFd fd(::accept4(listener.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
            if (!fd && (errno == EMFILE || errno == ENFILE) && spare) {
                spare = tp::UniqueFd();
                const bool accepted = static_cast<bool>(
                    tp::UniqueFd(::accept4(listener.get(), nullptr, nullptr, SOCK_CLOEXEC)));
                spare = tp::UniqueFd(::open("/dev/null", O_RDONLY | O_CLOEXEC));  // after the close above
                if (!accepted) return;
                ++stats.refused;  // closed at once, as over max_clients
                continue;
            }
            if (!fd) return;
            if (connections.size() >= options.max_clients) {
                ++stats.refused;
                continue;  // closed at once: the others keep their service
            }
            const int one = 1;
            ::setsockopt(fd.get(), IPPROTO_TCP, 1 /* TCP_NODELAY */, &one, sizeof one);
            Connection c;
            c.fd = std::move(fd);
            c.last_activity = Clock::now();
            ++stats.connections;
            connections.emplace(next_id++, std::move(c));
        }
    }

    // Returns false when the connection must be closed.
    bool read_stream(std::uint64_t id, Connection& c) {
        std::uint8_t buf[4096];
        for (;;) {
            const ssize_t n = ::read(c.fd.get(), buf, sizeof buf);
            if (n == 0) return c.serial;  // EOF: a TCP client left; a pty just has no writer now
            if (n < 0) {
                if (errno == EINTR) continue;
                if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
                return c.serial && errno == EIO;  // a pty whose client closed reads EIO until the next one
            }
            const auto now = Clock::now();
            c.last_activity = now;
            const std::span<const std::uint8_t> bytes(buf, static_cast<std::size_t>(n));
            if (!consume(id, c, bytes, now)) return false;
            if (c.unsent() >= max_unsent) return true;  // read again once the client takes its replies
            // A short read drained the socket: skip the read that would only say EAGAIN (a system call per
            // request saved; poll reports whatever arrives next).
            if (static_cast<std::size_t>(n) < sizeof buf) return true;
        }
    }

    bool consume(std::uint64_t id, Connection& c, std::span<const std::uint8_t> bytes,
                 Clock::time_point now) {
        modbus::DeframeEvents events;
        switch (framing) {
            case Framing::Tcp:
                c.mbap.feed(bytes, events);
                break;
            case Framing::Ascii:
                c.ascii.feed(bytes, c.serial ? stamp(now) : modbus::Timestamp{0}, events);
                break;
            case Framing::Rtu:
                if (c.serial) {
                    // SL §2.5.1.1: bytes after a silence above t1.5 (but below t3.5) spoil the frame.
                    if (!c.rtu.empty() && now - c.last_byte > endpoint.line.t1_5()) c.rtu_gap = true;
                    c.rtu.insert(c.rtu.end(), bytes.begin(), bytes.end());
                    c.last_byte = now;
                    if (c.rtu.size() > 4 * modbus::max_frame_bytes) {  // a runaway line: drop, resynchronise
                        ++stats.bad_frames;
                        c.rtu.clear();
                    }
                    return true;
                }
                c.rtu.insert(c.rtu.end(), bytes.begin(), bytes.end());
                c.last_byte = now;
                deframe_rtu_stream(id, c, false);
                c.partial = !c.rtu.empty();
                return true;
        }
        bool ok = true;
        for (auto& e : events) {
            if (const auto* f = std::get_if<modbus::Frame>(&e)) {
                on_frame(id, *f);
            } else {
                ++stats.bad_frames;
                if (framing == Framing::Tcp) ok = false;  // MBAP garbage: this client is lost, close it
            }
        }
        c.partial = framing == Framing::Tcp ? c.mbap.buffered() > 0 : c.ascii.buffered() > 0;
        return ok;
    }

    // RTU over TCP: frame ends come from the content (function code and byte counts, confirmed by the CRC).
    // What the content cannot end (FC8/00 echoes any number of data bytes, user-defined function codes, a
    // truncated frame whose predicted length swallows the next request) is ended by a silence, as the
    // gateway's serial side would end it: after options.stream_frame_silence the bytes held are taken as
    // complete (`at_end`): one frame if their CRC says so, else resynchronised and the garbage dropped.
    void deframe_rtu_stream(std::uint64_t id, Connection& c, bool at_end) {
        std::size_t head = 0;
        if (at_end && c.rtu.size() >= 4 && c.rtu.size() <= modbus::max_rtu_adu_length &&
            modbus::crc16(c.rtu) == 0) {
            if (auto f = modbus::decode_rtu(c.rtu); f) on_frame(id, *f);
            c.rtu.clear();
            return;
        }
        while (head < c.rtu.size()) {
            const std::span<const std::uint8_t> rest(c.rtu.data() + head, c.rtu.size() - head);
            const auto step = modbus::rtu_step(rest, at_end, false);
            // A frame whose length the content does not give (an unknown function code, FC8 with any
            // number of data bytes): the shortest prefix with a valid CRC is taken as the frame. For FC8
            // that is whatever rtu_step does not end with a good CRC at the usual five PDU bytes: with more
            // data bytes it sees a bad CRC there and, no frame following, garbage to skip or more to wait
            // for; or a damaged frame, when the data bytes from there on happen to hold a valid frame (which
            // would then be executed, a write nobody sent). A frame rtu_step ended with a bad CRC that no
            // valid prefix explains is a damaged request, dropped at once for the one after it.
            const bool ended_damaged = step.kind == modbus::DeframeStep::Kind::Complete && !step.checksum_ok;
            const bool diagnostics = rest.size() >= 2 && rest[1] == 8 &&
                                     (step.kind != modbus::DeframeStep::Kind::Complete || ended_damaged);
            const std::size_t too_long = impossible_request_length(rest);
            const bool unsized = diagnostics || too_long > 0 ||
                                 (step.kind == modbus::DeframeStep::Kind::Skip &&
                                  step.reason == modbus::UnparsedReason::UnknownFunction);
            if (unsized) {
                if (const std::size_t n = crc_valid_prefix(rest); n > 0) {
                    if (auto f = modbus::decode_rtu(rest.first(n)); f) on_frame(id, *f);
                    head += n;
                    continue;
                }
                // A frame of an impossible length that is not one valid frame as held: all the bytes its
                // header gives (longer than any frame), or those the silence ended (damaged or cut short),
                // are dropped as one, as a serial port drops them. Skipped byte by byte, a frame inside its
                // data was found and executed (an FC6 behind a damaged CRC).
                if (too_long > 0 && (rest.size() >= too_long || at_end)) {
                    ++stats.bad_frames;
                    head += std::min(too_long, rest.size());
                    continue;
                }
                // Its CRC may still come.
                if (!at_end && !ended_damaged && rest.size() < std::max(too_long, modbus::max_rtu_adu_length))
                    break;
            }
            if (step.kind == modbus::DeframeStep::Kind::NeedMore) break;
            if (step.kind == modbus::DeframeStep::Kind::Complete) {
                if (auto f = modbus::decode_rtu(rest.first(step.length)); f) on_frame(id, *f);
                head += step.length;
                continue;
            }
            // Bytes the content cannot end as one frame but whose CRC holds over all of them (a frame longer
            // than its header says), sent whole: on the line the silence after them ends them and the device
            // refuses the frame (exception 03, as over a serial port). Skipped byte by byte, a frame whose
            // CRC held by chance inside its data would be answered instead.
            if (crc_valid_prefix(rest) == rest.size()) {
                if (auto f = modbus::decode_rtu(rest); f) on_frame(id, *f);
                head = c.rtu.size();
                break;
            }
            ++stats.bad_frames;
            head += step.length ? step.length : 1;
        }
        c.rtu.erase(c.rtu.begin(), c.rtu.begin() + static_cast<long>(head));
    }

    // The length a request's header gives when no RTU frame is that long (FC16, quantity 123, byte count 255:
    // 264 bytes), else 0. Its content cannot end such a frame, so the silence after it does, as for an
    // unsized one: skipped as garbage while its bytes still came in over several segments, a frame whose CRC
    // held inside its data was found and answered before the rest arrived.
    static std::size_t impossible_request_length(std::span<const std::uint8_t> bytes) {
        if (bytes.empty()) return 0;
        const auto p = modbus::predict_pdu_length(bytes.subspan(1), modbus::Direction::Request);
        const std::size_t adu = 1 + p.length + 2;
        return p.kind == modbus::LengthPrediction::Kind::Known && adu > modbus::max_rtu_adu_length ? adu : 0;
    }

    // The length of a prefix of `bytes` (4 to 256 bytes) that ends in its own valid CRC, 0 if none: all the
    // bytes held when they qualify (a client writes one frame at a time, and a shorter prefix can pass the
    // CRC by chance, one time in 65536), else the shortest. One running CRC, checked at each length (the
    // CRC of a frame followed by its CRC is 0).
    static std::size_t crc_valid_prefix(std::span<const std::uint8_t> bytes) {
        std::uint16_t crc = modbus::crc16_init;
        const std::size_t limit = std::min(bytes.size(), modbus::max_rtu_adu_length);
        std::size_t shortest = 0;
        for (std::size_t n = 1; n <= limit; ++n) {
            crc = modbus::crc16(bytes.subspan(n - 1, 1), crc);
            if (n >= 4 && crc == 0 && shortest == 0) shortest = n;
        }
        return limit == bytes.size() && limit >= 4 && crc == 0 ? limit : shortest;
    }

    // Serial RTU: a silence of t3.5 ends the frame.
    void close_serial_frame(std::uint64_t id, Connection& c, Clock::time_point now) {
        if (c.rtu.empty() || now - c.last_byte < endpoint.line.t3_5()) return;
        std::vector<std::uint8_t> bytes;
        bytes.swap(c.rtu);
        const bool gap = std::exchange(c.rtu_gap, false);
        auto f = modbus::decode_rtu(bytes);
        if (!f) {
            ++stats.bad_frames;
            return;
        }
        if (gap) {
            for (Device* d : units)
                d->count_frame(false);
            ++stats.bad_frames;  // a silence above t1.5 inside the frame: incomplete, not answered
            return;
        }
        on_frame(id, *f);
    }

    void read_udp() {
        std::uint8_t buf[2048];
        for (;;) {
            sockaddr_storage peer{};
            socklen_t len = sizeof peer;
            const ssize_t n =
                ::recvfrom(udp.get(), buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&peer), &len);
            if (n < 0) return;
            auto f = modbus::decode_tcp(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n)));
            if (!f) {
                ++stats.bad_frames;
                continue;
            }
            // Another protocol id is not Modbus: the Responder discards it (unless the fault says otherwise).
            ++(f->protocol_id() == 0 ? stats.requests : stats.bad_frames);
            auto reply = responder.respond(*f);
            if (reply.empty()) continue;
            // Each copy of a reply sent twice (duplicate-reply) in a datagram of its own.
            const std::size_t copies = responder.last_copies();
            const std::size_t each = reply.size() / copies;
            for (std::size_t i = 1; i < copies; ++i)
                send(0, &peer, len, {reply.begin(), reply.begin() + static_cast<std::ptrdiff_t>(each)});
            reply.resize(each);
            send(0, &peer, len, std::move(reply));
        }
    }

    // After answering, the loop polls without sleeping for this long (yielding the core to anything else
    // runnable) before it blocks again. A master polling back to back sends its next request within tens
    // of microseconds; waking a sleeping thread for it costs about as much as the whole exchange (perf:
    // over half the slave's time in the scheduler's wake-up path), so one client's rate more than doubles.
    // A master polling every 100 ms costs the slave 50 us of a core per request.
    static constexpr auto spin_after_reply = std::chrono::microseconds(50);
    Clock::time_point spin_until{};

    modbus::Result<void, std::string> run(const std::atomic<bool>& stop) {
        std::vector<pollfd> fds;
        std::vector<std::uint64_t> ids;
        while (!stop.load(std::memory_order_relaxed)) {
            auto now = Clock::now();
            if (options.tick && now - last_tick >= options.tick_interval) {
                options.tick(now);
                last_tick = now;
            }
            // Timers: scheduled sends, the serial t3.5 silence, the next tick; at most 100 ms.
            auto wake = now + std::chrono::milliseconds(100);
            if (!scheduled.empty()) wake = std::min(wake, scheduled.front().due);
            if (options.tick) wake = std::min(wake, last_tick + options.tick_interval);
            for (auto& [id, c] : connections)
                if (!c.rtu.empty())
                    wake =
                        std::min(wake, c.last_byte + (c.serial ? std::chrono::duration_cast<Clock::duration>(
                                                                     endpoint.line.t3_5())
                                                               : std::chrono::duration_cast<Clock::duration>(
                                                                     options.stream_frame_silence)));
            fds.clear();
            ids.clear();
            if (listener) {
                fds.push_back({listener.get(), POLLIN, 0});
                ids.push_back(0);
            }
            if (udp) {
                fds.push_back({udp.get(), POLLIN, 0});
                ids.push_back(0);
            }
            for (auto& [id, c] : connections) {
                fds.push_back({c.fd.get(),
                               static_cast<short>((c.unsent() < max_unsent ? POLLIN : 0) |
                                                  (c.out.empty() ? 0 : POLLOUT)),
                               0});
                ids.push_back(id);
            }
            const auto wait = std::chrono::duration_cast<std::chrono::microseconds>(wake - now).count();
            const bool spin = now < spin_until;
            const int timeout_ms = spin || wait <= 0 ? 0 : static_cast<int>((wait + 999) / 1000);
            const auto responses_before = stats.responses;
            const int rc = ::poll(fds.data(), fds.size(), timeout_ms);
            if (rc < 0 && errno != EINTR) return std::string("poll: ") + std::strerror(errno);
            if (rc == 0 && spin) ::sched_yield();
            now = Clock::now();
            std::vector<std::uint64_t> to_close;
            for (std::size_t i = 0; rc > 0 && i < fds.size(); ++i) {
                if (fds[i].revents == 0) continue;
                if (fds[i].fd == listener.get()) {
                    accept_clients();
                    continue;
                }
                if (fds[i].fd == udp.get()) {
                    read_udp();
                    continue;
                }
                auto it = connections.find(ids[i]);
                if (it == connections.end()) continue;
                Connection& c = it->second;
                if (fds[i].revents & POLLOUT) flush(c);
                if (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) {
                    if (!read_stream(ids[i], c) || (!c.serial && (fds[i].revents & POLLERR)))
                        to_close.push_back(ids[i]);
                    // The port itself went away (a USB adapter unplugged, the far end of a pseudo-terminal
                    // closed): poll says so at once, for ever, with a read of nothing, and the loop spun a
                    // core in silence. The run ends with the reason (every write acknowledged is saved).
                    if (c.serial && !options.create_pty && (fds[i].revents & (POLLHUP | POLLERR)))
                        return endpoint.device + ": the port hung up";
                    // A pty of our own whose client closed reports POLLHUP until one opens it again: do not
                    // spin.
                    if (c.serial && (fds[i].revents & POLLHUP) && !(fds[i].revents & POLLIN))
                        ::poll(nullptr, 0, 10);
                }
            }
            for (auto& [id, c] : connections) {
                if (c.serial) {
                    if (framing == Framing::Rtu) close_serial_frame(id, c, now);
                    continue;
                }
                if (framing == Framing::Rtu && !c.rtu.empty() &&
                    now - c.last_byte >= options.stream_frame_silence) {
                    deframe_rtu_stream(id, c, true);
                    c.partial = !c.rtu.empty();
                }
                const auto idle = now - c.last_activity;
                if (idle > options.idle_timeout || (c.partial && idle > options.frame_timeout)) {
                    ++stats.closed_idle;
                    to_close.push_back(id);
                }
            }
            while (!scheduled.empty() && scheduled.front().due <= now) {
                Scheduled s = std::move(scheduled.front());
                scheduled.pop_front();
                if (const auto c = connections.find(s.connection);
                    s.connection != 0 && c != connections.end())
                    c->second.scheduled -= std::min(c->second.scheduled, s.bytes.size());
                deliver(s);
            }
            apply_line_change();
            for (auto id : to_close)
                connections.erase(id);
            if (stats.responses != responses_before) spin_until = now + spin_after_reply;
        }
        return {};
    }
};

Server::Server(tp::Endpoint endpoint, std::vector<Device*> units, FaultSet& faults, ServerOptions options)
    : impl_(std::make_unique<Impl>(std::move(endpoint), std::move(units), faults, std::move(options),
                                   stats_)) {}

Server::~Server() = default;

modbus::Result<void, std::string> Server::open() {
    return impl_->open();
}

modbus::Result<void, std::string> Server::run(const std::atomic<bool>& stop) {
    return impl_->run(stop);
}

tp::Endpoint Server::endpoint() const {
    tp::Endpoint e = impl_->endpoint;
    if (impl_->listener || impl_->udp) e.port = port();
    return e;
}

std::uint16_t Server::port() const noexcept {
    if (impl_->listener) return tp::bound_port(impl_->listener.get());
    if (impl_->udp) return tp::bound_port(impl_->udp.get());
    return 0;
}

std::string Server::address() const {
    if (!impl_->pty.slave_path.empty()) return impl_->pty.slave_path;
    if (tp::is_serial(impl_->endpoint.scheme)) return impl_->endpoint.device;
    tp::Endpoint e = impl_->endpoint;
    e.port = port();
    return e.text();
}

}  // namespace mbscope::slave
