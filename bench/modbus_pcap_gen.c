/* A large Modbus/TCP capture for bench/decode_vs_tshark.sh, written through libpcap (pcap_open_dead +
 * pcap_dump): Ethernet, IPv4, TCP; CLIENTS masters (10.0.0.1 onwards, port 40000 + i) polling one gateway 10.1.0.1:502 round
 * robin, one request and its response per segment, 2 ms apart. The mix is a plant's: FC3 reads of 1..64
 * registers (most), FC4 reads, FC6 writes with their echo, FC16 writes, one exception reply in 50.
 *
 *   modbus_pcap_gen OUT.pcap TRANSACTIONS [CLIENTS]      (default 16 clients)
 */
#include <pcap/pcap.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint32_t rng = 12345;
static uint32_t next_random(void) {
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return rng;
}

static void put16(uint8_t* p, unsigned v) {
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)v;
}
static void put32(uint8_t* p, uint32_t v) {
    put16(p, v >> 16);
    put16(p + 2, v & 0xFFFF);
}

static uint16_t ip_checksum(const uint8_t* h) {
    uint32_t sum = 0;
    for (int i = 0; i < 20; i += 2) sum += (uint32_t)(h[i] << 8 | h[i + 1]);
    while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
    return (uint16_t)~sum;
}

struct client {
    uint32_t seq, ack;  /* next sequence number of the client, of the server */
    uint16_t tid;
};

/* One TCP segment client <-> server carrying `adu`. */
static void segment(pcap_dumper_t* out, uint64_t us, int c, struct client* cl, int to_server, const uint8_t* adu,
                    unsigned len) {
    uint8_t p[14 + 20 + 20 + 260];
    memset(p, 0, sizeof p);
    const unsigned host = (unsigned)c + 1; /* 10.0.0.1 onwards */
    const uint8_t client_mac[6] = {0x02, 0, 0, 0, (uint8_t)(host >> 8), (uint8_t)host};
    const uint8_t server_mac[6] = {0x02, 0, 0, 1, 0, 1};
    memcpy(p, to_server ? server_mac : client_mac, 6);
    memcpy(p + 6, to_server ? client_mac : server_mac, 6);
    p[12] = 0x08;
    uint8_t* ip = p + 14;
    ip[0] = 0x45;
    put16(ip + 2, 40 + len);
    ip[6] = 0x40;
    ip[8] = 64;
    ip[9] = 6;
    const uint8_t client_ip[4] = {10, 0, (uint8_t)(host >> 8), (uint8_t)host}, server_ip[4] = {10, 1, 0, 1};
    memcpy(ip + 12, to_server ? client_ip : server_ip, 4);
    memcpy(ip + 16, to_server ? server_ip : client_ip, 4);
    put16(ip + 10, ip_checksum(ip));
    uint8_t* tcp = ip + 20;
    put16(tcp, to_server ? 40000 + c : 502);
    put16(tcp + 2, to_server ? 502 : 40000 + c);
    put32(tcp + 4, to_server ? cl->seq : cl->ack);
    put32(tcp + 8, to_server ? cl->ack : cl->seq);
    tcp[12] = 0x50;
    tcp[13] = 0x18; /* PSH ACK */
    put16(tcp + 14, 65535);
    memcpy(tcp + 20, adu, len);
    if (to_server)
        cl->seq += len;
    else
        cl->ack += len;
    struct pcap_pkthdr h;
    h.ts.tv_sec = (time_t)(us / 1000000);
    h.ts.tv_usec = (suseconds_t)(us % 1000000);
    h.caplen = h.len = 54 + len;
    pcap_dump((u_char*)out, &h, p);
}

/* MBAP header before a PDU of `pdu_len` bytes. */
static unsigned mbap(uint8_t* a, uint16_t tid, uint8_t unit, unsigned pdu_len) {
    put16(a, tid);
    put16(a + 2, 0);
    put16(a + 4, pdu_len + 1);
    a[6] = unit;
    return 7;
}

int main(int argc, char** argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: modbus_pcap_gen OUT.pcap TRANSACTIONS [CLIENTS]\n");
        return 2;
    }
    const unsigned long transactions = strtoul(argv[2], NULL, 10);
    const int clients = argc > 3 ? atoi(argv[3]) : 16;
    if (clients < 1 || clients > 60000) return 2;
    pcap_t* dead = pcap_open_dead(DLT_EN10MB, 65535);
    pcap_dumper_t* out = pcap_dump_open(dead, argv[1]);
    if (!out) {
        fprintf(stderr, "modbus_pcap_gen: %s\n", pcap_geterr(dead));
        return 2;
    }
    struct client* cl = calloc((size_t)clients, sizeof *cl);
    for (int c = 0; c < clients; ++c) {
        cl[c].seq = 1000 + (uint32_t)c * 7919;
        cl[c].ack = 5000 + (uint32_t)c * 104729;
    }
    uint64_t us = 1700000000ull * 1000000ull;
    uint8_t req[260], rsp[260];
    for (unsigned long t = 0; t < transactions; ++t) {
        const int c = (int)(t % (unsigned long)clients);
        struct client* k = &cl[c];
        const uint16_t tid = ++k->tid;
        const uint8_t unit = (uint8_t)(1 + next_random() % 8);
        const unsigned kind = next_random() % 100;
        const unsigned addr = next_random() % 1000;
        unsigned rl = 0, sl = 0;
        if (kind < 60 || kind >= 90) { /* FC3 / FC4 read */
            const uint8_t fc = kind < 60 ? 3 : 4;
            const unsigned n = 1 + next_random() % 64;
            rl = mbap(req, tid, unit, 5);
            req[rl++] = fc;
            put16(req + rl, addr);
            put16(req + rl + 2, n);
            rl += 4;
            sl = mbap(rsp, tid, unit, 2 + 2 * n);
            rsp[sl++] = fc;
            rsp[sl++] = (uint8_t)(2 * n);
            for (unsigned i = 0; i < n; ++i, sl += 2) put16(rsp + sl, next_random() & 0xFFFF);
        } else if (kind < 80) { /* FC6 write, echoed */
            rl = mbap(req, tid, unit, 5);
            req[rl++] = 6;
            put16(req + rl, addr);
            put16(req + rl + 2, next_random() & 0xFFFF);
            rl += 4;
            memcpy(rsp, req, rl);
            sl = rl;
        } else { /* FC16 write of 1..16 registers */
            const unsigned n = 1 + next_random() % 16;
            rl = mbap(req, tid, unit, 6 + 2 * n);
            req[rl++] = 16;
            put16(req + rl, addr);
            put16(req + rl + 2, n);
            req[rl + 4] = (uint8_t)(2 * n);
            rl += 5;
            for (unsigned i = 0; i < n; ++i, rl += 2) put16(req + rl, next_random() & 0xFFFF);
            sl = mbap(rsp, tid, unit, 5);
            rsp[sl++] = 16;
            put16(rsp + sl, addr);
            put16(rsp + sl + 2, n);
            sl += 4;
        }
        if (next_random() % 50 == 0) { /* exception 2, illegal data address */
            sl = mbap(rsp, tid, unit, 2);
            rsp[sl++] = (uint8_t)(req[7] | 0x80);
            rsp[sl++] = 2;
        }
        segment(out, us, c, k, 1, req, rl);
        us += 1000;
        segment(out, us, c, k, 0, rsp, sl);
        us += 1000;
    }
    pcap_dump_close(out);
    pcap_close(dead);
    free(cl);
    return 0;
}
