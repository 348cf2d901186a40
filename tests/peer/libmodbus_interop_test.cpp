// Interoperability with libmodbus, a Modbus stack nobody here wrote:
//  - requests libmodbus's client API produces decode with our codec to exactly the call's arguments, and the
//    responses our codec encodes are accepted by the libmodbus client (TCP on loopback, RTU on a pty);
//  - requests our codec encodes are answered by a libmodbus server (modbus_reply over a mapping), and its
//    replies decode to the mapping's values.
#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <functional>
#include <thread>

#include "modbus/adu.hpp"
#include "modbus/pdu.hpp"
#include "modbus/rtu_deframer.hpp"
#include "modbus/tcp_deframer.hpp"

namespace test_peer_libmodbus_interop_test {

namespace mb = mbscope::modbus;

namespace {

// Reads from fd until the deframer yields one frame (or 3 s pass).
template <class Deframer>
std::optional<mb::Frame> read_frame(int fd, Deframer& deframer) {
    mb::DeframeEvents events;
    std::uint8_t buf[512];
    for (int i = 0; i < 300; ++i) {
        for (auto& e : events)
            if (auto* f = std::get_if<mb::Frame>(&e)) return *f;
        pollfd p{fd, POLLIN, 0};
        if (poll(&p, 1, 10) <= 0) continue;
        const ssize_t n = read(fd, buf, sizeof buf);
        if (n <= 0) return std::nullopt;
        deframer.feed(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n)), events);
    }
    return std::nullopt;
}

void write_all(int fd, const std::vector<std::uint8_t>& bytes) {
    std::size_t off = 0;
    while (off < bytes.size()) {
        const ssize_t n = write(fd, bytes.data() + off, bytes.size() - off);
        ASSERT_GT(n, 0);
        off += static_cast<std::size_t>(n);
    }
}

int listen_loopback(int& port) {
    int s = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    if (bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || listen(s, 4) != 0) return -1;
    socklen_t len = sizeof a;
    getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
    return s;
}

// One exchange: what the client API call must put on the wire, and what our side answers.
struct Exchange {
    const char* name;
    std::function<int(modbus_t*)> call;                 // runs in the client thread, returns libmodbus rc
    std::function<void(const mb::Pdu&)> check_request;  // our decoding of libmodbus's request
    mb::Pdu response;                                   // encoded by our codec, must be accepted
};

std::vector<Exchange> exchanges(std::vector<std::uint16_t>& regs_out, std::vector<std::uint8_t>& bits_out) {
    static const std::uint16_t words[] = {0x000A, 0x0102, 0xFFFF};
    static const std::uint8_t coil_values[] = {1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
    const bool resp_bits[] = {true, false, true, true, false, false, true, true, true, false, true};
    const std::uint16_t resp_regs[] = {555, 0, 100};
    std::vector<Exchange> x;
    x.push_back({"read_bits", [&](modbus_t* c) { return modbus_read_bits(c, 19, 11, bits_out.data()); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(p.function_code(), 1);
                     EXPECT_EQ(std::get<mb::ReadRequest>(p.body), (mb::ReadRequest{19, 11}));
                 },
                 mb::make_read_bits_response(mb::FunctionCode::ReadCoils, resp_bits)});
    x.push_back({"read_input_bits",
                 [&](modbus_t* c) { return modbus_read_input_bits(c, 196, 11, bits_out.data()); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(p.function_code(), 2);
                     EXPECT_EQ(std::get<mb::ReadRequest>(p.body), (mb::ReadRequest{196, 11}));
                 },
                 mb::make_read_bits_response(mb::FunctionCode::ReadDiscreteInputs, resp_bits)});
    x.push_back({"read_registers",
                 [&](modbus_t* c) { return modbus_read_registers(c, 96, 3, regs_out.data()); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(p.function_code(), 3);
                     EXPECT_EQ(std::get<mb::ReadRequest>(p.body), (mb::ReadRequest{96, 3}));
                 },
                 mb::make_read_registers_response(mb::FunctionCode::ReadHoldingRegisters, resp_regs)});
    x.push_back({"read_input_registers",
                 [&](modbus_t* c) { return modbus_read_input_registers(c, 8, 3, regs_out.data()); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(p.function_code(), 4);
                     EXPECT_EQ(std::get<mb::ReadRequest>(p.body), (mb::ReadRequest{8, 3}));
                 },
                 mb::make_read_registers_response(mb::FunctionCode::ReadInputRegisters, resp_regs)});
    auto echo = [](mb::Pdu p) {
        p.direction = mb::Direction::Response;
        return p;
    };
    x.push_back({"write_bit", [](modbus_t* c) { return modbus_write_bit(c, 84, 1); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(std::get<mb::WriteSingle>(p.body), (mb::WriteSingle{84, 0xFF00}));
                 },
                 echo(mb::make_write_single_coil(84, true))});
    x.push_back({"write_register", [](modbus_t* c) { return modbus_write_register(c, 84, 926); },
                 [](const mb::Pdu& p) {
                     EXPECT_EQ(std::get<mb::WriteSingle>(p.body), (mb::WriteSingle{84, 926}));
                 },
                 echo(mb::make_write_single_register(84, 926))});
    x.push_back({"write_bits", [](modbus_t* c) { return modbus_write_bits(c, 19, 10, coil_values); },
                 [](const mb::Pdu& p) {
                     const auto& b = std::get<mb::WriteMultipleCoilsRequest>(p.body);
                     EXPECT_EQ(b.starting_address, 19);
                     EXPECT_EQ(b.quantity, 10);
                     EXPECT_EQ(b.values, (std::vector<std::uint8_t>{0xCD, 0x02}));
                     EXPECT_TRUE(p.violations.empty());
                 },
                 mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleCoils, 19, 10)});
    x.push_back({"write_registers", [](modbus_t* c) { return modbus_write_registers(c, 96, 3, words); },
                 [](const mb::Pdu& p) {
                     const auto& b = std::get<mb::WriteMultipleRegistersRequest>(p.body);
                     EXPECT_EQ(b.starting_address, 96);
                     EXPECT_EQ(b.values, (std::vector<std::uint16_t>{0x000A, 0x0102, 0xFFFF}));
                     EXPECT_TRUE(p.violations.empty());
                 },
                 mb::make_write_multiple_response(mb::FunctionCode::WriteMultipleRegisters, 96, 3)});
    x.push_back(
        {"write_and_read_registers",
         [&](modbus_t* c) { return modbus_write_and_read_registers(c, 14, 3, words, 3, 3, regs_out.data()); },
         [](const mb::Pdu& p) {
             const auto& b = std::get<mb::ReadWriteMultipleRequest>(p.body);
             EXPECT_EQ(b.read_starting_address, 3);
             EXPECT_EQ(b.quantity_to_read, 3);
             EXPECT_EQ(b.write_starting_address, 14);
             EXPECT_EQ(b.write_values, (std::vector<std::uint16_t>{0x000A, 0x0102, 0xFFFF}));
         },
         mb::make_read_registers_response(mb::FunctionCode::ReadWriteMultipleRegisters, resp_regs)});
    x.push_back(
        {"mask_write_register", [](modbus_t* c) { return modbus_mask_write_register(c, 4, 0x00F2, 0x0025); },
         [](const mb::Pdu& p) {
             EXPECT_EQ(std::get<mb::MaskWriteRegister>(p.body), (mb::MaskWriteRegister{4, 0x00F2, 0x0025}));
         },
         echo(mb::make_mask_write_register(4, 0x00F2, 0x0025))});
    return x;
}

void check_client_results(const char* name, int rc, const std::vector<std::uint16_t>& regs,
                          const std::vector<std::uint8_t>& bits) {
    SCOPED_TRACE(name);
    EXPECT_GE(rc, 0) << modbus_strerror(errno);
    const std::string n = name;
    if (n == "read_registers" || n == "read_input_registers" || n == "write_and_read_registers") {
        EXPECT_EQ(regs[0], 555);
        EXPECT_EQ(regs[2], 100);
    }
    if (n == "read_bits" || n == "read_input_bits") {
        const std::uint8_t expected[] = {1, 0, 1, 1, 0, 0, 1, 1, 1, 0, 1};
        for (int i = 0; i < 11; ++i)
            EXPECT_EQ(bits[i], expected[i]) << i;
    }
}

}  // namespace

TEST(LibmodbusTcpClient, RequestsDecodeAndOurResponsesAreAccepted) {
    int port = 0;
    const int listener = listen_loopback(port);
    ASSERT_GE(listener, 0);
    std::vector<std::uint16_t> regs(8);
    std::vector<std::uint8_t> bits(16);
    auto x = exchanges(regs, bits);
    std::vector<int> rcs(x.size(), -99);
    std::thread client([&] {
        modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
        modbus_set_slave(ctx, 17);
        modbus_set_response_timeout(ctx, 3, 0);
        if (modbus_connect(ctx) == 0)
            for (std::size_t i = 0; i < x.size(); ++i)
                rcs[i] = x[i].call(ctx);
        modbus_close(ctx);
        modbus_free(ctx);
    });
    const int conn = accept(listener, nullptr, nullptr);
    ASSERT_GE(conn, 0);
    mb::TcpStreamDeframer deframer;
    for (auto& ex : x) {
        SCOPED_TRACE(ex.name);
        auto frame = read_frame(conn, deframer);
        ASSERT_TRUE(frame.has_value());
        EXPECT_EQ(frame->unit_id(), 17);
        EXPECT_EQ(frame->protocol_id(), 0);
        auto pdu = mb::decode_request(frame->pdu());
        ASSERT_TRUE(pdu.has_value());
        EXPECT_TRUE(pdu->violations.empty());
        ex.check_request(pdu.value());
        write_all(conn, mb::encode_tcp(frame->transaction_id(), 17, mb::encode_pdu(ex.response)));
    }
    client.join();
    for (std::size_t i = 0; i < x.size(); ++i)
        check_client_results(x[i].name, rcs[i], regs, bits);
    close(conn);
    close(listener);
}

TEST(LibmodbusTcpClient, ExceptionWeEncodeIsReportedByLibmodbus) {
    int port = 0;
    const int listener = listen_loopback(port);
    ASSERT_GE(listener, 0);
    int rc = 0, err = 0;
    std::thread client([&] {
        modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
        modbus_set_response_timeout(ctx, 3, 0);
        std::uint16_t dest[4];
        if (modbus_connect(ctx) == 0) {
            rc = modbus_read_registers(ctx, 200, 1, dest);
            err = errno;
        }
        modbus_close(ctx);
        modbus_free(ctx);
    });
    const int conn = accept(listener, nullptr, nullptr);
    mb::TcpStreamDeframer deframer;
    auto frame = read_frame(conn, deframer);
    ASSERT_TRUE(frame.has_value());
    write_all(conn, mb::encode_tcp(frame->transaction_id(), frame->unit_id(),
                                   mb::encode_pdu(mb::make_exception(3, 2))));
    client.join();
    EXPECT_EQ(rc, -1);
    EXPECT_EQ(err, EMBXILADD);
    close(conn);
    close(listener);
}

TEST(LibmodbusTcpServer, AnswersOurRequestsWithItsMapping) {
    modbus_t* srv = modbus_new_tcp("127.0.0.1", 0);
    // libmodbus picks the port from the context; bind our own listener instead and hand it the socket.
    int port = 0;
    const int listener = listen_loopback(port);
    ASSERT_GE(listener, 0);
    modbus_mapping_t* map = modbus_mapping_new(100, 100, 200, 200);
    for (int i = 0; i < 200; ++i)
        map->tab_registers[i] = static_cast<std::uint16_t>(1000 + i);
    for (int i = 0; i < 200; ++i)
        map->tab_input_registers[i] = static_cast<std::uint16_t>(2000 + i);
    map->tab_bits[19] = 1;
    map->tab_bits[21] = 1;
    std::thread server([&] {
        int s = accept(listener, nullptr, nullptr);
        modbus_set_socket(srv, s);
        std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
        for (;;) {
            const int n = modbus_receive(srv, query);
            if (n <= 0) break;
            modbus_reply(srv, query, n, map);
        }
        close(s);
    });
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    mb::TcpStreamDeframer deframer;
    std::uint16_t tid = 0x7000;
    auto ask = [&](const mb::Pdu& request) -> mb::Pdu {
        write_all(fd, mb::encode_tcp(++tid, 1, mb::encode_pdu(request)));
        auto frame = read_frame(fd, deframer);
        EXPECT_TRUE(frame.has_value());
        if (!frame) return {};
        EXPECT_EQ(frame->transaction_id(), tid);
        auto pdu = mb::decode_response(frame->pdu());
        EXPECT_TRUE(pdu.has_value());
        EXPECT_TRUE(pdu->violations.empty());
        return pdu ? pdu.value() : mb::Pdu{};
    };
    auto r = ask(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 96, 3));
    EXPECT_EQ(std::get<mb::ReadRegistersResponse>(r.body).values,
              (std::vector<std::uint16_t>{1096, 1097, 1098}));
    r = ask(mb::make_read_request(mb::FunctionCode::ReadInputRegisters, 8, 2));
    EXPECT_EQ(std::get<mb::ReadRegistersResponse>(r.body).values, (std::vector<std::uint16_t>{2008, 2009}));
    r = ask(mb::make_read_request(mb::FunctionCode::ReadCoils, 19, 3));
    EXPECT_EQ(std::get<mb::ReadBitsResponse>(r.body).values, (std::vector<std::uint8_t>{0x05}));
    r = ask(mb::make_write_single_register(10, 4242));
    EXPECT_EQ(std::get<mb::WriteSingle>(r.body), (mb::WriteSingle{10, 4242}));
    const std::uint16_t values[] = {1, 2, 3};
    r = ask(mb::make_write_multiple_registers(20, values));
    EXPECT_EQ(std::get<mb::WriteMultipleResponse>(r.body), (mb::WriteMultipleResponse{20, 3}));
    const bool coils[] = {true, true, false, true};
    r = ask(mb::make_write_multiple_coils(40, coils));
    EXPECT_EQ(std::get<mb::WriteMultipleResponse>(r.body), (mb::WriteMultipleResponse{40, 4}));
    r = ask(mb::make_read_write_multiple(20, 3, 30, values));
    EXPECT_EQ(std::get<mb::ReadRegistersResponse>(r.body).values, (std::vector<std::uint16_t>{1, 2, 3}));
    r = ask(mb::make_mask_write_register(10, 0x00F2, 0x0025));
    EXPECT_EQ(std::get<mb::MaskWriteRegister>(r.body), (mb::MaskWriteRegister{10, 0x00F2, 0x0025}));
    // Out of the mapping: libmodbus answers exception 02, which we decode as such.
    r = ask(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 199, 2));
    EXPECT_TRUE(r.is_exception());
    EXPECT_EQ(std::get<mb::ExceptionResponse>(r.body).exception_code, 2);
    // Quantity 126: libmodbus answers exception 03 (AP §6.3), our codec flags the request itself.
    auto big = mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 126);
    EXPECT_TRUE(
        mb::decode_request(mb::encode_pdu(big))->violations.contains(mb::FindingCode::PduQuantityOutOfRange));
    r = ask(big);
    EXPECT_EQ(std::get<mb::ExceptionResponse>(r.body).exception_code, 3);
    EXPECT_EQ(map->tab_registers[10], (4242 & 0x00F2) | (0x0025 & ~0x00F2));
    close(fd);
    server.join();
    modbus_mapping_free(map);
    modbus_free(srv);
    close(listener);
}

TEST(LibmodbusRtuClient, RequestsOverAPseudoTerminal) {
    int master = -1, slave = -1;
    char name[256];
    ASSERT_EQ(openpty(&master, &slave, name, nullptr, nullptr), 0);
    termios t{};
    tcgetattr(master, &t);
    cfmakeraw(&t);
    tcsetattr(master, TCSANOW, &t);
    std::vector<std::uint16_t> regs(8);
    std::vector<std::uint8_t> bits(16);
    auto x = exchanges(regs, bits);
    std::vector<int> rcs(x.size(), -99);
    std::thread client([&] {
        modbus_t* ctx = modbus_new_rtu(name, 9600, 'E', 8, 1);
        modbus_set_slave(ctx, 17);
        modbus_set_response_timeout(ctx, 3, 0);
        if (modbus_connect(ctx) == 0)
            for (std::size_t i = 0; i < x.size(); ++i)
                rcs[i] = x[i].call(ctx);
        modbus_close(ctx);
        modbus_free(ctx);
    });
    mb::RtuDeframer deframer;
    for (auto& ex : x) {
        SCOPED_TRACE(ex.name);
        auto frame = read_frame(master, deframer);
        ASSERT_TRUE(frame.has_value());
        EXPECT_TRUE(frame->checksum_ok);
        EXPECT_EQ(frame->unit_id(), 17);
        auto pdu = mb::decode_request(frame->pdu());
        ASSERT_TRUE(pdu.has_value());
        ex.check_request(pdu.value());
        write_all(master, mb::encode_rtu(17, mb::encode_pdu(ex.response)));
    }
    client.join();
    for (std::size_t i = 0; i < x.size(); ++i)
        check_client_results(x[i].name, rcs[i], regs, bits);
    close(master);
    close(slave);
}

}  // namespace test_peer_libmodbus_interop_test
