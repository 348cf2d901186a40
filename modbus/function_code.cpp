#include "modbus/function_code.hpp"

namespace mbscope::modbus {

std::optional<std::string_view> function_name(std::uint8_t function_code) noexcept {
    switch (function_code) {
        case 0x01:
            return "Read Coils";
        case 0x02:
            return "Read Discrete Inputs";
        case 0x03:
            return "Read Holding Registers";
        case 0x04:
            return "Read Input Registers";
        case 0x05:
            return "Write Single Coil";
        case 0x06:
            return "Write Single Register";
        case 0x07:
            return "Read Exception Status";
        case 0x08:
            return "Diagnostics";
        case 0x0B:
            return "Get Comm Event Counter";
        case 0x0C:
            return "Get Comm Event Log";
        case 0x0F:
            return "Write Multiple Coils";
        case 0x10:
            return "Write Multiple Registers";
        case 0x11:
            return "Report Server ID";
        case 0x14:
            return "Read File Record";
        case 0x15:
            return "Write File Record";
        case 0x16:
            return "Mask Write Register";
        case 0x17:
            return "Read/Write Multiple Registers";
        case 0x18:
            return "Read FIFO Queue";
        case 0x2B:
            return "Encapsulated Interface Transport";
        default:
            return std::nullopt;
    }
}

bool is_restart_communications(std::span<const std::uint8_t> pdu) noexcept {
    return pdu.size() == 5 && pdu[0] == 0x08 && pdu[1] == 0x00 && pdu[2] == 0x01 &&
           diagnostic_request_data_defined(0x01, pdu.subspan(3));
}

bool is_public_function(std::uint8_t function_code) noexcept {
    return function_name(function_code).has_value();
}

bool writes_points(std::uint8_t function_code) noexcept {
    switch (function_code) {
        case 5:
        case 6:
        case 15:
        case 16:
        case 22:
        case 23:
            return true;
        default:
            return false;
    }
}

bool is_write_function(std::uint8_t function_code) noexcept {
    return writes_points(function_code) || function_code == 21;
}

bool only_reads(std::span<const std::uint8_t> pdu) noexcept {
    using F = FunctionCode;
    if (pdu.empty()) return false;
    if (pdu[0] == static_cast<std::uint8_t>(F::Diagnostics)) {
        if (pdu.size() < 3) return false;
        const unsigned sub = (pdu[1] << 8) | pdu[2];
        return sub == 0x00 || sub == 0x02 || (sub >= 0x0B && sub <= 0x12);
    }
    switch (static_cast<F>(pdu[0])) {
        case F::ReadCoils:
        case F::ReadDiscreteInputs:
        case F::ReadHoldingRegisters:
        case F::ReadInputRegisters:
        case F::ReadExceptionStatus:
        case F::GetCommEventCounter:
        case F::GetCommEventLog:
        case F::ReportServerId:
        case F::ReadFileRecord:
        case F::ReadFifoQueue:
        case F::EncapsulatedInterface:
            return true;
        default:
            return false;
    }
}

bool is_user_defined_function(std::uint8_t fc) noexcept {
    return (fc >= 65 && fc <= 72) || (fc >= 100 && fc <= 110);
}

bool is_reserved_function(std::uint8_t fc) noexcept {
    switch (fc) {
        case 9:
        case 10:
        case 13:
        case 14:
        case 41:
        case 42:
        case 90:
        case 91:
        case 125:
        case 126:
        case 127:
            return true;
        default:
            return false;
    }
}

std::optional<std::string_view> exception_name(std::uint8_t exception_code) noexcept {
    switch (exception_code) {
        case 0x01:
            return "Illegal Function";
        case 0x02:
            return "Illegal Data Address";
        case 0x03:
            return "Illegal Data Value";
        case 0x04:
            return "Server Device Failure";
        case 0x05:
            return "Acknowledge";
        case 0x06:
            return "Server Device Busy";
        case 0x07:
            return "Negative Acknowledge";
        case 0x08:
            return "Memory Parity Error";
        case 0x0A:
            return "Gateway Path Unavailable";
        case 0x0B:
            return "Gateway Target Device Failed to Respond";
        default:
            return std::nullopt;
    }
}

std::optional<std::string_view> diagnostic_name(std::uint16_t sub_function) noexcept {
    switch (sub_function) {
        case 0x00:
            return "Return Query Data";
        case 0x01:
            return "Restart Communications Option";
        case 0x02:
            return "Return Diagnostic Register";
        case 0x03:
            return "Change ASCII Input Delimiter";
        case 0x04:
            return "Force Listen Only Mode";
        case 0x0A:
            return "Clear Counters and Diagnostic Register";
        case 0x0B:
            return "Return Bus Message Count";
        case 0x0C:
            return "Return Bus Communication Error Count";
        case 0x0D:
            return "Return Bus Exception Error Count";
        case 0x0E:
            return "Return Server Message Count";
        case 0x0F:
            return "Return Server No Response Count";
        case 0x10:
            return "Return Server NAK Count";
        case 0x11:
            return "Return Server Busy Count";
        case 0x12:
            return "Return Bus Character Overrun Count";
        case 0x14:
            return "Clear Overrun Counter and Flag";
        default:
            return std::nullopt;
    }
}

bool diagnostic_request_data_defined(std::uint16_t sub_function,
                                     std::span<const std::uint8_t> data) noexcept {
    if (sub_function == 0x00 || !diagnostic_name(sub_function)) return true;
    if (data.size() != 2) return false;
    switch (sub_function) {
        case 0x01:
            return (data[0] == 0x00 || data[0] == 0xFF) && data[1] == 0x00;
        case 0x03:
            return data[1] == 0x00;
        default:
            return data[0] == 0x00 && data[1] == 0x00;
    }
}

}  // namespace mbscope::modbus
