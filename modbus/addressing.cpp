#include "modbus/addressing.hpp"

#include <charconv>

namespace mbscope::modbus {

std::string_view to_string(Table t) noexcept {
    switch (t) {
        case Table::Coils:
            return "coils";
        case Table::DiscreteInputs:
            return "discrete_inputs";
        case Table::InputRegisters:
            return "input_registers";
        case Table::HoldingRegisters:
            return "holding_registers";
    }
    return "?";
}

std::optional<Table> parse_table(std::string_view n) noexcept {
    if (n == "coils" || n == "coil" || n == "co" || n == "0x") return Table::Coils;
    if (n == "discrete_inputs" || n == "discrete-inputs" || n == "discrete" || n == "di" || n == "1x")
        return Table::DiscreteInputs;
    if (n == "input_registers" || n == "input-registers" || n == "input" || n == "ir" || n == "3x")
        return Table::InputRegisters;
    if (n == "holding_registers" || n == "holding-registers" || n == "holding" || n == "hr" || n == "4x")
        return Table::HoldingRegisters;
    return std::nullopt;
}

bool is_bit_table(Table t) noexcept {
    return t == Table::Coils || t == Table::DiscreteInputs;
}

Result<Reference> parse_reference(std::string_view text) noexcept {
    if (text.size() != 5 && text.size() != 6) return make_error(ErrorCode::BadReference, 0);
    for (char c : text)
        if (c < '0' || c > '9') return make_error(ErrorCode::BadReference, 0);
    Reference ref;
    switch (text[0]) {
        case '0':
            ref.table = Table::Coils;
            break;
        case '1':
            ref.table = Table::DiscreteInputs;
            break;
        case '3':
            ref.table = Table::InputRegisters;
            break;
        case '4':
            ref.table = Table::HoldingRegisters;
            break;
        default:
            return make_error(ErrorCode::BadReference, 0);
    }
    std::uint32_t number = 0;
    std::from_chars(text.data() + 1, text.data() + text.size(), number);
    if (number < 1 || number > 65536) return make_error(ErrorCode::BadReference, 1);
    ref.number = number;
    return ref;
}

ProtocolAddress to_protocol_address(const Reference& ref) noexcept {
    return ProtocolAddress{static_cast<std::uint16_t>(ref.number - 1)};
}

Reference to_reference(Table table, ProtocolAddress address) noexcept {
    return Reference{table, static_cast<std::uint32_t>(address.value) + 1};
}

std::string format_reference(const Reference& ref) {
    const char digit = static_cast<char>('0' + static_cast<int>(ref.table));
    std::string number = std::to_string(ref.number);
    const std::size_t width = ref.number <= 9999 ? 4 : 5;
    std::string out(1, digit);
    out.append(width - number.size(), '0');
    out += number;
    return out;
}

FunctionCode read_function(Table t) noexcept {
    switch (t) {
        case Table::Coils:
            return FunctionCode::ReadCoils;
        case Table::DiscreteInputs:
            return FunctionCode::ReadDiscreteInputs;
        case Table::InputRegisters:
            return FunctionCode::ReadInputRegisters;
        case Table::HoldingRegisters:
            break;
    }
    return FunctionCode::ReadHoldingRegisters;
}

std::optional<Table> table_of_function(std::uint8_t fc) noexcept {
    switch (fc) {
        case 0x01:
        case 0x05:
        case 0x0F:
            return Table::Coils;
        case 0x02:
            return Table::DiscreteInputs;
        case 0x04:
            return Table::InputRegisters;
        case 0x03:
        case 0x06:
        case 0x10:
        case 0x16:
        case 0x17:
            return Table::HoldingRegisters;
        default:
            return std::nullopt;
    }
}

}  // namespace mbscope::modbus
