#include "fuzz/libmodbus_peer.hpp"

#include <modbus/modbus.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>

namespace mbscope::fuzz {

namespace {

modbus_mapping_t* zeroed_mapping() {
    static modbus_mapping_t* mapping = modbus_mapping_new(0x10000, 0x10000, 0x10000, 0x10000);
    std::memset(mapping->tab_bits, 0, static_cast<std::size_t>(mapping->nb_bits));
    std::memset(mapping->tab_input_bits, 0, static_cast<std::size_t>(mapping->nb_input_bits));
    std::memset(mapping->tab_registers, 0,
                sizeof(std::uint16_t) * static_cast<std::size_t>(mapping->nb_registers));
    std::memset(mapping->tab_input_registers, 0,
                sizeof(std::uint16_t) * static_cast<std::size_t>(mapping->nb_input_registers));
    return mapping;
}

}  // namespace

LibmodbusOutcome libmodbus_serve(std::span<const std::uint8_t> adu) {
    LibmodbusOutcome out;
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) return out;
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", 502);
    modbus_set_socket(ctx, sv[1]);
    // libmodbus sleeps its response timeout before an exception it flushes after (3.1.6 response_exception):
    // keep that sleep to a microsecond.
    modbus_set_response_timeout(ctx, 0, 1);
    modbus_set_indication_timeout(ctx, 1, 0);
    std::size_t written = 0;
    while (written < adu.size()) {
        const ssize_t n = ::write(sv[0], adu.data() + written, adu.size() - written);
        if (n <= 0) break;
        written += static_cast<std::size_t>(n);
    }
    ::shutdown(sv[0], SHUT_WR);
    std::uint8_t request[MODBUS_TCP_MAX_ADU_LENGTH];
    out.received = modbus_receive(ctx, request);
    if (out.received > 0) {
        modbus_reply(ctx, request, out.received, zeroed_mapping());
        ::shutdown(sv[1], SHUT_WR);
        std::uint8_t buf[512];
        for (;;) {
            const ssize_t n = ::read(sv[0], buf, sizeof buf);
            if (n <= 0) break;
            out.reply.insert(out.reply.end(), buf, buf + n);
        }
    }
    modbus_free(ctx);  // does not close the socket set with modbus_set_socket
    ::close(sv[0]);
    ::close(sv[1]);
    return out;
}

}  // namespace mbscope::fuzz
