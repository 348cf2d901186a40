#pragma once
// The rules of one exchange, judged without choosing the request: whatever was sent (a fuzzer's mutation, a
// replayed reproducer), the oracle says what the specification and the device's manual allow in reply and
// whether the reply that came is one of those. The in-process fuzz target of the reference slave and the
// network fuzzer (`mbscope fuzz`) share it; its predictions use the same profile queries as `mbscope check`
// (modbus::check_read, check_writes, exception_for, FunctionRules::max_for).
//
// What it demands, in the specification's order (AP V1.1b3 §4.1 and §6 state diagrams):
//   silence  for a frame with a bad CRC/LRC (SL §2.5.1.2), a broadcast on a serial line (SL §2.1), a unit
//   that
//            is not on the line (SL §2.1), a device in listen-only mode (AP §6.8.1 sub-function 04), a
//            Modbus/TCP header whose protocol identifier is not 0 (TCP §3.1.3);
//   a reply  to every other request: framed like the request (checksum, unit, transaction and protocol
//            identifiers), for the request's function, well formed (AP §6 layouts, byte counts), and
//            once: the same reply again after it is reply.duplicate (SL §2.1; MK-MS-01, 000:246-248);
//   which    exception 01 for an unsupported function, 03 for a quantity outside 1..max or inconsistent
//            data, 02 for an address the map lacks, the profile's code for a rejected value, and a normal
//            response exactly where none of these applies; an echo where the function echoes;
//   state    no change of the device's registers on a refused request; a value written with an
//            acknowledgement reads back as written (the slave never loses an acknowledged write).
// Over a network `state_changed` is unknown; the read-back rule still holds.
// RTU frames end at a silence (SL §2.5.1.1), and a slave reading a stream or a line may end one where the
// function code says the request ends: a CRC-valid RTU request longer or shorter than its function's length,
// or of a function whose length cannot be told, may go unanswered over a stream (no rule demands an answer
// to it), though an answer must still keep the rules.

#include <bitset>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"
#include "modbus/transport/client.hpp"

namespace mbscope::conformance {

struct OracleViolation {
    std::string rule;      // stable id: "silence.bad_checksum", "reply.exception_code", "state.lost_write"
    std::string source;    // "SL §2.5.1.2", "AP §6.3", "000:325"
    std::string expected;  // "no reply", "exception 02 (Illegal Data Address)"
    std::string observed;  // what came back, in words
};
std::string to_string(const OracleViolation& v);

class ExchangeOracle {
  public:
    struct Unit {
        std::uint8_t id = 1;
        const modbus::Profile* profile = nullptr;
    };
    // `ip_network`: Modbus/TCP reached by an IP address (tcp://, udp://), where a lone device also answers
    // unit 0xFF (TCP §4.4.1.2), and every unit id when its manual says so.
    ExchangeOracle(modbus::Framing framing, std::vector<Unit> units, bool ip_network);

    // Judges one exchange. ex.sent is the request as written; ex.received/ex.response the reply (empty:
    // silence). `state_changed`: whether the device's registers changed, when the caller can tell.
    // An RTU request longer than its function's length whose first bytes are a CRC-valid request of that
    // length is two requests in one: the frame up to a silence (SL §2.5.1.1), and the frame its function
    // code ends (what a slave reading a stream, or ending frames by content, takes). A reply that keeps
    // the rules for either keeps them.
    std::vector<OracleViolation> judge(const modbus::transport::Exchange& ex,
                                       std::optional<bool> state_changed = std::nullopt);

    // What the oracle would accept for this request, in words ("no reply", "normal response or exception
    // 02"); "" when it does not judge the request (the bytes are no frame).
    std::string expectation(const std::vector<std::uint8_t>& sent) const;
    // The same, as what a sender should wait for: no opinion (the bytes are no frame, unit 0 over TCP),
    // silence demanded (a reply is a violation or a gateway's exception), a reply or silence both allowed,
    // a reply due.
    enum class Answer { Unjudged, Silence, Optional, Reply };
    Answer answer_due(const std::vector<std::uint8_t>& sent) const;

    // Forget what was learnt from acknowledged writes and listen-only mode (the target was restarted).
    void reset();
    // The `index`th of the units the oracle was made with answers at `to` now (a write to its address
    // register moved it, MK ENDER); what was learnt of it goes with it. The caller tells: a broadcast write
    // executes unseen. At address 0 a device answers nothing (communication disabled, MK-ADR-01).
    void moved(std::size_t index, std::uint8_t to);

  private:
    // Exception codes, one bit each: a judged request allocates nothing for them.
    struct Codes {
        std::bitset<256> bits;
        Codes() = default;
        Codes(std::initializer_list<std::uint8_t> codes) {
            for (auto c : codes)
                bits.set(c);
        }
        void insert(std::uint8_t c) { bits.set(c); }
        bool count(std::uint8_t c) const { return bits.test(c); }
        bool empty() const { return bits.none(); }
    };
    struct Expected {
        bool judged = true;            // false: the oracle has no opinion on this request
        bool silence = false;          // the rules demand silence
        bool silence_allowed = false;  // silence is one of the allowed answers
        bool normal = false;           // a normal response is allowed
        Codes exceptions;              // exception codes allowed
        std::string_view rule;         // the rule that decides (silence, or the refusal); a literal
        std::string_view source;       // a literal
    };
    std::vector<OracleViolation> judge_frame(const modbus::transport::Exchange& ex,
                                             std::optional<bool> state_changed);
    struct Request;  // the request as decoded from the bytes sent
    std::optional<Request> decode_sent(const std::vector<std::uint8_t>& sent) const;
    const Unit* route(std::uint8_t unit) const;
    Expected expect(const Request& r) const;
    Expected expect_served(const Request& r, const Unit& u) const;
    // Over Modbus/TCP and UDP, the lone device for a unit id no profile is given for: a server reached by
    // its IP address has no use for the unit id (TCP §4.4.1.2) and may serve it as its own. nullptr else.
    const Unit* lone_on_ip(std::uint8_t unit) const;
    const Unit* served_by(std::uint8_t unit) const;  // route(), else lone_on_ip()
    Expected expect_pdu(const Request& r, const modbus::Profile& p) const;
    void check_normal_shape(const Request& r, const modbus::Pdu& reply,
                            std::vector<OracleViolation>& out) const;
    void learn(const Request& r, const modbus::Pdu& reply);
    void forget_written(const Request& r);
    void forget_points_written(const Request& r);  // a write whose outcome is unknown

    using ShadowKey = std::tuple<std::uint8_t, int, std::uint16_t>;  // unit, resolved table, address
    bool tracked(const modbus::Profile& p, modbus::Table t, std::uint16_t address) const;

    modbus::Framing framing_;
    std::vector<Unit> units_;
    bool ip_network_;
    std::set<std::uint8_t> listen_only_;
    std::set<std::uint8_t> listen_only_unknown_;  // units a broadcast diagnostics request may have switched
    std::map<ShadowKey, std::uint16_t> written_;  // acknowledged writes, as they must read back
};

}  // namespace mbscope::conformance
