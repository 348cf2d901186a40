/* The reference point of issue 7's speed goal for the slave target: a libFuzzer harness built the way
 * libmodbus's own server harness is (OSS-Fuzz's FuzzServer.c): for each input a Modbus/TCP server context
 * and mapping are made, the server listens on loopback, a client thread connects and sends the input, and
 * the server receives one request with modbus_receive(). This one also answers it with modbus_reply(), so it
 * covers receive and reply as fuzz_slave does. Built and run by bench/fuzz_slave_vs_libmodbus.sh with the
 * flags of the project's fuzz targets; not part of the build (it needs clang's libFuzzer).
 */
#include <arpa/inet.h>
#include <modbus.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <unistd.h>

enum { harness_port = 15020 };

struct sender {
    const uint8_t* data;
    size_t size;
};

/* The client side: connects (retrying until the server listens), writes the input, and reads until the
 * server closes the connection. */
static void* send_input(void* arg) {
    const struct sender* s = arg;
    struct sockaddr_in to = {0};
    to.sin_family = AF_INET;
    to.sin_port = htons(harness_port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    int fd = -1;
    for (;;) {
        fd = socket(AF_INET, SOCK_STREAM, 0);
        if (fd < 0) return NULL;
        if (connect(fd, (struct sockaddr*)&to, sizeof to) == 0) break;
        close(fd);
    }
    if (send(fd, s->data, s->size, 0) < 0) perror("send");
    /* Read what the server answers, so that its reply is written whole before the connection closes. */
    uint8_t reply[MODBUS_TCP_MAX_ADU_LENGTH];
    while (recv(fd, reply, sizeof reply, 0) > 0) {
    }
    close(fd);
    return NULL;
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 8) return 0; /* shorter than an MBAP header and a function code: libmodbus waits forever */
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", harness_port);
    modbus_mapping_t* map = modbus_mapping_new(512, 512, 512, 512);
    if (ctx == NULL || map == NULL) abort();
    /* A request shorter than its function code and byte count promise waits for the rest: the wait for the
     * first byte and between bytes (0.5 s by default) is cut to 1 ms, as the input is sent in one write on
     * loopback and bytes missing then never come. */
    modbus_set_indication_timeout(ctx, 0, 1000);
    modbus_set_byte_timeout(ctx, 0, 1000);
    /* After an exception for a bad request libmodbus's server sleeps the response timeout (0.5 s by default)
     * and flushes the line; OSS-Fuzz's harness keeps that, which holds it to a few executions a second. Made
     * 1 µs here so that the reference point measures receiving and replying, not a deliberate sleep. */
    modbus_set_response_timeout(ctx, 0, 1);
    int listener = modbus_tcp_listen(ctx, 1);
    if (listener < 0) abort();
    struct sender s = {data, size};
    pthread_t client;
    pthread_create(&client, NULL, send_input, &s);
    if (modbus_tcp_accept(ctx, &listener) >= 0) {
        uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
        int rc = modbus_receive(ctx, query);
        if (rc > 0) modbus_reply(ctx, query, rc, map);
    }
    modbus_close(ctx); /* the accepted connection: the client's recv() ends */
    close(listener);
    pthread_join(client, NULL);
    modbus_mapping_free(map);
    modbus_free(ctx);
    return 0;
}
