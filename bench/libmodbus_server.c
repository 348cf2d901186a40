/* The reference point of the slave benchmark: a Modbus/TCP server built on libmodbus alone, serving a
 * mapping equivalent to `mbscope slave --profile modbus` for the registers the load reads (10000 holding
 * registers, 10000 coils). Several clients at once, served by one select() loop as libmodbus's own
 * multi-client examples do. Prints the bound port on stdout, runs until SIGTERM or its parent's end.
 *
 *   libmodbus_server PORT    (0: any free port)
 */
#include <errno.h>
#include <modbus.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

static volatile sig_atomic_t stop;
static void on_signal(int sig) {
    (void)sig;
    stop = 1;
}

int main(int argc, char** argv) {
    /* Ends with whoever started it (a test or the bench script): a parent killed from outside left this
     * server behind, serving nobody. Asked before anything else, then checked: the parent may be gone. */
    const pid_t parent = getppid();
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) return 0;
    const int port = argc > 1 ? atoi(argv[1]) : 0;
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
    modbus_mapping_t* map = modbus_mapping_new(10000, 10000, 10000, 10000);
    if (!ctx || !map) {
        fprintf(stderr, "libmodbus_server: %s\n", modbus_strerror(errno));
        return 2;
    }
    for (int i = 0; i < 10000; ++i)
        map->tab_registers[i] = (uint16_t)i;
    const int listener = modbus_tcp_listen(ctx, 512);
    if (listener < 0) {
        fprintf(stderr, "libmodbus_server: listen: %s\n", modbus_strerror(errno));
        return 2;
    }
    struct sockaddr_in addr;
    socklen_t len = sizeof addr;
    getsockname(listener, (struct sockaddr*)&addr, &len);
    printf("tcp://127.0.0.1:%d\n", ntohs(addr.sin_port));
    fflush(stdout);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);

    fd_set clients;
    FD_ZERO(&clients);
    FD_SET(listener, &clients);
    int max_fd = listener;
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stop) {
        fd_set ready = clients;
        struct timeval tv = {0, 100000};
        const int n = select(max_fd + 1, &ready, NULL, NULL, &tv);
        if (n < 0) {
            if (errno == EINTR) continue;
            break;
        }
        for (int fd = 0; fd <= max_fd && n > 0; ++fd) {
            if (!FD_ISSET(fd, &ready)) continue;
            if (fd == listener) {
                const int c = accept(listener, NULL, NULL);
                if (c >= 0 && c < FD_SETSIZE) {
                    FD_SET(c, &clients);
                    if (c > max_fd) max_fd = c;
                } else if (c >= 0) {
                    close(c);
                }
                continue;
            }
            modbus_set_socket(ctx, fd);
            const int rc = modbus_receive(ctx, query);
            if (rc > 0) {
                modbus_reply(ctx, query, rc, map);
            } else if (rc == -1) {
                close(fd);
                FD_CLR(fd, &clients);
            }
        }
    }
    close(listener);
    modbus_mapping_free(map);
    modbus_free(ctx);
    return 0;
}
