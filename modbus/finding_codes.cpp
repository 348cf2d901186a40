#include "modbus/finding_codes.hpp"

#include <array>

namespace mbscope::modbus {
namespace {

using enum FindingCode;
using S = Severity;

constexpr std::array findings{
    FindingInfo{PduQuantityOutOfRange, "pdu.quantity_out_of_range", S::Error,
                "quantity is 0 or above the function's maximum", "AP §6.1-6.4, §6.11, §6.12, §6.17"},
    FindingInfo{PduByteCountMismatch, "pdu.byte_count_mismatch", S::Error,
                "byte count disagrees with the quantity or with the bytes present",
                "AP §6.1-6.4, §6.11, §6.12"},
    FindingInfo{PduCoilValueInvalid, "pdu.coil_value_invalid", S::Error,
                "single coil value is neither 0xFF00 nor 0x0000", "AP §6.5"},
    FindingInfo{PduAddressOverflow, "pdu.address_overflow", S::Error,
                "starting address plus quantity runs past address 65535", "AP §6.1"},
    FindingInfo{PduPaddingBitsSet, "pdu.padding_bits_set", S::Warning,
                "unused high bits of the last coil byte are not zero", "AP §6.1"},
    FindingInfo{PduUnknownExceptionCode, "pdu.unknown_exception_code", S::Warning,
                "exception code is not one the specification defines", "AP §7"},
    FindingInfo{PduUnknownFunction, "pdu.unknown_function", S::Note,
                "function code is not a public one (user-defined, reserved or unassigned)", "AP §5.1"},
    FindingInfo{PduReservedSubFunction, "pdu.reserved_sub_function", S::Warning,
                "diagnostics sub-function is reserved", "AP §6.8.1"},
    FindingInfo{PduFileRecordInvalid, "pdu.file_record_invalid", S::Error,
                "file record reference type is not 6, or record number above 9999", "AP §6.14, §6.15"},
    FindingInfo{PduMeiTypeUnknown, "pdu.mei_type_unknown", S::Warning,
                "encapsulated interface MEI type is neither 13 nor 14", "AP §6.19"},
    FindingInfo{PduDeviceIdCodeInvalid, "pdu.device_id_code_invalid", S::Error,
                "read device identification code is not 1..4", "AP §6.21"},
    FindingInfo{PduFifoCountTooLarge, "pdu.fifo_count_too_large", S::Error, "FIFO count above 31",
                "AP §6.18"},
    FindingInfo{PduMalformed, "pdu.malformed", S::Error,
                "PDU structure cannot be decoded: truncated, or bytes left over after it", "AP §4.1, §6"},
    FindingInfo{PduDiagnosticDataLength, "pdu.diagnostic_data_length", S::Error,
                "diagnostics sub-function other than 00 (and 15 hex) carries other than two data bytes",
                "AP §6.8.1"},
    FindingInfo{RtuCrcMismatch, "rtu.crc_mismatch", S::Error, "CRC does not match the frame's bytes",
                "SL §2.5.1.2"},
    FindingInfo{RtuGapInsideFrame, "rtu.gap_inside_frame", S::Error,
                "silence longer than 1.5 character times inside a frame", "SL §2.5.1.1"},
    FindingInfo{RtuFrameTooShort, "rtu.frame_too_short", S::Error,
                "frame shorter than address, function code and CRC", "SL §2.5.1"},
    FindingInfo{RtuFrameTooLong, "rtu.frame_too_long", S::Error, "frame longer than 256 bytes", "SL §2.5.1"},
    FindingInfo{RtuBroadcastResponse, "rtu.broadcast_response", S::Error,
                "a response carries unit 0 (broadcast): slaves never answer a broadcast", "SL §2.1"},
    FindingInfo{RtuShortSilenceBeforeFrame, "rtu.short_silence_before_frame", S::Warning,
                "a frame began less than 3.5 character times after the line's bytes before it",
                "SL §2.5.1.1"},
    FindingInfo{RtuUnitIdReserved, "rtu.unit_id_reserved", S::Warning, "unit id 248..255 is reserved",
                "SL §2.2"},
    FindingInfo{AsciiLrcMismatch, "ascii.lrc_mismatch", S::Error, "LRC does not match the frame's bytes",
                "SL §2.5.2.2"},
    FindingInfo{AsciiLowercaseHex, "ascii.lowercase_hex", S::Warning,
                "frame uses lower-case hex digits; the specification and the manuals use upper case",
                "SL §2.5.2.1; 000:258-264"},
    FindingInfo{AsciiBadCharacter, "ascii.bad_character", S::Error,
                "frame holds a character that is not a hex digit", "SL §2.5.2.1"},
    FindingInfo{AsciiOddLength, "ascii.odd_length", S::Error, "odd number of hex digits", "SL §2.5.2.1"},
    FindingInfo{AsciiMissingEnd, "ascii.missing_end", S::Error,
                "frame not ended by CR LF before the next ':'", "SL §2.5.2.1"},
    FindingInfo{AsciiInterCharTimeout, "ascii.inter_char_timeout", S::Error,
                "pause between characters longer than the inter-character timeout (1 s)",
                "SL §2.5.2.1; 000:304"},
    FindingInfo{AsciiFrameTooShort, "ascii.frame_too_short", S::Error,
                "frame shorter than address, function code and LRC", "SL §2.5.2"},
    FindingInfo{AsciiFrameTooLong, "ascii.frame_too_long", S::Error, "frame longer than 513 characters",
                "SL §2.5.2.1"},
    FindingInfo{TcpProtocolIdNonzero, "tcp.protocol_id_nonzero", S::Error,
                "MBAP protocol identifier is not 0 (not Modbus)", "TCP §3.1.3"},
    FindingInfo{TcpLengthInvalid, "tcp.length_invalid", S::Error, "MBAP length field outside 2..254",
                "TCP §3.1.3; AP §4.1"},
    // An error: the connection's traffic is not decoded at all (read as MBAP it made up units and
    // transactions), and only the user can say the port is a gateway's.
    FindingInfo{TcpRtuFraming, "tcp.rtu_framing", S::Error,
                "a connection decoded as Modbus/TCP carries raw RTU frames (unit, PDU, CRC: a serial gateway "
                "in transparent mode), no MBAP header: its bytes are not decoded; decode the port with "
                "--rtu-over-tcp PORT",
                "TCP §3.1.3; SL §2.5.1"},
    // An error against the sender: the ADU came whole in one segment, but a receiver reading by the length
    // waits for bytes that were never sent and takes them from the next ADU (told by the analyzer only when
    // the next segment starts with a whole ADU: see tcp_deframer.hpp).
    FindingInfo{TcpLengthBeyondSegment, "tcp.length_beyond_segment", S::Error,
                "MBAP length counts 1 or 2 bytes more than the sender put in the segment that carried the "
                "whole ADU (a gateway counting the RTU CRC?): a receiver reading by the length waits for "
                "them and takes them from the next ADU",
                "TCP §3.1.3"},
    FindingInfo{StreamUnparsedBytes, "stream.unparsed_bytes", S::Warning,
                "bytes that formed no frame (garbage, noise or a truncated frame)", "SL §2.5"},
    FindingInfo{StreamGap, "stream.gap", S::Warning, "bytes missing from a captured stream", "capture"},
    FindingInfo{StreamLineError, "stream.line_error", S::Error,
                "the capturing UART saw a framing or parity error, a break or an overrun on the line",
                "SL §2.5.1 (character format)"},
    FindingInfo{StreamRetransmissionConflict, "stream.retransmission_conflict", S::Error,
                "a TCP retransmission carries other bytes than the first copy of the same stream offsets",
                "RFC 9293 §3.4"},
    FindingInfo{
        StreamResetOutsideWindow, "stream.reset_outside_window", S::Warning,
        "a TCP reset whose sequence number lies far outside the stream it would end: a receiver ignores "
        "it, and the connection is decoded on",
        "RFC 9293 §3.10.7.3; RFC 5961 §3.2"},
    FindingInfo{PairNoResponse, "pair.no_response", S::Error, "request got no response within the timeout",
                "AP §4.1; SL §2.4.1; TCP §4.3.1.3"},
    FindingInfo{PairNoResponseAtEnd, "pair.no_response_at_end", S::Note,
                "request still unanswered when the capture ended (shorter than the timeout)", "capture"},
    FindingInfo{PairUnsolicitedResponse, "pair.unsolicited_response", S::Error,
                "response that answers no outstanding request", "AP §4.1"},
    FindingInfo{PairTransactionIdMismatch, "pair.transaction_id_mismatch", S::Error,
                "response carries another transaction id than the request it answers", "TCP §3.1.3"},
    FindingInfo{PairTransactionIdDuplicate, "pair.transaction_id_duplicate", S::Warning,
                "new request reuses the transaction id of a request still unanswered", "TCP §4.2.1"},
    FindingInfo{PairFunctionMismatch, "pair.function_mismatch", S::Error,
                "response function code differs from the request's", "AP §4.1"},
    FindingInfo{PairUnitMismatch, "pair.unit_mismatch", S::Error,
                "response comes from another unit than asked", "SL §2.2; TCP §3.1.3"},
    FindingInfo{PairResponseSizeMismatch, "pair.response_size_mismatch", S::Error,
                "response carries another quantity of data than the request asked for", "AP §6.1-6.4"},
    FindingInfo{PairEchoMismatch, "pair.echo_mismatch", S::Error,
                "response that must echo the request (FC5, FC6, FC8, FC15, FC16, FC22) does not",
                "AP §6.5-6.16"},
    FindingInfo{PairExceptionResponse, "pair.exception_response", S::Warning,
                "the slave answered with an exception", "AP §7"},
    // A gateway's two exceptions are not the device refusing a request: they say the request never
    // reached an answer. Exception 11 is the timeout of the unit behind the gateway, as the master sees it
    // (an error like pair.no_response on a line the master drives itself), exception 10 a gateway that
    // could not route the request at all.
    FindingInfo{PairGatewayPathUnavailable, "pair.gateway_path_unavailable", S::Error,
                "a gateway answered that it has no path to the unit asked (exception 10): usually "
                "misconfigured or overloaded",
                "AP §7"},
    FindingInfo{PairGatewayTargetNoResponse, "pair.gateway_target_no_response", S::Error,
                "a gateway answered that the unit asked did not respond (exception 11): the unit's timeout, "
                "seen through the gateway",
                "AP §7"},
    FindingInfo{PairPendingOverflow, "pair.pending_overflow", S::Warning,
                "too many unanswered requests on one link: the oldest were given up", "capture"},
    FindingInfo{PairBroadcastResponse, "pair.broadcast_response", S::Error,
                "a slave answered a broadcast (unit 0) request", "SL §2.1; 000:248, 285"},
    FindingInfo{PairBroadcastRead, "pair.broadcast_read", S::Warning,
                "a request that only reads sent in broadcast (unit 0): no slave answers it, so nothing it "
                "reads comes back",
                "SL §2.1; 000:313"},
    FindingInfo{PairResponseNotCaptured, "pair.response_not_captured", S::Warning,
                "the request was answered (the reply's MBAP header names it), but the capture holds only "
                "the reply's first bytes (a record cut to the snapshot length, a tap's drop), or none, bytes "
                "of the response stream the capture lacks having gone by while it waited: its values are "
                "unknown, and the device is not blamed with a timeout",
                "capture"},
    FindingInfo{PairDamagedRequestUnanswered, "pair.damaged_request_unanswered", S::Note,
                "no reply to a request whose CRC or LRC failed, or with a silence above t1.5 inside it "
                "(RTU): a slave discards such a frame, so the silence is what the rules want (its checksum "
                "or gap finding says what went wrong)",
                "SL §2.5.1.1, §2.5.1.2, §2.5.2.2"},
    // A warning, not an error: a passive tap cannot tell a device that does not check the checksum from
    // damage that happened only on the tap's side of the line (the device then got the request whole).
    FindingInfo{PairDamagedRequestAnswered, "pair.damaged_request_answered", S::Warning,
                "a device answered a request whose CRC or LRC failed as captured: a slave must discard such "
                "a frame and not reply, so either it does not check the checksum or the capture damaged the "
                "request (a passive tap cannot tell which)",
                "SL §2.4.2, §2.5.1.2, §2.5.2.2"},
    FindingInfo{PairClientAborted, "pair.client_aborted", S::Note,
                "the client reset the connection while the request waited, and no reply came after: the "
                "client gave up on it, not a timeout of the device",
                "TCP §4.3.1.3; RFC 9293 §3.10.7.3"},
    FindingInfo{PairResponseDamaged, "pair.response_damaged", S::Error,
                "the reply began with the unit and function code asked for but formed no frame (a character "
                "that is no hex digit, an odd number of digits, a pause or a new ':' inside it): a master "
                "discards it, and its values are unknown; the device answered, so it is no timeout",
                "SL §2.5.2.1; 000:304-309"},
    FindingInfo{PairRequestNotCaptured, "pair.request_not_captured", S::Warning,
                "a reply to a request the capture holds only in part (its MBAP header names the transaction "
                "id and function; on a serial line, bytes before it formed no frame): not unsolicited",
                "capture"},
    FindingInfo{
        PairDuplicateResponse, "pair.duplicate_response", S::Error,
        "the last response again, byte for byte, after its request was answered: one request answered "
        "twice",
        "AP §4.1; SL §2.1; 000:246-248"},
    FindingInfo{
        PairResponseBeforeRequest, "pair.response_before_request", S::Warning,
        "the response is stamped earlier than its request: the capture's clock went back (a merged or "
        "re-stamped capture), so no latency is measured",
        "capture"},
    FindingInfo{PairLateResponse, "pair.late_response", S::Warning,
                "response to a request already reported unanswered: it came after the timeout (a slow "
                "device, a timeout too short for it, or a network that held it up)",
                "AP §4.1; SL §2.4.1; TCP §4.3.1.3"},
    FindingInfo{ProfileFunctionUnsupported, "profile.function_unsupported", S::Warning,
                "request uses a function code the device's manual does not list", "device manual"},
    FindingInfo{
        ProfileQuantityAboveLimit, "profile.quantity_above_limit", S::Error,
        "request asks for more than the device's manual allows (e.g. 16 registers where it allows 15)",
        "device manual"},
    FindingInfo{ProfileAddressUnknown, "profile.address_unknown", S::Warning,
                "request addresses a point the device map does not have", "device manual"},
    FindingInfo{ProfileValueOutOfRange, "profile.value_out_of_range", S::Error,
                "write of a value outside the point's documented range or enumeration", "device manual"},
    FindingInfo{ProfileWriteReadOnly, "profile.write_read_only", S::Error,
                "write to a point the device's manual marks read-only", "device manual"},
    FindingInfo{ProfileExceptionUnexpected, "profile.exception_unexpected", S::Warning,
                "the device answered a request its map says is valid with an exception, or one its manual "
                "refuses with another code than the manual gives",
                "device manual"},
    FindingInfo{ProfileAddressMoved, "profile.address_moved", S::Note,
                "a write to the device's address register was acknowledged: it answers at the new unit id "
                "from then on",
                "device manual"},
    FindingInfo{ProfileLineDeparture, "profile.line_departure", S::Warning,
                "a device talks a serial framing its manual does not list, or answers at a unit id outside "
                "its manual's addresses",
                "device manual"},
    FindingInfo{ProfileLineSettingsChanged, "profile.line_settings_changed", S::Note,
                "a write to the device's framing, speed or parity registers was acknowledged: it talks with "
                "the new settings from then on",
                "device manual"},
};

}  // namespace

std::string_view to_string(Severity s) noexcept {
    switch (s) {
        case Severity::Note:
            return "note";
        case Severity::Warning:
            return "warning";
        case Severity::Error:
            return "error";
    }
    return "?";
}

std::span<const FindingInfo> all_findings() noexcept {
    return findings;
}

const FindingInfo& info(FindingCode code) noexcept {
    for (const auto& f : findings)
        if (f.code == code) return f;
    return findings[0];  // unreachable for codes of the enum; every enumerator is in the table (tested)
}

std::string_view to_string(FindingCode code) noexcept {
    return info(code).name;
}

std::optional<FindingCode> finding_from_name(std::string_view name) noexcept {
    for (const auto& f : findings)
        if (f.name == name) return f.code;
    return std::nullopt;
}

}  // namespace mbscope::modbus
