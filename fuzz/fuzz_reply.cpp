// What any slave sends back, as `mbscope check` and `mbscope fuzz` meet it: the client's reply framing
// (modbus/transport/exchange.hpp: where a response ends, which frames are late replies set aside)
// and the exchange oracle's judgement (conformance/oracle.hpp) on bytes nobody here wrote. The input is a
// bundled profile, a framing, then exchanges: a request (framed correctly or raw, as the slave target's),
// and its reply in up to four pieces, each raw or framed around the input's bytes (over Modbus/TCP with the
// request's transaction id or one up to three behind, a late reply), each followed or not by a silence.
// Over RTU and ASCII the requests that got nothing back are owed, as the conformance session keeps them
// (the last four, cleared by any reply), so a framed piece can be a late reply to one of them.
// Properties: no crash and no exception escapes; the frames set aside are the first bytes received, one
// after another, and over Modbus/TCP replies to one of the 256 requests before, over RTU and ASCII frames
// with a good checksum that could answer an owed request and could not answer the request's own; the
// response lies within what came for the request; every violation names its rule ("silence.", "reply." or
// "state.") and its source; judging is deterministic (a copy of the oracle judges the same exchange the
// same way).
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <string>
#include <vector>

#include "conformance/oracle.hpp"
#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/transport/exchange.hpp"

using namespace mbscope;
using modbus::Framing;

namespace {

constexpr const char* target = "fuzz_reply";

std::vector<std::uint8_t> framed(Framing framing, std::uint16_t tid, std::uint8_t unit,
                                 std::span<const std::uint8_t> pdu) {
    return modbus::encode_adu(framing, tid, unit, pdu.first(std::min<std::size_t>(pdu.size(), 253)));
}

std::string exchange_text(const modbus::transport::Exchange& ex) {
    return "\n  request " + modbus::hex_bytes(ex.sent) + "\n  received " + modbus::hex_bytes(ex.received);
}

// Why a serial frame set aside should not have been, "" when it may be.
std::string serial_stale_fault(const modbus::transport::Exchange& ex, const modbus::Frame& stale,
                               std::span<const modbus::transport::OwedRequest> owed) {
    using modbus::transport::could_answer;
    if (!stale.checksum_ok) return "a frame with a bad checksum set aside";
    if (std::none_of(owed.begin(), owed.end(),
                     [&](const auto& o) { return could_answer(o.unit, o.pdu, stale); }))
        return "a frame set aside that answers no owed request";
    const auto own = modbus::decode_adu(stale.framing, ex.sent);
    if (own && could_answer(own->unit_id(), own->pdu(), stale))
        return "a frame set aside that could answer the request";
    return "";
}

void check_scanned(Framing framing, const modbus::transport::Exchange& ex,
                   std::span<const modbus::transport::OwedRequest> owed) {
    std::size_t offset = 0;
    for (const auto& stale : ex.stale_replies) {
        if (stale.framing != framing)
            fuzz::fail(target, "a frame set aside of another framing" + exchange_text(ex));
        if (framing == Framing::Tcp) {
            if (ex.sent.size() < 7)
                fuzz::fail(target, "a frame set aside after no request" + exchange_text(ex));
            const auto sent_tid = static_cast<std::uint16_t>((ex.sent[0] << 8) | ex.sent[1]);
            const auto behind = static_cast<std::uint16_t>(sent_tid - stale.transaction_id());
            if (behind < 1 || behind > 256)
                fuzz::fail(target, "a frame set aside " + std::to_string(behind) + " requests behind" +
                                       exchange_text(ex));
        } else if (const auto fault = serial_stale_fault(ex, stale, owed); !fault.empty()) {
            fuzz::fail(target, fault + exchange_text(ex));
        }
        const std::span<const std::uint8_t> at(ex.received.data() + std::min(offset, ex.received.size()),
                                               ex.received.size() - std::min(offset, ex.received.size()));
        const auto again =
            modbus::decode_adu(framing, at.first(std::min<std::size_t>(at.size(), stale.wire_length)));
        const auto same = again && again->length == stale.length &&
                          std::equal(stale.adu().begin(), stale.adu().end(), again->adu().begin());
        if (!same)
            fuzz::fail(target, "a frame set aside is not the received bytes at " + std::to_string(offset) +
                                   exchange_text(ex));
        offset += stale.wire_length;
    }
    if (ex.response && ex.response->wire_length > ex.own_received().size())
        fuzz::fail(target, "a response of " + std::to_string(ex.response->wire_length) + " bytes in " +
                               std::to_string(ex.own_received().size()) + " bytes for the request" +
                               exchange_text(ex));
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)fuzz::bundled_profiles();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const auto& profiles = fuzz::bundled_profiles();
    const modbus::Profile& profile = profiles[in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1)];
    const Framing framing = in.PickValueInArray({Framing::Rtu, Framing::Ascii, Framing::Tcp});
    const bool ip_network = framing == Framing::Tcp && in.ConsumeBool();
    const bool datagram = ip_network && in.ConsumeBool();
    const auto unit = static_cast<std::uint8_t>(
        std::clamp(1, std::max(1, profile.line.unit_min), std::max(1, profile.line.unit_max)));
    conformance::ExchangeOracle oracle(framing, {{unit, &profile}}, ip_network);

    std::uint16_t tid = 0;
    modbus::transport::OwedRequests owed;  // RTU and ASCII, as conformance::Session keeps them
    while (in.remaining_bytes() > 0) {
        const auto shape = in.ConsumeIntegral<std::uint8_t>();
        auto body = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 260));
        modbus::transport::Exchange ex;
        ++tid;
        if ((shape & 0x03) != 0) {
            const std::uint8_t to = (shape & 0x04) ? unit : static_cast<std::uint8_t>(shape >> 3);
            ex.sent = framed(framing, tid, to, body);
        } else {
            ex.sent = std::move(body);
        }

        modbus::transport::ReplyScanner scanner(framing, datagram, 1, owed.list());
        const auto pieces = in.ConsumeIntegralInRange<int>(0, 4);
        for (int i = 0; i < pieces && !scanner.complete(); ++i) {
            const auto kind = in.ConsumeIntegral<std::uint8_t>();
            auto bytes = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 300));
            if (kind & 0x01) {
                const auto behind = static_cast<std::uint16_t>((kind >> 1) & 0x03);
                const std::uint8_t from = (kind & 0x08) ? unit : static_cast<std::uint8_t>(kind >> 4);
                bytes = framed(framing, static_cast<std::uint16_t>(tid - behind), from, bytes);
            }
            ex.received.insert(ex.received.end(), bytes.begin(), bytes.end());
            // A silence after the piece (it ends an RTU frame); a datagram is always one piece.
            (void)scanner.scan(ex, (kind & 0x80) != 0 || datagram);
        }
        // The client stops at its timeout: over a serial line after a silence when bytes came.
        if (!scanner.complete() && framing == Framing::Rtu && !ex.received.empty())
            (void)scanner.scan(ex, true);
        ex.timed_out = scanner.found() == 0;
        check_scanned(framing, ex, owed.list());
        if (framing != Framing::Tcp) {
            const auto request = modbus::decode_adu(framing, ex.sent);
            (void)owed.after(ex, request ? request->unit_id() : 0,
                             request ? request->pdu() : std::span<const std::uint8_t>{});
        }

        const std::optional<bool> changed =
            (shape & 0x60) == 0 ? std::nullopt : std::optional<bool>((shape & 0x20) != 0);
        (void)oracle.expectation(ex.sent);
        auto twin = oracle;
        const auto violations = oracle.judge(ex, changed);
        const auto again = twin.judge(ex, changed);
        std::string first, second;
        for (const auto& v : violations) {
            const bool named = v.rule.starts_with("silence.") || v.rule.starts_with("reply.") ||
                               v.rule.starts_with("state.");
            if (!named || v.source.empty())
                fuzz::fail(target, "a violation without a rule or a source: " + conformance::to_string(v) +
                                       exchange_text(ex));
            first += conformance::to_string(v) + "\n";
        }
        for (const auto& v : again)
            second += conformance::to_string(v) + "\n";
        if (first != second)
            fuzz::fail(target, "judged twice, differently:\n" + first + "--\n" + second + exchange_text(ex));
    }
    return 0;
}
