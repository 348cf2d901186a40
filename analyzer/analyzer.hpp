#pragma once
// The analyzer pipeline for network captures: packet → flow → TCP reassembly (or UDP datagram) → deframer →
// frame records → pairing → transactions and findings → sink. Requests are the bytes sent to a server port
// (502 and any --tcp-port); pairing uses a hashed table keyed by (flow, transaction id), bounded and expired
// by capture time, so memory stays flat however long the capture is. Serial gateways' ports
// (--rtu-over-tcp) carry raw RTU frames in the TCP stream instead of MBAP. Serial bytes inside pcap files
// (USER0..15 with --user-dlt, Wireshark exported PDUs, SEL RTAC serial records) go the way of the serial
// captures.

#include <array>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "analyzer/capture_merge.hpp"
#include "analyzer/capture_source.hpp"
#include "analyzer/ip_reassembly.hpp"
#include "analyzer/modbus_like_ports.hpp"
#include "analyzer/packet_parser.hpp"
#include "analyzer/records.hpp"
#include "analyzer/rtu_over_tcp_probe.hpp"
#include "analyzer/semantics.hpp"
#include "analyzer/tcp_reassembler.hpp"
#include "modbus/ascii_deframer.hpp"
#include "modbus/rtu_deframer.hpp"
#include "modbus/tcp_deframer.hpp"

namespace mbscope::analyzer {

// The direction pseudo-header of USER0..15 records with --user-dlt rtu-dir|ascii-dir: one byte ahead of the
// line's bytes (in the manner of LINKTYPE_PPP_WITH_DIR and the other *_WITH_DIR link types).
enum class UserDltDirection : std::uint8_t { MasterToSlave = 0, SlaveToMaster = 1 };

struct AnalyzerOptions {
    std::vector<std::uint16_t> tcp_ports{502};
    std::vector<std::uint16_t> udp_ports{502};
    modbus::Timestamp timeout = std::chrono::seconds(3);  // TCP default (issue 4; profile may override)
    std::size_t max_pending_per_flow = 1024;
    std::shared_ptr<Semantics> semantics;  // device profiles; null: values stay raw
    // Serial lines: framing, character format (t1.5/t3.5 when timestamps are known) and response timeout.
    // No framing: each line's is told from its first bytes (ASCII when a frame with a valid LRC comes
    // before bytes no ASCII line carries, RTU otherwise). A device that acknowledges other line settings
    // (MK PROT, BAUD, PARID) changes its line's from there, once every unit that answered on it has been
    // told the same (the way the reference slave's line follows).
    std::optional<modbus::Framing> serial_framing;
    modbus::SerialLine serial_line{};
    modbus::Timestamp serial_timeout = std::chrono::seconds(1);  // issue 4: 1 s serial default
    // TCP server ports of serial gateways whose streams carry raw RTU frames (no MBAP header).
    std::vector<std::uint16_t> rtu_over_tcp_ports;
    // What link types USER0..USER15 (147-162) carry: they are private by definition, so only the user can
    // say. nullopt: such packets are not decoded (and the input says why once); else serial bytes in the
    // framing held, or, holding none, in the framing the line's bytes tell (--user-dlt serial).
    std::optional<std::optional<modbus::Framing>> user_dlt;
    // USER0..15 records start with a one-byte direction pseudo-header (UserDltDirection), as mbscope sniff
    // writes two serial taps; other values of the byte leave the direction to the state machine.
    bool user_dlt_direction = false;
    // SEL RTAC serial captures (link type 250): what the RTAC's TX bytes are, Request when it is the master
    // on that port, Response when it is the slave; nullopt: the request → response state machine decides.
    std::optional<modbus::Direction> rtac_tx;
    // FC3/FC4 replies of devices without a profile also read as 32-bit values in this order.
    std::optional<modbus::WordOrder> word_order;
    // Called every few hundred packets while a capture file is read, with the summary so far and the byte
    // offset reached in that file (for a progress line); empty: not called.
    std::function<void(const Summary&, std::uint64_t offset)> progress;
};

class Analyzer {
  public:
    Analyzer(AnalyzerOptions options, Sink& sink);
    ~Analyzer();

    void packet(const std::string& source, const Packet& packet);
    // Bytes seen on a half-duplex serial line, in order. `received`: when the chunk's last byte ended (zero
    // when the capture has no timing); `hint`: the direction when the capture knows it (two ports, a
    // direction column), else Unknown and the request → expected-response state machine decides.
    void serial(const std::string& source, std::span<const std::uint8_t> bytes, modbus::Timestamp received,
                modbus::Direction hint = modbus::Direction::Unknown);
    // The bytes of `source` continue the line of `line` (a log written a file an hour, a capture in pieces):
    // one stream, one set of devices named after `line`; records keep `source` as the file they came from.
    void serial_part_of(const std::string& source, const std::string& line);
    // The input `source` ended, and with it its line (not a part that another input continues): what its
    // deframers hold is framed now, as at the end of the capture, and the requests still waiting within
    // their timeout when its last bytes came are unanswered at its end. Without it, the line's last frame
    // waited for the end of every input while the next input's clock ran on: the last request of the
    // first of two logs was timed out by the second's times and its reply, read last, came "late".
    void end_serial(const std::string& source);
    // Nothing was captured up to `now` (a live capture's quiet line or network, by the host's clock): a
    // frame the line's silence has ended is complete, and a request whose timeout has run out is unanswered,
    // said now rather than at the next byte or packet, or at the end as "unanswered when the capture ended".
    // What was decoded so far is then written out (Sink::flush).
    void idle(modbus::Timestamp now);
    // The latest time the input has shown (a packet's, or one idle() was told).
    modbus::Timestamp latest_time() const noexcept { return now_; }
    // What was decoded so far, written out now (Sink::flush): an input that streams has gone quiet.
    void flush_output() { sink_.flush(); }
    // The character a serial source's line is read in now (speed, parity, data and stop bits): the line
    // given, or the one its devices acknowledged since (a live sniffer sets its ports to it). nullopt
    // before the source's first bytes.
    std::optional<modbus::SerialLine> serial_line(const std::string& source) const;
    // Reads a whole capture file; returns false (and records the error in the summary) if it could not be
    // read to its end. Everything before the damage is still analysed. `name` (the path when empty) is what
    // the capture is reported as.
    bool read_capture(const std::string& path, const std::string& name = {});
    bool read_capture(CaptureSource& capture);
    // Several capture files as one capture, merged by time (analyzer/capture_merge.hpp); false (and the
    // errors in the summary) when one of them could not be read to its end.
    bool read_capture(CaptureMerge& captures);
    // An input problem, named with its file and place. Control characters are escaped (messages quote input
    // bytes and end up on terminals). The first max_listed_input_errors are kept; the rest are counted
    // (Summary::input_errors_unlisted): a file read in the wrong format has an error on every line.
    void input_error(const std::string& message);
    // What the input is, read whole, that the results depend on (Summary::input_notes); listed as errors are.
    void input_note(const std::string& message);
    static constexpr std::size_t max_listed_input_errors = 100;
    // How far a reader has got in its file, in bytes: passed on to the progress callback. Readers call it
    // every so many records (finding the offset of a stream is not free).
    void reached(std::uint64_t offset) {
        if (options_.progress) options_.progress(summary_, offset);
    }
    void set_serial_framing(std::optional<modbus::Framing> framing) noexcept {
        options_.serial_framing = framing;
    }
    std::optional<modbus::Framing> serial_framing() const noexcept { return options_.serial_framing; }
    void finish();
    const Summary& summary() const noexcept { return summary_; }
    // The framings the serial lines were first read in (stated, or told from their bytes), each once.
    std::vector<modbus::Framing> serial_framings_read() const;

  private:
    struct Flow;
    struct Pending {
        // made from the request's record (clang 14 has no parenthesised aggregate initialisation)
        Pending(FrameRecord&& r, std::uint64_t s, DeviceStats* d)
            : request(std::move(r)), serial(s), stats(d) {}
        FrameRecord request;
        std::uint64_t serial = 0;
        DeviceStats* stats = nullptr;  // its device's, in the summary
        // On a serial line, the frame of a reply from another unit that came while it waited (no answer to
        // it: see on_response), and that unit; 0 when none.
        std::uint64_t other_unit_reply = 0;
        std::uint8_t other_unit = 0;
        // A damaged request to a unit its link had not shown (no stats yet): its link, until settle_unit
        // decides whose it is; no_device when that found none.
        Flow* unseen_unit_link = nullptr;
        bool no_device = false;
        // Bytes of the response stream the capture lacks that went by while it waited (a gap): its reply may
        // be among them, so no reply is no timeout held against the device (pair.response_not_captured).
        std::uint64_t reply_gap = 0;
        // The client reset the connection while it waited: a reply already on its way still answers it,
        // none is the client's abort, not the server's timeout (pair.client_aborted).
        bool client_reset = false;
    };
    struct PendingKey {
        std::uint64_t flow;
        std::uint16_t tid;
        bool operator==(const PendingKey&) const = default;
    };
    struct PendingHash {
        std::size_t operator()(const PendingKey& k) const noexcept {
            return std::hash<std::uint64_t>()(k.flow * 65536 + k.tid);
        }
    };
    struct Expiry {
        modbus::Timestamp deadline;
        PendingKey key;
        std::uint64_t serial;
    };
    // A request reported unanswered, kept by its key until the key is used again (or many later): a reply
    // that comes for it after all is late, not unsolicited, and is paired with it (its values named, what it
    // acknowledges followed). Bounded, oldest forgotten first.
    struct TimedOut {
        Pending pending;               // the request, a copy of the one its timed-out transaction took
        modbus::Timestamp timeout{0};  // how long it was waited for
        std::string what;              // the request described
        std::uint64_t serial = 0;
        std::uint64_t moved_on_at = 0;  // the frame of the master's next request, when it moved on first
        // Its wait ended by the client's next request on a link without transaction ids (not by its
        // timeout, nor by the link's queue overflowing): the client gave up on it.
        bool given_up_by_client = false;
    };
    static constexpr std::size_t max_timed_out = 4096;

    // The flow of a packet by its binary addresses, packed in five words (both addresses, then ports, the
    // IPv6 flags and the transport): finding a packet's flow must not cost formatting endpoints as text.
    struct FlowKey {
        std::uint64_t words[5];
        bool operator==(const FlowKey& o) const noexcept {  // word by word: not a call to memcmp
            return ((words[0] ^ o.words[0]) | (words[1] ^ o.words[1]) | (words[2] ^ o.words[2]) |
                    (words[3] ^ o.words[3]) | (words[4] ^ o.words[4])) == 0;
        }
    };
    struct FlowKeyHash {
        std::size_t operator()(const FlowKey& k) const noexcept;
    };
    static FlowKey flow_key(Transport transport, const Endpoint& client, const Endpoint& server);
    bool server_port(Transport transport, std::uint16_t port) const;
    // Both of a packet's ports are server ports (a client that bound 502 as its own port, as some PLCs and
    // gateways do): whether its sender is the client, or nullopt while nothing has told yet.
    std::optional<bool> sent_by_client(const L4Packet& l4);
    Flow& flow_for(const L4Packet& l4, bool to_server);
    void stream_bytes(Flow& flow, int dir, std::span<const std::uint8_t> bytes, modbus::Timestamp t);
    // A Modbus/TCP stream's bytes to its MBAP deframer, `packet` the one that carried them.
    void feed_mbap(Flow& flow, int dir, std::span<const std::uint8_t> bytes, modbus::Timestamp t,
                   std::uint64_t packet);
    // The end of a connection's probing (Flow::held): the probe's verdict (settled on what it has read when
    // it has none yet), and the bytes held fed or reported accordingly. `t`: the time of what ended it.
    void settle_framing(Flow& flow, modbus::Timestamp t);
    // A connection found to carry RTU: `length` more bytes of direction `dir`, not decoded; and the run
    // gathered so far reported (an unparsed record and its finding).
    void not_decoded(Flow& flow, int dir, std::size_t length, modbus::Timestamp t, std::uint64_t packet);
    void report_not_decoded(Flow& flow, int dir);
    FrameRecord about_stream(const Flow& flow, modbus::Timestamp t) const;
    void stream_gap(Flow& flow, int dir, std::uint64_t missing, modbus::Timestamp t);
    // Both directions' buffered bytes (or direction `only`'s) delivered and deframed to the end (at the end
    // of the capture).
    void close_streams(Flow& flow, modbus::Timestamp t, int only = -1);
    // A connection reset, or replaced by a new one on the same addresses and ports: its streams closed,
    // its requests still waiting given up (`how` it ended, after "before"), then started afresh.
    void end_connection(Flow& flow, modbus::Timestamp t, const std::string& how);
    // The streams started afresh for the next connection (after close_streams): nothing buffered, transaction
    // ids free again. With `only`, that direction's stream alone (the client's, at its reset), the ids kept.
    void restart_streams(Flow& flow, int only = -1);
    // The flow's requests still waiting will not be answered (`how`, after "before"): each a timeout.
    void give_up_waiting(Flow& flow, modbus::Timestamp t, const std::string& how);
    void retransmission_conflict(Flow& flow, int dir, std::uint64_t at, std::size_t differing,
                                 modbus::Timestamp t);
    // `packet`: the packet that carried the bytes (0: the one being read).
    void deframed(Flow& flow, bool to_server, modbus::DeframeEvents& events, modbus::Timestamp t,
                  std::uint64_t packet = 0);
    // The client reset the connection: its streams end as at end_connection, but its requests still wait
    // (Pending::client_reset) for a reply the server sent before the reset reached it.
    void client_reset(Flow& flow, modbus::Timestamp t);
    // Records pass by reference down the pipeline (a frame record is over 500 bytes): the request is moved
    // once into the pending table, and both frames once into their transaction.
    // A frame of `flow` from or to `unit`: named by its device, decoded, judged (on_frame).
    void decode_and_judge(Flow& flow, FrameRecord& record, std::uint8_t unit);
    void on_frame(Flow& flow, FrameRecord& record, DeviceStats* stats);  // null: no device's
    struct SerialLink;
    SerialLink& serial_link(const std::string& key, const std::string& link, const std::string& server,
                            Carrier carrier);
    SerialLink& serial_link(const std::string& source);
    // The serial line a record's link names; null for other carriers.
    SerialLink* serial_line_of(const std::string& link, Carrier carrier);
    // A chunk of the line: to the link's deframers at once, or through its kept chunks (pump) when its
    // framing is not known yet or may change. `framing`: the line's, when the input fixes it.
    void serial_bytes(SerialLink& link, std::optional<modbus::Framing> framing,
                      std::span<const std::uint8_t> bytes, modbus::Timestamp received, modbus::Direction hint,
                      std::uint64_t packet = 0);
    // The frame on the line is over (a direction change, the UART's end of message): in order with the
    // chunks around it.
    void close_frames(SerialLink& link, modbus::Timestamp t, std::uint64_t packet = 0);
    // Ends the frame in progress, at its own time, on every timed RTU line whose t3.5 of silence has passed
    // by `now`, but the line of the source named `except` (whose bytes at `now` are still to come), and with
    // `only_when_due` only on lines whose request is about to be timed out at `now`: before requests are
    // timed out, a reply held for the silence after it until the line's next bytes, more than a timeout
    // later, was a timeout and then a late reply.
    void end_silent_frames(modbus::Timestamp now, const std::string* except, bool only_when_due);
    void deframe(SerialLink& link, std::span<const std::uint8_t> bytes, modbus::Timestamp received,
                 modbus::Direction hint, std::uint64_t packet, std::uint64_t offset);
    // `input_ended`: at the end of the input, where a frame is cut rather than ended by a silence.
    void flush_deframers(SerialLink& link, modbus::Timestamp t, std::uint64_t packet,
                         bool input_ended = false);
    // The kept chunks not yet deframed, to the deframers; after a change of line settings, again from the
    // change on.
    void pump(SerialLink& link);
    void restart(SerialLink& link);
    void tell_framing(SerialLink& link, std::span<const std::uint8_t> bytes, bool at_end);
    // A broadcast write of line settings, taken by the devices on the line whose manuals allow it: the
    // note's message, or nullopt.
    std::optional<std::string> follow_broadcast(Flow& flow, const FrameRecord& request);
    // A unit on a serial link acknowledged other line settings (the response ending at stream offset `at`):
    // what the capture does about it, as the end of the note's sentence.
    std::string follow_line(SerialLink& link, std::uint8_t unit, const modbus::LineState& told,
                            const modbus::LineRules& rules, std::uint64_t at);
    void serial_events(SerialLink& link, modbus::DeframeEvents& events, modbus::Timestamp t,
                       std::uint64_t packet = 0);
    void user_dlt_packet(const Packet& packet);
    void exported_pdu(const Packet& packet);
    void rtac_packet(const Packet& packet);
    modbus::Direction classify(const Flow& flow, const modbus::Frame& frame) const;
    void on_request(Flow& flow, FrameRecord& record, DeviceStats* stats);
    // Over Modbus/TCP, `record` carries the transaction id of `newest`, still waiting: said (a warning, the
    // client's doing), and the oldest with the id given up when too many wait with it.
    void transaction_id_reused(Flow& flow, const Pending& newest, const FrameRecord& record);
    // RTU over TCP: whether `later` began in the segment that completed `waiting`, the client writing both at
    // once (pipelined) rather than giving up on `waiting` and moving on.
    bool sent_with(const Flow& flow, const FrameRecord& waiting, const FrameRecord& later) const;
    bool settle_unit(Pending& pending);
    void release_unseen(Flow& flow);
    void on_response(Flow& flow, FrameRecord& record);
    // Why a request is given up without a response: the finding about it, which its transaction carries.
    struct Unanswered {
        modbus::FindingCode code;
        std::string message;
        bool only_other_unit =
            false;  // only another unit replied while it waited (Pending::other_unit_reply)
    };
    // `late`: the response came after the request's timeout, which was reported and counted already.
    // `unanswered`: there is no response, and this is why.
    void complete(Pending& pending, FrameRecord* response, bool timed_out, const TimedOut* late = nullptr,
                  Unanswered* unanswered = nullptr);
    // An ASCII run of characters that formed no frame (a bad character, an odd number of digits, a pause or a
    // new ':' inside it) but begins with the unit and function code of the request waiting on its line is
    // that request's reply, damaged on the way (pair.response_damaged): answered, not a timeout held against
    // the device, as a reply whose LRC fails for the same noise on another character is.
    // `sides_unknown`: the capture does not tell which side sent the characters.
    bool damaged_reply(Flow& f, const modbus::Unparsed& u, modbus::Timestamp t, bool sides_unknown);
    // The request will not be answered: counted as a timeout (`timed_out`) or as unanswered at the end, and
    // reported with its transaction.
    void give_up(Pending& pending, bool timed_out, Unanswered unanswered) {
        complete(pending, nullptr, timed_out, nullptr, &unanswered);
    }
    // Why a request that got no reply got none, when the capture or the client is the reason rather than the
    // server: a reply may be in a gap of the response stream, or the client reset the connection.
    std::optional<Unanswered> not_the_servers(const Pending& pending) const;
    std::optional<Unanswered> reply_cut_by_the_end(const Pending& pending, const Flow& flow) const;
    // Counts and finds what a request and its response (or its absence) show; with `made`, fills the
    // transaction record and gives it to the sink before the findings.
    void judge(const FrameRecord& request, const FrameRecord* response, DeviceStats& stats, bool timed_out,
               const TimedOut* late, Unanswered* unanswered, TransactionRecord* made);
    void expire(modbus::Timestamp now, bool at_end);
    // A due request whose reply may wait behind a hole in its response stream (bytes captured by its
    // deadline are held there): not timed out until the hole fills or is given up.
    bool reply_may_wait_behind_hole(const Expiry& e, const Flow& flow);
    Flow* flow_of(std::uint64_t id) const;
    void release_held_expiries(bool at_end);
    // A reply `r` on `flow` captured after the deadline of a held request it may answer: that request timed
    // out first, and the reply is late (the hole held a reply in time for another request, not for it).
    void time_out_held_before(const Flow& flow, const FrameRecord& r);
    void time_out(const Expiry& e, bool at_end);
    // Keyed by late_id: the transaction id, or on a serial line the unit.
    void remember_timed_out(const PendingKey& key, Pending& pending, modbus::Timestamp timeout,
                            std::string what, std::uint64_t moved_on_at = 0, bool given_up_by_client = false);
    // The timed-out request a response answers late, when there is one; it is forgotten then.
    std::optional<TimedOut> late_for(const PendingKey& key);
    // A packet or a serial chunk (`where`) stamped well before the latest time seen: the capture's clock was
    // set back.
    // Time going from `from` back to `to` by more than the longer pairing timeout: not coarse or jittery
    // stamps, the clock itself stepped back.
    bool clock_stepped_back(modbus::Timestamp from, modbus::Timestamp to, bool serial = false) const;
    void clock_went_back(modbus::Timestamp to, const std::string& where);
    void report(modbus::FindingCode code, const FrameRecord& about, std::string message,
                std::vector<std::uint64_t> frames = {});
    void count_finding(modbus::FindingCode code);

    AnalyzerOptions options_;
    Sink& sink_;
    const bool sink_wants_transactions_;
    Summary summary_;
    const SharedText& device_of(Flow& flow, std::uint8_t unit, DeviceStats*& stats);
    void set_source(const std::string& source);
    void packet_in_source(const Packet& packet);  // packet() from the source set last

    std::map<std::string, std::unique_ptr<Flow>> flows_;  // owner, in a stable order for the end
    std::unordered_map<FlowKey, Flow*, FlowKeyHash> flow_index_;
    std::vector<Flow*> flow_by_id_;  // [id - 1]: ids are given in order and flows never leave
    // Of the pairs of endpoints whose ports are both server ports, the ones the analyzer has told the client
    // of (sent_by_client): keyed client first.
    std::unordered_set<FlowKey, FlowKeyHash> told_clients_;
    ModbusLikePorts modbus_like_;  // ADUs on ports not decoded, for the summary's hint
    // Connections whose first bytes are held while their framing is told (Flow::held), settled at the
    // latest when the first held could time out; and whether held bytes are being fed (settle_framing).
    std::vector<Flow*> probing_;
    bool replaying_ = false;
    IpReassembler ip_fragments_;
    // In front of the index: a direct-mapped cache by the hash's top bits, so that a packet of a known flow
    // costs a hash and a compare, not the index's division by a prime and its node (the index's lookup was
    // the largest single item of a summary run).
    struct FlowCacheEntry {
        FlowKey key{};
        Flow* flow = nullptr;
    };
    std::array<FlowCacheEntry, 64> flow_cache_{};
    std::map<std::string, std::unique_ptr<SerialLink>> serial_links_;
    std::map<std::string, std::string> serial_parts_;  // source → the line it continues (serial_part_of)
    std::unordered_map<PendingKey, Pending, PendingHash> pending_;
    // Over Modbus/TCP, requests still waiting whose transaction id a later request on the link reused, oldest
    // first (the newest with the id is in pending_). Clients that number every request alike exist; a server
    // answers them in turn, so each keeps waiting for its own reply (take_pending, on_response). On RTU over
    // TCP, which has no ids, the requests a gateway has queued before the newest.
    std::unordered_map<PendingKey, std::deque<Pending>, PendingHash> reused_;
    static constexpr std::size_t max_reused_per_id = 16;
    // The waiting request with this key and serial, from pending_ or reused_; nullptr when answered or given
    // up meanwhile.
    Pending* find_pending(const PendingKey& key, std::uint64_t serial);
    // The oldest request waiting with this key that `fits` (those that reused its id first, then the newest);
    // nullptr when none does.
    template <typename Fits>
    Pending* oldest_waiting(const PendingKey& key, Fits fits);
    // Takes it out; when it was the newest with its key, the one before it (reused_) takes its place. `key`
    // is a copy: it may name the entry erased.
    std::optional<Pending> take_pending(PendingKey key, std::uint64_t serial);
    // An ADU cut by a gap in its stream (a record cut to the snapshot length), as far as its MBAP header
    // tells: the transaction it belongs to, how long it is and how much of it the capture holds.
    struct CutAdu {
        std::uint16_t tid = 0;
        // nullopt when the cut kept the header only up to the length (unit) or the unit (function).
        std::optional<std::uint8_t> unit;
        std::optional<std::uint8_t> function;  // without the exception bit
        // Whether a frame or request with this unit and function (exception bit ignored) is the one cut.
        bool names(std::uint8_t unit_id, std::uint8_t function_code) const noexcept {
            return (!unit || *unit == unit_id) && (!function || *function == (function_code & 0x7F));
        }
        std::size_t captured = 0;
        std::size_t length = 0;
        bool snapshot_length = false;  // the gap is a packet's bytes past the capture's snapshot length
    };
    static std::optional<CutAdu> cut_adu(std::span<const std::uint8_t> incomplete, bool snapshot_length);
    // The request a cut reply answers is given up as answered, its values unknown (not a timeout).
    void reply_cut(Flow& flow, const CutAdu& cut, modbus::Timestamp t);
    // RTU over TCP: a hole of `missing` bytes in the gateway's stream right after bytes that formed no frame
    // and begin with a waiting request's unit and function code cut that request's reply. It is given up as
    // answered, its values unknown (pair.response_not_captured, as a cut MBAP reply is), not a timeout held
    // against the device.
    void rtu_reply_cut(Flow& flow, std::uint64_t missing);
    // Requests cut by a gap, by flow and transaction id: a reply to one is not unsolicited. Bounded.
    std::unordered_map<PendingKey, CutAdu, PendingHash> cut_requests_;
    static constexpr std::size_t max_cut_requests = 1024;
    // Requests by deadline, one queue per timeout: each is then in deadline order, and a serial request (1 s)
    // is not held up behind a Modbus/TCP one (3 s) sent before it. Requests without a time stamp (raw
    // dumps) wait in a queue of their own: they end only when the master moves on, or the capture.
    enum ExpiryQueue : std::uint8_t { tcp_timeout, serial_timeout, untimed };
    std::array<std::deque<Expiry>, 3> expiries_;
    std::size_t expiry_entries_ = 0;  // in all three queues and held_expiries_
    // Due, but held by reply_may_wait_behind_hole(), with the queue each goes back to and its flow (flows
    // are never removed: looked up by id for every held entry at every packet, the flows made it quadratic).
    struct HeldExpiry {
        ExpiryQueue queue;
        Expiry expiry;
        const Flow* flow;
    };
    std::vector<HeldExpiry> held_expiries_;
    std::unordered_map<PendingKey, TimedOut, PendingHash> timed_out_;
    std::deque<std::pair<PendingKey, std::uint64_t>> timed_out_order_;  // key and serial, oldest first
    std::uint64_t next_serial_ = 0, next_frame_ = 0, next_flow_ = 0;
    modbus::DeframeEvents stream_events_;
    SharedText source_;
    std::string time_warned_source_;   // the last source whose out-of-range timestamps were reported
    std::string clock_warned_source_;  // the last source whose clock going back was reported
    std::uint64_t packet_number_ = 0;
    modbus::Timestamp now_{0};
    // A link type a source was told about (USER link types need --user-dlt; others are not decoded): once a
    // source and link type, whether this is the first time.
    bool first_told(int linktype);
    std::vector<std::pair<std::string, int>> told_links_;
};

// A serial source's line (a file's, a port's): its key, its name in records and the summary's
// `serial_lines`, and its devices' server.
std::string serial_line_name(const std::string& source);

}  // namespace mbscope::analyzer
