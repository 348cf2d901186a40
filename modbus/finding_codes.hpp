#pragma once
// The one registry of findings: every rule a frame or a transaction can break, with a stable dotted name,
// a severity, a one-line summary and the rule it comes from. Names never change meaning and are never
// reused; a retired code stays in the table marked retired. The README list and --help text are generated
// from this table, and tests check that every code has a trigger test and a silence test.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace mbscope::modbus {

enum class Severity : std::uint8_t { Note = 0, Warning = 1, Error = 2 };
std::string_view to_string(Severity s) noexcept;

enum class FindingCode : std::uint16_t {
    // pdu: rules of the Modbus Application Protocol on the PDU itself
    PduQuantityOutOfRange = 100,
    PduByteCountMismatch = 101,
    PduCoilValueInvalid = 102,
    PduAddressOverflow = 103,
    PduPaddingBitsSet = 104,
    PduUnknownExceptionCode = 105,
    PduUnknownFunction = 106,
    PduReservedSubFunction = 107,
    PduFileRecordInvalid = 108,
    PduMeiTypeUnknown = 109,
    PduDeviceIdCodeInvalid = 110,
    PduFifoCountTooLarge = 111,
    PduMalformed = 112,
    PduDiagnosticDataLength = 113,
    // rtu: serial line RTU framing (SL §2.5.1)
    RtuCrcMismatch = 200,
    RtuGapInsideFrame = 201,
    RtuFrameTooShort = 202,
    RtuFrameTooLong = 203,
    RtuBroadcastResponse = 204,
    RtuUnitIdReserved = 205,
    RtuShortSilenceBeforeFrame = 206,
    // ascii: serial line ASCII framing (SL §2.5.2)
    AsciiLrcMismatch = 300,
    AsciiLowercaseHex = 301,
    AsciiBadCharacter = 302,
    AsciiOddLength = 303,
    AsciiMissingEnd = 304,
    AsciiInterCharTimeout = 305,
    AsciiFrameTooShort = 306,
    AsciiFrameTooLong = 307,
    // tcp: MBAP header (TCP §3.1.3)
    TcpProtocolIdNonzero = 400,
    TcpLengthInvalid = 401,
    TcpRtuFraming = 402,
    TcpLengthBeyondSegment = 403,
    // stream: bytes that formed no frame
    StreamUnparsedBytes = 500,
    StreamGap = 501,
    StreamLineError = 502,
    StreamRetransmissionConflict = 503,
    StreamResetOutsideWindow = 504,
    // pair: a request and its response, judged together
    PairNoResponse = 600,
    PairNoResponseAtEnd = 601,
    PairUnsolicitedResponse = 602,
    PairTransactionIdMismatch = 603,
    PairTransactionIdDuplicate = 604,
    PairFunctionMismatch = 605,
    PairUnitMismatch = 606,
    PairResponseSizeMismatch = 607,
    PairEchoMismatch = 608,
    PairExceptionResponse = 609,
    PairPendingOverflow = 610,
    PairBroadcastResponse = 611,
    PairDuplicateResponse = 612,
    PairResponseBeforeRequest = 613,
    PairLateResponse = 614,
    PairGatewayPathUnavailable = 615,
    PairGatewayTargetNoResponse = 616,
    PairBroadcastRead = 617,
    PairResponseNotCaptured = 618,
    PairRequestNotCaptured = 619,
    PairDamagedRequestUnanswered = 620,
    PairClientAborted = 621,
    PairResponseDamaged = 622,
    PairDamagedRequestAnswered = 623,
    // profile: what the device's manual says, applied to traffic
    ProfileFunctionUnsupported = 700,
    ProfileQuantityAboveLimit = 701,
    ProfileAddressUnknown = 702,
    ProfileValueOutOfRange = 703,
    ProfileWriteReadOnly = 704,
    ProfileExceptionUnexpected = 705,
    ProfileAddressMoved = 706,
    ProfileLineSettingsChanged = 707,
    ProfileLineDeparture = 708,
};

struct FindingInfo {
    FindingCode code;
    std::string_view name;  // stable dotted name, e.g. "rtu.crc_mismatch"
    Severity severity;
    std::string_view summary;  // one line a technician understands
    std::string_view rule;     // where the rule comes from
};

std::span<const FindingInfo> all_findings() noexcept;
const FindingInfo& info(FindingCode code) noexcept;
std::string_view to_string(FindingCode code) noexcept;
std::optional<FindingCode> finding_from_name(std::string_view name) noexcept;

// A small inline list of codes attached to a decoded frame or PDU: no allocation on the hot path.
class FindingList {
  public:
    static constexpr std::size_t capacity = 8;
    void add(FindingCode code) noexcept {
        if (contains(code)) return;
        if (size_ < capacity) codes_[size_++] = code;
    }
    bool contains(FindingCode code) const noexcept {
        for (std::size_t i = 0; i < size_; ++i)
            if (codes_[i] == code) return true;
        return false;
    }
    bool empty() const noexcept { return size_ == 0; }
    std::size_t size() const noexcept { return size_; }
    const FindingCode* begin() const noexcept { return codes_; }
    const FindingCode* end() const noexcept { return codes_ + size_; }
    void merge(const FindingList& other) noexcept {
        for (auto c : other)
            add(c);
    }

  private:
    FindingCode codes_[capacity]{};
    std::size_t size_ = 0;
};

}  // namespace mbscope::modbus
