/* Load generator of the slave benchmark: N libmodbus clients, one thread each, reading 10 holding
 * registers (FC3) in a loop for a fixed time against one Modbus/TCP server. The same client code drives
 * both servers, so the ratio of the two request rates compares the servers alone.
 *
 *   slave_load HOST PORT CLIENTS SECONDS   → prints "requests errors" on stdout
 */
#include <errno.h>
#include <modbus.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

struct worker {
    const char* host;
    int port;
    double seconds;
    long requests;
    long errors;
};

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

static void* run(void* arg) {
    struct worker* w = arg;
    modbus_t* ctx = modbus_new_tcp(w->host, w->port);
    if (!ctx || modbus_connect(ctx) != 0) {
        fprintf(stderr, "slave_load: connect: %s\n", modbus_strerror(errno));
        w->errors = -1;
        return NULL;
    }
    modbus_set_slave(ctx, 1);
    uint16_t regs[10];
    const double end = now() + w->seconds;
    while (now() < end) {
        for (int i = 0; i < 64; ++i) { /* check the clock every 64 requests: it is not free */
            if (modbus_read_registers(ctx, 100, 10, regs) == 10)
                ++w->requests;
            else
                ++w->errors;
        }
    }
    modbus_close(ctx);
    modbus_free(ctx);
    return NULL;
}

int main(int argc, char** argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: slave_load HOST PORT CLIENTS SECONDS\n");
        return 2;
    }
    const int clients = atoi(argv[3]);
    if (clients < 1 || clients > 1024) return 2;
    struct worker* workers = calloc((size_t)clients, sizeof *workers);
    pthread_t* threads = calloc((size_t)clients, sizeof *threads);
    for (int i = 0; i < clients; ++i) {
        workers[i] = (struct worker){argv[1], atoi(argv[2]), atof(argv[4]), 0, 0};
        pthread_create(&threads[i], NULL, run, &workers[i]);
    }
    long requests = 0, errors = 0;
    for (int i = 0; i < clients; ++i) {
        pthread_join(threads[i], NULL);
        requests += workers[i].requests;
        errors += workers[i].errors < 0 ? 1 : workers[i].errors;
    }
    printf("%ld %ld\n", requests, errors);
    free(workers);
    free(threads);
    return errors ? 1 : 0;
}
