#pragma once
// What the analyzer reports: frames, transactions (a request with its response, exception or timeout),
// findings and unparsed bytes, then a summary. Stages produce these records; sinks format them. No stage
// prints.

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "analyzer/shared_text.hpp"
#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"

namespace mbscope::analyzer {

// What brought a frame into the capture: a TCP stream (Modbus/TCP, or RTU from a serial gateway), UDP
// datagrams, a serial line (raw dumps, the text format, USER link types), or Wireshark's exported PDUs.
enum class Carrier : std::uint8_t { Tcp = 0, Udp = 1, Serial = 2, ExportedPdu = 3 };
std::string_view to_string(Carrier c) noexcept;

// Two registers read as one 32-bit value (--word-order, devices without a profile).
struct Register32 {
    std::uint16_t address = 0;  // the first of the two registers
    std::uint32_t u32 = 0;
    float f32 = 0;
};

struct FrameRecord {
    FrameRecord() = default;
    // With its frame from the start: a new Frame zeroes its whole buffer, a copy copies only the bytes the
    // frame holds (made for every frame of a capture, this was a tenth of the summary's time).
    explicit FrameRecord(const modbus::Frame& f) : frame(f) {}
    std::uint64_t index = 0;   // 1-based frame number in this analysis
    std::uint64_t packet = 0;  // capture packet in which the frame ended
    modbus::Timestamp time{0};
    SharedText source;  // input file
    SharedText link;    // "client -> server" (TCP/UDP) or the serial port
    SharedText device;  // "server unit N": what a finding is about
    modbus::Direction direction = modbus::Direction::Unknown;
    Carrier carrier = Carrier::Tcp;
    modbus::Frame frame;
    std::optional<modbus::Pdu> pdu;
    std::string error;  // why the PDU could not be decoded
    // Findings reported about this frame as it was seen, before its transaction was made (the manual's rules
    // a request breaks, a broadcast that only reads, a reply whose transaction id is not its request's):
    // carried into its transaction's findings with the frame's own.
    std::vector<modbus::FindingCode> reported_findings;
};

// The exception code a response carries: its decoded PDU's, or, when the PDU did not decode (an exception
// with bytes after its code: "83 06 00"), the byte after an exception function code, as the device sent it
// (tshark reads it so too). nullopt for anything else.
std::optional<std::uint8_t> exception_code_of(const FrameRecord& response) noexcept;

struct TransactionRecord {
    TransactionRecord() = default;
    explicit TransactionRecord(FrameRecord&& r) : request(std::move(r)) {}  // see FrameRecord(const Frame&)
    FrameRecord request;
    std::optional<FrameRecord> response;
    std::optional<modbus::Timestamp> latency;
    bool timed_out = false;
    // The response came after the request's timeout: the request was reported unanswered (a transaction of
    // its own, timed out) and this one pairs the reply with it after all. How long it was waited for: the
    // timeout, or when the master moved on to its next request first (late_moved_on), until then.
    std::optional<modbus::Timestamp> late_past;
    bool late_moved_on = false;
    bool broadcast = false;  // serial unit 0: executed by every slave, answered by none
    // Answered, but the capture holds only the reply's first bytes (pair.response_not_captured).
    bool reply_not_captured = false;
    bool reply_damaged = false;  // answered with a reply that formed no frame (pair.response_damaged)
    // The request's CRC or LRC failed and no reply came: discarded, as the rules want.
    bool discarded = false;
    // The client reset the connection while the request waited, and no reply came (pair.client_aborted).
    bool client_aborted = false;
    // Unanswered (timed out, or at the end) on a serial line while another unit replied (pair.unit_mismatch),
    // which a master discards.
    bool answered_by_other_unit = false;
    std::vector<modbus::FindingCode> findings;
    std::vector<modbus::NamedValue> values;  // with a profile: the values named in the device's terms
    const modbus::Profile* profile = nullptr;
    // --word-order without a profile: FC3/FC4 replies read two registers at a time, in that order.
    std::optional<modbus::WordOrder> word_order;
    std::vector<Register32> registers32;
};

struct FindingRecord {
    modbus::FindingCode code{};
    modbus::Timestamp time{0};
    SharedText source;
    SharedText link;
    SharedText device;
    std::vector<std::uint64_t> frames;
    std::uint64_t packet = 0;
    std::string message;
};

struct UnparsedRecord {
    SharedText source;
    SharedText link;
    modbus::Direction direction = modbus::Direction::Unknown;
    modbus::Timestamp time{0};
    std::uint64_t packet = 0;
    std::uint64_t offset = 0;  // stream offset
    std::uint64_t length = 0;
    modbus::UnparsedReason reason = modbus::UnparsedReason::Garbage;
};

// Latencies kept in a fixed log-scale histogram (32 buckets per power of two, ~3 % resolution) so memory
// does not grow with the capture; min and max are exact.
class LatencyHistogram {
  public:
    void add(modbus::Timestamp latency);
    std::uint64_t count() const noexcept { return count_; }
    modbus::Timestamp min() const noexcept { return min_; }
    modbus::Timestamp max() const noexcept { return max_; }
    modbus::Timestamp quantile(double q) const;

  private:
    static constexpr int sub = 32;
    std::array<std::uint64_t, 64 * sub> buckets_{};
    std::uint64_t count_ = 0;
    modbus::Timestamp min_{0}, max_{0};
};

struct DeviceStats {
    // checksum_errors: its frames (requests to it, replies from it) whose CRC or LRC fails.
    std::uint64_t requests = 0, responses = 0, exceptions = 0, timeouts = 0, checksum_errors = 0;
    // Requests still waiting, within their timeout, when the capture ended: not timeouts, nor answered.
    std::uint64_t unanswered_at_end = 0;
    // Timeouts whose reply came after all (not counted as responses or exceptions; their latencies are in
    // the histogram).
    std::uint64_t late_responses = 0;
    // Requests answered with a reply the capture holds only in part (pair.response_not_captured): neither
    // responses (nothing of their values is known) nor timeouts.
    std::uint64_t replies_not_captured = 0;
    // Requests answered with a serial reply that began with their unit and function code but formed no frame
    // (pair.response_damaged): neither responses (a master discards them) nor timeouts.
    std::uint64_t damaged_replies = 0;
    // Requests whose CRC or LRC failed and that drew no reply (pair.damaged_request_unanswered): the device
    // was right to discard them, so they are not timeouts.
    std::uint64_t damaged_unanswered = 0;
    // Requests the client reset its connection on before a reply came, none coming after
    // (pair.client_aborted): the client gave up on them, so they are not timeouts.
    std::uint64_t client_aborted = 0;
    // Of the timeouts and the requests unanswered at the end, those on a serial line during which another
    // unit replied (pair.unit_mismatch): a master discards that reply, so it is neither this device's
    // response nor its exception, and its values are not this device's.
    std::uint64_t answered_by_other_unit = 0;
    LatencyHistogram latency;
    std::map<int, std::uint64_t> functions;  // function code → requests
    // The exception codes among `exceptions` (code → count): what the device refused, or the gateway in front
    // of it could not do (10, 11).
    std::map<int, std::uint64_t> exception_codes;
    // The findings about this device (code name → count): which device did it. Findings about a stream or
    // a line rather than a device (unparsed bytes, gaps) are in the summary's only.
    std::map<std::string, std::uint64_t> findings;
};

// Device names in the order a reader counts: numbers within them by value, so "unit 2" comes before
// "unit 10" and 10.0.0.9 before 10.0.0.10 (as text, unit 199 came before unit 2 on a multi-drop line).
struct NaturalOrder {
    bool operator()(std::string_view a, std::string_view b) const noexcept;
};

struct Summary {
    std::uint64_t packets = 0, frames = 0, transactions = 0, unparsed_bytes = 0;
    // Requests to unit 0 on serial lines (and RTU over TCP) whose CRC or LRC fails: every slave discards
    // them, so none is a broadcast transaction; their checksum findings name them.
    std::uint64_t damaged_broadcasts = 0;
    // Requests whose CRC or LRC fails to a unit that no frame of their line had shown before and that no
    // reply from that unit answered: line noise, most often, and no device's.
    std::uint64_t damaged_to_unseen_units = 0;
    std::map<std::string, DeviceStats, NaturalOrder> devices;
    std::map<std::string, std::uint64_t> findings;  // code name → count
    std::uint64_t errors = 0;                       // error-severity findings
    std::vector<std::string> input_errors;          // files that could not be read (fully)
    std::uint64_t input_errors_unlisted = 0;        // more of them, beyond Analyzer::max_listed_input_errors
    // What was read whole but is not as a capture should be (its clock going back, a timestamp no clock
    // holds): decoded, and said beside the results; an input error fails the run, a note does not.
    std::vector<std::string> input_notes;
    std::uint64_t input_notes_unlisted = 0;
    // IP datagrams whose fragments never all arrived (ip_reassembly.hpp), the fragments they had, and
    // fragments reaching past the largest datagram: captured packets that could not be decoded.
    std::uint64_t ip_datagrams_incomplete = 0, ip_fragments_incomplete = 0, ip_fragments_invalid = 0;
    // Packets whose link, IP or transport header is damaged or cut short by the snapshot length: whatever
    // they carried was not decoded.
    std::uint64_t packets_malformed = 0;
    // TCP segments whose record was cut to the snapshot length: their missing bytes are stream gaps.
    std::uint64_t packets_cut = 0;
    // Packets with data on TCP port 802, Modbus/TCP Security: TLS, which no capture alone can decrypt.
    std::uint64_t modbus_security_packets = 0;
    // Packets on ports not decoded as Modbus whose payload is one whole Modbus/TCP ADU (protocol 0, a length
    // that fits the payload, a public function code), by (UDP?, the lower of the two ports): a server port a
    // user may have left out (--tcp-port, --udp-port), told rather than decoding to nothing.
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> modbus_like_ports;
    // The same for raw RTU frames (a serial gateway in transparent mode): packets of conversations on ports
    // not decoded that held three or more whole RTU ADUs with valid CRCs in a row, by (UDP?, server port),
    // told to decode them with --rtu-over-tcp (TCP) or --udp-port (UDP, where datagrams' CRCs tell RTU).
    // Their packets that also parse as one MBAP ADU (01 03 00 00 00 02 C4 0B does) are not counted above.
    std::map<std::pair<bool, std::uint16_t>, std::uint64_t> rtu_like_ports;
    // Connections to a port decoded as Modbus/TCP that carried RTU frames instead (tcp.rtu_framing), by
    // server port: their bytes were not decoded, and --rtu-over-tcp PORT decodes them.
    std::map<std::uint16_t, std::uint64_t> rtu_over_tcp_connections;
    // Serial lines (not exported PDUs): the framings each was read in, in order (more than one when a device
    // was told another), and whether the first was told from the line's bytes rather than stated.
    struct SerialLineRead {
        std::vector<modbus::Framing> framings;
        bool told = false;
    };
    std::map<std::string, SerialLineRead> serial_lines;
};

class Sink {
  public:
    virtual ~Sink() = default;
    virtual void frame(const FrameRecord&) {}
    virtual void transaction(const TransactionRecord&) {}
    virtual void finding(const FindingRecord&) {}
    virtual void unparsed(const UnparsedRecord&) {}
    virtual void end(const Summary&) {}
    // What the sink took so far, written out now: a live capture is quiet (Analyzer::idle), and whoever
    // reads the output should see what was decoded without waiting for a buffer to fill.
    virtual void flush() {}
    // False for a sink that never looks at transaction records (a summary): the analyzer then does not
    // make them, and transaction() is not called. Asked once, when the analyzer is made.
    virtual bool wants_transactions() const { return true; }
};

}  // namespace mbscope::analyzer
