#include "modbus/addressing.hpp"

#include <gtest/gtest.h>

namespace test_modbus_addressing_test {

namespace mb = mbscope::modbus;

TEST(Addressing, FiveAndSixDigitReferences) {
    auto r = mb::parse_reference("40001");
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->table, mb::Table::HoldingRegisters);
    EXPECT_EQ(mb::to_protocol_address(*r).value, 0);
    auto six = mb::parse_reference("465536");
    ASSERT_TRUE(six.has_value());
    EXPECT_EQ(mb::to_protocol_address(*six).value, 65535);
    EXPECT_EQ(mb::parse_reference("00001")->table, mb::Table::Coils);
    EXPECT_EQ(mb::parse_reference("10001")->table, mb::Table::DiscreteInputs);
    EXPECT_EQ(mb::parse_reference("30001")->table, mb::Table::InputRegisters);
}

TEST(Addressing, WalchemManualExamples) {
    // 002:494-498: firmware version = input registers 30039..30040; Sensor 2-1 low alarm as coil 00893
    // (x0865 + 28); relay 3 set-point holding registers 49007..49008 (x9001 + 6).
    EXPECT_EQ(mb::to_protocol_address(*mb::parse_reference("30039")).value, 38);
    EXPECT_EQ(mb::to_protocol_address(*mb::parse_reference("00893")).value, 892);
    EXPECT_EQ(mb::to_protocol_address(*mb::parse_reference("49007")).value, 9006);
}

TEST(Addressing, MkManualUsesPduAddresses) {
    // 000:356: "registers 96..98" are sent as 00 60: the MK numbering is the PDU address; as a reference
    // the same register is 40097.
    EXPECT_EQ(mb::format_reference(mb::to_reference(mb::Table::HoldingRegisters, mb::ProtocolAddress{0x60})),
              "40097");
    EXPECT_EQ(mb::format_reference(mb::to_reference(mb::Table::Coils, mb::ProtocolAddress{19})), "00020");
    EXPECT_EQ(mb::format_reference(mb::to_reference(mb::Table::HoldingRegisters, mb::ProtocolAddress{9999})),
              "410000");
}

TEST(Addressing, BadReferences) {
    for (const char* bad : {"", "4000", "50001", "4000A", "40000", "4655370", "465537"})
        EXPECT_FALSE(mb::parse_reference(bad).has_value()) << bad;
}

TEST(Addressing, TablesOfFunctions) {
    EXPECT_EQ(mb::table_of_function(1), mb::Table::Coils);
    EXPECT_EQ(mb::table_of_function(2), mb::Table::DiscreteInputs);
    EXPECT_EQ(mb::table_of_function(4), mb::Table::InputRegisters);
    EXPECT_EQ(mb::table_of_function(16), mb::Table::HoldingRegisters);
    EXPECT_FALSE(mb::table_of_function(8).has_value());
    EXPECT_EQ(mb::parse_table("hr"), mb::Table::HoldingRegisters);
    EXPECT_FALSE(mb::parse_table("registers").has_value());
}

// The read of each table is the function that addresses it (AP §6.1-6.4).
TEST(Addressing, ReadFunctionOfEachTable) {
    EXPECT_EQ(mb::read_function(mb::Table::Coils), mb::FunctionCode::ReadCoils);
    EXPECT_EQ(mb::read_function(mb::Table::DiscreteInputs), mb::FunctionCode::ReadDiscreteInputs);
    EXPECT_EQ(mb::read_function(mb::Table::InputRegisters), mb::FunctionCode::ReadInputRegisters);
    EXPECT_EQ(mb::read_function(mb::Table::HoldingRegisters), mb::FunctionCode::ReadHoldingRegisters);
    for (auto t : {mb::Table::Coils, mb::Table::DiscreteInputs, mb::Table::InputRegisters,
                   mb::Table::HoldingRegisters})
        EXPECT_EQ(mb::table_of_function(static_cast<std::uint8_t>(mb::read_function(t))), t);
}

}  // namespace test_modbus_addressing_test
