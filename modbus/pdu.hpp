#pragma once
// Protocol data units of the Modbus Application Protocol V1.1b3: function code + data, both directions.
//
//   request/response PDU:  +----------+----------------------+
//                          | function | data (0..252 bytes)  |
//                          +----------+----------------------+
//   exception response:    | fc|0x80  | exception code       |
//
// Decoders never throw and never read outside the span. A PDU whose structure can be recovered is decoded in
// full even when it breaks a rule of the specification; each broken rule is one FindingCode in `violations`
// (AP limits, byte counts, coil values), so a caller can show the frame *and* say which rule it breaks.
// An error result means the structure itself could not be recovered (truncated, bytes left over).
// A function code this codec does not know decodes to RawPdu; the raw byte is always kept.

#include <cstdint>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "modbus/finding_codes.hpp"
#include "modbus/function_code.hpp"
#include "modbus/result.hpp"

namespace mbscope::modbus {

enum class Direction : std::uint8_t { Request = 0, Response = 1, Unknown = 2 };
std::string_view to_string(Direction d) noexcept;

// ---- bodies shared by several function codes or both directions ----
struct RawPdu {  // unknown function code, or MEI type 13 payload: the data bytes as they are
    std::vector<std::uint8_t> data;
    bool operator==(const RawPdu&) const = default;
};
struct ReadRequest {  // FC1, FC2, FC3, FC4 request
    std::uint16_t starting_address = 0;
    std::uint16_t quantity = 0;
    bool operator==(const ReadRequest&) const = default;
};
struct WriteSingle {  // FC5, FC6 request and its echo response
    std::uint16_t address = 0;
    std::uint16_t value = 0;
    bool operator==(const WriteSingle&) const = default;
};
struct NoData {  // FC7, FC11, FC12, FC17 requests
    bool operator==(const NoData&) const = default;
};
struct Diagnostics {  // FC8 request and response
    std::uint16_t sub_function = 0;
    std::vector<std::uint8_t> data;
    bool operator==(const Diagnostics&) const = default;
};
struct WriteMultipleCoilsRequest {  // FC15
    std::uint16_t starting_address = 0;
    std::uint16_t quantity = 0;
    std::uint8_t byte_count = 0;
    std::vector<std::uint8_t> values;  // packed, LSB of the first byte = starting_address
    bool operator==(const WriteMultipleCoilsRequest&) const = default;
};
struct WriteMultipleRegistersRequest {  // FC16
    std::uint16_t starting_address = 0;
    std::uint16_t quantity = 0;
    std::uint8_t byte_count = 0;
    std::vector<std::uint16_t> values;
    bool operator==(const WriteMultipleRegistersRequest&) const = default;
};
struct FileSubRequest {  // one sub-request of FC20 (no record_data) or FC21 (with record_data)
    std::uint8_t reference_type = file_reference_type;
    std::uint16_t file_number = 0;
    std::uint16_t record_number = 0;
    std::uint16_t record_length = 0;
    std::vector<std::uint16_t> record_data;
    bool operator==(const FileSubRequest&) const = default;
};
struct FileRecordRequest {  // FC20 request, FC21 request and FC21 response (echo)
    std::uint8_t byte_count = 0;
    std::vector<FileSubRequest> sub_requests;
    bool operator==(const FileRecordRequest&) const = default;
};
struct MaskWriteRegister {  // FC22 request and its echo response
    std::uint16_t reference_address = 0;
    std::uint16_t and_mask = 0;
    std::uint16_t or_mask = 0;
    bool operator==(const MaskWriteRegister&) const = default;
};
struct ReadWriteMultipleRequest {  // FC23
    std::uint16_t read_starting_address = 0;
    std::uint16_t quantity_to_read = 0;
    std::uint16_t write_starting_address = 0;
    std::uint16_t quantity_to_write = 0;
    std::uint8_t write_byte_count = 0;
    std::vector<std::uint16_t> write_values;
    bool operator==(const ReadWriteMultipleRequest&) const = default;
};
struct ReadFifoQueueRequest {  // FC24
    std::uint16_t fifo_pointer_address = 0;
    bool operator==(const ReadFifoQueueRequest&) const = default;
};
struct ReadDeviceIdRequest {  // FC43 / MEI 14
    std::uint8_t read_device_id_code = 1;
    std::uint8_t object_id = 0;
    bool operator==(const ReadDeviceIdRequest&) const = default;
};
struct MeiTransport {  // FC43 with MEI type 13 (CANopen) or an unknown MEI type, either direction
    std::uint8_t mei_type = mei_canopen_general_reference;
    std::vector<std::uint8_t> data;
    bool operator==(const MeiTransport&) const = default;
};

// ---- responses ----
struct ReadBitsResponse {  // FC1, FC2
    std::uint8_t byte_count = 0;
    std::vector<std::uint8_t> values;  // packed
    bool operator==(const ReadBitsResponse&) const = default;
};
struct ReadRegistersResponse {  // FC3, FC4, FC23
    std::uint8_t byte_count = 0;
    std::vector<std::uint16_t> values;
    bool operator==(const ReadRegistersResponse&) const = default;
};
struct ReadExceptionStatusResponse {  // FC7
    std::uint8_t output_data = 0;
    bool operator==(const ReadExceptionStatusResponse&) const = default;
};
struct CommEventCounterResponse {  // FC11
    std::uint16_t status = 0;
    std::uint16_t event_count = 0;
    bool operator==(const CommEventCounterResponse&) const = default;
};
struct CommEventLogResponse {  // FC12
    std::uint8_t byte_count = 0;
    std::uint16_t status = 0;
    std::uint16_t event_count = 0;
    std::uint16_t message_count = 0;
    std::vector<std::uint8_t> events;
    bool operator==(const CommEventLogResponse&) const = default;
};
struct WriteMultipleResponse {  // FC15, FC16
    std::uint16_t starting_address = 0;
    std::uint16_t quantity = 0;
    bool operator==(const WriteMultipleResponse&) const = default;
};
struct ReportServerIdResponse {  // FC17: server id, run indicator and device-specific data, opaque
    std::uint8_t byte_count = 0;
    std::vector<std::uint8_t> data;
    bool operator==(const ReportServerIdResponse&) const = default;
};
struct FileSubResponse {
    std::uint8_t length = 0;  // file response length: reference type byte + data bytes
    std::uint8_t reference_type = file_reference_type;
    std::vector<std::uint16_t> record_data;
    bool operator==(const FileSubResponse&) const = default;
};
struct ReadFileRecordResponse {  // FC20
    std::uint8_t byte_count = 0;
    std::vector<FileSubResponse> sub_responses;
    bool operator==(const ReadFileRecordResponse&) const = default;
};
struct ReadFifoQueueResponse {  // FC24
    std::uint16_t byte_count = 0;
    std::uint16_t fifo_count = 0;
    std::vector<std::uint16_t> values;
    bool operator==(const ReadFifoQueueResponse&) const = default;
};
struct DeviceIdObject {
    std::uint8_t id = 0;
    std::vector<std::uint8_t> value;
    bool operator==(const DeviceIdObject&) const = default;
};
struct ReadDeviceIdResponse {  // FC43 / MEI 14
    std::uint8_t read_device_id_code = 1;
    std::uint8_t conformity_level = 0x01;
    std::uint8_t more_follows = 0;
    std::uint8_t next_object_id = 0;
    std::uint8_t number_of_objects = 0;
    std::vector<DeviceIdObject> objects;
    bool operator==(const ReadDeviceIdResponse&) const = default;
};
struct ExceptionResponse {
    std::uint8_t exception_code = 0;
    bool operator==(const ExceptionResponse&) const = default;
};

using PduBody = std::variant<RawPdu, ReadRequest, WriteSingle, NoData, Diagnostics, WriteMultipleCoilsRequest,
                             WriteMultipleRegistersRequest, FileRecordRequest, MaskWriteRegister,
                             ReadWriteMultipleRequest, ReadFifoQueueRequest, ReadDeviceIdRequest,
                             MeiTransport, ReadBitsResponse, ReadRegistersResponse,
                             ReadExceptionStatusResponse, CommEventCounterResponse, CommEventLogResponse,
                             WriteMultipleResponse, ReportServerIdResponse, ReadFileRecordResponse,
                             ReadFifoQueueResponse, ReadDeviceIdResponse, ExceptionResponse>;

struct Pdu {
    std::uint8_t function_raw = 0;  // as on the wire, exception bit included
    Direction direction = Direction::Unknown;
    PduBody body;
    FindingList violations;  // rules of the specification this PDU breaks (empty for encoders' output)

    std::uint8_t function_code() const noexcept { return function_raw & 0x7F; }
    // An exception response, as decoded: the exception bit alone does not make one (a request carrying a
    // function code above 127 decodes as raw data, and code reading exception_code must not assume it).
    bool is_exception() const noexcept { return std::holds_alternative<ExceptionResponse>(body); }
    bool operator==(const Pdu& o) const { return function_raw == o.function_raw && body == o.body; }
};

// Decode a request PDU (function code first). Errors: EmptyPdu, Truncated, TrailingBytes.
Result<Pdu> decode_request(std::span<const std::uint8_t> pdu) noexcept;
// Decode a response PDU, exception responses included. Errors: EmptyPdu, Truncated, TrailingBytes.
Result<Pdu> decode_response(std::span<const std::uint8_t> pdu) noexcept;
// Decode in the given direction; Unknown tries request first, then response.
Result<Pdu> decode_pdu(std::span<const std::uint8_t> pdu, Direction direction) noexcept;

// Encode exactly what the body holds (byte counts included, even when inconsistent: fault injection and
// fuzzing need to produce broken PDUs). Use the make_* builders for consistent ones.
std::vector<std::uint8_t> encode_pdu(const Pdu& pdu);
void encode_pdu_into(const Pdu& pdu, std::vector<std::uint8_t>& out);

// ---- builders: consistent PDUs with byte counts computed ----
Pdu make_read_request(FunctionCode fc, std::uint16_t starting_address, std::uint16_t quantity);
Pdu make_write_single_coil(std::uint16_t address, bool on);
Pdu make_write_single_register(std::uint16_t address, std::uint16_t value);
Pdu make_write_multiple_coils(std::uint16_t starting_address, std::span<const bool> values);
Pdu make_write_multiple_registers(std::uint16_t starting_address, std::span<const std::uint16_t> values);
Pdu make_read_write_multiple(std::uint16_t read_start, std::uint16_t read_quantity, std::uint16_t write_start,
                             std::span<const std::uint16_t> values);
Pdu make_diagnostics(std::uint16_t sub_function, std::span<const std::uint8_t> data);
Pdu make_mask_write_register(std::uint16_t address, std::uint16_t and_mask, std::uint16_t or_mask);
Pdu make_read_fifo_queue(std::uint16_t fifo_pointer_address);
Pdu make_read_device_id(std::uint8_t read_device_id_code, std::uint8_t object_id);
Pdu make_no_data_request(FunctionCode fc);
Pdu make_read_bits_response(FunctionCode fc, std::span<const bool> values);
Pdu make_read_registers_response(FunctionCode fc, std::span<const std::uint16_t> values);
Pdu make_write_multiple_response(FunctionCode fc, std::uint16_t starting_address, std::uint16_t quantity);
Pdu make_exception(std::uint8_t function_code, std::uint8_t exception_code);

// Packed coil helpers (AP §6.1: LSB of the first byte is the first coil; unused high bits are zero).
std::vector<std::uint8_t> pack_bits(std::span<const bool> bits);
bool bit_at(std::span<const std::uint8_t> packed, std::size_t index) noexcept;
// Whether `packed`, holding exactly `quantity` bits, sets a bit of its last byte past them (zero padding,
// AP §6.1, §6.2, §6.11): judged for an FC15 request on its own, for an FC1/FC2 reply with its request.
bool padding_bits_set(std::span<const std::uint8_t> packed, std::uint16_t quantity) noexcept;

// ---- length prediction: how long is the PDU that starts here? ----
// Used by the RTU deframer without timing (and by any framing that must find frame ends from content),
// the same three steps as libmodbus (function → meta → data), but direction-explicit and never guessing
// a length for an unknown function code.
struct LengthPrediction {
    enum class Kind : std::uint8_t { Known, NeedMore, Unknown } kind = Kind::Unknown;
    std::size_t length = 0;  // Known: PDU length; NeedMore: at least this many PDU bytes are needed to tell
};
LengthPrediction predict_pdu_length(std::span<const std::uint8_t> pdu_prefix, Direction direction) noexcept;

}  // namespace mbscope::modbus
