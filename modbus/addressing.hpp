#pragma once
// Protocol addresses versus reference numbers. The PDU carries a 0-based protocol address; manuals and
// HMIs often print 1-based references with the table in the leading digit: 5 digits (00001-09999 coils,
// 10001 discrete inputs, 30001 input registers, 40001 holding registers) or 6 digits (000001-065536,
// 100001, 300001, 400001). The manuals mix both (MK uses PDU addresses, Walchem 5-digit references), so
// the two are distinct types and conversion happens only at the profile and user-interface edge.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "modbus/function_code.hpp"
#include "modbus/result.hpp"

namespace mbscope::modbus {

enum class Table : std::uint8_t { Coils = 0, DiscreteInputs = 1, InputRegisters = 3, HoldingRegisters = 4 };
std::string_view to_string(Table t) noexcept;  // "coils", "discrete_inputs", "input_registers", ...
std::optional<Table> parse_table(
    std::string_view name) noexcept;  // also accepts "coil", "hr", "ir", "di", "4x"
bool is_bit_table(Table t) noexcept;

// How many of `count` items from protocol address `start` have an address: addresses end at 65535. The
// items of a block past it (a request that runs past the end, pdu.address_overflow) are no register of any
// map; wrapped round to 0, 1, ... they would be taken for registers they are not.
constexpr std::size_t count_within_address_space(std::uint16_t start, std::size_t count) noexcept {
    return count < std::size_t{0x10000} - start ? count : std::size_t{0x10000} - start;
}

struct ProtocolAddress {
    std::uint16_t value = 0;  // as in the PDU, 0-based
    bool operator==(const ProtocolAddress&) const = default;
};

struct Reference {
    Table table = Table::HoldingRegisters;
    std::uint32_t number = 1;  // 1-based within the table (1..65536)
    bool operator==(const Reference&) const = default;
};

// "40001" → {HoldingRegisters, 1}; "400001" → {HoldingRegisters, 1}; "x0037" style is not a reference.
// Errors: BadReference.
Result<Reference> parse_reference(std::string_view text) noexcept;
ProtocolAddress to_protocol_address(const Reference& ref) noexcept;  // number - 1
Reference to_reference(Table table, ProtocolAddress address) noexcept;
// 5-digit form when the number fits in 4 digits (≤ 9999), 6-digit form otherwise.
std::string format_reference(const Reference& ref);

// The table a read or write function code addresses (FC1/5/15 coils, FC2 discrete inputs, FC4 input
// registers, FC3/6/16/22/23 holding registers).
std::optional<Table> table_of_function(std::uint8_t function_code) noexcept;
// The function that reads a table: FC1 coils, FC2 discrete inputs, FC4 input registers, FC3 holding
// registers.
FunctionCode read_function(Table t) noexcept;

}  // namespace mbscope::modbus
