#include "analyzer/analyzer.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <iterator>

#include "analyzer/exported_pdu.hpp"
#include "analyzer/rtac_serial.hpp"
#include "analyzer/timestamps.hpp"
#include "analyzer/word_order.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/reply_fit.hpp"

namespace mbscope::analyzer {

using namespace mbscope::modbus;

namespace {
// `carries`: a client's stream carries requests, a server's replies.
TcpStreamDeframer passive(Direction carries) {
    TcpStreamDeframer d;
    d.observe_passively(carries);
    return d;
}

// tcp.length_beyond_segment: the MBAP length, what the segment held, what a receiver reading by the length
// does.
std::string length_beyond_segment_text(const FrameRecord& r) {
    const Frame& f = r.frame;
    const bool reply = r.direction == Direction::Response;
    const std::size_t held = f.length > 6 ? f.length - 6u : 0;
    const std::size_t more = f.length_field() > held ? f.length_field() - held : 0;
    return "MBAP length " + std::to_string(f.length_field()) + ", the " + (reply ? "server" : "client") +
           "'s segment held " + std::to_string(held) +
           " bytes after the first 6 (unit id + PDU): " + (reply ? "a client" : "the server") +
           " reading by the length waits for " + std::to_string(more) +
           (more == 1 ? " more byte and takes it" : " more bytes and takes them") + " from the next " +
           (reply ? "reply" : "request");
}
}  // namespace

struct Analyzer::Flow {
    std::uint64_t id = 0;
    SharedText link;                                 // "client -> server"
    std::string server;                              // "server"
    Carrier carrier = Carrier::Tcp;                  // Tcp: reassembled; the others come whole
    std::unique_ptr<TcpReassembler> reassembler[2];  // [0] client → server, [1] server → client
    TcpStreamDeframer deframer[2] = {passive(Direction::Request), passive(Direction::Response)};
    // Unparsed bytes are reported at the packet that carried them, not at whatever packet (of any
    // connection) ends them. Per direction: the last packet fed to the deframer and the stream offset its
    // bytes start at, and, for earlier packets whose bytes were still unreported when the next came, the
    // same (offset, packet) from the one holding the first unreported byte on (empty while every packet's
    // bytes form frames, as they do on a healthy stream).
    std::uint64_t last_fed_from[2] = {0, 0}, last_fed_packet[2] = {0, 0};
    std::deque<std::pair<std::uint64_t, std::uint64_t>> fed[2];
    std::uint64_t packet_at(int dir, std::uint64_t offset, std::uint64_t otherwise) const {
        if (last_fed_packet[dir] && offset >= last_fed_from[dir]) return last_fed_packet[dir];
        const auto& f = fed[dir];
        auto after = std::upper_bound(f.begin(), f.end(), offset,
                                      [](std::uint64_t o, const auto& entry) { return o < entry.first; });
        return after == f.begin() ? otherwise : std::prev(after)->second;
    }
    // A serial gateway's port: the stream holds raw RTU frames, delimited by content and CRC.
    bool rtu_over_tcp = false;
    RtuDeframer rtu_deframer[2];
    std::uint64_t rtu_lost[2] = {0, 0};  // stream bytes lost in gaps, so that offsets stay stream offsets
    // Where each side's bytes arrived, by the stream offset each packet's bytes start at: the packet and
    // its time. A frame whose CRC fails is closed only by later bytes (the next frame from its side, the
    // other side's turn, the end), and is the packet's that held it, not theirs.
    struct Arrival {
        std::uint64_t offset;
        std::uint64_t packet;
        Timestamp time;
    };
    std::deque<Arrival> rtu_arrivals[2];
    // A Modbus/TCP port's connection may carry raw RTU frames instead (a serial gateway in transparent
    // mode, left without --rtu-over-tcp): read as MBAP they made up units and transactions, which no later
    // finding could take back from the records already written. So each connection's first bytes are held,
    // both directions in the order they came, until the probe tells its framing (rtu_over_tcp_probe.hpp;
    // for a genuine Modbus/TCP stream, almost always at its first request or reply): then fed to the MBAP
    // deframers as they would have been, each chunk with its own time and packet, or, for RTU, reported as
    // bytes not decoded. A stream event (a gap, the connection's end, the capture's) or the first held
    // request's timeout settles it on what the probe has read.
    // RTU is not decoded in its stead: the framing is the port's, which the user names, and a guess that
    // decoded some connections of a port one way and some the other would make two views of one device.
    enum class Reading : std::uint8_t { Probing, Mbap, Rtu };
    Reading reading = Reading::Probing;
    RtuOverTcpProbe probe;
    struct HeldChunk {
        int dir;
        std::vector<std::uint8_t> bytes;
        Timestamp time;
        std::uint64_t packet;
        SharedText source;  // the input that held the packet (several are merged by time)
    };
    std::vector<HeldChunk> held;
    std::uint16_t server_port = 0;
    // Reading::Rtu: each direction's bytes since the last report, as one run (offset, length, where its
    // first byte came), reported when the connection ends or a gap breaks the run; and the next byte's
    // stream offset.
    struct NotDecoded {
        std::uint64_t offset = 0, length = 0, packet = 0;
        Timestamp time{0};
        SharedText source;
    } not_decoded[2];
    std::uint64_t not_decoded_next[2] = {0, 0};
    const Arrival* rtu_arrival(int dir, std::uint64_t offset) const {
        const auto& a = rtu_arrivals[dir];
        const auto after = std::upper_bound(a.begin(), a.end(), offset,
                                            [](std::uint64_t o, const Arrival& x) { return o < x.offset; });
        return after == a.begin() ? nullptr : &*std::prev(after);
    }
    // Bytes about to be fed: the arrivals no event can name any more are dropped first (those before the
    // one holding the first unreported byte, whose run needs only its first byte's, and those between it
    // and the one holding the first byte held for a frame).
    void rtu_arrived(int dir, std::uint64_t packet, Timestamp t) {
        auto& a = rtu_arrivals[dir];
        const std::uint64_t first = rtu_deframer[dir].unreported() + rtu_lost[dir];
        const std::uint64_t held = rtu_deframer[dir].held_from() + rtu_lost[dir];
        while (a.size() > 1 && a[1].offset <= first)
            a.pop_front();
        std::size_t from = 1;
        while (from + 1 < a.size() && a[from + 1].offset <= held)
            ++from;
        if (from > 1) a.erase(a.begin() + 1, a.begin() + static_cast<std::ptrdiff_t>(from));
        a.push_back({rtu_deframer[dir].bytes_in() + rtu_lost[dir], packet, t});
    }
    // The gateway's last run of bytes that formed no frame, while no frame has come after it (length 0:
    // none), when it came and the unit and function code it begins with: a hole in the response stream
    // right after it cut a reply that began with them (stream_gap).
    struct ReplyTail {
        std::uint32_t length = 0;
        Timestamp time{0};
        std::array<std::uint8_t, 2> head{};
    } rtu_reply_tail;
    std::size_t pending = 0;
    // On a serial line, the serial of the last request a reply answered in time (0: none yet): the requests
    // given up before it take no late reply while another unit's request waits (on_response).
    std::uint64_t late_closed_before = 0;
    // The serial the first request after bytes of the request stream were lost gets (0: none lost, or a
    // request after them was answered): a reply nobody waits for may answer a request among those bytes.
    std::uint64_t first_request_after_gap = 0;
    // The last response paired on the link (its ADU, decoded): the same response again, with no request
    // waiting for it, is that request answered twice rather than a reply nobody asked for.
    // (A late reply, too: a copy of it is that request answered twice.)
    std::array<std::uint8_t, max_frame_bytes> last_response{};
    std::size_t last_response_length = 0;
    std::uint64_t last_response_index = 0;
    void keep_last_response(const FrameRecord& r) {
        // A damaged one is the last response too: a copy of the one before it is no longer "the last
        // response again" (another request came between them, and was answered).
        if (!r.frame.checksum_ok) {
            last_response_length = 0;
            return;
        }
        last_response_length = r.frame.length;
        std::memcpy(last_response.data(), r.frame.bytes.data(), r.frame.length);
        last_response_index = r.index;
    }
    // The last request to unit 0 on the link whose checksum failed (frame index, 0: none), and when: a reply
    // nobody waits for right after it answers a frame every slave should have discarded, or one the capture
    // damaged.
    std::uint64_t damaged_request = 0;
    Timestamp damaged_request_time{0};
    // A damaged request to a unit the link had not shown, whose timeout ran out before the link showed
    // whose it is: given up when the next frame tells (release_unseen), as one to a known unit is at its
    // timeout; a reply from its unit after it is then late, as it would be.
    std::optional<Pending> unseen_expired;
    // The last broadcast on a serial link (frame index, 0: none, or a unicast request since), and when: a
    // slave's reply right after it answers what no slave may answer (SL §2.1).
    std::uint64_t last_broadcast = 0;
    Timestamp last_broadcast_time{0};
    std::vector<std::uint8_t> last_broadcast_pdu;  // what a slave's echo of it would carry (classify)
    // The last run of serial bytes that formed no frame, and how many frames the capture had when it came: a
    // reply nobody waits for after it may answer a request among those bytes.
    std::uint64_t unparsed_offset = 0;
    std::uint32_t unparsed_length = 0;
    std::uint64_t unparsed_after_frame = 0;
    // The last run of RTU bytes (or ASCII frame the capture's end cut) that formed no frame, not from the
    // master's side, while no frame has come after it (tail_length 0: none), and the unit and function code
    // it begins with: at the end of the capture, a reply it cut begins with those its request asked for.
    std::uint64_t tail_offset = 0;
    std::uint32_t tail_length = 0;
    std::array<std::uint8_t, 2> tail_head{};
    // Whether the tail is the start of a reply to `request`: after it, with its unit and function (or the
    // exception to it).
    bool tail_begins_reply_to(const FrameRecord& request) const {
        const auto pdu = request.frame.pdu();
        return tail_length >= 2 && !pdu.empty() &&
               tail_offset >= request.frame.offset + request.frame.wire_length &&
               tail_head[0] == request.frame.unit_id() && (tail_head[1] & 0x7F) == pdu[0];
    }
    std::optional<Framing> udp_framing;  // what the link's datagrams were shown to carry
    // Whether a request on the link was captured: until then, on a connection whose opening the capture did
    // not show, a reply answers a request sent before the capture began.
    bool request_seen = false;
    // After it, until a reply answers a captured request (a server answers a connection's requests in turn),
    // a reply may still answer one pipelined ahead of the capture's first: the first request's transaction
    // id, to tell the ids that came before it, and those already excused so (a request is answered once).
    std::uint16_t first_request_id = 0;
    bool captured_request_answered = false;
    std::vector<std::uint16_t> excused_before_capture;
    // Whether `tid` may name a request sent before the capture's first request of the link: a client numbers
    // its transactions upwards, so the requests in flight when the capture began carry the ids just before
    // it, no more of them than a link may have waiting.
    bool may_predate_first_request(std::uint16_t tid, std::size_t max_waiting) const {
        const auto before = static_cast<std::uint16_t>(first_request_id - tid);
        return before != 0 && before <= max_waiting && may_answer_uncaptured_request(tid, max_waiting);
    }
    // Whether a reply with `tid` may still answer a request sent before the capture, whatever its id: after
    // the link's first captured request, before any reply answered one, not excused already, and no more of
    // them than a link may have waiting. A client whose ids start over (ModbusTCP.pcap: replies 31998 to
    // 32000 in flight, the first captured request 0) numbers them from anywhere.
    bool may_answer_uncaptured_request(std::uint16_t tid, std::size_t max_waiting) const {
        return request_seen && !captured_request_answered && excused_before_capture.size() < max_waiting &&
               std::find(excused_before_capture.begin(), excused_before_capture.end(), tid) ==
                   excused_before_capture.end();
    }
    // The id after the last one excused so: a client numbers its requests upwards, and the replies to those
    // in flight when the capture began come in turn (31998, 31999 and 32000 in one segment: 31999 fits the
    // captured request 0, whose own reply follows).
    bool follows_excused(std::uint16_t tid) const {
        return !excused_before_capture.empty() &&
               static_cast<std::uint16_t>(excused_before_capture.back() + 1) == tid;
    }
    // The client stream's position (+1) at a hole whose acknowledged bytes excused a reply already.
    std::uint64_t excused_hole = 0;
    // The client reset the connection and requests of it still wait (Pending::client_reset): its next SYN
    // gives them up before the new connection's ids start over.
    bool client_reset = false;
    // "server unit N" and its statistics, made once per unit seen on the link rather than once per frame.
    struct Unit {
        std::uint8_t id;
        SharedText device;
        DeviceStats* stats;
    };
    std::vector<Unit> units;
    // The unit if the link has shown it, else null (device_of makes it).
    const Unit* unit(std::uint8_t id) const {
        for (const auto& u : units)
            if (u.id == id) return &u;
        return nullptr;
    }
    // A request whose checksum failed, that no device answers: a reply nobody waits for right after it says
    // so, and is not "the last response again".
    void mark_damaged_request(const FrameRecord& r) {
        damaged_request = r.index;
        damaged_request_time = r.time;
    }
};

// A link whose frames come whole or from a serial deframer, never from TCP reassembly: serial lines, and
// exported PDUs.
struct Analyzer::SerialLink {
    Flow* flow = nullptr;
    std::string source;  // input file
    std::unique_ptr<RtuDeframer> untimed;
    std::unique_ptr<RtuTimedDeframer> timed;
    std::unique_ptr<AsciiDeframer> ascii;
    Direction hint = Direction::Unknown;
    Timestamp last_received{0};  // the time of the last chunk deframed, to see the line's clock go back
    std::uint64_t offset = 0;    // exported PDUs: bytes of the records before this one
    int rtac_side = -1;          // RTAC serial: 0 sending, 1 receiving, -1 not yet known

    // The line as the link reads it: its framing (none until the first bytes tell it, when the input does
    // not) and its character (t1.5/t3.5), both changed by a device told other settings (follow_line).
    std::optional<Framing> framing;
    std::vector<Framing> read_as;  // every framing it was read in, in order
    bool framing_told = false;     // the first one from the bytes, not from the input or the user
    SerialLine line;
    std::uint64_t base = 0;     // stream offset of the deframers' first byte: their offsets count from it
    std::uint64_t fed = 0;      // stream bytes given to the link
    std::uint64_t settled = 0;  // every byte before this is in a reported frame or unparsed record
    // Kept when the framing is not known yet, or may change mid-stream (profiles can tell a device other
    // settings): the chunks from the first byte not yet settled on, so that the bytes after a change are
    // deframed again the new way. A close (close_frames) is a chunk of its own, without bytes.
    struct Chunk {
        std::vector<std::uint8_t> bytes;
        std::uint64_t offset;  // stream offset of bytes[0]
        Timestamp received;
        Direction hint;
        std::uint64_t packet;
        bool close;
    };
    bool keeps_chunks = false;
    std::deque<Chunk> chunks;
    std::size_t next_chunk = 0;               // the next chunk for the deframers
    std::size_t next_skip = 0;                // its bytes already given (a restart inside it)
    std::optional<std::uint64_t> restart_at;  // follow_line: deframe again from here, the new way
    // Telling the framing (there while it is not known): an ASCII deframer that has not seen a frame with
    // a valid LRC yet, an RTU one that has not seen a frame with a valid CRC holding a byte no ASCII line
    // carries, and the count of such bytes.
    std::unique_ptr<AsciiDeframer> probe;
    std::unique_ptr<RtuDeframer> rtu_probe;
    std::size_t foreign = 0;
    // Units that answered on the line, and the settings each was told: the line follows once all of them
    // hold the same.
    std::vector<std::uint8_t> answered;
    std::map<std::uint8_t, LineState> told;
    // A line read from several files (serial_part_of): the stream offset at which each file's bytes begin,
    // and the file, for the records' `source` (a frame is closed by the next bytes, maybe the next file's).
    std::vector<std::pair<std::uint64_t, SharedText>> parts;

    const SharedText& source_at(std::uint64_t offset, const SharedText& current) const noexcept {
        if (parts.empty()) return current;
        const auto after = std::upper_bound(parts.begin(), parts.end(), offset,
                                            [](std::uint64_t o, const auto& part) { return o < part.first; });
        return after == parts.begin() ? current : std::prev(after)->second;
    }

    // The packet (a log's record, a capture's packet) each stretch of the stream came in, by the stream
    // offset of its first byte. A frame or unparsed run is the packet's in which it began: a timed deframer
    // closes a frame only when the next chunk shows the silence after it, and a log's records were all
    // "packet 0". Stretches wholly before `settled` are dropped.
    std::deque<std::pair<std::uint64_t, std::uint64_t>> packets;
    void note_packet(std::uint64_t offset, std::uint64_t packet) {
        while (packets.size() > 1 && packets[1].first <= settled)
            packets.pop_front();
        packets.emplace_back(offset, packet);
    }
    std::uint64_t packet_at(std::uint64_t offset, std::uint64_t current) const noexcept {
        const auto after = std::upper_bound(packets.begin(), packets.end(), offset,
                                            [](std::uint64_t o, const auto& p) { return o < p.first; });
        return after == packets.begin() ? current : std::prev(after)->second;
    }
};

std::size_t Analyzer::FlowKeyHash::operator()(const FlowKey& k) const noexcept {
    // the words mixed side by side rather than in a chain of multiplications, then folded once
    const std::uint64_t h = (k.words[0] ^ 0x9E3779B97F4A7C15ull) * 0xBF58476D1CE4E5B9ull +
                            (k.words[1] ^ 0x94D049BB133111EBull) * 0x9E3779B97F4A7C15ull +
                            (k.words[2] ^ 0xBF58476D1CE4E5B9ull) * 0x94D049BB133111EBull +
                            (k.words[3] ^ 0xD6E8FEB86659FD93ull) * 0xC2B2AE3D27D4EB4Full +
                            (k.words[4] ^ 0xC2B2AE3D27D4EB4Full) * 0xD6E8FEB86659FD93ull;
    return static_cast<std::size_t>((h ^ (h >> 29)) * 0xBF58476D1CE4E5B9ull);
}

Analyzer::FlowKey Analyzer::flow_key(Transport transport, const Endpoint& client, const Endpoint& server) {
    FlowKey k;
    std::memcpy(&k.words[0], client.address.data(), 16);
    std::memcpy(&k.words[2], server.address.data(), 16);
    k.words[4] = std::uint64_t{client.port} | std::uint64_t{server.port} << 16 |
                 std::uint64_t{client.v6} << 32 | std::uint64_t{server.v6} << 33 |
                 std::uint64_t{static_cast<std::uint8_t>(transport)} << 34;
    return k;
}

const SharedText& Analyzer::device_of(Flow& flow, std::uint8_t unit, DeviceStats*& stats) {
    if (const Flow::Unit* known = flow.unit(unit)) {
        stats = known->stats;
        return known->device;
    }
    std::string device = flow.server + " unit " + std::to_string(unit);
    stats = &summary_.devices[device];
    flow.units.push_back({unit, std::move(device), stats});
    return flow.units.back().device;
}

Analyzer::Analyzer(AnalyzerOptions options, Sink& sink)
    : options_(std::move(options)), sink_(sink), sink_wants_transactions_(sink.wants_transactions()) {}
Analyzer::~Analyzer() = default;

void Analyzer::count_finding(FindingCode code) {
    ++summary_.findings[std::string(to_string(code))];
    if (info(code).severity == Severity::Error) ++summary_.errors;
}

void Analyzer::report(FindingCode code, const FrameRecord& about, std::string message,
                      std::vector<std::uint64_t> frames) {
    count_finding(code);
    if (!about.device.empty())
        if (auto it = summary_.devices.find(about.device.str()); it != summary_.devices.end())
            ++it->second.findings[std::string(to_string(code))];
    if (frames.empty() && about.index) frames.push_back(about.index);
    sink_.finding(FindingRecord{code, about.time, about.source, about.link, about.device, std::move(frames),
                                about.packet, std::move(message)});
}

namespace {
// Packets between two calls of the progress callback: the clock is not free.
constexpr std::uint64_t packets_between_progress = 256;

bool contains(const std::vector<std::uint16_t>& ports, std::uint16_t port) {
    return std::find(ports.begin(), ports.end(), port) != ports.end();
}
}  // namespace

bool Analyzer::server_port(Transport transport, std::uint16_t port) const {
    if (transport == Transport::Udp) return contains(options_.udp_ports, port);
    return contains(options_.tcp_ports, port) || contains(options_.rtu_over_tcp_ports, port);
}

// A SYN tells who the client is (its sender; a SYN-ACK's receiver), whatever came before it on these
// endpoints; without one, the end that spoke first is taken for the client, as a Modbus client speaks first
// (a capture begun between a request and its reply gets it wrong; one begun with the connection does not).
// Spoke: at least an MBAP header and a function code, the shortest ADU; a keepalive probe's one byte, which
// a server's stack may send first, tells nothing.
std::optional<bool> Analyzer::sent_by_client(const L4Packet& l4) {
    const FlowKey forward = flow_key(l4.transport, l4.source, l4.destination);
    const FlowKey backward = flow_key(l4.transport, l4.destination, l4.source);
    if (l4.transport == Transport::Tcp && l4.syn) {
        const bool from_client = !l4.has_ack;
        told_clients_.erase(from_client ? backward : forward);
        told_clients_.insert(from_client ? forward : backward);
        return from_client;
    }
    if (told_clients_.count(forward)) return true;
    if (told_clients_.count(backward)) return false;
    constexpr std::size_t shortest_adu = 8;
    if (l4.payload.size() < shortest_adu) return std::nullopt;  // an ACK, a keepalive probe: nothing told
    told_clients_.insert(forward);
    return true;
}

Analyzer::Flow& Analyzer::flow_for(const L4Packet& l4, bool to_server) {
    const Endpoint& client = to_server ? l4.source : l4.destination;
    const Endpoint& server = to_server ? l4.destination : l4.source;
    const FlowKey binary = flow_key(l4.transport, client, server);
    const std::size_t hash = FlowKeyHash()(binary);
    FlowCacheEntry& cached = flow_cache_[hash >> (8 * sizeof(std::size_t) - 6)];
    if (cached.flow && cached.key == binary) return *cached.flow;
    Flow*& known = flow_index_[binary];
    cached.key = binary;
    if (known) return *(cached.flow = known);
    std::string key =
        (l4.transport == Transport::Tcp ? "tcp " : "udp ") + client.to_string() + " -> " + server.to_string();
    auto& slot = flows_[key];
    if (!slot) {
        slot = std::make_unique<Flow>();
        Flow& f = *slot;
        f.id = ++next_flow_;
        flow_by_id_.push_back(&f);
        f.link = client.to_string() + " -> " + server.to_string();
        f.server = server.to_string();
        f.carrier = l4.transport == Transport::Tcp ? Carrier::Tcp : Carrier::Udp;
        if (l4.transport == Transport::Tcp) {
            f.rtu_over_tcp = contains(options_.rtu_over_tcp_ports, server.port);
            f.server_port = server.port;
            for (int dir = 0; dir < 2; ++dir) {
                f.reassembler[dir] = std::make_unique<TcpReassembler>(
                    [this, &f, dir](std::span<const std::uint8_t> bytes, Timestamp t) {
                        stream_bytes(f, dir, bytes, t);
                    },
                    [this, &f, dir](std::uint64_t missing, Timestamp t) { stream_gap(f, dir, missing, t); });
                f.reassembler[dir]->on_conflict(
                    [this, &f, dir](std::uint64_t at, std::size_t differing, Timestamp t) {
                        retransmission_conflict(f, dir, at, differing, t);
                    });
                f.reassembler[dir]->on_before_start([this, &f, dir](std::size_t bytes, Timestamp t) {
                    DeframeEvents events;
                    events.emplace_back(
                        std::in_place_type<Unparsed>,
                        Unparsed{0, static_cast<std::uint32_t>(bytes), UnparsedReason::BeforeStreamStart, t});
                    deframed(f, dir == 0, events, t);
                });
            }
        }
    }
    known = cached.flow = slot.get();
    return *slot;
}

namespace {
// RTU deframers count the bytes they were given; a flow adds what its gaps lost.
void shift_offsets(DeframeEvents& events, std::uint64_t by) {
    for (auto& e : events) {
        if (auto* f = std::get_if<Frame>(&e)) f->offset += by;
        if (auto* u = std::get_if<Unparsed>(&e)) u->offset += by;
    }
}
}  // namespace

void Analyzer::stream_bytes(Flow& f, int dir, std::span<const std::uint8_t> bytes, Timestamp t) {
    DeframeEvents& events = stream_events_;  // reused: one allocation for the run, not one a packet
    events.clear();
    // The packet that carried them: bytes that waited behind a hole are released by a later packet (the
    // acknowledgement that gave the hole up, the segment that filled it), and were credited to it.
    const std::uint64_t carried = f.reassembler[dir]->delivering_packet();
    const std::uint64_t packet = carried ? carried : packet_number_;
    if (!f.rtu_over_tcp) {
        switch (f.reading) {
            case Flow::Reading::Probing:
                if (f.held.empty()) probing_.push_back(&f);
                f.held.push_back({dir, {bytes.begin(), bytes.end()}, t, packet, source_});
                if (f.probe.feed(dir, bytes, !f.reassembler[dir]->saw_syn()) !=
                    RtuOverTcpProbe::Verdict::Undecided)
                    settle_framing(f, t);
                return;
            case Flow::Reading::Rtu:
                return not_decoded(f, dir, bytes.size(), t, packet);
            case Flow::Reading::Mbap:
                return feed_mbap(f, dir, bytes, t, packet);
        }
        return;
    }
    // A gateway carries one request and its response at a time: when one side speaks, what the other side
    // sent is complete. Without this a frame with a bad CRC would wait for the next frame from its own side
    // to confirm where it ends, and its response would be decoded before it. (Either way it keeps the
    // packet and time it came with: deframed stamps it by its bytes' arrival.)
    const int other = 1 - dir;
    f.rtu_deframer[other].finish(events);
    shift_offsets(events, f.rtu_lost[other]);
    deframed(f, other == 0, events, t);
    f.rtu_arrived(dir, packet, t);
    f.rtu_deframer[dir].feed(bytes, events);
    shift_offsets(events, f.rtu_lost[dir]);
    deframed(f, dir == 0, events, t, packet);
}

void Analyzer::feed_mbap(Flow& f, int dir, std::span<const std::uint8_t> bytes, Timestamp t,
                         std::uint64_t packet) {
    DeframeEvents& events = stream_events_;
    events.clear();
    auto& fed = f.fed[dir];
    const std::uint64_t at = f.deframer[dir].offset();
    if (at == 0 && !f.reassembler[dir]->saw_syn()) f.deframer[dir].start_unaligned();
    if (f.last_fed_packet[dir] != packet) {
        // The packet before left bytes unreported: kept where they start.
        if (f.last_fed_packet[dir] && f.deframer[dir].unreported() < at)
            fed.emplace_back(f.last_fed_from[dir], f.last_fed_packet[dir]);
        f.last_fed_from[dir] = at;
        f.last_fed_packet[dir] = packet;
    }
    f.deframer[dir].feed(bytes, t, events);
    deframed(f, dir == 0, events, t, packet);
    if (fed.empty()) return;
    // Kept: the entry holding the first unreported byte (a run of unparsed bytes still gathering needs
    // only its first byte's packet), and those from the one holding the first buffered byte on.
    const std::uint64_t first = f.deframer[dir].unreported();
    if (first >= f.last_fed_from[dir]) {
        fed.clear();
        return;
    }
    const std::uint64_t buffered = f.deframer[dir].offset() - f.deframer[dir].buffered();
    while (fed.size() > 1 && fed[1].first <= first)
        fed.pop_front();
    std::size_t from = 1;
    while (from + 1 < fed.size() && fed[from + 1].first <= buffered)
        ++from;
    if (from > 1) fed.erase(fed.begin() + 1, fed.begin() + static_cast<std::ptrdiff_t>(from));
}

void Analyzer::settle_framing(Flow& f, Timestamp t) {
    if (f.rtu_over_tcp || f.carrier != Carrier::Tcp || f.reading != Flow::Reading::Probing) return;
    const bool rtu = f.probe.settle() == RtuOverTcpProbe::Verdict::Rtu;
    f.reading = rtu ? Flow::Reading::Rtu : Flow::Reading::Mbap;
    std::vector<Flow::HeldChunk> held;
    held.swap(f.held);
    if (rtu) {
        // Said at the bytes that told it (the last held), not at whatever ended the probing.
        ++summary_.rtu_over_tcp_connections[f.server_port];
        FrameRecord about = about_stream(f, held.empty() ? t : held.back().time);
        if (!held.empty()) {
            about.packet = held.back().packet;
            about.source = held.back().source;
        }
        char first[64];
        std::snprintf(first, sizeof first, "the first from unit %u, FC%u", unsigned{f.probe.first_unit()},
                      unsigned{f.probe.first_function()});
        const std::string port = std::to_string(f.server_port);
        report(FindingCode::TcpRtuFraming, about,
               "the connection " + f.link.str() + " carries RTU frames, not Modbus/TCP: " +
                   (f.probe.frames() == 1
                        ? std::string("an RTU frame with a valid CRC (")
                        : std::to_string(f.probe.frames()) + " frames back to back with valid CRCs (") +
                   first + "), while read as MBAP " + f.probe.mbap_misreading() +
                   " (a serial gateway in transparent mode?); its bytes are not decoded as MBAP, which "
                   "would make up units and transactions: decode with --rtu-over-tcp " +
                   port);
    }
    // As if fed when they came, each from its own input: before each chunk the requests due by its time
    // expire, as at its packet (a reply held behind its request's deadline is late, not in time).
    const SharedText source = source_;
    const bool nested = replaying_;
    replaying_ = true;
    for (const auto& c : held) {
        source_ = c.source;
        if (rtu) {
            not_decoded(f, c.dir, c.bytes.size(), c.time, c.packet);
            continue;
        }
        expire(c.time, false);
        feed_mbap(f, c.dir, c.bytes, c.time, c.packet);
    }
    replaying_ = nested;
    source_ = source;
}

void Analyzer::not_decoded(Flow& f, int dir, std::size_t length, Timestamp t, std::uint64_t packet) {
    auto& run = f.not_decoded[dir];
    if (run.length == 0) run = {f.not_decoded_next[dir], 0, packet, t, source_};
    run.length += length;
    f.not_decoded_next[dir] += length;
}

void Analyzer::report_not_decoded(Flow& f, int dir) {
    auto& run = f.not_decoded[dir];
    if (run.length == 0) return;
    summary_.unparsed_bytes += run.length;
    const Direction direction = dir == 0 ? Direction::Request : Direction::Response;
    sink_.unparsed(UnparsedRecord{run.source, f.link, direction, run.time, run.packet, run.offset,
                                  static_cast<std::uint32_t>(std::min<std::uint64_t>(run.length, UINT32_MAX)),
                                  UnparsedReason::RtuOverTcp});
    FrameRecord about;
    about.time = run.time;
    about.source = run.source;
    about.link = f.link;
    about.packet = run.packet;
    report(FindingCode::StreamUnparsedBytes, about,
           std::to_string(run.length) + " bytes at stream offset " + std::to_string(run.offset) + " of the " +
               (dir == 0 ? "request" : "response") +
               " stream are RTU frames, not Modbus/TCP: not decoded (decode with --rtu-over-tcp " +
               std::to_string(f.server_port) + ")");
    run = {};
}

// What a finding about a flow's stream, rather than one of its frames, is attached to.
FrameRecord Analyzer::about_stream(const Flow& f, Timestamp t) const {
    FrameRecord about;
    about.time = t;
    about.source = source_;
    about.link = f.link;
    about.packet = packet_number_;
    return about;
}

void Analyzer::stream_gap(Flow& f, int dir, std::uint64_t missing, Timestamp t) {
    // The probe reads contiguous bytes: what it holds is read as it stands (MBAP, unless RTU was told).
    settle_framing(f, t);
    if (!f.rtu_over_tcp && f.reading == Flow::Reading::Rtu) {
        report_not_decoded(f, dir);
        f.not_decoded_next[dir] += missing;
        report(FindingCode::StreamGap, about_stream(f, t),
               std::to_string(missing) + " bytes of the " + (dir == 0 ? "request" : "response") +
                   " stream were not captured, on a connection that carries RTU frames (not decoded)");
        return;
    }
    DeframeEvents events;
    std::optional<CutAdu> cut;  // the ADU the hole cuts, named by its header
    if (f.rtu_over_tcp) {
        f.rtu_deframer[dir].finish(events);  // the frame in progress ends at the hole
        shift_offsets(events, f.rtu_lost[dir]);
        f.rtu_lost[dir] += missing;
    } else {
        cut = cut_adu(f.deframer[dir].incomplete(), f.reassembler[dir]->gap_is_cut());
        f.deframer[dir].gap(missing, events);
    }
    if (dir == 0) f.first_request_after_gap = next_serial_ + 1;
    report(FindingCode::StreamGap, about_stream(f, t),
           std::to_string(missing) + " bytes of the " + (dir == 0 ? "request" : "response") +
               " stream were not captured" +
               (f.reassembler[dir] && f.reassembler[dir]->gap_is_cut()
                    ? " (a packet cut to the capture's snapshot length)"
                    : "") +
               "; decoding resumes at the next " + (f.rtu_over_tcp ? "RTU frame" : "plausible MBAP header"));
    deframed(f, dir == 0, events, t);
    if (dir == 1) {
        if (cut) reply_cut(f, *cut, t);
        if (f.rtu_over_tcp) rtu_reply_cut(f, missing);
        // The requests still waiting may have been answered in the hole (a tap's drop the client's
        // acknowledgement covered): the mirror of a request among lost bytes (first_request_after_gap).
        // Unless the hole is the tail of the reply cut, too short to hold anything of another; and not a
        // request sent after the client acknowledged the hole's bytes, which were sent before it.
        if (f.pending && (!cut || missing > cut->length - cut->captured)) {
            const auto acknowledged =
                f.reassembler[1] ? f.reassembler[1]->gap_acknowledged_at() : std::nullopt;
            const auto mark = [&](Pending& p) {
                if (!acknowledged || p.request.time <= *acknowledged) p.reply_gap += missing;
            };
            for (auto& [k, p] : pending_)
                if (k.flow == f.id) mark(p);
            for (auto& [k, older] : reused_)
                if (k.flow == f.id)
                    for (Pending& p : older)
                        mark(p);
        }
        return;
    }
    if (!cut) return;
    if (cut_requests_.size() >= max_cut_requests) cut_requests_.clear();
    cut_requests_.insert_or_assign({f.id, cut->tid}, *cut);
}

std::optional<Analyzer::CutAdu> Analyzer::cut_adu(std::span<const std::uint8_t> b, bool snapshot_length) {
    // Transaction id, protocol id 0 and length name it (on its connection the transaction id is the
    // client's own); the unit and function code, when the cut kept them, confirm it.
    if (b.size() < 6 || b[2] != 0 || b[3] != 0) return std::nullopt;
    const std::size_t length = 6u + ((std::size_t{b[4]} << 8) | b[5]);
    if (length < 8 || length <= b.size()) return std::nullopt;
    CutAdu cut{static_cast<std::uint16_t>((b[0] << 8) | b[1]),
               std::nullopt,
               std::nullopt,
               b.size(),
               length,
               snapshot_length};
    if (b.size() > 6) cut.unit = b[6];
    if (b.size() > 7) cut.function = static_cast<std::uint8_t>(b[7] & 0x7F);
    return cut;
}

// Two copies of the same stream bytes that disagree: a broken TCP stack, a middlebox rewriting the stream,
// or an attempt to make a monitor decode something other than what the device received.
void Analyzer::retransmission_conflict(Flow& f, int dir, std::uint64_t at, std::size_t differing,
                                       Timestamp t) {
    report(FindingCode::StreamRetransmissionConflict, about_stream(f, t),
           std::string("a retransmission of the ") + (dir == 0 ? "request" : "response") +
               " stream differs from the first copy in " + std::to_string(differing) +
               (differing == 1 ? " byte" : " bytes") + ", the first at stream offset " + std::to_string(at) +
               "; the first copy was decoded, and the receiver may have kept the other");
}

void Analyzer::set_source(const std::string& source) {
    if (source_.str() != source) source_ = source;  // shared by every record from that file
}

void Analyzer::packet(const std::string& source, const Packet& p) {
    set_source(source);
    packet_in_source(p);
}

void Analyzer::packet_in_source(const Packet& p) {
    const std::string& source = source_.str();
    packet_number_ = p.number;
    ++summary_.packets;
    if (p.time_out_of_range && time_warned_source_ != source) {
        time_warned_source_ = source;
        input_note(source + ": packet " + std::to_string(p.number) +
                   ": timestamp beyond April 2262, not representable; such packets are decoded at the "
                   "time of the packet before them");
    }
    if (p.time > now_)
        now_ = p.time;
    else if (clock_stepped_back(now_, p.time))
        clock_went_back(p.time, "packet " + std::to_string(p.number));
    // A record of serial bytes: the frame its line holds may continue in it, and is ended by it otherwise,
    // at its own time; requests are timed out at this record's time once its bytes are in.
    const bool serial_record =
        (p.linktype >= link_user0 && p.linktype <= link_user15) || p.linktype == link_rtac_serial;
    if (!serial_links_.empty()) end_silent_frames(now_, serial_record ? &source_.str() : nullptr, true);
    if (serial_record) {
        if (p.linktype == link_rtac_serial)
            rtac_packet(p);
        else
            user_dlt_packet(p);
        return expire(now_, false);
    }
    expire(now_, false);
    if (p.linktype == link_upper_pdu) return exported_pdu(p);
    L4Packet l4;
    IpFragment fragment;
    std::optional<IpDatagram> whole;  // a reassembled datagram: l4's payload points into it
    ip_fragments_.expire(now_, false);
    const ParseStatus status = parse_packet(p.linktype, p.data, l4, &fragment);
    if (status == ParseStatus::Fragment) {
        whole = ip_fragments_.add(fragment, p.time);
        if (!whole) return;
        if (const ParseStatus inside = parse_datagram(*whole, l4); inside != ParseStatus::Ok) {
            summary_.packets_malformed += inside == ParseStatus::Malformed;
            return;
        }
    } else if (status == ParseStatus::UnsupportedLink) {
        // A capture of a link mbscope does not read (802.11, PPP, ...) decoded to nothing without a word, as
        // if the line carried no Modbus. Said once a file and link type; the run fails (exit 2).
        if (first_told(p.linktype))
            input_error(
                source + ": link type " + std::to_string(p.linktype) +
                " is not one mbscope decodes (Ethernet, Linux cooked, raw IP, BSD loopback, Wireshark's "
                "exported PDUs, SEL RTAC serial; serial bytes in USER0-15 with --user-dlt): its packets "
                "are not decoded");
        return;
    } else if (status == ParseStatus::Malformed) {
        ++summary_.packets_malformed;  // it may have been Modbus: counted, not dropped without a word
        return;
    } else if (status != ParseStatus::Ok) {
        return;  // not IP, not TCP or UDP: not Modbus
    }
    if (!server_port(l4.transport, l4.destination.port) && !server_port(l4.transport, l4.source.port)) {
        // Modbus/TCP Security (TLS on port 802): encrypted, so nothing decodes; said, not left as a quiet
        // line.
        constexpr std::uint16_t modbus_security_port = 802;
        if (l4.transport == Transport::Tcp && !l4.payload.empty() &&
            (l4.destination.port == modbus_security_port || l4.source.port == modbus_security_port))
            ++summary_.modbus_security_packets;
        else
            modbus_like_.note(l4);
        return;
    }
    bool to_server = server_port(l4.transport, l4.destination.port);
    if (to_server && server_port(l4.transport, l4.source.port)) {
        const auto from_client = sent_by_client(l4);
        if (!from_client) return;
        to_server = *from_client;
    }
    Flow& flow = flow_for(l4, to_server);
    if (l4.transport == Transport::Tcp) {
        auto& stream = *flow.reassembler[to_server ? 0 : 1];
        if (l4.syn && stream.opens_new_connection(l4.seq))
            end_connection(
                flow, p.time,
                to_server ? "the client opened the connection again" : "the connection was opened again");
        else if (l4.syn && flow.client_reset)  // a new connection: ids and the server's stream start over
            end_connection(flow, p.time, "the client reset the connection");
        // The acknowledgement first: it says what the sender had received before it sent this segment's
        // bytes (a request behind a lost segment is released before the reply to it is paired).
        if (l4.has_ack) flow.reassembler[to_server ? 1 : 0]->acknowledged(l4.ack, p.time);
        if (!l4.payload.empty()) flow.reassembler[to_server ? 1 : 0]->peer_spoke();
        // Through a gateway on TCP (RTU over TCP) the client's next data is its next request, which ends the
        // wait of those still waiting (on_request): a reply it had acknowledged that the capture lacks was
        // in the hole, given up now as at a request's deadline (expire), so that the request it answered is
        // the capture's loss (pair.response_not_captured), not the device's no response before the next
        // request.
        if (flow.rtu_over_tcp && to_server && !l4.payload.empty() && flow.pending)
            flow.reassembler[1]->give_up_acknowledged_before(p.time);
        stream.segment(l4.seq, l4.syn, l4.payload, p.time, p.number);
        // Bytes the IP header counts past the record's end are cut only when the record says so (its
        // original length): an IP length that lies about a whole record is not a snapshot length's doing.
        const std::uint32_t record_cut = !whole && p.original_length > p.data.size()
                                             ? p.original_length - static_cast<std::uint32_t>(p.data.size())
                                             : 0;
        if (const auto cut = std::min(l4.payload_cut, record_cut)) {
            // A hole at once, at this packet (a whole copy may still fill it): found only when later bytes
            // showed it, the gap was put at the next packet, or nowhere for the last.
            ++summary_.packets_cut;
            stream.cut_by_capture(l4.seq + (l4.syn ? 1u : 0u) + static_cast<std::uint32_t>(l4.payload.size()),
                                  cut, p.time);
        }
        if (l4.fin) stream.finished_at(l4.seq + static_cast<std::uint32_t>(l4.payload.size()));
        // The server closed its side with every byte it sent delivered: no reply will follow on this
        // connection. (A client's FIN is no end: a half-closed client may still be answered.)
        if (l4.fin && !to_server && stream.finished())
            give_up_waiting(flow, p.time, "the server closed the connection");
        // A reset connection sends nothing more: half an ADU in either direction will never complete. Not a
        // reset far outside the stream, which its receiver ignores: it ended a live connection's decoding.
        if (l4.rst && stream.reset_in_window(l4.seq)) {
            if (to_server)
                client_reset(flow, p.time);
            else
                end_connection(flow, p.time, "the server reset the connection");
        } else if (l4.rst) {
            report(FindingCode::StreamResetOutsideWindow, about_stream(flow, p.time),
                   std::string("a TCP reset from the ") + (to_server ? "client" : "server") +
                       " with a sequence number far outside its stream (sequence number " +
                       std::to_string(l4.seq) + "); a receiver ignores it, and the connection is decoded on");
        }
        return;
    }
    // Modbus/UDP: one ADU per datagram (no stream to resynchronise). Serial gateways send RTU frames in
    // datagrams instead. A valid CRC proves RTU (an RTU FC3 request can also parse as a well-formed MBAP
    // ADU: 01 03 00 00 00 02 C4 0B); once a link is known to carry RTU, its datagrams stay RTU, bad CRCs
    // included, rather than being misread as MBAP (the mistake tshark makes without -d ...,mbrtu).
    if (l4.payload.empty()) return;
    DeframeEvents events;
    const bool rtu_size = l4.payload.size() >= 4 && l4.payload.size() <= max_rtu_adu_length;
    auto rtu = rtu_size ? decode_rtu(l4.payload) : Result<Frame>(make_error(ErrorCode::Truncated, 0));
    if (rtu && (rtu->checksum_ok || flow.udp_framing == Framing::Rtu)) {
        flow.udp_framing = Framing::Rtu;
        events.emplace_back(std::move(rtu.value()));
        deframed(flow, to_server, events, p.time);
        return;
    }
    if (auto mbap = decode_tcp(l4.payload); mbap && mbap->protocol_id() == 0) flow.udp_framing = Framing::Tcp;
    TcpStreamDeframer datagram;
    datagram.feed(l4.payload, p.time, events);
    datagram.finish(events);
    deframed(flow, to_server, events, p.time);
}

void Analyzer::deframed(Flow& flow, bool to_server, DeframeEvents& events, Timestamp t,
                        std::uint64_t carried) {
    const std::uint64_t current = carried ? carried : packet_number_;
    for (auto& e : events) {
        if (auto* u = std::get_if<Unparsed>(&e)) {
            summary_.unparsed_bytes += u->length;
            // Where the bytes came: their first byte's packet and its time (a Modbus/TCP stream's; a
            // datagram's or a serial record's are the packet being read, as are bytes that came before the
            // stream's start, which were never fed to the deframer).
            const bool fed = u->reason != UnparsedReason::BeforeStreamStart && !flow.rtu_over_tcp;
            std::uint64_t packet = fed ? flow.packet_at(to_server ? 0 : 1, u->offset, current) : current;
            Timestamp when = fed && u->time.count() != 0 ? u->time : t;
            if (u->reason != UnparsedReason::BeforeStreamStart && flow.rtu_over_tcp)
                if (const auto* arrived = flow.rtu_arrival(to_server ? 0 : 1, u->offset)) {
                    packet = arrived->packet;
                    when = arrived->time;
                }
            UnparsedRecord rec{source_,   flow.link, to_server ? Direction::Request : Direction::Response,
                               when,      packet,    u->offset,
                               u->length, u->reason};
            sink_.unparsed(rec);
            if (flow.rtu_over_tcp && !to_server) flow.rtu_reply_tail = {u->length, when, u->head};
            FrameRecord about;
            about.time = when;
            about.source = source_;
            about.link = flow.link;
            about.packet = packet;
            const FindingCode code = u->reason == UnparsedReason::BadHeader
                                         ? FindingCode::TcpLengthInvalid
                                         : FindingCode::StreamUnparsedBytes;
            const std::string stream = to_server ? "request" : "response";
            report(code, about,
                   u->reason == UnparsedReason::BeforeStreamStart
                       ? std::to_string(u->length) + " bytes of the " + stream +
                             " stream came after later ones at the start of the capture (it began "
                             "mid-connection): they precede the first byte decoded and are not decoded"
                   : u->reason == UnparsedReason::BeforeFirstHeader
                       ? std::to_string(u->length) + " bytes at the start of the " + stream +
                             " stream, whose connection opened before the capture began, come before its "
                             "first header: the end of an ADU sent before the capture, not decoded"
                   : u->reason == UnparsedReason::AfterGap
                       ? std::to_string(u->length) + " bytes at stream offset " + std::to_string(u->offset) +
                             " of the " + stream +
                             " stream follow bytes the capture lacks and come before the next header: the "
                             "end of an ADU the gap cut, not decoded"
                       : std::to_string(u->length) + " bytes at stream offset " + std::to_string(u->offset) +
                             " of the " + stream + " stream formed no frame (" +
                             std::string(to_string(u->reason)) + ")");
            continue;
        }
        if (flow.rtu_over_tcp && !to_server) flow.rtu_reply_tail.length = 0;
        FrameRecord r(std::get<Frame>(e));
        r.index = ++next_frame_;
        r.packet = current;
        r.time = t;
        // A TCP stream's bytes come with the time and packet that carried them, and a frame is whole at the
        // later of its first and last bytes': its first bytes may have come after its last, which waited
        // for them ahead of a hole.
        if (flow.carrier == Carrier::Tcp && !flow.rtu_over_tcp && r.frame.start > t) {
            r.time = r.frame.start;
            r.packet = flow.packet_at(to_server ? 0 : 1, r.frame.offset, current);
        }
        // An ADU sent whole with an MBAP length too long is cut at its segment's end when the next segment
        // comes: it was whole at its own segment's time and packet, not the next's.
        if (r.frame.findings.contains(FindingCode::TcpLengthBeyondSegment) && r.frame.end < r.time) {
            r.time = r.frame.end;
            r.packet = flow.packet_at(to_server ? 0 : 1, r.frame.offset + r.frame.length - 1u, current);
        }
        // A gateway's frame is whole at its last byte, as a Modbus/TCP ADU is (a frame in one packet: that
        // packet), whichever later bytes closed it.
        if (flow.rtu_over_tcp && r.frame.wire_length != 0)
            if (const auto* arrived =
                    flow.rtu_arrival(to_server ? 0 : 1, r.frame.offset + r.frame.wire_length - 1)) {
                r.packet = arrived->packet;
                r.time = arrived->time;
            }
        r.source = source_;
        r.link = flow.link;
        r.direction = to_server ? Direction::Request : Direction::Response;
        r.carrier = flow.carrier;
        // Over Modbus/TCP the transaction id pairs a reply with its request: one naming another unit is the
        // asked unit's reply (counted there, its pair.unit_mismatch says which unit it named). Named after
        // the unit in its header, it made a device nobody asked, which the error was filed under.
        std::uint8_t unit = r.frame.unit_id();
        if (!to_server && r.frame.framing == Framing::Tcp)
            if (const auto it = pending_.find(PendingKey{flow.id, r.frame.transaction_id()});
                it != pending_.end())
                unit = it->second.request.frame.unit_id();
        decode_and_judge(flow, r, unit);
    }
    events.clear();
}

void Analyzer::decode_and_judge(Flow& flow, FrameRecord& r, std::uint8_t unit) {
    // A request to unit 0 whose checksum fails is no broadcast (see on_frame), and its unit byte may be among
    // the damage, or the frame line noise: it is unit 0's only when broadcasts were seen on the link, else no
    // device's, rather than a device the noise made up. So is a damaged reply that no waiting request made
    // some unit's (serial_bytes) and whose unit byte names no unit seen on the link: the tail of a reply cut
    // by a silence, five bytes of noise, were "unit 0 answering a broadcast".
    // (The units are looked through only for such a frame: this runs for every frame.)
    // A damaged request to another unit the link has not seen is no device's either until the link shows
    // the unit is there (settle_unit).
    // A serial reply carrying unit 0 is no device's whatever its checksum: no slave has that address
    // (on_response says whose reply slot it took).
    const bool named_by_damage =
        r.frame.framing != Framing::Tcp &&
        (!r.frame.checksum_ok || (unit == 0 && r.direction == Direction::Response)) && !flow.unit(unit);
    DeviceStats* stats = nullptr;
    if (!named_by_damage) r.device = device_of(flow, unit, stats);
    auto pdu = decode_pdu(r.frame.pdu(), r.direction);
    if (pdu)
        r.pdu = std::move(pdu.value());
    else
        r.error =
            std::string(to_string(pdu.error().code)) + " at PDU byte " + std::to_string(pdu.error().offset);
    on_frame(flow, r, stats);
}

namespace {
// Where the longest silence inside a timed RTU frame was and how long: "silence of 2.0 character times
// between bytes 4 and 5 of 8".
std::string gap_place_text(const Frame& f) {
    char chars[32];
    std::snprintf(chars, sizeof chars, "%.1f", static_cast<double>(f.max_gap_chars));
    return "silence of " + std::string(chars) + " character times between bytes " +
           std::to_string(f.gap_before_byte) + " and " + std::to_string(f.gap_before_byte + 1) + " of " +
           std::to_string(f.wire_length);
}

// A frame a silence of t3.5 or more cut in two, whose pieces verify only together (the timed deframer
// joined them): no frame on the wire, though its bytes were all sent. Who paused is its sender, unit N for a
// reply, the master for a request.
std::string t3_5_gap_text(const FrameRecord& r) {
    const std::string unit = "unit " + std::to_string(r.frame.unit_id());
    const bool reply = r.direction == Direction::Response;
    return gap_place_text(r.frame) +
           ", at or above t3.5: " + (reply ? unit + "'s reply" : "the master's request to " + unit) +
           " came in two pieces (its sender paused, or the capture stamped its reads apart) whose CRC holds "
           "over both only; a receiver keeping t3.5 takes two frames whose CRCs both fail, and " +
           (reply ? "a strict master discards the reply" : unit + " discards the request");
}

// "2.0 character times": a silence measured on a timed RTU line.
std::string chars_text(float chars) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f", static_cast<double>(chars));
    return std::string(text) + " character times";
}

// A serial request every slave discards: its checksum failed, it has a silence above t1.5 inside, or one
// below t3.5 parts it from the line's bytes before or after it, with which a receiver keeping t3.5 takes it
// as one frame (SL §2.5.1.1, §2.5.1.2, §2.5.2.2).
bool discardable(const FrameRecord& request) {
    return request.frame.framing != Framing::Tcp &&
           (!request.frame.checksum_ok || request.frame.findings.contains(FindingCode::RtuGapInsideFrame) ||
            request.frame.short_silence_before_chars > 0 || request.frame.short_silence_after_chars > 0);
}

// Why a request every slave discards is discarded, for the finding that says it drew no reply.
std::string discarded_because(const FrameRecord& request) {
    const Frame& f = request.frame;
    if (!f.checksum_ok)
        return std::string("its ") + (f.framing == Framing::Ascii ? "LRC" : "CRC") + " failed";
    if (f.findings.contains(FindingCode::RtuGapInsideFrame))
        return "a " + gap_place_text(f) + (f.gap_at_t3_5 ? ", at or above t3.5," : "") + " inside it";
    if (f.short_silence_before_chars > 0)
        return "only " + chars_text(f.short_silence_before_chars) +
               " of silence before it, below t3.5, joined it to the bytes before";
    return "only " + chars_text(f.short_silence_after_chars) +
           " of silence after it, below t3.5, joined it to the bytes after";
}
}  // namespace

void Analyzer::on_frame(Flow& flow, FrameRecord& r, DeviceStats* stats) {
    ++summary_.frames;
    const bool damaged = r.frame.framing != Framing::Tcp && !r.frame.checksum_ok;
    if (damaged && stats) ++stats->checksum_errors;
    sink_.frame(r);
    for (auto code : r.frame.findings) {
        std::string message(info(code).summary);
        if (code == FindingCode::TcpProtocolIdNonzero)
            message = "MBAP protocol id is " + std::to_string(r.frame.protocol_id()) + ", not 0 (Modbus)";
        if (code == FindingCode::TcpLengthInvalid)
            message =
                "MBAP length " + std::to_string(r.frame.length_field()) + " is above the 254 of TCP §3.1.3";
        if (code == FindingCode::TcpLengthBeyondSegment) message = length_beyond_segment_text(r);
        if (code == FindingCode::RtuGapInsideFrame && !r.frame.gap_at_t3_5)
            message = gap_place_text(r.frame) + ", above t1.5: a receiver keeping t1.5 discards the frame";
        if (code == FindingCode::RtuGapInsideFrame && r.frame.gap_at_t3_5) message = t3_5_gap_text(r);
        if (code == FindingCode::RtuShortSilenceBeforeFrame)
            message =
                "began after a silence of " + chars_text(r.frame.short_silence_before_chars) +
                " from the line's bytes before it, below t3.5: a receiver keeping t3.5 takes them and it "
                "as one frame, whose CRC fails (the silence as the capture's timestamps measure it)";
        if (code == FindingCode::RtuCrcMismatch)
            message = "CRC " + hex16(r.frame.checksum_received()) + " received, " +
                      hex16(r.frame.checksum_computed()) + " computed";
        if (code == FindingCode::AsciiLrcMismatch)  // one byte (SL §2.5.2.2)
            message = "LRC " + hex8(static_cast<std::uint8_t>(r.frame.checksum_received())) + " received, " +
                      hex8(static_cast<std::uint8_t>(r.frame.checksum_computed())) + " computed";
        report(code, r, message);
    }
    if (r.pdu)
        for (auto code : r.pdu->violations)
            report(code, r, std::string(info(code).summary));
    if (!r.error.empty()) report(FindingCode::PduMalformed, r, "PDU could not be decoded: " + r.error);
    if (r.direction == Direction::Response) return on_response(flow, r);
    if (damaged && r.frame.unit_id() == 0) {
        // Every slave discards a frame whose CRC or LRC fails (SL §2.5.1.2, §2.5.2.2; MK-ERR-01,
        // 000:270-272): one to unit 0 is no broadcast that every slave executes (line noise of four bytes
        // made one, and a device "unit 0"). Its checksum finding says what happened; it is counted. (A
        // damaged request to another unit still waits: a capture can damage what the device got whole,
        // and its reply is then paired with it.)
        ++summary_.damaged_broadcasts;
        flow.mark_damaged_request(r);
        return;
    }
    // A damaged request to a unit the link has not seen (decode_and_judge) waits as any other, its device
    // left open until the wait ends (complete).
    on_request(flow, r, stats);
}

namespace {
// A frame's own findings, as its transaction carries them: the codec's about its bytes, the specification's
// about its PDU, a PDU that does not decode, and the manual's rules the request breaks.
void add_frame_findings(const FrameRecord& r, std::vector<FindingCode>& out) {
    out.insert(out.end(), r.frame.findings.begin(), r.frame.findings.end());
    if (r.pdu) out.insert(out.end(), r.pdu->violations.begin(), r.pdu->violations.end());
    if (!r.error.empty()) out.push_back(FindingCode::PduMalformed);
    out.insert(out.end(), r.reported_findings.begin(), r.reported_findings.end());
}

// Serial framings carry no transaction id: a link has one outstanding request at a time (key 0).
std::uint16_t pairing_id(const Frame& f) {
    return f.framing == Framing::Tcp ? f.transaction_id() : 0;
}
std::string describe_request(const Pdu& p) {
    // The function byte whole: in a request bit 7 is no exception flag, and 0x83 is no FC3 (the summary's
    // function counts take the byte whole too).
    std::string s = "FC" + std::to_string(p.function_raw);
    if (auto n = function_name(p.function_raw)) s += " " + std::string(*n);
    // What it asked of which addresses, as the transaction lines say it: a message names the request alone.
    const auto range = [](std::uint16_t start, std::uint16_t quantity) {
        return " " + std::to_string(start) + "+" + std::to_string(quantity);
    };
    if (const auto* r = std::get_if<ReadRequest>(&p.body)) s += range(r->starting_address, r->quantity);
    if (const auto* w = std::get_if<WriteSingle>(&p.body)) {
        s += " " + std::to_string(w->address) + " = ";
        s += p.function_code() == 5 ? (w->value == 0xFF00 ? "ON"
                                       : w->value == 0    ? "OFF"
                                                          : std::to_string(w->value))
                                    : std::to_string(w->value);
    }
    if (const auto* c = std::get_if<WriteMultipleCoilsRequest>(&p.body))
        s += range(c->starting_address, c->quantity);
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&p.body))
        s += range(w->starting_address, w->quantity);
    if (const auto* m = std::get_if<MaskWriteRegister>(&p.body))
        s += " " + std::to_string(m->reference_address);
    if (const auto* rw = std::get_if<ReadWriteMultipleRequest>(&p.body))
        s += ", read" + range(rw->read_starting_address, rw->quantity_to_read) + ", write" +
             range(rw->write_starting_address, rw->quantity_to_write);
    if (const auto* d = std::get_if<Diagnostics>(&p.body))
        s += " sub-function " + std::to_string(d->sub_function);
    if (const auto* f = std::get_if<ReadFifoQueueRequest>(&p.body))
        s += " " + std::to_string(f->fifo_pointer_address);
    if (const auto* id = std::get_if<ReadDeviceIdRequest>(&p.body))
        s += ", read device identification code " + std::to_string(id->read_device_id_code) + " object " +
             std::to_string(id->object_id);
    return s;
}

std::string describe_request(const FrameRecord& r) {
    if (r.pdu) return describe_request(*r.pdu);
    const auto pdu = r.frame.pdu();
    if (pdu.empty()) return "request";
    // Its function code byte still says what it asked for.
    std::string s = "FC" + std::to_string(pdu[0]);
    if (auto n = function_name(pdu[0])) s += " " + std::string(*n);
    return s + " (malformed request)";
}

// pair.no_response's message wherever a request is given up: "FC3 Read Holding Registers 0+2 to
// 10.0.0.2:502 unit 1 got no response " and `when`, and how long after the request `ended` came (nothing
// for a capture without a clock).
std::string no_response_message(const FrameRecord& request, const std::string& when, Timestamp ended = {}) {
    std::string text = describe_request(request) + " to " + request.device.str() + " got no response " + when;
    if (request.time.count() && ended.count() && ended >= request.time)
        text += ", " + milliseconds_text(ended - request.time) + " after it";
    return text;
}

// A timed-out request is kept by its transaction id over Modbus/TCP, and by its unit on a serial line:
// there the master polls the next unit while a slow one's reply is still on its way.
std::uint16_t late_id(const Frame& f) {
    return f.framing == Framing::Tcp ? f.transaction_id() : f.unit_id();
}
}  // namespace

namespace {
void count_request(const FrameRecord& r, DeviceStats& stats) {
    ++stats.requests;
    // By the function code byte: a request whose PDU cannot be decoded still asked for that function.
    if (const auto pdu = r.frame.pdu(); !pdu.empty()) ++stats.functions[pdu[0]];
}
}  // namespace

// A damaged request to a unit its link had not shown when it came (line noise of a few bytes makes such
// frames, and made "unit 60" a device with a request): whose it is, once its wait ends. The unit's, if the
// link has shown the unit by then (it answered, or the master asked it again: the capture damaged what the
// device got whole, or the line damaged a request to it), counted as its request then; else no device's,
// counted on the line. Decided once; false for no device.
bool Analyzer::settle_unit(Pending& p) {
    if (!p.unseen_unit_link) return !p.no_device;
    const Flow& flow = *p.unseen_unit_link;
    p.unseen_unit_link = nullptr;
    const Flow::Unit* unit = flow.unit(p.request.frame.unit_id());
    if (!unit) {
        p.no_device = true;
        ++summary_.damaged_to_unseen_units;
        return false;
    }
    p.request.device = unit->device;
    p.stats = unit->stats;
    count_request(p.request, *p.stats);
    ++p.stats->checksum_errors;
    std::vector<FindingCode> own;  // reported when it came, with no device to count them for
    add_frame_findings(p.request, own);
    for (const auto code : own)
        ++p.stats->findings[std::string(to_string(code))];
    return true;
}

// The damaged request of unseen_expired, given up now as it would have been at its timeout had its unit been
// known: settled (its unit's if the link has shown the unit since, else no device's), and remembered, so that
// its unit's reply after it is late.
void Analyzer::release_unseen(Flow& flow) {
    if (!flow.unseen_expired) return;
    Pending p = std::move(*flow.unseen_expired);
    flow.unseen_expired.reset();
    std::string what = describe_request(p.request);
    remember_timed_out({flow.id, late_id(p.request.frame)}, p, options_.serial_timeout, what);
    give_up(p, true,
            {FindingCode::PairNoResponse,
             no_response_message(p.request, "within " + milliseconds_text(options_.serial_timeout))});
}

void Analyzer::on_request(Flow& flow, FrameRecord& r, DeviceStats* stats) {
    if (!flow.request_seen) flow.first_request_id = pairing_id(r.frame);
    flow.request_seen = true;
    if (stats) count_request(r, *stats);
    if (options_.semantics && r.pdu && stats)
        if (const Profile* profile = options_.semantics->profile_for(flow.server, r.frame.unit_id())) {
            for (auto& rule : options_.semantics->check_line(*profile, r.device.str(), r.frame))
                report(rule.code, r, rule.message);
            for (auto& rule : options_.semantics->check_request(*profile, r.device.str(), *r.pdu)) {
                r.reported_findings.push_back(rule.code);
                report(rule.code, r, rule.message);
            }
        }
    // A damaged request to a unit the link had not shown, whose timeout ran out before this frame: given up
    // first, as it would have been at its timeout, so that this request supersedes it below as it does any
    // request that timed out. (Given up after, it stayed the unit's late one: through a gateway on TCP the
    // reply to this request, 2 s later, was paired with it as late, and this one was left unanswered.)
    if (r.frame.framing != Framing::Tcp) release_unseen(flow);
    // A reply with this id (on a serial line, from this unit) now answers this request. (Before the request
    // waiting is given up below: a reply that fits only that one is its late one.)
    if (!timed_out_.empty()) timed_out_.erase({flow.id, late_id(r.frame)});
    // The master moved on (a broadcast too: a master sends nothing while it waits for a reply): the requests
    // waiting were never answered. So through a gateway on TCP (RTU over TCP): without transaction ids a
    // client waits for each reply as a master on a line does, and its next request means it gave up on the
    // last, its timeout often shorter than ours (kept waiting, one lost reply left every later reply paired
    // with the request before its own). Only a request that began in the segment holding the last one
    // waiting shows a client pipelining (check's framing.back_to_back writes two at once): the gateway
    // queues them and answers in turn, so each waits to its own timeout (below, as a reused transaction id
    // waits).
    if (r.frame.framing != Framing::Tcp)
        if (auto it = pending_.find({flow.id, 0});
            it != pending_.end() && !(flow.rtu_over_tcp && sent_with(flow, it->second.request, r)))
            while (Pending* oldest = oldest_waiting({flow.id, 0}, [](const Pending&) { return true; })) {
                Pending old = std::move(*take_pending({flow.id, 0}, oldest->serial));
                --flow.pending;
                // Its reply may still come, from a slow unit, while the master waits on another: late then.
                // To the same unit again, a reply answers the new request, unless only the old one's fits it
                // (on_response).
                remember_timed_out({flow.id, late_id(old.request.frame)}, old, r.time - old.request.time,
                                   describe_request(old.request), r.index, true);
                give_up(old, true,
                        {FindingCode::PairNoResponse, "request to " + old.request.device.str() +
                                                          " got no response before the next request"});
            }
    if (r.frame.framing != Framing::Tcp) flow.last_broadcast = 0;
    if (r.frame.framing != Framing::Tcp && r.frame.unit_id() == 0) {
        flow.last_broadcast = r.index;
        flow.last_broadcast_time = r.time;
        const auto pdu = r.frame.pdu();
        flow.last_broadcast_pdu.assign(pdu.begin(), pdu.end());
        ++summary_.transactions;  // a broadcast: executed by every slave, answered by none
        if (only_reads(r.frame.pdu())) {
            r.reported_findings.push_back(FindingCode::PairBroadcastRead);
            report(FindingCode::PairBroadcastRead, r,
                   describe_request(r) +
                       " sent to unit 0: broadcast requests are writes, and nobody answers this one");
        }
        auto told = follow_broadcast(flow, r);
        if (!sink_wants_transactions_) {
            if (told) report(FindingCode::ProfileLineSettingsChanged, r, std::move(*told), {r.index});
            return;
        }
        TransactionRecord t(std::move(r));
        t.broadcast = true;
        add_frame_findings(t.request, t.findings);
        if (told) t.findings.push_back(FindingCode::ProfileLineSettingsChanged);  // as a unicast's has it
        sink_.transaction(t);
        if (told)
            report(FindingCode::ProfileLineSettingsChanged, t.request, std::move(*told), {t.request.index});
        return;
    }
    const PendingKey key{flow.id, pairing_id(r.frame)};
    if (auto it = pending_.find(key); it != pending_.end()) {
        // Both still wait: a server answers a connection's requests in turn. RTU carries no transaction id
        // (every request has key 0), so on RTU over TCP this is how requests queue, no client's doing; its
        // queue is bounded by the link's (max_pending_per_flow, below).
        if (!flow.rtu_over_tcp) transaction_id_reused(flow, it->second, r);
        reused_[key].push_back(std::move(it->second));
        pending_.erase(it);
    }
    if (flow.pending >= options_.max_pending_per_flow) {
        report(FindingCode::PairPendingOverflow, r,
               std::to_string(flow.pending) + " requests unanswered on this link; the oldest is given up");
        // The link's oldest request still pending: the first due in each queue (deadline order, which is the
        // order requests came but for one released from behind a hole), the smallest serial of those.
        std::optional<Expiry> oldest;
        for (const auto& queue : expiries_)
            for (const Expiry& e : queue) {
                if (e.key.flow != flow.id || !find_pending(e.key, e.serial)) continue;
                if (!oldest || e.serial < oldest->serial) oldest = e;
                break;
            }
        for (const HeldExpiry& held : held_expiries_)
            if (const Expiry& e = held.expiry; e.key.flow == flow.id && find_pending(e.key, e.serial) &&
                                               (!oldest || e.serial < oldest->serial))
                oldest = e;
        if (auto taken = oldest ? take_pending(oldest->key, oldest->serial) : std::nullopt) {
            Pending given_up = std::move(*taken);
            --flow.pending;
            // A timeout like any other, reported as one (the overflow warning is about the new request), and
            // like any other its reply may still come: late then, not unsolicited.
            remember_timed_out({flow.id, late_id(given_up.request.frame)}, given_up,
                               r.time - given_up.request.time, describe_request(given_up.request), r.index);
            give_up(given_up, true,
                    {FindingCode::PairNoResponse,
                     no_response_message(given_up.request,
                                         "before " + std::to_string(options_.max_pending_per_flow) +
                                             " later requests on its link left no room to wait for it",
                                         r.time)});
        }
    }
    const std::uint64_t serial = ++next_serial_;
    ++expiry_entries_;
    // An untimed capture (raw dump) has no clock: its requests expire only when the master moves on.
    if (!r.time.count()) {
        expiries_[untimed].push_back({Timestamp::max(), key, serial});
    } else {
        // In deadline order: a request released from behind a hole in its stream comes with the time its
        // packet was captured, earlier than requests queued meanwhile, and expire() reads only the front
        // (behind them, it outlived its timeout: a reply 3.3 s after it with a 3 s timeout was in time).
        auto& queue = expiries_[r.frame.framing == Framing::Tcp ? tcp_timeout : serial_timeout];
        const Expiry e{
            r.time + (r.frame.framing == Framing::Tcp ? options_.timeout : options_.serial_timeout), key,
            serial};
        if (queue.empty() || queue.back().deadline <= e.deadline)
            queue.push_back(e);
        else
            queue.insert(std::upper_bound(queue.begin(), queue.end(), e.deadline,
                                          [](Timestamp d, const Expiry& x) { return d < x.deadline; }),
                         e);
    }
    // made from the record (any earlier one with the key was completed above): a default-made record would
    // zero a frame's whole buffer first, a third of this function's time
    const auto made = pending_.try_emplace(key, std::move(r), serial, stats).first;
    if (!stats) made->second.unseen_unit_link = &flow;
    ++flow.pending;
}

bool Analyzer::sent_with(const Flow& flow, const FrameRecord& waiting, const FrameRecord& later) const {
    // The later request's first byte, not its last: two requests written at once may straddle segments.
    const auto* arrived = flow.rtu_arrival(0, later.frame.offset);
    return (arrived ? arrived->packet : later.packet) == waiting.packet;
}

void Analyzer::transaction_id_reused(Flow& flow, const Pending& newest, const FrameRecord& r) {
    const PendingKey key{flow.id, pairing_id(r.frame)};
    report(FindingCode::PairTransactionIdDuplicate, r,
           "transaction id " + std::to_string(key.tid) + " reused while frame " +
               std::to_string(newest.request.index) +
               " is still unanswered; replies with it are paired with the requests in turn",
           {newest.request.index, r.index});
    // Both still wait: a client that numbers every request alike (some do) gets every reply. Giving the
    // older one up here blamed the device with a timeout, its reply with an echo mismatch and the last
    // reply as unsolicited. Only so many, though.
    auto& older = reused_[key];
    if (older.size() < max_reused_per_id) return;
    Pending old = std::move(older.front());
    older.pop_front();
    --flow.pending;
    give_up(old, true,
            {FindingCode::PairNoResponse,
             no_response_message(old.request,
                                 "before its transaction id was used " +
                                     std::to_string(max_reused_per_id + 1) + " more times",
                                 r.time)});
}

namespace {

// Whether `response`'s PDU fits `request`'s, whatever unit either names: its function (or the exception to
// it), and for a pair that decodes, the echo and the data size the request asks for.
bool fits_pdu(const FrameRecord& request, const FrameRecord& response) {
    const auto q = request.frame.pdu();
    const auto a = response.frame.pdu();
    if (q.empty() || a.empty() || (a[0] & 0x7F) != q[0]) return false;
    if (!request.pdu || !response.pdu || response.pdu->is_exception()) return true;
    const auto misfit = reply_misfit(*request.pdu, *response.pdu);
    return !misfit ||
           misfit->kind == ReplyMisfit::Kind::Padding;  // padding is the reply's fault, not another's
}

// Could `response` be the reply to `request`, as far as its bytes tell: its unit, and its PDU (fits_pdu).
bool could_answer(const FrameRecord& request, const FrameRecord& response) {
    return request.frame.unit_id() == response.frame.unit_id() && fits_pdu(request, response);
}

}  // namespace

void Analyzer::on_response(Flow& flow, FrameRecord& r) {
    if (!held_expiries_.empty()) time_out_held_before(flow, r);
    if (flow.unseen_expired && r.frame.checksum_ok) {
        // A reply shows whose the damaged request was, if it is its unit's (a late one then), and that the
        // master asked another unit in bytes the capture lost, if it is another's.
        if (r.frame.unit_id() != flow.unseen_expired->request.frame.unit_id()) {
            flow.mark_damaged_request(flow.unseen_expired->request);
        }
        release_unseen(flow);
    }
    // (A damaged frame's unit byte may be the damage: its checksum finding says what it is.)
    if (r.frame.framing != Framing::Tcp && r.frame.unit_id() == 0 && r.frame.checksum_ok) {
        // Unit 0 is no slave's address (SL §2.2): the frame is no device's (decode_and_judge). In the reply
        // slot of a request to a unit, it is that unit's reply slot a frame with a wrong address took: held
        // against the unit asked, and the request keeps waiting, as for a reply from another unit. Else it
        // answers a broadcast, which no slave may.
        // (Through a gateway on TCP, the oldest request waiting: replies come in turn.)
        if (Pending* oldest = oldest_waiting({flow.id, 0}, [](const Pending&) { return true; })) {
            Pending& asked = *oldest;
            asked.other_unit_reply = r.index;
            asked.other_unit = 0;
            FrameRecord about(r);
            about.device = asked.request.device;
            report(
                FindingCode::PairUnitMismatch, about,
                "request to unit " + std::to_string(asked.request.frame.unit_id()) + " (frame " +
                    std::to_string(asked.request.index) +
                    ") waits, and the response in its place carries unit 0, the broadcast address, which no "
                    "slave answers with: no answer from unit " +
                    std::to_string(asked.request.frame.unit_id()) + " (a master discards it), nor its values",
                {asked.request.index, r.index});
            return;
        }
        report(FindingCode::PairBroadcastResponse, r,
               flow.last_broadcast ? "a response carries unit 0: no slave may answer a broadcast (frame " +
                                         std::to_string(flow.last_broadcast) + ")"
                                   : "a response carries unit 0: no slave may answer a broadcast");
        return;
    }
    const PendingKey key{flow.id, pairing_id(r.frame)};
    auto it = pending_.find(key);
    // (Through a gateway on TCP only when it is the one request waiting: the reply may answer another.)
    if (it != pending_.end() && it->second.unseen_unit_link && r.frame.checksum_ok &&
        r.frame.unit_id() != it->second.request.frame.unit_id() &&
        (!flow.rtu_over_tcp || flow.pending == 1)) {
        // What waits is a damaged request to a unit the link had not shown, and another unit answers: the
        // master asked that one (in bytes the capture lost), not the unit the damage names. Settled now, and
        // no request waits.
        Pending waiting = std::move(it->second);
        pending_.erase(it);
        --flow.pending;
        flow.mark_damaged_request(waiting.request);  // a reply right after it: said so, and no duplicate
        give_up(waiting, false,
                {FindingCode::PairNoResponse,
                 no_response_message(waiting.request,
                                     "before unit " + std::to_string(r.frame.unit_id()) + " replied")});
        it = pending_.end();
    }
    // Without transaction ids, the request a reply answers is found by its unit: on a serial line the one
    // waiting, through a gateway on TCP the oldest of the unit's that wait (the gateway answers in turn).
    const auto any = [](const Pending&) { return true; };
    const auto same_unit = [&](const Pending& p) { return p.request.frame.unit_id() == r.frame.unit_id(); };
    const auto fits = [&](const Pending& p) { return could_answer(p.request, r); };
    // On a serial line the request waiting may be to another unit, the master having moved on from this
    // one's: a reply that unit's late one names (with a checksum that holds, so its unit byte can be
    // trusted) is that one's, not the waiting request's with a unit mismatch. (So through a gateway when no
    // request to the unit waits.)
    const bool other_unit_waits = it != pending_.end() && r.frame.framing != Framing::Tcp &&
                                  r.frame.checksum_ok && !oldest_waiting(key, same_unit);
    // A half-duplex line carries one exchange at a time: once the master asked another request and a reply
    // answered it, a request given up before it is over, and a reply that comes while yet another unit's
    // request waits is that request's slot, answered with a wrong unit byte, not the old one's late reply
    // (an exception from unit 17, 2 s after it was asked and 20 ms after the master polled unit 18 a second
    // time, 18 having answered the first: it was unit 17's, 2020 ms late, in its latency and exceptions).
    // With nothing waiting the old request keeps its late reply: a slow slave answers when it is done,
    // whatever the master did meanwhile. Only on a line captured as one: through a gateway on TCP or UDP
    // the requests of several units may wait at once (queued, or on the gateway's several serial ports),
    // and their replies come as they do.
    if (flow.carrier == Carrier::Serial && other_unit_waits && flow.late_closed_before && !timed_out_.empty())
        if (const auto t = timed_out_.find({flow.id, late_id(r.frame)});
            t != timed_out_.end() && t->second.pending.serial < flow.late_closed_before)
            timed_out_.erase(t);
    // Over Modbus/TCP a request timed out while later ones that reused its id waited (a timed-out request's
    // entry is dropped when its id is sent again, so one that is here timed out after they were sent): a
    // reply that fits it is its late one, the oldest's, as a server answers in turn. Before, the reply went
    // to a waiting request, and every reply after it shifted by one.
    const auto late_one_fits = [&] {
        const auto t = timed_out_.find({flow.id, late_id(r.frame)});
        return t != timed_out_.end() && could_answer(t->second.pending.request, r);
    };
    // A timed-out request whose checksum failed was discarded by the gateway or the device, and a waiting
    // request with a good checksum that the reply fits (the client's copy of it, sent again) is the one
    // answered, as among the requests waiting (below). Taken for the damaged one's late reply, it left the
    // good copy a timeout against the device, and the device "answered a damaged request".
    const auto good_copy_of_discarded_waits = [&] {
        const auto t = timed_out_.find({flow.id, late_id(r.frame)});
        return t != timed_out_.end() && !t->second.pending.request.frame.checksum_ok &&
               oldest_waiting(key, [&](const Pending& p) { return p.request.frame.checksum_ok && fits(p); });
    };
    // So through a gateway on TCP, where a request to the unit that timed out was queued before those
    // waiting (pipelined). Not one whose wait the client's next request ended: the client gave up on it,
    // and a reply that fits the request now waiting too is that one's (as on a line, below); taken as the
    // old one's late reply, one lost reply left every later one paired with the request before its own.
    const auto late_one_queued = [&] {
        const auto t = timed_out_.find({flow.id, late_id(r.frame)});
        return t != timed_out_.end() && !t->second.given_up_by_client;
    };
    const bool late_behind_reuse = it != pending_.end() && !timed_out_.empty() &&
                                   (r.frame.framing == Framing::Tcp ||
                                    (flow.rtu_over_tcp && r.frame.checksum_ok && late_one_queued())) &&
                                   late_one_fits() && !good_copy_of_discarded_waits();
    // On a serial line the master asked the same unit again (other registers) before the reply to the first
    // came: a reply whose size or echo fits only the first request is that one's, late, and the new request
    // keeps waiting for its own. Before, it was paired with the new one (a size mismatch) and the new one's
    // reply that followed was unsolicited: two errors against a device that was only slow.
    const bool late_for_same_unit = it != pending_.end() && r.frame.framing != Framing::Tcp &&
                                    r.frame.checksum_ok && !other_unit_waits && !timed_out_.empty() &&
                                    late_one_fits() && !oldest_waiting(key, fits);
    // Another unit's request waits, and the reply names a unit whose earlier request was given up: the unit
    // byte (its checksum holding) says it is that one's late reply, unless its PDU fits the request waiting
    // and not that one (3 registers asked of unit 17, 20 ms before, and 1 of unit 18, 1.5 s before: a reply
    // from "unit 18" with 3 registers is unit 17's slot answered with a wrong unit byte, as with no earlier
    // request of unit 18, not unit 18's reply 1.5 s late with a size mismatch, its latency in unit 18's).
    // A PDU that fits both, or neither, leaves the unit byte to decide: late.
    const Pending* const waiting_other = other_unit_waits ? oldest_waiting(key, any) : nullptr;
    const bool fits_only_waiting_other =
        waiting_other && !timed_out_.empty() && fits_pdu(waiting_other->request, r) && !late_one_fits();
    if ((it == pending_.end() || (other_unit_waits && !fits_only_waiting_other) || late_behind_reuse ||
         late_for_same_unit) &&
        !timed_out_.empty()) {
        // The reply to a request already reported unanswered: late, not unsolicited, nor the last reply
        // again (a poll's late reply on a serial line often carries the same bytes as the one before).
        // Unless a broadcast came after it, and the reply does not fit it: that answers the broadcast
        // (below), an FC16 echo was no late reply to an FC3.
        const bool answers_broadcast = it == pending_.end() && flow.last_broadcast &&
                                       r.frame.framing != Framing::Tcp && !late_one_fits();
        if (auto late = answers_broadcast ? std::nullopt : late_for({flow.id, late_id(r.frame)})) {
            flow.keep_last_response(r);
            flow.captured_request_answered = true;
            complete(late->pending, &r, false, &*late);
            return;
        }
    }
    // A reply from another unit than the one asked, its checksum holding (so its unit byte is what was sent),
    // and no late request of that unit it is taken for (above): no answer to the waiting request, as a slave
    // answers only frames with its own address (SL §2.2; MK-MS-02, 000:285) and a master discards it. The
    // request keeps waiting for its own unit's reply; what the other unit sent is held against that unit, and
    // its values are neither named from the asked unit's map nor remembered as its (the decimal places
    // another unit reported scaled every later value of the asked one).
    if (other_unit_waits) {
        Pending& waiting = *oldest_waiting(key, any);
        waiting.other_unit_reply = r.index;
        waiting.other_unit = r.frame.unit_id();
        // The named unit's earlier request, whose PDU the reply does not fit: said, as the reason it is no
        // late reply to that one.
        std::string not_late;
        if (fits_only_waiting_other)
            if (const auto t = timed_out_.find({flow.id, late_id(r.frame)}); t != timed_out_.end())
                not_late = "; it fits this request, not unit " + std::to_string(r.frame.unit_id()) +
                           "'s frame " + std::to_string(t->second.pending.request.index) + " (" +
                           t->second.what + ") given up before: no late reply to that";
        report(FindingCode::PairUnitMismatch, r,
               "request to unit " + std::to_string(waiting.request.frame.unit_id()) + " (frame " +
                   std::to_string(waiting.request.index) + ") waits, response from unit " +
                   std::to_string(r.frame.unit_id()) + ": no answer from unit " +
                   std::to_string(waiting.request.frame.unit_id()) +
                   " (a master discards it), nor its values" + not_late,
               {waiting.request.index, r.index});
        return;
    }
    // Its request was cut by a gap in the request stream, and its header names this reply's transaction: not
    // unsolicited, nor (a client that sends the same id and request again) the last reply again.
    if (it == pending_.end() && r.frame.framing == Framing::Tcp && !cut_requests_.empty())
        if (auto cut = cut_requests_.find(key); cut != cut_requests_.end() && !r.frame.pdu().empty() &&
                                                cut->second.names(r.frame.unit_id(), r.frame.pdu()[0])) {
            report(FindingCode::PairRequestNotCaptured, r,
                   "the reply to transaction id " + std::to_string(key.tid) +
                       ", whose request the capture holds only in part (" +
                       std::to_string(cut->second.captured) + " of its " +
                       std::to_string(cut->second.length) + " bytes" +
                       (cut->second.snapshot_length ? ", cut to the capture's snapshot length" : "") + ")");
            cut_requests_.erase(cut);
            return;
        }
    // On a serial line, bytes that formed no frame since the last reply (a request cut short, noise over
    // its first bytes, an ASCII request whose LF came too late): a reply nobody waits for may answer a
    // request among them, and is neither a request answered twice nor a reply nobody asked for.
    if (it == pending_.end() && r.frame.framing != Framing::Tcp && r.frame.checksum_ok &&
        flow.unparsed_length != 0 && flow.unparsed_after_frame >= flow.last_response_index) {
        report(FindingCode::PairRequestNotCaptured, r,
               "no request to unit " + std::to_string(r.frame.unit_id()) + " waits, but the " +
                   std::to_string(flow.unparsed_length) + " bytes at offset " +
                   std::to_string(flow.unparsed_offset) +
                   " before it formed no frame: its request may be among them");
        flow.unparsed_length = 0;
        flow.keep_last_response(r);
        return;
    }
    // (Not after a damaged request since: that is the one it answers, the same question again.)
    // (Nor after a broadcast since: slaves answering the same broadcast twice answered a broadcast twice.)
    if (it == pending_.end() && r.frame.checksum_ok && r.frame.length == flow.last_response_length &&
        flow.damaged_request < flow.last_response_index && flow.last_broadcast < flow.last_response_index &&
        std::memcmp(r.frame.bytes.data(), flow.last_response.data(), r.frame.length) == 0) {
        // No request waits for it. (Over Modbus/TCP a request that does was found above by its transaction
        // id; on a serial line with a request waiting, the same bytes may be that request's own reply to the
        // same question, and are taken as such.)
        report(FindingCode::PairDuplicateResponse, r,
               "the response of frame " + std::to_string(flow.last_response_index) +
                   " again: one request answered twice",
               {flow.last_response_index, r.index});
        return;
    }
    if (it == pending_.end()) {
        // A connection whose opening the capture did not show (and UDP, and RTU over TCP alike), before the
        // capture shows any request on it: a reply answers a request sent before the capture began (those
        // in flight then, the bytes of one it began inside). An "unsolicited" error held the capture's start
        // against the device. (Once a request is captured, a reply with another id is still the
        // transaction-id mismatch it may be: a device that always answers with a wrong id must show.)
        const bool opening_unseen =
            flow.carrier == Carrier::Udp ||
            (flow.carrier == Carrier::Tcp && flow.reassembler[0] && !flow.reassembler[0]->saw_syn());
        const std::string which = r.frame.framing == Framing::Tcp
                                      ? "the reply to transaction id " + std::to_string(key.tid)
                                      : "a reply from unit " + std::to_string(r.frame.unit_id());
        if (opening_unseen && !flow.request_seen) {
            report(FindingCode::PairRequestNotCaptured, r,
                   which +
                       " comes before any request of this link in the capture, which joined it after it "
                       "opened: its request went before the capture began");
            flow.keep_last_response(r);
            return;
        }
        // Whether the reply fits a request of the link waiting (its unit, function and size).
        const auto fits_a_waiting_request = [&] {
            std::size_t looked_at = 0;
            for (const auto& entry : pending_) {
                if (entry.first.flow != flow.id) continue;
                if (oldest_waiting(entry.first, fits)) return true;
                const auto queued = reused_.find(entry.first);
                looked_at += 1 + (queued == reused_.end() ? 0 : queued->second.size());
                if (looked_at >= flow.pending) break;
            }
            return false;
        };
        // Requests the capture holds wait, but none with this id, and no reply has answered one yet: a
        // reply whose id comes before the first of them answers a request pipelined ahead of it, before
        // the capture began, and the waiting requests' own replies may follow. Paired with one of them
        // (the only one: a transaction-id mismatch), it made three errors and an unsolicited fourth of
        // that request's own reply, and showed one unit's values as another's. Unless it fits a waiting
        // request: then it is that request's reply with a wrong id, as from a device that answers every
        // request with id 0 (a firmware bug some have); excused, the first such reply hid the mismatch,
        // every later one was unsolicited and every request a timeout.
        // So is one whose id is not just before the first captured (a client's ids may start over) when it
        // fits none of the waiting requests, and one whose id follows the last excused (the replies to the
        // requests in flight come in turn): paired with the only request waiting, reply 31998 of 198 bytes
        // was request 0's (a transaction-id and a size mismatch), and every reply after it went astray.
        if (opening_unseen && r.frame.framing == Framing::Tcp &&
            flow.may_answer_uncaptured_request(key.tid, options_.max_pending_per_flow)) {
            const bool just_before = flow.may_predate_first_request(key.tid, options_.max_pending_per_flow);
            const bool in_turn = !just_before && flow.follows_excused(key.tid);
            if (in_turn || !fits_a_waiting_request()) {
                const std::string previous =
                    in_turn ? std::to_string(flow.excused_before_capture.back()) : "";
                flow.excused_before_capture.push_back(key.tid);
                report(
                    FindingCode::PairRequestNotCaptured, r,
                    which + " comes before any reply to a request the capture holds, " +
                        (just_before ? "its id before that of the link's first one captured (" +
                                           std::to_string(flow.first_request_id) + ")"
                         : in_turn ? "its id next after that of " + previous + " (replies come in turn)"
                                   : "and fits none of the requests waiting (unit, function, size)") +
                        ", on a connection the capture joined after it opened: its request went before the "
                        "capture began");
                flow.keep_last_response(r);
                return;
            }
        }
        // The server acknowledged client bytes the capture does not hold (a tap's drop, given up as a gap
        // only at the client's next segment): the request this reply answers may be among them, once per
        // hole. An "unsolicited" error held the tap's loss against the device, where a request cut by the
        // snapshot length was a warning.
        if (flow.carrier == Carrier::Tcp && flow.reassembler[0])
            if (const auto unseen = flow.reassembler[0]->acknowledged_unseen();
                unseen && flow.excused_hole != flow.reassembler[0]->delivered() + 1) {
                flow.excused_hole = flow.reassembler[0]->delivered() + 1;
                report(FindingCode::PairRequestNotCaptured, r,
                       "no request waits for " + which + ", but the server had acknowledged " +
                           std::to_string(unseen) +
                           " bytes of the client's stream that the capture does not hold: its request may "
                           "be among them");
                flow.keep_last_response(r);
                return;
            }
        // One request outstanding on this link and the reply carries another id: a transaction-id mismatch,
        // not an unsolicited reply. Unless that request came after bytes of the request stream were lost: a
        // request among them (pipelined before it) is the one the reply answers, and the outstanding
        // request's own reply may follow.
        std::optional<PendingKey> only;
        bool after_gap = false;
        if (flow.pending == 1)
            for (const auto& [k, v] : pending_)
                if (k.flow == flow.id) {
                    only = k;
                    after_gap = flow.first_request_after_gap && v.serial >= flow.first_request_after_gap;
                }
        if (only && !after_gap) {
            it = pending_.find(*only);
            r.reported_findings.push_back(FindingCode::PairTransactionIdMismatch);
            report(FindingCode::PairTransactionIdMismatch, r,
                   "response transaction id " + std::to_string(key.tid) + " answers the request with id " +
                       std::to_string(only->tid),
                   {it->second.request.index, r.index});
        } else {
            // Damaged bytes on a serial line that no request waits for, naming no unit seen there: their
            // checksum finding is all that can be said (no unit sent them that the bytes can show).
            if (r.frame.framing != Framing::Tcp && !r.frame.checksum_ok && r.device.empty()) return;
            // Right after a broadcast (within the serial timeout), a unit answered it: what no slave may do
            // (SL §2.1), said as such rather than as a reply nobody asked for.
            if (r.frame.framing != Framing::Tcp && r.frame.checksum_ok && flow.last_broadcast &&
                (!r.time.count() || (r.time >= flow.last_broadcast_time &&
                                     r.time - flow.last_broadcast_time <= options_.serial_timeout))) {
                report(FindingCode::PairBroadcastResponse, r,
                       "unit " + std::to_string(r.frame.unit_id()) + " answered the broadcast of frame " +
                           std::to_string(flow.last_broadcast) + ": no slave may answer a broadcast",
                       {flow.last_broadcast, r.index});
                flow.keep_last_response(r);
                return;
            }
            // A serial line has no transaction ids: name the unit whose reply nobody asked for.
            report(
                FindingCode::PairUnsolicitedResponse, r,
                (r.frame.framing == Framing::Tcp ? "no outstanding request with transaction id " +
                                                       std::to_string(key.tid) + " on this link"
                                                 : "no request to unit " + std::to_string(r.frame.unit_id()) +
                                                       " waits for a reply on this link") +
                    (after_gap ? " (bytes of the request stream were not captured: its request may be "
                                 "among them)"
                               : "") +
                    (flow.damaged_request && r.time.count() && r.time >= flow.damaged_request_time &&
                             r.time - flow.damaged_request_time <= options_.serial_timeout
                         ? " (after frame " + std::to_string(flow.damaged_request) +
                               ", a request whose checksum failed: the device answered a frame "
                               "it should have discarded, or the capture damaged the request)"
                         : ""));
            return;
        }
    }
    --flow.pending;
    flow.captured_request_answered = true;
    // The transaction id reused while older requests with it still wait (through a gateway on TCP, several
    // requests queued): the oldest the reply fits is the one it answers (a server answers in turn), else
    // the oldest (without ids, of the reply's unit). A request whose checksum failed, which the gateway or
    // the device discards, only when no other fits: a client's good copy of it queued after it is the one
    // answered (it took the reply, and the good copy was a timeout).
    const PendingKey waiting = it->first;
    Pending* answered =
        oldest_waiting(waiting, [&](const Pending& p) { return p.request.frame.checksum_ok && fits(p); });
    if (!answered) answered = oldest_waiting(waiting, fits);
    if (!answered && r.frame.framing != Framing::Tcp) answered = oldest_waiting(waiting, same_unit);
    if (!answered) answered = oldest_waiting(waiting, any);
    // A request after the lost bytes answered: the replies to those before it have had their turn.
    if (flow.first_request_after_gap && answered->serial >= flow.first_request_after_gap)
        flow.first_request_after_gap = 0;
    flow.keep_last_response(r);
    // An exchange completed on a line: the requests given up before this one take no late reply in another
    // unit's slot now.
    if (flow.carrier == Carrier::Serial) flow.late_closed_before = answered->serial;
    complete(*answered, &r, false);  // reports and sinks never touch the pending table
    (void)take_pending(waiting, answered->serial);
}

template <typename Fits>
Analyzer::Pending* Analyzer::oldest_waiting(const PendingKey& key, Fits fits) {
    if (!reused_.empty())
        if (auto older = reused_.find(key); older != reused_.end())
            for (Pending& p : older->second)
                if (fits(p)) return &p;
    if (auto it = pending_.find(key); it != pending_.end() && fits(it->second)) return &it->second;
    return nullptr;
}

Analyzer::Pending* Analyzer::find_pending(const PendingKey& key, std::uint64_t serial) {
    if (auto it = pending_.find(key); it != pending_.end() && it->second.serial == serial) return &it->second;
    if (reused_.empty()) return nullptr;
    auto older = reused_.find(key);
    if (older == reused_.end()) return nullptr;
    for (Pending& p : older->second)
        if (p.serial == serial) return &p;
    return nullptr;
}

std::optional<Analyzer::Pending> Analyzer::take_pending(PendingKey key, std::uint64_t serial) {
    std::optional<Pending> out;
    auto older = reused_.empty() ? reused_.end() : reused_.find(key);
    if (auto it = pending_.find(key); it != pending_.end() && it->second.serial == serial) {
        out.emplace(std::move(it->second));
        pending_.erase(it);
        if (older != reused_.end()) {  // the one before it with the id is now the newest
            pending_.try_emplace(key, std::move(older->second.back()));
            older->second.pop_back();
        }
    } else if (older != reused_.end()) {
        auto p = std::find_if(older->second.begin(), older->second.end(),
                              [&](const Pending& q) { return q.serial == serial; });
        if (p == older->second.end()) return out;
        out.emplace(std::move(*p));
        older->second.erase(p);
    } else {
        return out;
    }
    if (older != reused_.end() && older->second.empty()) reused_.erase(older);
    return out;
}

void Analyzer::reply_cut(Flow& f, const CutAdu& cut, Timestamp t) {
    const PendingKey key{f.id, cut.tid};
    // The oldest request waiting with the id whose unit and function the reply's header names.
    const Pending* answered = oldest_waiting(key, [&](const Pending& p) {
        const auto pdu = p.request.frame.pdu();
        return !pdu.empty() && cut.names(p.request.frame.unit_id(), pdu[0]);
    });
    if (!answered) {
        // Its request cut too: one transaction, both halves partly in the capture. Else a reply to nothing
        // waiting, whose bytes are reported unparsed as they are.
        const auto request = cut_requests_.find(key);
        if (request == cut_requests_.end() ||
            (request->second.unit && cut.unit && *request->second.unit != *cut.unit) ||
            (request->second.function && cut.function && *request->second.function != *cut.function))
            return;
        const auto part = [](const CutAdu& c) {
            return std::to_string(c.captured) + " of its " + std::to_string(c.length) + " bytes" +
                   (c.snapshot_length ? ", cut to the snapshot length" : "");
        };
        const auto unit = cut.unit ? cut.unit : request->second.unit;
        report(FindingCode::PairRequestNotCaptured, about_stream(f, t),
               "transaction id " + std::to_string(cut.tid) +
                   (unit ? " to unit " + std::to_string(*unit) : "") +
                   ": the capture holds only part of its request (" + part(request->second) +
                   ") and of its reply (" + part(cut) + ")");
        cut_requests_.erase(request);
        return;
    }
    auto taken = take_pending(key, answered->serial);
    --f.pending;
    f.captured_request_answered = true;
    Unanswered why{FindingCode::PairResponseNotCaptured,
                   describe_request(taken->request) + " to " + taken->request.device.str() +
                       " was answered (transaction id " + std::to_string(cut.tid) +
                       "), but the capture holds only " + std::to_string(cut.captured) + " of the reply's " +
                       std::to_string(cut.length) + " bytes" +
                       (cut.snapshot_length ? " (a packet cut to the capture's snapshot length)" : "") +
                       ": its values are unknown"};
    complete(*taken, nullptr, false, nullptr, &why);
}

void Analyzer::rtu_reply_cut(Flow& f, std::uint64_t missing) {
    const Flow::ReplyTail tail = f.rtu_reply_tail;
    f.rtu_reply_tail.length = 0;  // the hole ends it: bytes after the hole begin anew
    if (tail.length == 0 || !f.pending) return;
    // Replies come in turn: the oldest request waiting that asked the unit and function the bytes begin
    // with (an exception to it too), sent before they came.
    const PendingKey key{f.id, 0};
    const Pending* answered = oldest_waiting(key, [&](const Pending& p) {
        const auto pdu = p.request.frame.pdu();
        return !pdu.empty() && p.request.frame.unit_id() == tail.head[0] && pdu[0] == (tail.head[1] & 0x7F) &&
               p.request.time <= tail.time;
    });
    if (!answered) return;
    auto taken = take_pending(key, answered->serial);
    --f.pending;
    Unanswered why{FindingCode::PairResponseNotCaptured,
                   describe_request(taken->request) + " to " + taken->request.device.str() +
                       " was answered, but the capture holds only the first " + std::to_string(tail.length) +
                       " bytes of the reply (unit " + std::to_string(tail.head[0]) + ", function code " +
                       std::to_string(tail.head[1]) + "), the rest among " + std::to_string(missing) +
                       " bytes of the response stream it lacks: its values are unknown"};
    complete(*taken, nullptr, false, nullptr, &why);
}

bool Analyzer::damaged_reply(Flow& f, const Unparsed& u, Timestamp t, bool sides_unknown) {
    // The end of the capture cutting a frame is the capture's doing (expire: pair.response_not_captured);
    // characters outside ':' ... CR LF are no frame at all.
    if (u.reason == UnparsedReason::Truncated || u.reason == UnparsedReason::NoStart || u.head[0] == 0)
        return false;
    expire(t, false);  // a request whose timeout ran out before the characters came is not answered by them
    const PendingKey key{f.id, 0};
    const auto it = pending_.find(key);
    if (it == pending_.end()) return false;
    const FrameRecord& request = it->second.request;
    const auto pdu = request.frame.pdu();
    if (pdu.empty() || u.head[0] != request.frame.unit_id() || (u.head[1] & 0x7F) != pdu[0] ||
        u.offset < request.frame.offset + request.frame.wire_length)
        return false;
    // Where the capture does not tell sides, the master's retry of the request, damaged, begins the same and
    // is as long as the request: not claimed as the device's reply (the good reply after it then answers).
    if (sides_unknown && u.length == request.frame.wire_length) return false;
    auto taken = take_pending(key, it->second.serial);
    --f.pending;
    Unanswered why{FindingCode::PairResponseDamaged,
                   describe_request(taken->request) + " to " + taken->request.device.str() +
                       " was answered, but the reply formed no frame (" + std::string(to_string(u.reason)) +
                       ", " + std::to_string(u.length) + " characters at offset " + std::to_string(u.offset) +
                       " beginning with unit " + std::to_string(u.head[0]) + ", function code " +
                       std::to_string(u.head[1]) + "): a master discards it, and its values are unknown"};
    complete(*taken, nullptr, false, nullptr, &why);
    return true;
}

void Analyzer::complete(Pending& pending, FrameRecord* response, bool timed_out, const TimedOut* late,
                        Unanswered* unanswered) {
    // Line noise that made a request to a unit never seen: its checksum finding was all there is to say.
    if (!settle_unit(pending)) return;
    if (unanswered && pending.other_unit_reply) {
        unanswered->only_other_unit = true;
        unanswered->message += " (only unit " + std::to_string(pending.other_unit) + " replied, frame " +
                               std::to_string(pending.other_unit_reply) + ", which a master discards)";
    }
    // The transaction record is made only when the sink takes transactions (--summary does not): moving
    // both frames into it and destroying it were a twentieth of a summary run. The checks read the frames
    // where they are, so that they are the same either way.
    if (!sink_wants_transactions_)
        return judge(pending.request, response, *pending.stats, timed_out, late, unanswered, nullptr);
    TransactionRecord made(std::move(pending.request));
    if (response) made.response.emplace(std::move(*response));
    judge(made.request, made.response ? &*made.response : nullptr, *pending.stats, timed_out, late,
          unanswered, &made);
}

namespace {
// Whether `response` is a reply to `request`, a serial request whose CRC or LRC failed as captured: the same
// unit, and its function (or the exception to it). The reply's own checksum must hold: a damaged reply's
// unit and function bytes may be the damage, and what replied is then not known.
bool answers_damaged_request(const FrameRecord& request, const FrameRecord& response) {
    if (request.frame.framing == Framing::Tcp || request.frame.checksum_ok || !response.frame.checksum_ok)
        return false;
    const auto q = request.frame.pdu();
    const auto a = response.frame.pdu();
    return request.frame.unit_id() == response.frame.unit_id() && !q.empty() && !a.empty() &&
           (a[0] & 0x7F) == q[0];
}

// pair.damaged_request_answered's message. Both readings, since a passive tap cannot tell them apart: the
// device does not check the checksum, or the damage happened only on the tap's side of the line.
std::string damaged_request_answered_message(const FrameRecord& request, const FrameRecord& response) {
    const bool ascii = request.frame.framing == Framing::Ascii;
    const std::string checksum = ascii ? "LRC" : "CRC";
    return response.device.str() + " answered frame " + std::to_string(request.index) + " (" +
           describe_request(request) + "), a request whose " + checksum +
           " failed as captured: either it does not check the " + checksum +
           " (a slave must discard such a frame and not reply, SL " + (ascii ? "§2.5.2.2" : "§2.5.1.2") +
           ") or the capture damaged the request";
}
}  // namespace

void Analyzer::judge(const FrameRecord& request, const FrameRecord* rsp_record, DeviceStats& stats,
                     bool timed_out, const TimedOut* late, Unanswered* unanswered, TransactionRecord* made) {
    // A reply whose CRC or LRC fails has a damaged byte somewhere (SL §2.5.1.2: the master discards it):
    // its checksum finding says so, and its unit, function code and data are not held against the request
    // as if the device had sent them, nor named from the map, remembered or checked against the manual.
    const bool damaged = rsp_record && !rsp_record->frame.checksum_ok;
    // The transaction is written first, then what was found in it.
    struct Deferred {
        FindingCode code;
        const FrameRecord* about;
        std::string message;
        std::vector<std::uint64_t> frames;
    };
    std::vector<Deferred> found;
    // A transaction's findings include its frames' own (a response with a bad CRC, a request breaking the
    // specification): a CSV row or a transaction record alone must not pass for a clean exchange.
    if (made)
        for (const FrameRecord* frame : {&request, rsp_record})
            if (frame) add_frame_findings(*frame, made->findings);
    const auto pair_finding = [&](FindingCode code, std::string message) {
        // the frames a finding about the pair names
        found.push_back({code, rsp_record, std::move(message), {request.index, rsp_record->index}});
    };
    if (rsp_record && late) {
        // Counted as a timeout already, and as a transaction: a late reply is neither a second one nor a
        // response (or exception) in time. Its latency is what the device took, and goes into the histogram.
        const auto ms = [](Timestamp d) {
            return std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(d).count());
        };
        ++stats.late_responses;
        // Counted discarded at its timeout (its checksum failed, or a silence inside it), and answered
        // after all: the device got it, late. A timeout answered late, as late_responses counts them.
        if (discardable(request) && stats.damaged_unanswered > 0) {
            --stats.damaged_unanswered;
            ++stats.timeouts;
        }
        if (made) {
            made->late_past = late->timeout;
            made->late_moved_on = late->moved_on_at != 0;
        }
        const bool timed = rsp_record->time.count() && request.time.count();
        std::string message =
            "the reply to frame " + std::to_string(request.index) + " (" + late->what + ") came ";
        if (timed) message += ms(rsp_record->time - request.time) + " ms after it, ";
        if (late->moved_on_at)
            message += "after the master had moved on to frame " + std::to_string(late->moved_on_at) +
                       (timed ? " (" + ms(late->timeout) + " ms after it)" : "");
        else
            message += "past the " + ms(late->timeout) + " ms timeout";
        pair_finding(FindingCode::PairLateResponse, message + ": the request was reported unanswered");
    } else if (rsp_record) {
        ++stats.responses;
    }
    if (rsp_record) {
        const FrameRecord& rsp = *rsp_record;
        if (rsp.time.count() && request.time.count()) {  // raw dumps carry no time: no latency either
            const Timestamp latency = rsp.time - request.time;
            if (latency >= Timestamp{0}) {
                stats.latency.add(latency);
                if (made) made->latency = latency;
            } else {
                // A device cannot answer before it is asked: the clock is wrong, not the device.
                pair_finding(
                    FindingCode::PairResponseBeforeRequest,
                    "the response is stamped " +
                        std::to_string(
                            std::chrono::duration_cast<std::chrono::microseconds>(-latency).count()) +
                        " µs before its request: the capture's clock went back");
            }
        }
        // A slave discards a request whose checksum failed (SL §2.5.1.2, §2.5.2.2): a reply to it is said,
        // against the device that sent it, in time or late.
        if (answers_damaged_request(request, rsp))
            pair_finding(FindingCode::PairDamagedRequestAnswered,
                         damaged_request_answered_message(request, rsp));
        if (!damaged && rsp.frame.unit_id() != request.frame.unit_id())
            pair_finding(FindingCode::PairUnitMismatch,
                         "request to unit " + std::to_string(request.frame.unit_id()) +
                             ", response from unit " + std::to_string(rsp.frame.unit_id()));
        // An exception is the device's answer whatever it answers: to a request that does not decode (the
        // device's very reason to refuse it) or to another function than asked. Counted only for a request
        // that decoded, the summary's exceptions fell short of the replies that carried one.
        // One whose PDU did not decode for a byte too many after its code still carries the code.
        const auto exception = damaged ? std::nullopt : exception_code_of(rsp);
        if (exception) {
            const auto code = *exception;
            if (!late) {  // of the responses; a late one is among the timeouts
                ++stats.exceptions;
                ++stats.exception_codes[code];
            }
            const auto name = exception_name(code);
            pair_finding(code == 10   ? FindingCode::PairGatewayPathUnavailable
                         : code == 11 ? FindingCode::PairGatewayTargetNoResponse
                                      : FindingCode::PairExceptionResponse,
                         "exception " + std::to_string(code) + " (" +
                             (name ? std::string(*name) : "undefined") + ") to " + describe_request(request));
        }
        if (!damaged && request.pdu && rsp.pdu) {
            const Pdu& q = *request.pdu;
            const Pdu& a = *rsp.pdu;
            if (a.function_code() != q.function_code()) {
                pair_finding(FindingCode::PairFunctionMismatch,
                             "request FC" + std::to_string(q.function_code()) + ", response FC" +
                                 std::to_string(a.function_code()));
            } else if (!exception) {
                if (const auto misfit = reply_misfit(q, a)) {
                    switch (misfit->kind) {
                        case ReplyMisfit::Kind::DataSize:
                            pair_finding(
                                FindingCode::PairResponseSizeMismatch,
                                describe_request(q) + " needs " + std::to_string(misfit->expected_bytes) +
                                    " data bytes, the response has " + std::to_string(misfit->got_bytes));
                            break;
                        // The bits of the last byte past the quantity asked are padded with zeros (AP §6.1,
                        // §6.2): only the request says how many are used, so the response is judged with it,
                        // as an FC15 request is on its own.
                        case ReplyMisfit::Kind::Padding: {
                            const auto& bits = std::get<ReadBitsResponse>(a.body);
                            pair_finding(FindingCode::PduPaddingBitsSet,
                                         describe_request(q) + ": the response's last byte, " +
                                             hex8(bits.values.back()) + ", sets bits past the " +
                                             std::to_string(std::get<ReadRequest>(q.body).quantity) +
                                             " asked");
                            break;
                        }
                        case ReplyMisfit::Kind::Echo:
                            pair_finding(FindingCode::PairEchoMismatch,
                                         describe_request(q) + ": the response is not " + misfit->expected +
                                             (misfit->differs.empty() ? "" : ": " + misfit->differs));
                            break;
                    }
                }
            }
        }
    } else {
        // A request whose checksum failed is discarded by every slave (SL §2.5.1.2, §2.5.2.2), and so is one
        // with a silence above t1.5 inside it (SL §2.5.1.1): its silence is right, not a timeout held
        // against the device. (It waited all the same: a capture can damage what the device got whole, and
        // a reply then answers it; a device that ignores t1.5 answers the gapped one.)
        const bool discarded = discardable(request) && unanswered &&
                               (unanswered->code == FindingCode::PairNoResponse ||
                                unanswered->code == FindingCode::PairNoResponseAtEnd);
        if (discarded) {
            unanswered->code = FindingCode::PairDamagedRequestUnanswered;
            unanswered->message = describe_request(request) + " to " + request.device.str() + ": " +
                                  discarded_because(request) +
                                  " and no reply came, as a slave that discards such a frame does";
            timed_out = false;
        }
        // Only another unit replied while it waited (on_response): a timeout (or unanswered at the end) all
        // the same, counted among them and said apart.
        const bool other_unit = !discarded && unanswered && unanswered->only_other_unit &&
                                (unanswered->code == FindingCode::PairNoResponse ||
                                 unanswered->code == FindingCode::PairNoResponseAtEnd);
        if (made) {
            made->timed_out = timed_out;
            made->discarded = discarded;
            made->answered_by_other_unit = other_unit;
            if (other_unit) made->findings.push_back(FindingCode::PairUnitMismatch);
        }
        if (other_unit) ++stats.answered_by_other_unit;
        if (discarded) {
            ++stats.damaged_unanswered;
        } else if (unanswered && unanswered->code == FindingCode::PairResponseNotCaptured) {
            ++stats.replies_not_captured;  // answered: neither a timeout nor waiting at the end
            if (made) made->reply_not_captured = true;
        } else if (unanswered && unanswered->code == FindingCode::PairResponseDamaged) {
            ++stats.damaged_replies;  // answered, with nothing a master keeps: neither a response nor a
                                      // timeout
            if (made) made->reply_damaged = true;
        } else if (unanswered && unanswered->code == FindingCode::PairClientAborted) {
            ++stats.client_aborted;  // the client's doing: no timeout of the device's
            if (made) made->client_aborted = true;
        } else {
            ++(timed_out ? stats.timeouts : stats.unanswered_at_end);
        }
        // Why there is none: in the transaction's findings too, as an exception's is in its own (a CSV row
        // of a timeout must not read as a clean exchange).
        if (unanswered)
            found.push_back({unanswered->code, &request, std::move(unanswered->message), {request.index}});
    }
    if (options_.semantics && rsp_record && request.pdu && rsp_record->pdu) {
        // The flow's server, as on_request took it: "client -> server" over IP, the link itself on a line.
        const std::string& link = request.link.str();
        const auto arrow = link.find(" -> ");
        const std::string server = arrow == std::string::npos ? link : link.substr(arrow + 4);
        if (const Profile* profile = options_.semantics->profile_for(server, request.frame.unit_id())) {
            if (auto told = options_.semantics->follow_line_settings(request.device, *profile, *request.pdu,
                                                                     *rsp_record->pdu)) {
                // On a serial line the capture follows the device (a TCP connection carries none of it).
                if (SerialLink* line = serial_line_of(request.link.str(), request.carrier))
                    told->note.message +=
                        follow_line(*line, request.frame.unit_id(), told->settings, profile->line,
                                    rsp_record->frame.offset + rsp_record->frame.wire_length);
                found.push_back({told->note.code,
                                 rsp_record,
                                 std::move(told->note.message),
                                 {request.index, rsp_record->index}});
            }
            // Remembered whether or not the sink takes transactions: what a later write changes (and so the
            // findings) must not depend on the output chosen. Named only for a transaction record.
            // A damaged reply is not what the device holds: a damaged decimal-point register, remembered,
            // would scale every later value wrong.
            if (made) made->profile = profile;
            if (made && !damaged)
                made->values =
                    options_.semantics->values(*profile, request.device, *request.pdu, *rsp_record->pdu);
            else if (!damaged)
                options_.semantics->remember(*profile, request.device, *request.pdu, *rsp_record->pdu);
            if (!damaged)
                for (auto& rule : options_.semantics->check_response(*profile, request.device, *request.pdu,
                                                                     *rsp_record->pdu))
                    found.push_back(
                        {rule.code, rsp_record, std::move(rule.message), {request.index, rsp_record->index}});
            if (auto moved = options_.semantics->follow_address(server, request.device.str(), *profile,
                                                                *request.pdu, *rsp_record->pdu)) {
                // The unit no longer answers at its old address: it is not on the line there any more.
                if (SerialLink* line = serial_line_of(request.link.str(), request.carrier)) {
                    std::erase(line->answered, request.frame.unit_id());
                    line->told.erase(request.frame.unit_id());
                }
                found.push_back(
                    {moved->code, rsp_record, std::move(moved->message), {request.index, rsp_record->index}});
            }
        }
    }
    // (Not from a damaged reply: its registers are not what the device holds.)
    // The generic profile maps nothing: its registers are read as a device's without a profile.
    if (made && options_.word_order && (!made->profile || made->profile->open_address_space) && rsp_record &&
        !damaged && request.pdu && rsp_record->pdu) {
        const auto fc = request.pdu->function_code();
        const auto* read = std::get_if<ReadRequest>(&request.pdu->body);
        const auto* regs = std::get_if<ReadRegistersResponse>(&rsp_record->pdu->body);
        if ((fc == 3 || fc == 4) && read && regs) {
            made->word_order = options_.word_order;
            made->registers32 = registers32(read->starting_address, regs->values, *options_.word_order);
        }
    }
    if (!late) ++summary_.transactions;
    // Everything found about the pair is the transaction's too (a profile rule its reply breaks, the reason
    // there is none): a CSV row or a transaction record alone must not pass for a clean exchange.
    if (made)
        for (const auto& f : found)
            made->findings.push_back(f.code);
    if (made) sink_.transaction(*made);
    for (auto& f : found)
        report(f.code, *f.about, std::move(f.message), std::move(f.frames));
}

// Requests are timed out against the latest time seen (packets a little out of order, as several capture
// queues stamp them, move nothing back). A step back longer than a timeout is the clock set back (by hand,
// NTP, a tap's clock restored): left as it was, every request after it would expire at the next packet, its
// response unsolicited, until the clock caught up, hours later. The pending requests' deadlines move back
// with the clock, each keeping the wait it had left, and the step is said once per file. A serial line's
// bytes are held to its own timeout: against the TCP one (3 s) a reply stamped 2.9 s before its request on a
// line of 1 s was set back to back after it, with a latency made up from the baud rate and no word.
bool Analyzer::clock_stepped_back(Timestamp from, Timestamp to, bool serial) const {
    return from - to >
           (serial ? options_.serial_timeout : std::max(options_.timeout, options_.serial_timeout));
}

void Analyzer::clock_went_back(Timestamp to, const std::string& where) {
    const Timestamp back = now_ - to;
    for (auto& queue : expiries_)
        for (auto& e : queue)
            if (e.deadline != Timestamp::max()) e.deadline -= back;
    for (HeldExpiry& held : held_expiries_)
        held.expiry.deadline -= back;
    now_ = to;
    const std::string& source = source_.str();
    if (clock_warned_source_ == source) return;
    clock_warned_source_ = source;
    input_note(source + ": " + where + ": the capture's clock goes back " +
               std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(back).count()) +
               " ms; requests are timed out by the clock from here (later steps back are not listed)");
}

void Analyzer::expire(Timestamp now, bool at_end) {
    // A connection whose framing is still being told holds its first bytes, and its requests wait in them
    // unseen: by the time the first could time out it is settled on what the probe has read, so that they
    // time out in time (in a live capture's quiet time too). Not while one is fed (settle_framing).
    if (!probing_.empty() && !replaying_) {
        // Not one whose bytes so far are all RTU frames while its MBAP reading holds: the quiet time would
        // settle it as MBAP (a first poll of 2 registers unanswered) and make up units for good; it waits
        // for its next bytes (its requests' timeouts are then said late, at their own times) or its end.
        const auto due = [&](Flow* f) {
            return f->held.empty() || at_end ||
                   (f->held.front().time + options_.timeout <= now &&
                    (!f->probe.rtu_reading_holds() || f->probe.settles_as_rtu()));
        };
        std::vector<Flow*> settling;
        for (Flow* f : probing_)
            if (due(f)) settling.push_back(f);
        std::erase_if(probing_, due);
        for (Flow* f : settling)
            settle_framing(*f, now);
    }
    release_held_expiries(at_end);
    // An answered request's entry would wait for its deadline: at 50,000 requests a second and a 3 s timeout
    // that is 150,000 entries. When entries outnumber the requests still pending, the answered ones at the
    // front leave at once, so memory follows what is outstanding, not the traffic's rate.
    for (auto& queue : expiries_)
        while (expiry_entries_ > 2 * pending_.size() + 64 && !queue.empty()) {
            const Expiry& e = queue.front();
            if (find_pending(e.key, e.serial)) break;  // still pending: its deadline decides
            queue.pop_front();
            --expiry_entries_;
        }
    // Each queue is in deadline order (one timeout each, capture time only moves forward): the next due is
    // at the front of one of them.
    for (;;) {
        std::deque<Expiry>* next = nullptr;
        for (auto& queue : expiries_)
            if (!queue.empty() && (!next || queue.front().deadline < next->front().deadline)) next = &queue;
        if (!next) break;
        const Expiry e = next->front();
        if (!at_end && e.deadline > now) break;
        next->pop_front();
        --expiry_entries_;
        // A reply cut to the snapshot length waits as a hole in its stream, which a whole copy may still
        // fill, until the client speaks again. Cut before this request's deadline it answered in time: given
        // up now, it completes the request as answered, not captured whole (a poll slower than the timeout
        // made a device's cut reply a timeout).
        // So does a reply the client acknowledged that the capture lacks (a tap's drop): when no later byte
        // of the server's has shown the hole yet, it waits, and the request was a timeout. Acknowledged
        // before this request's deadline, it is given up now: a gap, and the requests waiting may have been
        // answered in it (stream_gap).
        // A request still pending whose reply may wait behind a hole in its response stream is held
        // (reply_may_wait_behind_hole); its flow is looked up only then, not for every answered entry.
        if (!at_end && find_pending(e.key, e.serial))
            if (Flow* flow = flow_of(e.key.flow); flow && flow->reassembler[1]) {
                if (flow->reassembler[1]->cut_before(e.deadline)) flow->reassembler[1]->peer_spoke();
                flow->reassembler[1]->give_up_acknowledged_before(e.deadline);
                if (reply_may_wait_behind_hole(e, *flow)) {
                    held_expiries_.push_back({static_cast<ExpiryQueue>(next - expiries_.data()), e, flow});
                    ++expiry_entries_;
                    continue;
                }
            }
        time_out(e, at_end);
    }
}

// A serial request whose reply the end of the capture (or of its input) cut: answered, its values unknown
// (as a Modbus/TCP reply cut by the snapshot length is), not "no response".
std::optional<Analyzer::Unanswered> Analyzer::reply_cut_by_the_end(const Pending& p, const Flow& flow) const {
    if (p.request.frame.framing == Framing::Tcp || !flow.tail_begins_reply_to(p.request)) return std::nullopt;
    const bool ascii = p.request.frame.framing == Framing::Ascii;
    return Unanswered{FindingCode::PairResponseNotCaptured,
                      describe_request(p.request) + " to " + p.request.device.str() +
                          " was answered, but the capture ends " + std::to_string(flow.tail_length) +
                          (ascii ? " characters" : " bytes") + " into the reply (unit " +
                          std::to_string(flow.tail_head[0]) + ", function code " +
                          std::to_string(flow.tail_head[1]) + "): its values are unknown"};
}

// The request of a due entry, still pending, is given up: a timeout, or what else the capture says of it.
void Analyzer::time_out(const Expiry& e, bool at_end) {
    auto taken = take_pending(e.key, e.serial);
    if (!taken) return;  // answered meanwhile
    Pending p = std::move(*taken);
    Flow* flow = nullptr;
    for (auto& [k, f] : flows_)
        if (f->id == e.key.flow) {
            --f->pending;
            flow = f.get();
        }
    const bool ended = at_end && e.deadline > now_;
    if (!ended && flow && p.unseen_unit_link) {
        // Whose it was is not known yet: the next frame on its link tells (release_unseen).
        release_unseen(*flow);
        flow->unseen_expired.emplace(std::move(p));
        return;
    }
    std::string what = describe_request(p.request);
    if (ended && flow) {
        if (auto cut = reply_cut_by_the_end(p, *flow)) {
            give_up(p, false, std::move(*cut));
            return;
        }
    }
    if (auto why = not_the_servers(p)) {
        give_up(p, false, std::move(*why));
        return;
    }
    if (ended) {
        give_up(p, false, {FindingCode::PairNoResponseAtEnd, what + " unanswered when the capture ended"});
        return;
    }
    const Timestamp timeout =
        p.request.frame.framing == Framing::Tcp ? options_.timeout : options_.serial_timeout;
    Unanswered why{
        FindingCode::PairNoResponse,
        no_response_message(
            p.request,
            "within " +
                std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count()) +
                " ms")};
    remember_timed_out({e.key.flow, late_id(p.request.frame)}, p, timeout, std::move(what));
    give_up(p, true, std::move(why));
}

// Bytes of the server's stream captured by the request's deadline wait behind a hole (the reply to an
// earlier request lost and sent again, a segment the tap dropped): its reply may be among them, sent in
// time. Timed out at its deadline, it was a pair.no_response held against the device and then a reply
// "50 ms after it, past the 3000 ms timeout" when the hole filled.
bool Analyzer::reply_may_wait_behind_hole(const Expiry& e, const Flow& flow) {
    return flow.reassembler[1] && flow.reassembler[1]->holds_bytes_captured_by(e.deadline) &&
           find_pending(e.key, e.serial);
}

Analyzer::Flow* Analyzer::flow_of(std::uint64_t id) const {
    return id >= 1 && id <= flow_by_id_.size() ? flow_by_id_[id - 1] : nullptr;
}

// Held requests go back to their queues, in deadline order, once their flow's hole filled or was given up
// (the reply, if it was there, has been paired meanwhile) or at the end; answered ones leave.
void Analyzer::release_held_expiries(bool at_end) {
    if (held_expiries_.empty()) return;
    std::erase_if(held_expiries_, [&](const HeldExpiry& held) {
        const Expiry& e = held.expiry;
        if (!find_pending(e.key, e.serial)) {
            --expiry_entries_;
            return true;
        }
        if (!at_end && reply_may_wait_behind_hole(e, *held.flow)) return false;
        auto& queue = expiries_[held.queue];
        queue.insert(std::upper_bound(queue.begin(), queue.end(), e.deadline,
                                      [](Timestamp d, const Expiry& x) { return d < x.deadline; }),
                     e);
        return true;
    });
}

// With a transaction id, the held request of that id; through an RTU gateway (one key for the link), the
// oldest held, whose reply comes first.
void Analyzer::time_out_held_before(const Flow& flow, const FrameRecord& r) {
    const PendingKey key{flow.id, pairing_id(r.frame)};
    auto first = held_expiries_.end();
    for (auto it = held_expiries_.begin(); it != held_expiries_.end(); ++it)
        if (it->expiry.key == key &&
            (first == held_expiries_.end() || it->expiry.serial < first->expiry.serial))
            first = it;
    if (first == held_expiries_.end() || first->expiry.deadline >= r.time) return;
    const Expiry e = first->expiry;
    held_expiries_.erase(first);
    --expiry_entries_;
    time_out(e, false);
}

void Analyzer::remember_timed_out(const PendingKey& key, Pending& pending, Timestamp timeout,
                                  std::string what, std::uint64_t moved_on_at, bool given_up_by_client) {
    if (!settle_unit(pending)) return;  // no device's: a reply from a unit that shows up later is not its
    const std::uint64_t serial = ++next_serial_;
    timed_out_.insert_or_assign(
        key, TimedOut{Pending(FrameRecord(pending.request), pending.serial, pending.stats), timeout,
                      std::move(what), serial, moved_on_at, given_up_by_client});
    timed_out_order_.emplace_back(key, serial);
    while (timed_out_order_.size() > max_timed_out) {  // entries whose key was used again count too
        const auto& [old_key, old_serial] = timed_out_order_.front();
        if (auto it = timed_out_.find(old_key); it != timed_out_.end() && it->second.serial == old_serial)
            timed_out_.erase(it);
        timed_out_order_.pop_front();
    }
}

std::optional<Analyzer::TimedOut> Analyzer::late_for(const PendingKey& key) {
    const auto it = timed_out_.find(key);
    if (it == timed_out_.end()) return std::nullopt;
    TimedOut late = std::move(it->second);
    timed_out_.erase(it);
    return late;
}

// ---------------------------------------------------------------- serial lines

Analyzer::SerialLink& Analyzer::serial_link(const std::string& key, const std::string& link,
                                            const std::string& server, Carrier carrier) {
    auto& slot = serial_links_[key];
    if (!slot) {
        slot = std::make_unique<SerialLink>();
        slot->source = source_;
        auto& flow = flows_[key];
        flow = std::make_unique<Flow>();
        flow->id = ++next_flow_;
        flow_by_id_.push_back(flow.get());
        flow->link = link;
        flow->server = server;
        flow->carrier = carrier;
        slot->flow = flow.get();
        slot->line = options_.serial_line;
        slot->keeps_chunks = options_.semantics != nullptr;
    }
    return *slot;
}

Analyzer::SerialLink* Analyzer::serial_line_of(const std::string& link, Carrier carrier) {
    if (carrier != Carrier::Serial) return nullptr;  // exported PDUs come framed; TCP carries no line
    const auto it = serial_links_.find(link);
    return it == serial_links_.end() ? nullptr : it->second.get();
}

std::string serial_line_name(const std::string& source) {
    return "serial " + source;
}

Analyzer::SerialLink& Analyzer::serial_link(const std::string& source) {
    const std::string key = serial_line_name(source);
    return serial_link(key, key, key, Carrier::Serial);
}

Direction Analyzer::classify(const Flow& flow, const Frame& frame) const {
    const auto pdu = frame.pdu();
    auto request = decode_request(pdu);
    auto response = decode_response(pdu);
    const bool req_clean = request && request->violations.empty();
    const bool rsp_ok = response.has_value();
    if (auto it = pending_.find({flow.id, pairing_id(frame)}); it != pending_.end()) {
        // A request is outstanding: this is its response if it comes from that unit with that function
        // (or its exception); otherwise the master has moved on.
        // A master's retry after its own timeout (000:274) carries the unit and the function too: the very
        // bytes of the request waiting, decoding cleanly as a request and only with violations as a response
        // (an FC3 request read as a reply has byte count 0 and three bytes too many), are the retry, not a
        // malformed reply. So is a request for other registers of that unit and function (a master polling
        // blocks that moved on before the reply came): its bytes are not shaped as a reply to the one waiting
        // (a byte count the read does not need, which counts none of the bytes after it; a multiple write
        // longer than its reply, to another address). A malformed reply so shaped (a short FC3 reply
        // "11 03 04 00 00 01" to a read of 2 registers, which reads as a request for register 1024; an odd
        // byte count of its own bytes, "11 03 03 00 00 05") is the device's fault to report. An echo (FC5,
        // FC6, FC8) is both, and stays the reply.
        const FrameRecord& q = it->second.request;
        if (rsp_ok && frame.unit_id() == q.frame.unit_id() && q.pdu &&
            response->function_code() == q.pdu->function_code()) {
            const bool same_bytes = frame.length == q.frame.length &&
                                    std::memcmp(frame.bytes.data(), q.frame.bytes.data(), frame.length) == 0;
            const bool retry = req_clean && !response->violations.empty() &&
                               (same_bytes || !reply_claims_to_answer(*q.pdu, pdu));
            return retry ? Direction::Request : Direction::Response;
        }
        return req_clean ? Direction::Request : (rsp_ok ? Direction::Response : Direction::Request);
    }
    // A unit's echo of the broadcast just sent (FC5, FC6 and FC8 replies repeat their request): a slave
    // answering it, not the master asking that unit the very same, as a master sends nothing during its
    // turnaround delay after a broadcast (SL §2.1). Read as a request, it made a timeout for a unit that
    // had done nothing wrong but answer.
    if (flow.last_broadcast && frame.unit_id() != 0 && frame.checksum_ok &&
        std::ranges::equal(pdu, flow.last_broadcast_pdu) &&
        (!frame.end.count() || (frame.end >= flow.last_broadcast_time &&
                                frame.end - flow.last_broadcast_time <= options_.serial_timeout)))
        return Direction::Response;
    if (req_clean) return Direction::Request;
    if (rsp_ok && response->violations.empty()) return Direction::Response;
    return Direction::Request;
}

namespace {

// An ASCII frame begun with ':' and broken before its CR LF is a damaged frame, not noise: each way has its
// finding (SL §2.5.2.1), an error as an RTU frame's gap is. A frame broken by a pause of 1.5 s was a warning
// of unparsed bytes, exit 0, though every slave must discard it. Characters outside any frame, and a frame
// the capture's end cut, stay unparsed bytes.
FindingCode ascii_damage(UnparsedReason reason) noexcept {
    switch (reason) {
        case UnparsedReason::Timeout:
            return FindingCode::AsciiInterCharTimeout;
        case UnparsedReason::MissingEnd:
            return FindingCode::AsciiMissingEnd;
        case UnparsedReason::BadCharacter:
            return FindingCode::AsciiBadCharacter;
        case UnparsedReason::OddLength:
            return FindingCode::AsciiOddLength;
        case UnparsedReason::TooLong:
            return FindingCode::AsciiFrameTooLong;
        case UnparsedReason::TooShort:
            return FindingCode::AsciiFrameTooShort;
        default:
            return FindingCode::StreamUnparsedBytes;
    }
}

}  // namespace

void Analyzer::serial_events(SerialLink& link, DeframeEvents& events, Timestamp t, std::uint64_t packet) {
    Flow& flow = *link.flow;
    for (auto& e : events) {
        if (link.restart_at) break;  // the rest was deframed the old way: it is deframed again (pump)
        if (auto* u = std::get_if<Unparsed>(&e)) {
            u->offset += link.base;
            link.settled = std::max(link.settled, u->offset + u->length);
            summary_.unparsed_bytes += u->length;
            const Timestamp when = u->time.count() ? u->time : t;
            const SharedText& source = link.source_at(u->offset, source_);
            const std::uint64_t began_in = link.packet_at(u->offset, packet);
            sink_.unparsed(UnparsedRecord{source, flow.link, link.hint, when, began_in, u->offset, u->length,
                                          u->reason});
            const bool answered = link.framing == Framing::Ascii && link.hint != Direction::Request &&
                                  damaged_reply(flow, *u, when, link.hint == Direction::Unknown);
            // Bytes that may hold a request: the master's side of the line, or, where the capture does not
            // tell sides, at least a unit and a function (RTU; ASCII: ':' and their four digits). A glitch
            // byte at a turnaround holds none, and must not excuse the reply after it.
            // The longest such run since the last reply is named (an ASCII request's characters, not the LF
            // that came late after them).
            const bool may_hold_request =
                !answered && (link.hint == Direction::Request ||
                              (link.hint == Direction::Unknown &&
                               u->length >= (link.framing == Framing::Ascii ? 5u : 3u)));
            if (may_hold_request && (flow.unparsed_after_frame < flow.last_response_index ||
                                     flow.unparsed_length == 0 || u->length > flow.unparsed_length)) {
                flow.unparsed_offset = u->offset;
                flow.unparsed_length = u->length;
                flow.unparsed_after_frame = next_frame_;
            }
            // An ASCII frame is cut only where the capture ends inside it (a pause or a new ':' cuts it
            // on the line, and the master moves on).
            if (link.hint != Direction::Request &&
                (link.framing == Framing::Rtu ||
                 (link.framing == Framing::Ascii && u->reason == UnparsedReason::Truncated))) {
                flow.tail_offset = u->offset;
                flow.tail_length = u->length;
                flow.tail_head = u->head;
            }
            FrameRecord about;
            about.time = when;
            about.source = source;
            about.link = flow.link;
            about.packet = began_in;
            report(
                link.framing == Framing::Ascii ? ascii_damage(u->reason) : FindingCode::StreamUnparsedBytes,
                about,
                std::to_string(u->length) + " bytes at offset " + std::to_string(u->offset) +
                    " formed no frame (" + std::string(to_string(u->reason)) + ")");
            continue;
        }
        Frame& frame = std::get<Frame>(e);
        frame.offset += link.base;
        link.settled = std::max(link.settled, frame.offset + frame.wire_length);
        flow.tail_length = 0;
        FrameRecord r(frame);
        r.index = ++next_frame_;
        r.packet = link.packet_at(frame.offset, packet);
        r.time = frame.end.count() ? frame.end : t;
        if (r.time > now_) now_ = r.time;
        r.source = link.source_at(frame.offset, source_);
        r.link = flow.link;
        // Up to this frame's own time, not the capture's: a timed deframer closes a frame only when later
        // bytes show the silence after it, so a request and its response read in one chunk come out when the
        // next chunk arrives, which may be more than the timeout later. Before the frame is classified: a
        // master's retry after a timeout was taken for the timed-out request's response (a malformed one,
        // "unsolicited" by the time it was paired). Up to its first character: a master's response timeout
        // runs until a reply begins, and a long reply on a slow line (71 characters at 300 baud, 2.4 s) that
        // began in time was "no response" and then late.
        expire(frame.start.count() && frame.start <= r.time ? frame.start : r.time, false);
        r.direction = link.hint != Direction::Unknown ? link.hint : classify(flow, frame);
        // A unit on the line: one that answered with a frame whose checksum holds (noise read as a frame
        // names units nobody has).
        if (link.keeps_chunks && r.direction == Direction::Response && frame.checksum_ok &&
            frame.unit_id() != 0 &&
            std::find(link.answered.begin(), link.answered.end(), frame.unit_id()) == link.answered.end())
            link.answered.push_back(frame.unit_id());
        r.carrier = flow.carrier;
        // A reply whose checksum fails may have its unit byte damaged: while a request waits on the line it
        // is that unit's reply, garbled on the way (the other units do not talk unasked), not a unit nobody
        // asked, which would stand in the summary as a device of its own.
        std::uint8_t unit = frame.unit_id();
        if (r.direction == Direction::Response && !frame.checksum_ok)
            if (const auto it = pending_.find({flow.id, pairing_id(frame)}); it != pending_.end())
                unit = it->second.request.frame.unit_id();
        decode_and_judge(flow, r, unit);
    }
    events.clear();
}

void Analyzer::serial(const std::string& source, std::span<const std::uint8_t> bytes, Timestamp received,
                      Direction hint) {
    set_source(source);
    // A timed chunk is one record of the capture (a read of the port, a log's record, a text line), as each
    // becomes a record of sniff --write's file: counted as the packets a decode of that file counts. An
    // untimed dump comes in buffers of no meaning to anyone.
    const std::uint64_t packet = received.count() != 0 ? ++summary_.packets : 0;
    const auto part = serial_parts_.find(source);
    if (part == serial_parts_.end())
        return serial_bytes(serial_link(source), options_.serial_framing, bytes, received, hint, packet);
    SerialLink& link = serial_link(part->second);
    if (link.parts.empty()) link.parts.emplace_back(0, link.source);
    if (link.parts.back().second != source_) link.parts.emplace_back(link.fed, source_);
    serial_bytes(link, options_.serial_framing, bytes, received, hint, packet);
}

void Analyzer::serial_part_of(const std::string& source, const std::string& line) {
    if (source != line) serial_parts_[source] = line;
}

void Analyzer::end_serial(const std::string& source) {
    if (serial_parts_.count(source)) return;  // a part: the line goes on in the next
    const auto it = serial_links_.find(serial_line_name(source));
    if (it == serial_links_.end()) return;
    SerialLink& link = *it->second;
    set_source(link.source);
    if (link.probe) tell_framing(link, {}, true);
    do {
        if (link.restart_at) restart(link);
        pump(link);
        flush_deframers(link, link.last_received, 0, true);
    } while (link.restart_at);
    Flow& flow = *link.flow;
    std::vector<std::pair<PendingKey, std::uint64_t>> ended;
    for (const auto& [key, p] : pending_)
        if (key.flow == flow.id && p.request.time + options_.serial_timeout > link.last_received)
            ended.emplace_back(key, p.serial);
    std::sort(ended.begin(), ended.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    for (const auto& [key, serial] : ended)
        if (auto p = take_pending(key, serial)) {
            --flow.pending;
            // Judged as at the end of the whole capture: a reply the input's end cut was "no response" when
            // other inputs followed it, and "not captured whole" when it was the only one.
            auto cut = reply_cut_by_the_end(*p, flow);
            give_up(*p, false,
                    cut ? std::move(*cut)
                        : Unanswered{FindingCode::PairNoResponseAtEnd,
                                     describe_request(p->request) + " unanswered when its input ended"});
        }
}

void Analyzer::serial_bytes(SerialLink& link, std::optional<Framing> framing,
                            std::span<const std::uint8_t> bytes, Timestamp received, Direction hint,
                            std::uint64_t packet) {
    if (packet != 0 && !bytes.empty()) link.note_packet(link.fed, packet);
    if (!link.framing && !link.probe) {  // the line's first bytes
        link.framing = framing;
        if (framing)
            link.read_as.push_back(*framing);
        else {
            link.probe = std::make_unique<AsciiDeframer>();
            link.rtu_probe = std::make_unique<RtuDeframer>();
        }
    }
    if (!link.keeps_chunks && link.framing && link.next_chunk == link.chunks.size()) {
        link.chunks.clear();  // those that told the framing
        link.next_chunk = 0;
        link.fed += bytes.size();
        deframe(link, bytes, received, hint, packet, link.fed - bytes.size());
        return;
    }
    link.chunks.push_back({{bytes.begin(), bytes.end()}, link.fed, received, hint, packet, false});
    link.fed += bytes.size();
    if (!link.framing) tell_framing(link, bytes, false);
    if (link.framing) pump(link);
}

void Analyzer::close_frames(SerialLink& link, Timestamp t, std::uint64_t packet) {
    if (link.next_chunk == link.chunks.size() && !link.keeps_chunks) return flush_deframers(link, t, packet);
    link.chunks.push_back({{}, link.fed, t, link.hint, packet, true});
    if (link.framing) pump(link);
}

void Analyzer::flush_deframers(SerialLink& link, Timestamp t, std::uint64_t packet, bool input_ended) {
    DeframeEvents events;
    if (link.timed && input_ended)
        link.timed->finish(events);
    else if (link.timed)
        link.timed->advance(Timestamp::max(), events);
    if (link.untimed) link.untimed->finish(events);
    if (link.ascii) link.ascii->finish(events);
    serial_events(link, events, t, packet);
}

void Analyzer::deframe(SerialLink& link, std::span<const std::uint8_t> bytes, Timestamp received,
                       Direction hint, std::uint64_t packet, std::uint64_t offset) {
    // A log's clock set back, or logs of two sessions joined: the timed deframer took the later bytes for
    // ones right after the earlier (timestamps are coarse, never earlier than the last), so every frame after
    // the step was restamped at the end of the first session, with no word. What the line held ends at the
    // step; the deframer starts again from these bytes' times, and requests are timed out by the clock from
    // here, as in a capture.
    if (received.count() && link.last_received.count() &&
        clock_stepped_back(link.last_received, received, true)) {
        flush_deframers(link, link.last_received, packet);
        if (link.restart_at) return;  // those bytes come again, after the change (pump)
        // The new deframer counts its offsets from these bytes: the stream's offsets of what it reports
        // start here (they started again at 0, and the records named the wrong offsets and packets).
        if (link.timed && !link.untimed && !link.ascii) link.base = offset;
        link.timed.reset();
        if (received < now_) {
            char at[48];
            std::snprintf(at, sizeof at, "the chunk stamped %.6f s",
                          std::chrono::duration<double>(received).count());
            clock_went_back(received,
                            packet ? "packet " + std::to_string(packet) + ", " + at : std::string(at));
        }
    }
    if (received.count()) link.last_received = received;
    if (hint != link.hint) {
        // The other side is talking now: whatever the line held before is complete, and belongs to the
        // direction it was captured in.
        flush_deframers(link, received, packet);
        link.hint = hint;
        if (link.restart_at) return;  // those bytes come again, after the change (pump)
    }
    DeframeEvents events;
    if (link.framing == Framing::Ascii) {
        if (!link.ascii)
            link.ascii = std::make_unique<AsciiDeframer>(AsciiDeframer::Options{
                .inter_char_timeout = std::chrono::seconds(1), .character_time = link.line.character_time()});
        link.ascii->feed(bytes, received, events);
    } else if (received.count()) {
        if (!link.timed) link.timed = std::make_unique<RtuTimedDeframer>(link.line);
        // a direction change ends the frame in progress: close it before these bytes
        link.timed->advance(received - link.line.character_time() * static_cast<std::int64_t>(bytes.size()),
                            events);
        link.timed->feed(bytes, received, events);
    } else {
        if (!link.untimed) link.untimed = std::make_unique<RtuDeframer>();
        link.untimed->feed(bytes, events);
    }
    serial_events(link, events, received, packet);
}

void Analyzer::pump(SerialLink& link) {
    while (link.next_chunk < link.chunks.size()) {
        const std::size_t skip = std::exchange(link.next_skip, 0);
        const SerialLink::Chunk& c = link.chunks[link.next_chunk++];  // nothing is added while it is read
        if (c.close)
            flush_deframers(link, c.received, c.packet);
        else
            deframe(link, std::span<const std::uint8_t>(c.bytes).subspan(skip), c.received, c.hint, c.packet,
                    c.offset + skip);
        if (link.restart_at) restart(link);
    }
    // A chunk goes once its bytes are all in reported records, or far enough behind that no deframer holds
    // any of them (a timed RTU deframer keeps at most 1,024 bytes without a silence, an ASCII one a frame of
    // 513 characters; noise between frames is only counted): a line of noise keeps no more than that.
    constexpr std::uint64_t held_at_most = 4096;
    while (link.next_chunk > 0) {
        const auto end = link.chunks.front().offset + link.chunks.front().bytes.size();
        if (end > link.settled && end + held_at_most > link.fed) break;
        link.chunks.pop_front();
        --link.next_chunk;
    }
}

void Analyzer::restart(SerialLink& link) {
    const std::uint64_t at = *std::exchange(link.restart_at, std::nullopt);
    link.last_received = Timestamp{0};  // the chunks from `at` come again, in their times
    link.untimed.reset();
    link.timed.reset();
    link.ascii.reset();
    link.base = at;
    // From the first chunk with bytes at or after `at` (the chunks from the settled offset on are kept, and
    // `at` ends the last frame reported).
    std::size_t i = 0;
    while (i < link.chunks.size() &&
           (link.chunks[i].close ? link.chunks[i].offset < at
                                 : link.chunks[i].offset + link.chunks[i].bytes.size() <= at))
        ++i;
    link.next_chunk = i;
    link.next_skip = i < link.chunks.size() && at > link.chunks[i].offset ? at - link.chunks[i].offset : 0;
}

namespace {
// What an ASCII line carries: ':', hex digits (lower case too, a finding but a frame), CR and LF.
bool ascii_line_byte(std::uint8_t b) noexcept {
    return b == ':' || b == '\r' || b == '\n' || (b >= '0' && b <= '9') || (b >= 'A' && b <= 'F') ||
           (b >= 'a' && b <= 'f');
}
}  // namespace

void Analyzer::tell_framing(SerialLink& link, std::span<const std::uint8_t> bytes, bool at_end) {
    // An RTU frame is binary: its unit, function code, CRC and most data bytes fall outside what an ASCII
    // line carries, so a few such bytes tell RTU; noise on an ASCII line is rarer than that before the
    // first good frame. So does a whole frame whose CRC holds and which has such a byte (an ASCII line's
    // noise does not make one): a lone request to a device that never answers (8 bytes, 7 foreign for FC3)
    // is then framed and timed out while the line stays quiet, not when the next bytes come. A line of ASCII
    // characters without a valid frame in its first few hundred bytes is read as RTU too (and then reported
    // as unparsed, not dropped).
    constexpr std::size_t foreign_for_rtu = 8;
    constexpr std::uint64_t bytes_to_tell = 600;  // above the longest ASCII frame (513 characters)
    // Whichever the stream shows first: the end of a frame with a valid LRC, of one with a valid CRC and a
    // foreign byte, or the foreign byte that makes the count.
    DeframeEvents events;
    link.probe->feed(bytes, events);
    if (at_end) link.probe->finish(events);
    std::optional<std::uint64_t> ascii_at, rtu_at;
    for (const auto& e : events)
        if (const auto* f = std::get_if<Frame>(&e); f && f->checksum_ok && !ascii_at)
            ascii_at = f->offset + f->wire_length;
    events.clear();
    link.rtu_probe->feed(bytes, events);
    if (at_end) link.rtu_probe->finish(events);
    for (const auto& e : events)
        if (const auto* f = std::get_if<Frame>(&e);
            f && f->checksum_ok && !rtu_at && !std::ranges::all_of(f->adu(), ascii_line_byte))
            rtu_at = f->offset + f->wire_length;
    const std::uint64_t start = link.fed - bytes.size();
    for (std::size_t i = 0; i < bytes.size(); ++i)
        if (!ascii_line_byte(bytes[i]) && ++link.foreign == foreign_for_rtu &&
            (!rtu_at || start + i + 1 < *rtu_at))
            rtu_at = start + i + 1;
    if (ascii_at && (!rtu_at || *ascii_at <= *rtu_at))
        link.framing = Framing::Ascii;
    else if (rtu_at || link.fed >= bytes_to_tell || at_end)
        link.framing = Framing::Rtu;
    if (link.framing) {
        link.read_as.push_back(*link.framing);
        link.framing_told = true;
        link.probe.reset();
        link.rtu_probe.reset();
    }
}

std::optional<std::string> Analyzer::follow_broadcast(Flow& flow, const FrameRecord& r) {
    SerialLink* line = serial_line_of(flow.link.str(), flow.carrier);
    if (!options_.semantics || !r.pdu || !line) return std::nullopt;
    SerialLink& link = *line;
    // Every device on the line takes it whose manual allows the function in broadcast: those that answered
    // on it, or before any did, the device every unit is described as (--profile).
    std::vector<std::uint8_t> units = link.answered;
    if (units.empty()) units.push_back(0);
    std::string who, written, now, ids, line_said;
    for (const std::uint8_t unit : units) {
        const Profile* profile = options_.semantics->profile_for(flow.server, unit);
        if (!profile) continue;
        DeviceStats* stats = nullptr;
        const std::string& device = unit == 0 ? r.device.str() : device_of(flow, unit, stats).str();
        auto told = options_.semantics->follow_broadcast_line_settings(device, *profile, *r.pdu);
        if (!told) continue;
        line_said =
            follow_line(link, unit, told->settings, profile->line, r.frame.offset + r.frame.wire_length);
        if (unit != 0) who += (who.empty() ? "" : ", ") + std::to_string(unit);
        if (written.empty()) {
            written = told->written;
            now = told->now;
        }
        if (ids.find(profile->id) == std::string::npos) ids += (ids.empty() ? "" : ", ") + profile->id;
    }
    if (written.empty()) return std::nullopt;
    const bool several = who.find(',') != std::string::npos;
    return written + " broadcast: " + (who.empty() ? "the devices" : (several ? "units " : "unit ") + who) +
           (several || who.empty() ? " talk " : " talks ") + now + " from now on (" + ids +
           "'s manual); a master that keeps the old settings no longer reaches " +
           (several || who.empty() ? "them" : "it") + line_said;
}

std::string Analyzer::follow_line(SerialLink& link, std::uint8_t unit, const LineState& told,
                                  const LineRules& rules, std::uint64_t at) {
    if (!link.keeps_chunks || !link.framing) return {};
    LineState& own = link.told[unit];
    if (told.framing) own.framing = told.framing;
    if (told.baud) own.baud = told.baud;
    if (told.parity) own.parity = told.parity;
    const Framing framing = own.framing.value_or(*link.framing);
    SerialLine line = link.line;
    line.baud = own.baud.value_or(line.baud);
    line.parity = own.parity.value_or(line.parity);
    if (framing == *link.framing && line.baud == link.line.baud && line.parity == link.line.parity) return {};
    std::string behind;
    for (const std::uint8_t other : link.answered) {
        if (other == unit) continue;
        const auto it = link.told.find(other);
        const LineState held = it == link.told.end() ? LineState{} : it->second;
        if (held.framing.value_or(*link.framing) != framing ||
            held.baud.value_or(link.line.baud) != line.baud ||
            held.parity.value_or(link.line.parity) != line.parity)
            behind += (behind.empty() ? "" : ", ") + std::to_string(other);
    }
    const bool speed = own.baud || own.parity;  // said when the speed or parity changes
    if (!behind.empty())
        return "; the line is still read as " + settings_text(*link.framing, link.line, speed) + ": unit" +
               (behind.find(',') == std::string::npos ? " " : "s ") + behind +
               ", which answered on it, was not told the same";
    if (framing != *link.framing) link.read_as.push_back(framing);
    link.framing = framing;
    link.line = rules.character_for(framing, line);
    link.restart_at = at;
    return "; the line is read as " + settings_text(framing, link.line, speed) + " from here on";
}

bool Analyzer::first_told(int linktype) {
    // Asked for every packet of such a file: a look through a list of a few, nothing copied.
    if (std::any_of(told_links_.begin(), told_links_.end(),
                    [&](const auto& told) { return told.second == linktype && told.first == source_.str(); }))
        return false;
    told_links_.emplace_back(source_.str(), linktype);
    return true;
}

void Analyzer::user_dlt_packet(const Packet& p) {
    if (!options_.user_dlt) {
        // USER0..15 are private: without --user-dlt nothing says the bytes are Modbus. Said once a file.
        if (first_told(p.linktype)) {
            input_error(source_ + ": link type " + std::to_string(p.linktype) + " (USER" +
                        std::to_string(p.linktype - link_user0) +
                        ") is private; --user-dlt rtu|ascii|serial says what it carries");
        }
        return;
    }
    // Each record is a chunk of the line as the sniffer read it, stamped when its last byte arrived.
    auto bytes = p.data;
    Direction hint = Direction::Unknown;
    if (options_.user_dlt_direction) {
        if (bytes.empty()) {
            input_error(source_ + ": packet " + std::to_string(p.number) +
                        ": empty record where a direction byte was expected (--user-dlt " +
                        (*options_.user_dlt ? std::string(to_string(**options_.user_dlt)) : "serial") +
                        "-dir)");
            return;
        }
        if (bytes[0] == static_cast<std::uint8_t>(UserDltDirection::MasterToSlave)) hint = Direction::Request;
        if (bytes[0] == static_cast<std::uint8_t>(UserDltDirection::SlaveToMaster))
            hint = Direction::Response;
        bytes = bytes.subspan(1);
    }
    serial_bytes(serial_link(source_), *options_.user_dlt, bytes, p.time, hint, p.number);
}

void Analyzer::exported_pdu(const Packet& p) {
    const auto record = parse_exported_pdu(p.data);
    if (!record) return;  // not an exported PDU we can follow: nothing says it is Modbus either
    std::optional<Framing> framing;
    if (record->dissector == "mbrtu") framing = Framing::Rtu;
    if (record->dissector == "mbtcp" || record->dissector == "mbudp") framing = Framing::Tcp;
    if (!framing || record->pdu.empty()) return;  // another protocol's PDU

    // Addresses and ports, when exported, give the link and the direction (as flows do); otherwise the
    // file is one link and the request → response state machine decides.
    Direction hint = Direction::Unknown;
    std::string key = "exported " + source_, link = key, server = key;
    if (record->source && record->destination) {
        const Endpoint& src = *record->source;
        const Endpoint& dst = *record->destination;
        const bool to_server = server_port(Transport::Tcp, dst.port) || server_port(Transport::Udp, dst.port);
        const bool from_server =
            server_port(Transport::Tcp, src.port) || server_port(Transport::Udp, src.port);
        if (to_server || from_server) {
            hint = to_server ? Direction::Request : Direction::Response;
            const Endpoint& client = to_server ? src : dst;
            server = (to_server ? dst : src).to_string();
            link = client.to_string() + " -> " + server;
            key = "exported " + link;
        }
    }
    SerialLink& l = serial_link(key, link, server, Carrier::ExportedPdu);
    l.hint = hint;
    DeframeEvents events;
    if (*framing == Framing::Rtu) {
        // One RTU frame a record: the exporter already knew where it ends.
        auto frame = decode_rtu(record->pdu);
        if (frame) {
            frame->offset = l.offset;
            frame->end = p.time;
            events.emplace_back(std::move(frame.value()));
        } else {
            events.emplace_back(Unparsed{
                l.offset, static_cast<std::uint32_t>(record->pdu.size()),
                frame.error().code == ErrorCode::TooLong ? UnparsedReason::TooLong : UnparsedReason::TooShort,
                p.time});
        }
    } else {
        TcpStreamDeframer one;  // a record holds whole ADUs (Wireshark exports after reassembly)
        one.feed(record->pdu, p.time, events);
        one.finish(events);
        shift_offsets(events, l.offset);
    }
    l.offset += record->pdu.size();
    serial_events(l, events, p.time, p.number);
}

void Analyzer::rtac_packet(const Packet& p) {
    const auto r = parse_rtac_serial(p.data);
    if (!r) {
        input_error(source_ + ": packet " + std::to_string(p.number) + ": RTAC serial record of " +
                    std::to_string(p.data.size()) + " bytes is shorter than its 12-byte header");
        return;
    }
    SerialLink& link = serial_link(source_);
    const Timestamp t = r->arrived.count() ? r->arrived : p.time;
    if (t > now_) now_ = t;
    const auto event = static_cast<RtacEvent>(r->event);
    const auto finding = [&](FindingCode code, const std::string& message) {
        FrameRecord about;
        about.time = t;
        about.source = source_;
        about.link = link.flow->link;
        about.packet = p.number;
        report(code, about, message);
    };
    // TX is what the RTAC sent: requests when it is the master on the port. Without --rtac-role the
    // direction is left to the state machine, but a change of side still ends the frame on the line.
    Direction hint = link.hint;
    const bool tx = event == RtacEvent::TxStart || event == RtacEvent::TxEnd;
    const bool rx = event == RtacEvent::RxStart || event == RtacEvent::RxEnd;
    if (tx || rx) {
        const int side = tx ? 0 : 1;
        if (options_.rtac_tx)
            hint = tx ? *options_.rtac_tx
                      : (*options_.rtac_tx == Direction::Request ? Direction::Response : Direction::Request);
        if (link.rtac_side != side && link.rtac_side != -1) close_frames(link, t, p.number);
        link.rtac_side = side;
    }
    switch (event) {
        case RtacEvent::FramingError:
        case RtacEvent::ParityError:
        case RtacEvent::Break:
        case RtacEvent::Overflow:
            finding(FindingCode::StreamLineError,
                    "the RTAC's UART reported " + std::string(to_string(event)) +
                        (link.rtac_side == 0   ? " while sending"
                         : link.rtac_side == 1 ? " while receiving"
                                               : "") +
                        "; the frame around it may be damaged (check baud rate, parity and wiring)");
            break;
        case RtacEvent::DataLost:
            finding(FindingCode::StreamGap,
                    "the RTAC lost captured data (CAPTURE_DATA_LOST): frames around it may be incomplete");
            close_frames(link, t, p.number);
            break;
        default:
            break;
    }
    if (!r->payload.empty()) serial_bytes(link, options_.serial_framing, r->payload, t, hint, p.number);
    // The UART says the message is over: the frame on the line is complete.
    if (event == RtacEvent::TxEnd || event == RtacEvent::RxEnd) close_frames(link, t, p.number);
}

bool Analyzer::read_capture(CaptureSource& capture) {
    set_source(capture.name());  // once, not a comparison of names for every packet
    bool any = false;
    while (auto p = capture.next()) {
        any = true;
        packet_in_source(*p);
        if (options_.progress && p->number % packets_between_progress == 0)
            options_.progress(summary_, capture.offset());
    }
    if (!capture.error().empty()) {
        input_error(capture.error());
        return false;
    }
    // A file header and nothing after it: a tap that recorded nothing is not a quiet network, as an empty
    // serial dump is not a quiet line.
    if (!any) {
        input_error(capture.name() + ": the capture holds no packets, nothing to decode");
        return false;
    }
    return true;
}

bool Analyzer::read_capture(CaptureMerge& captures) {
    const std::string* source = nullptr;
    std::uint64_t count = 0;
    while (auto p = captures.next()) {
        if (&captures.name() != source) {  // the files' names stay where they are: a pointer tells a change
            source = &captures.name();
            set_source(*source);
        }
        packet_in_source(*p);
        if (options_.progress && ++count % packets_between_progress == 0)
            options_.progress(summary_, captures.offset());
    }
    for (const auto& e : captures.errors())
        input_error(e);
    return captures.errors().empty();
}

bool Analyzer::read_capture(const std::string& path, const std::string& name) {
    std::string error;
    auto capture = CaptureSource::open_file(path, error, name);
    if (!capture) {
        input_error(error);
        return false;
    }
    return read_capture(*capture);
}

namespace {

void list_or_count(std::vector<std::string>& listed, std::uint64_t& unlisted, const std::string& message) {
    if (listed.size() < Analyzer::max_listed_input_errors)
        listed.push_back(modbus::printable(message));
    else
        ++unlisted;
}

}  // namespace

void Analyzer::input_error(const std::string& message) {
    list_or_count(summary_.input_errors, summary_.input_errors_unlisted, message);
}

void Analyzer::input_note(const std::string& message) {
    list_or_count(summary_.input_notes, summary_.input_notes_unlisted, message);
}

void Analyzer::close_streams(Flow& f, Timestamp t, int only) {
    for (int dir = 0; dir < 2; ++dir) {
        if (only >= 0 && dir != only) continue;
        f.reassembler[dir]->flush(t);
        // Bytes still held are settled with the first stream that ends (a client's reset ends only its
        // own, but the probe reads the connection): the other's come after them, as they came.
        settle_framing(f, t);
        DeframeEvents events;
        if (!f.rtu_over_tcp && f.reading == Flow::Reading::Rtu) {
            report_not_decoded(f, dir);
            continue;
        }
        if (f.rtu_over_tcp) {
            f.rtu_deframer[dir].finish(events);
            shift_offsets(events, f.rtu_lost[dir]);
            deframed(f, dir == 0, events, t);
            continue;
        }
        f.deframer[dir].finish(events);
        deframed(f, dir == 0, events, t);
    }
}

void Analyzer::give_up_waiting(Flow& f, Timestamp t, const std::string& how) {
    settle_framing(f, t);  // requests still held are waiting too
    f.client_reset = false;
    if (!f.pending) return;
    std::vector<Pending> waiting;
    for (auto it = pending_.begin(); it != pending_.end();) {
        if (it->first.flow != f.id) {
            ++it;
            continue;
        }
        waiting.push_back(std::move(it->second));
        it = pending_.erase(it);
    }
    for (auto it = reused_.begin(); it != reused_.end();) {
        if (it->first.flow != f.id) {
            ++it;
            continue;
        }
        for (Pending& p : it->second)
            waiting.push_back(std::move(p));
        it = reused_.erase(it);
    }
    f.pending = 0;
    std::sort(waiting.begin(), waiting.end(),
              [](const Pending& a, const Pending& b) { return a.serial < b.serial; });
    for (Pending& p : waiting) {
        if (auto why = not_the_servers(p))
            give_up(p, false, std::move(*why));
        else
            give_up(p, true,
                    {FindingCode::PairNoResponse, no_response_message(p.request, "before " + how, t)});
    }
}

std::optional<Analyzer::Unanswered> Analyzer::not_the_servers(const Pending& p) const {
    if (p.reply_gap)
        return Unanswered{FindingCode::PairResponseNotCaptured,
                          describe_request(p.request) + " to " + p.request.device.str() +
                              " got no reply the capture holds, but " + std::to_string(p.reply_gap) +
                              " bytes of the response stream that the capture lacks went by while it waited: "
                              "its reply may be among them"};
    if (p.client_reset)
        return Unanswered{
            FindingCode::PairClientAborted,
            describe_request(p.request) + " to " + p.request.device.str() +
                ": the client reset the connection before a whole reply came, and none came after: "
                "the client gave up on it, no timeout of the device's"};
    return std::nullopt;
}

void Analyzer::client_reset(Flow& f, Timestamp t) {
    settle_framing(f, t);  // requests still held wait for their replies as the others do
    // The streams end as at any reset (what they left unfinished reported, the next connection started
    // afresh), but a reply the server sent before the reset reached it still comes, after the reset in the
    // capture, and answers its request (tshark pairs it): the requests wait for it, to their timeout, a new
    // SYN or the server's own reset. Given up at once, the request was the server's timeout and its reply,
    // a millisecond later, unsolicited.
    // Only the client's stream ends: the server's goes on at its own sequence numbers, and a reply it
    // sent in several segments, some after the reset in the capture, is still one reply (restarting it
    // cut the reply in two, "truncated" and "before the first header").
    // A connection found to carry RTU frames has no requests waiting (none was decoded), but the server's
    // stream goes on as RTU: only the client's ends.
    if (!f.pending && f.reading != Flow::Reading::Rtu)
        return end_connection(f, t, "the client reset the connection");
    for (auto& [k, p] : pending_)
        if (k.flow == f.id) p.client_reset = true;
    for (auto& [k, older] : reused_)
        if (k.flow == f.id)
            for (Pending& p : older)
                p.client_reset = true;
    close_streams(f, t, 0);
    restart_streams(f, 0);
    f.client_reset = true;
}

void Analyzer::end_connection(Flow& f, Timestamp t, const std::string& how) {
    // What the connection left unfinished is reported now, at its end; the next connection on the same
    // addresses and ports starts at stream offset 0 with nothing buffered. Before this, a half ADU cut by a
    // reset took the first bytes of the next connection's request into it.
    close_streams(f, t);
    // Its requests still waiting will not be answered: no reply comes on a connection that is gone. Left
    // waiting, they clashed with the next connection's transaction ids (which start over), as duplicates
    // whose timeouts went unreported, or timed out seconds after the reset that ended them.
    give_up_waiting(f, t, how);
    restart_streams(f);
}

void Analyzer::restart_streams(Flow& f, int only) {
    f.first_request_after_gap = 0;
    std::erase_if(cut_requests_, [&f](const auto& entry) { return entry.first.flow == f.id; });
    if (only < 0)
        std::erase_if(timed_out_,
                      [&f](const auto& entry) { return entry.first.flow == f.id; });  // ids start over
    for (int dir = 0; dir < 2; ++dir) {
        if (only >= 0 && dir != only) continue;
        f.reassembler[dir]->reset(TcpReassembler::default_max_buffered);
        f.deframer[dir].reset();
        f.fed[dir].clear();
        f.last_fed_from[dir] = f.last_fed_packet[dir] = 0;
        f.rtu_deframer[dir].reset();
        f.rtu_lost[dir] = 0;
        f.rtu_arrivals[dir].clear();
    }
    // A new connection is probed afresh; after a client's reset the server's stream goes on, and so does
    // the framing found for it.
    if (only < 0) {
        f.reading = Flow::Reading::Probing;
        f.probe.reset();
        f.held.clear();
        for (int dir = 0; dir < 2; ++dir) {
            f.not_decoded[dir] = {};
            f.not_decoded_next[dir] = 0;
        }
    } else {
        f.not_decoded[only] = {};
        f.not_decoded_next[only] = 0;
    }
}

std::vector<Framing> Analyzer::serial_framings_read() const {
    std::vector<Framing> out;
    for (const auto& [key, link] : serial_links_)
        if (!link->read_as.empty() && std::find(out.begin(), out.end(), link->read_as.front()) == out.end())
            out.push_back(link->read_as.front());
    return out;
}

std::optional<SerialLine> Analyzer::serial_line(const std::string& source) const {
    const auto it = serial_links_.find(serial_line_name(source));
    if (it == serial_links_.end()) return std::nullopt;
    return it->second->line;
}

void Analyzer::end_silent_frames(Timestamp now, const std::string* except, bool only_when_due) {
    const SharedText source = source_;
    for (auto& [name, link] : serial_links_) {
        // A timed RTU line holding the start of a frame: its t3.5 of silence has passed by now. (An ASCII
        // frame ends at its LF; a line whose framing is not told yet has no frames to end.)
        if (link->framing != Framing::Rtu || !link->timed || !link->timed->holding() ||
            !link->last_received.count() || now - link->last_received < link->line.t3_5() ||
            (except && link->source == *except))
            continue;
        // A packet of another input says nothing of this line: its next record may carry the rest of the
        // frame with no gap (a reply read in two chunks, the second stamped at its last byte). Only a request
        // on the line about to be timed out at `now` makes the frame end here, so that its reply, if this is
        // it, is paired first. (In a live capture's quiet time the silence is the line's own.)
        const auto waiting = pending_.find({link->flow->id, 0});
        const bool due =
            waiting != pending_.end() && now - waiting->second.request.time >= options_.serial_timeout;
        if (only_when_due && !due) continue;
        // The head of a frame a silence cut, which the deframer holds for its tail (a reply read in two
        // chunks stamped far apart), waits as long as the deframer would, unless a request is due.
        if (!due && now - link->last_received < link->timed->closing_silence()) continue;
        source_ = link->source;
        close_frames(*link, now);
    }
    source_ = source;
}

void Analyzer::idle(Timestamp now) {
    if (now <= now_) return flush_output();
    end_silent_frames(now, nullptr, false);
    now_ = now;
    expire(now_, false);
    flush_output();
}

void Analyzer::finish() {
    ip_fragments_.expire(now_, true);
    summary_.ip_datagrams_incomplete = ip_fragments_.incomplete_datagrams();
    summary_.ip_fragments_incomplete = ip_fragments_.incomplete_fragments();
    summary_.ip_fragments_invalid = ip_fragments_.invalid_fragments();
    for (auto& [key, f] : flows_)
        if (f->carrier == Carrier::Tcp) close_streams(*f, now_);
    for (auto& [name, link] : serial_links_) {
        source_ = link->source;
        if (link->probe) tell_framing(*link, {}, true);
        // A change of line settings in what the deframers give up at the end is followed too: the bytes
        // after it are deframed again, and given up in their turn.
        do {
            if (link->restart_at) restart(*link);
            pump(*link);
            flush_deframers(*link, now_, 0, true);
        } while (link->restart_at);
    }
    for (const auto& [key, link] : serial_links_)
        if (link->flow->carrier == Carrier::Serial && !link->read_as.empty())
            summary_.serial_lines[link->flow->link.str()] = {link->read_as, link->framing_told};
    expire(now_, true);
    for (auto& [key, f] : flows_)
        release_unseen(*f);  // whose they were, as far as the capture shows
    summary_.modbus_like_ports = modbus_like_.tally();
    summary_.rtu_like_ports = modbus_like_.rtu_tally();
    sink_.end(summary_);
}

}  // namespace mbscope::analyzer
