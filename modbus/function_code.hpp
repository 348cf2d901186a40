#pragma once
// Function codes and exception codes of the Modbus Application Protocol V1.1b3 (AP §5.1, §7).
// The raw byte is always kept next to these enums; a code that is not listed here is still a valid
// byte on the wire and decodes to a raw PDU.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace mbscope::modbus {

enum class FunctionCode : std::uint8_t {
    ReadCoils = 0x01,                   // AP §6.1
    ReadDiscreteInputs = 0x02,          // AP §6.2
    ReadHoldingRegisters = 0x03,        // AP §6.3
    ReadInputRegisters = 0x04,          // AP §6.4
    WriteSingleCoil = 0x05,             // AP §6.5
    WriteSingleRegister = 0x06,         // AP §6.6
    ReadExceptionStatus = 0x07,         // AP §6.7, serial line only
    Diagnostics = 0x08,                 // AP §6.8, serial line only
    GetCommEventCounter = 0x0B,         // AP §6.9, serial line only
    GetCommEventLog = 0x0C,             // AP §6.10, serial line only
    WriteMultipleCoils = 0x0F,          // AP §6.11
    WriteMultipleRegisters = 0x10,      // AP §6.12
    ReportServerId = 0x11,              // AP §6.13, serial line only
    ReadFileRecord = 0x14,              // AP §6.14
    WriteFileRecord = 0x15,             // AP §6.15
    MaskWriteRegister = 0x16,           // AP §6.16
    ReadWriteMultipleRegisters = 0x17,  // AP §6.17
    ReadFifoQueue = 0x18,               // AP §6.18
    EncapsulatedInterface = 0x2B,       // AP §6.19-6.21 (MEI types 13 and 14)
};

inline constexpr std::uint8_t exception_bit = 0x80;

// Name of a public function code ("Read Holding Registers"), or nullopt for any other byte.
std::optional<std::string_view> function_name(std::uint8_t function_code) noexcept;
bool is_public_function(std::uint8_t function_code) noexcept;
// AP §5.1: 65-72 and 100-110 are user-defined; 9, 10, 13, 14, 41, 42, 90, 91, 125, 126, 127 are reserved.
bool is_user_defined_function(std::uint8_t function_code) noexcept;
bool is_reserved_function(std::uint8_t function_code) noexcept;
// A request PDU that only reads (FC1-4, 7, 11, 12, 17, 20, 24, 43, and FC8's sub-functions that return data
// or a counter: 00, 02, 0B-12, AP §6.8.1): one sent in broadcast asks what no slave will ever return (SL
// §2.1: broadcast requests are writes). FC8's restart, listen-only and clearing sub-functions change a
// device's state, and FC23 writes: not among them.
bool only_reads(std::span<const std::uint8_t> pdu) noexcept;
// The functions that write coils or registers (FC5, 6, 15, 16, 22, 23), and those that write anything: the
// same and FC21, which writes file records.
bool writes_points(std::uint8_t function_code) noexcept;
bool is_write_function(std::uint8_t function_code) noexcept;
// AP §6.8.1: FC8 sub-function 01 with the data the specification allows (0000 or FF00), the one request a
// device in listen-only mode acts upon.
bool is_restart_communications(std::span<const std::uint8_t> pdu) noexcept;

enum class ExceptionCode : std::uint8_t {
    IllegalFunction = 0x01,
    IllegalDataAddress = 0x02,
    IllegalDataValue = 0x03,
    ServerDeviceFailure = 0x04,
    Acknowledge = 0x05,
    ServerDeviceBusy = 0x06,
    NegativeAcknowledge = 0x07,  // listed in older specifications, kept for captures that use it
    MemoryParityError = 0x08,
    GatewayPathUnavailable = 0x0A,
    GatewayTargetFailedToRespond = 0x0B,
};

std::optional<std::string_view> exception_name(std::uint8_t exception_code) noexcept;

// FC8 sub-functions (AP §6.8.1).
std::optional<std::string_view> diagnostic_name(std::uint16_t sub_function) noexcept;

// Whether an FC8 request's data field is the one AP §6.8.1 gives its sub-function: any data for 00, 00 00 or
// FF 00 for 01, a character and 00 for 03, 00 00 for the others. A value the device does not accept is
// exception 03 in AP §6.8's state diagram. True for sub-functions the specification does not define.
bool diagnostic_request_data_defined(std::uint16_t sub_function, std::span<const std::uint8_t> data) noexcept;

// MEI types of FC43 (AP §6.19-6.21).
inline constexpr std::uint8_t mei_canopen_general_reference = 0x0D;
inline constexpr std::uint8_t mei_read_device_identification = 0x0E;

// Limits (AP §6.x, one constant per rule, named as the spec names them).
inline constexpr std::uint16_t max_read_bits = 2000;             // AP §6.1, §6.2: 0x0001..0x07D0
inline constexpr std::uint16_t max_read_registers = 125;         // AP §6.3, §6.4: 0x0001..0x007D
inline constexpr std::uint16_t max_write_bits = 1968;            // AP §6.11: 0x0001..0x07B0
inline constexpr std::uint16_t max_write_registers = 123;        // AP §6.12: 0x0001..0x007B
inline constexpr std::uint16_t max_rw_read_registers = 125;      // AP §6.17: 0x0001..0x007D
inline constexpr std::uint16_t max_rw_write_registers = 121;     // AP §6.17: 0x0001..0x0079
inline constexpr std::uint16_t max_fifo_count = 31;              // AP §6.18
inline constexpr std::uint8_t min_file_request_bytes = 0x07;     // AP §6.14: 0x07..0xF5
inline constexpr std::uint8_t max_file_request_bytes = 0xF5;     // AP §6.14
inline constexpr std::uint16_t max_file_record_number = 0x270F;  // AP §6.14: 0..9999
inline constexpr std::uint8_t file_reference_type = 0x06;        // AP §6.14
inline constexpr std::size_t max_pdu_length = 253;               // SL §2.5.1: 256 - address - CRC
inline constexpr std::size_t max_rtu_adu_length = 256;           // SL §2.5.1
inline constexpr std::size_t max_tcp_adu_length = 260;           // TCP §4.1: MBAP 7 + PDU 253
inline constexpr std::size_t max_ascii_frame_length = 513;       // SL §2.5.2.1: ':' + 2*(1+253+1) + CR LF

}  // namespace mbscope::modbus
