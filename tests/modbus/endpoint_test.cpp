// The endpoint URIs every part of mbscope shares (modbus/transport/endpoint.hpp): every scheme, IPv6
// literals, serial options and their specification defaults, and errors that name the offending part.
#include <gtest/gtest.h>

#include "modbus/transport/endpoint.hpp"

namespace mbscope::modbus::transport::test_modbus_endpoint_test {
namespace {

struct NetworkCase {
    const char* name;
    const char* uri;
    Scheme scheme;
    const char* host;
    std::uint16_t port;
    Framing framing;
    const char* text;  // Endpoint::text(), the form printed back
};

class EndpointNetwork : public ::testing::TestWithParam<NetworkCase> {};

TEST_P(EndpointNetwork, Parses) {
    const auto& c = GetParam();
    auto ep = parse_endpoint(c.uri);
    ASSERT_TRUE(ep.has_value()) << ep.error();
    EXPECT_EQ(ep->scheme, c.scheme);
    EXPECT_EQ(ep->host, c.host);
    EXPECT_EQ(ep->port, c.port);
    EXPECT_EQ(framing_of(ep->scheme), c.framing);
    EXPECT_FALSE(is_serial(ep->scheme));
    EXPECT_EQ(ep->text(), c.text);
    auto again = parse_endpoint(ep->text());  // what is printed parses back to the same endpoint
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->text(), ep->text());
}

INSTANTIATE_TEST_SUITE_P(
    Uri, EndpointNetwork,
    ::testing::Values(NetworkCase{"Tcp", "tcp://127.0.0.1:5020", Scheme::Tcp, "127.0.0.1", 5020, Framing::Tcp,
                                  "tcp://127.0.0.1:5020"},
                      NetworkCase{"TcpDefaultPort", "tcp://plc.local", Scheme::Tcp, "plc.local", 502,
                                  Framing::Tcp, "tcp://plc.local:502"},
                      NetworkCase{"TcpPortZero", "tcp://0.0.0.0:0", Scheme::Tcp, "0.0.0.0", 0, Framing::Tcp,
                                  "tcp://0.0.0.0:0"},
                      NetworkCase{"TcpHighestPort", "tcp://h:65535", Scheme::Tcp, "h", 65535, Framing::Tcp,
                                  "tcp://h:65535"},
                      NetworkCase{"Udp", "udp://10.0.0.3:502", Scheme::Udp, "10.0.0.3", 502, Framing::Tcp,
                                  "udp://10.0.0.3:502"},
                      NetworkCase{"RtuOverTcp", "rtu-tcp://gw:4001", Scheme::RtuOverTcp, "gw", 4001,
                                  Framing::Rtu, "rtu-tcp://gw:4001"},
                      NetworkCase{"AsciiOverTcp", "ascii-tcp://gw:4002", Scheme::AsciiOverTcp, "gw", 4002,
                                  Framing::Ascii, "ascii-tcp://gw:4002"},
                      NetworkCase{"Ipv6Loopback", "tcp://[::1]:502", Scheme::Tcp, "::1", 502, Framing::Tcp,
                                  "tcp://[::1]:502"},
                      NetworkCase{"Ipv6NoPort", "udp://[fe80::1]", Scheme::Udp, "fe80::1", 502, Framing::Tcp,
                                  "udp://[fe80::1]:502"},
                      NetworkCase{"Ipv6RtuOverTcp", "rtu-tcp://[2001:db8::5]:1502", Scheme::RtuOverTcp,
                                  "2001:db8::5", 1502, Framing::Rtu, "rtu-tcp://[2001:db8::5]:1502"}),
    [](const auto& info) { return std::string(info.param.name); });

struct SerialCase {
    const char* name;
    const char* uri;
    Scheme scheme;
    const char* device;
    std::uint32_t baud;
    Parity parity;
    int stop_bits;
    int data_bits;
};

class EndpointSerial : public ::testing::TestWithParam<SerialCase> {};

TEST_P(EndpointSerial, Parses) {
    const auto& c = GetParam();
    auto ep = parse_endpoint(c.uri);
    ASSERT_TRUE(ep.has_value()) << ep.error();
    EXPECT_EQ(ep->scheme, c.scheme);
    EXPECT_TRUE(is_serial(ep->scheme));
    EXPECT_EQ(ep->device, c.device);
    EXPECT_EQ(ep->line.baud, c.baud);
    EXPECT_EQ(ep->line.parity, c.parity);
    EXPECT_EQ(ep->line.stop_bits, c.stop_bits);
    EXPECT_EQ(ep->line.data_bits, c.data_bits);
    auto again = parse_endpoint(ep->text());
    ASSERT_TRUE(again.has_value()) << ep->text();
    EXPECT_EQ(again->text(), ep->text());
    EXPECT_EQ(again->line.parity, c.parity);
}

// SL §2.5.1: RTU defaults to 8 data bits, even parity; §2.5.2: ASCII to 7 data bits, even parity; 9600 baud.
INSTANTIATE_TEST_SUITE_P(
    Uri, EndpointSerial,
    ::testing::Values(
        SerialCase{"RtuDefaults", "rtu:/dev/ttyUSB0", Scheme::RtuSerial, "/dev/ttyUSB0", 9600, Parity::Even,
                   1, 8},
        SerialCase{"AsciiDefaults", "ascii:/dev/ttyS1", Scheme::AsciiSerial, "/dev/ttyS1", 9600, Parity::Even,
                   1, 7},
        // The MK instruments run 8N1 (000:186-188), given explicitly.
        SerialCase{"RtuMk8N1", "rtu:/dev/ttyS0?baud=9600&parity=N&stop=1&data=8", Scheme::RtuSerial,
                   "/dev/ttyS0", 9600, Parity::None, 1, 8},
        SerialCase{"RtuOddTwoStop", "rtu:/dev/ttyS0?baud=19200&parity=odd&stop=2", Scheme::RtuSerial,
                   "/dev/ttyS0", 19200, Parity::Odd, 2, 8},
        SerialCase{"AsciiLowerCaseParity", "ascii:/dev/pts/3?parity=n&stop=2&baud=300", Scheme::AsciiSerial,
                   "/dev/pts/3", 300, Parity::None, 2, 7},
        SerialCase{"EmptyQuery", "rtu:pty?", Scheme::RtuSerial, "pty", 9600, Parity::Even, 1, 8},
        SerialCase{"Pty", "rtu:pty?baud=1200&parity=E", Scheme::RtuSerial, "pty", 1200, Parity::Even, 1, 8}),
    [](const auto& info) { return std::string(info.param.name); });

struct ErrorCase {
    const char* name;
    const char* uri;
    const char* says;  // part of the message
};

class EndpointError : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(EndpointError, IsRefusedNamingThePart) {
    auto ep = parse_endpoint(GetParam().uri);
    ASSERT_FALSE(ep.has_value()) << GetParam().uri;
    EXPECT_NE(ep.error().find(GetParam().says), std::string::npos) << ep.error();
}

INSTANTIATE_TEST_SUITE_P(
    Uri, EndpointError,
    ::testing::Values(ErrorCase{"UnknownScheme", "http://x:80", "unknown endpoint 'http://x:80'"},
                      ErrorCase{"NoScheme", "127.0.0.1:502", "unknown endpoint"},
                      ErrorCase{"Empty", "", "unknown endpoint ''"},
                      ErrorCase{"UpperCaseScheme", "TCP://h:502", "unknown endpoint"},
                      ErrorCase{"MissingHost", "tcp://:502", "missing host in tcp://:502"},
                      ErrorCase{"MissingHostEmpty", "udp://", "missing host"},
                      ErrorCase{"PortTooLarge", "tcp://h:65536", "bad port '65536'"},
                      ErrorCase{"PortNotANumber", "tcp://h:50x", "bad port '50x'"},
                      ErrorCase{"PortNegative", "tcp://h:-1", "bad port '-1'"},
                      ErrorCase{"UnterminatedIpv6", "tcp://[::1:502", "unterminated '['"},
                      ErrorCase{"JunkAfterIpv6", "tcp://[::1]502", "expected ':PORT' after ']'"},
                      ErrorCase{"EmptyIpv6", "tcp://[]:502", "missing host"},
                      ErrorCase{"Ipv6WithoutBrackets", "tcp://::1:502", "an IPv6 address needs brackets"},
                      ErrorCase{"EmptyPort", "tcp://h:", "missing port after ':' in tcp://h:"},
                      ErrorCase{"EmptyPortAfterIpv6", "udp://[::1]:", "missing port after ':'"},
                      ErrorCase{"MissingDevice", "rtu:?baud=9600", "missing device in rtu:?baud=9600"},
                      ErrorCase{"MissingDeviceAscii", "ascii:", "missing device"},
                      ErrorCase{"BadBaud", "rtu:/dev/x?baud=fast", "bad baud 'fast'"},
                      ErrorCase{"ZeroBaud", "rtu:/dev/x?baud=0", "bad baud '0'"},
                      ErrorCase{"EmptyBaud", "rtu:/dev/x?baud=", "bad baud ''"},
                      ErrorCase{"BadParity", "rtu:/dev/x?parity=M", "bad parity 'M'"},
                      ErrorCase{"BadStop", "rtu:/dev/x?stop=3", "bad stop '3'"},
                      ErrorCase{"BadData", "ascii:/dev/x?data=9", "bad data '9'"},
                      ErrorCase{"DataTooFew", "ascii:/dev/x?data=6", "bad data '6'"},
                      ErrorCase{"UnknownOption", "rtu:/dev/x?speed=9600", "unknown option 'speed'"},
                      ErrorCase{"OptionWithoutValue", "rtu:/dev/x?baud", "expected KEY=VALUE, got 'baud'"},
                      ErrorCase{"OptionTwice", "rtu:/dev/x?baud=9600&parity=N&baud=19200",
                                "baud given twice in rtu:/dev/x?baud=9600&parity=N&baud=19200"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(EndpointScheme, NamesAreTheUriSchemes) {
    EXPECT_EQ(to_string(Scheme::Tcp), "tcp");
    EXPECT_EQ(to_string(Scheme::Udp), "udp");
    EXPECT_EQ(to_string(Scheme::RtuOverTcp), "rtu-tcp");
    EXPECT_EQ(to_string(Scheme::AsciiOverTcp), "ascii-tcp");
    EXPECT_EQ(to_string(Scheme::RtuSerial), "rtu");
    EXPECT_EQ(to_string(Scheme::AsciiSerial), "ascii");
}

}  // namespace
}  // namespace mbscope::modbus::transport::test_modbus_endpoint_test
