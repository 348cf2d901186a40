#pragma once
// Shared by the analyzer tests: a sink that keeps every record, IPv4 packets built by hand (link type raw
// IP) between a client 10.0.0.1:40000 and a server 10.0.0.2:502 (or another server port), and classic pcap
// files holding records of any link type, and files of any bytes in the test's temporary directory.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/analyzer.hpp"
#include "analyzer/records.hpp"

namespace mbscope::test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;

inline constexpr int link_raw = 101;

struct Collect : an::Sink {
    std::vector<an::FrameRecord> frames;
    std::vector<an::TransactionRecord> transactions;
    std::vector<an::FindingRecord> findings;
    std::vector<an::UnparsedRecord> unparsed_records;
    void frame(const an::FrameRecord& f) override { frames.push_back(f); }
    void transaction(const an::TransactionRecord& t) override { transactions.push_back(t); }
    void finding(const an::FindingRecord& f) override { findings.push_back(f); }
    void unparsed(const an::UnparsedRecord& u) override { unparsed_records.push_back(u); }
    int count(mb::FindingCode c) const {
        int n = 0;
        for (const auto& f : findings)
            n += f.code == c;
        return n;
    }
    // The first finding of the code, or none.
    const an::FindingRecord* first(mb::FindingCode c) const {
        for (const auto& f : findings)
            if (f.code == c) return &f;
        return nullptr;
    }
};

// IPv4 + TCP (or UDP) packet from client 10.0.0.1:40000 to server 10.0.0.2:502, or back. `ack` is the
// acknowledgement number (with flags 0x18, PSH and ACK); the client's port may be another.
inline std::vector<std::uint8_t> packet(bool to_server, std::uint32_t seq,
                                        const std::vector<std::uint8_t>& payload, bool udp = false,
                                        std::uint8_t flags = 0x18, std::uint16_t server_port = 502,
                                        std::uint32_t ack = 0, std::uint16_t client_port = 40000) {
    const std::size_t l4 = udp ? 8 : 20;
    const std::size_t total = 20 + l4 + payload.size();
    std::vector<std::uint8_t> p;
    p.reserve(total);
    const std::uint8_t a[4] = {10, 0, 0, 1}, b[4] = {10, 0, 0, 2};
    const std::uint8_t* src = to_server ? a : b;
    const std::uint8_t* dst = to_server ? b : a;
    p.insert(p.end(), {0x45, 0, static_cast<std::uint8_t>(total >> 8), static_cast<std::uint8_t>(total), 0, 1,
                       0x40, 0, 64, static_cast<std::uint8_t>(udp ? 17 : 6), 0, 0});
    p.insert(p.end(), src, src + 4);
    p.insert(p.end(), dst, dst + 4);
    const std::uint16_t sport = to_server ? client_port : server_port,
                        dport = to_server ? server_port : client_port;
    p.insert(p.end(), {static_cast<std::uint8_t>(sport >> 8), static_cast<std::uint8_t>(sport),
                       static_cast<std::uint8_t>(dport >> 8), static_cast<std::uint8_t>(dport)});
    if (udp) {
        const std::size_t len = 8 + payload.size();
        p.insert(p.end(), {static_cast<std::uint8_t>(len >> 8), static_cast<std::uint8_t>(len), 0, 0});
    } else {
        p.insert(p.end(), {static_cast<std::uint8_t>(seq >> 24), static_cast<std::uint8_t>(seq >> 16),
                           static_cast<std::uint8_t>(seq >> 8), static_cast<std::uint8_t>(seq),
                           static_cast<std::uint8_t>(ack >> 24), static_cast<std::uint8_t>(ack >> 16),
                           static_cast<std::uint8_t>(ack >> 8), static_cast<std::uint8_t>(ack), 0x50, flags,
                           0xFF, 0xFF, 0, 0, 0, 0});
    }
    p.insert(p.end(), payload.begin(), payload.end());
    return p;
}

struct PcapRecord {
    mb::Timestamp time{0};
    std::vector<std::uint8_t> data;
};

// A classic pcap file, little-endian with nanosecond timestamps (magic A1B23C4D), as libpcap reads it.
inline std::vector<std::uint8_t> pcap_file(std::uint32_t linktype, const std::vector<PcapRecord>& records) {
    std::vector<std::uint8_t> f;
    auto u32 = [&f](std::uint64_t v) {
        for (int i = 0; i < 4; ++i)
            f.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
    };
    u32(0xA1B23C4D);
    u32(0x00040002);  // version 2.4 (minor, major as 16-bit halves, little-endian)
    u32(0);           // this zone
    u32(0);           // sigfigs
    u32(65535);       // snap length
    u32(linktype);
    for (const auto& r : records) {
        const auto ns = static_cast<std::uint64_t>(r.time.count());
        u32(ns / 1'000'000'000);
        u32(ns % 1'000'000'000);
        u32(r.data.size());
        u32(r.data.size());
        f.insert(f.end(), r.data.begin(), r.data.end());
    }
    return f;
}

// TCP segments between the client and a server port, sequence numbers kept per direction, as a pcap file.
// Each segment acknowledges everything the other side has sent.
struct Conversation {
    std::uint16_t server_port = 502;
    std::vector<PcapRecord> records;
    std::uint32_t seq[2] = {1000, 5000};
    void send(bool to_server, const std::vector<std::uint8_t>& payload, mb::Timestamp t) {
        records.push_back({t, packet(to_server, seq[to_server ? 0 : 1], payload, false, 0x18, server_port,
                                     seq[to_server ? 1 : 0])});
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
    }
    // Sent, received by the other side, and not captured.
    void lose(bool to_server, const std::vector<std::uint8_t>& payload) {
        seq[to_server ? 0 : 1] += static_cast<std::uint32_t>(payload.size());
    }
    std::vector<std::uint8_t> file() const { return pcap_file(link_raw, records); }
};

// A pcap file run through the analyzer: every record and the summary.
struct Decoded {
    Collect sink;
    an::Summary summary;
};
inline std::unique_ptr<Decoded> decode_pcap(const std::vector<std::uint8_t>& file,
                                            an::AnalyzerOptions options = {}) {
    auto d = std::make_unique<Decoded>();
    an::Analyzer a(std::move(options), d->sink);
    std::string error;
    auto capture = an::CaptureSource::open_memory(file, error);
    if (capture) a.read_capture(*capture);
    if (!capture) a.input_error(error);
    a.finish();
    d->summary = a.summary();
    return d;
}

inline std::vector<std::uint8_t> bytes(std::initializer_list<int> values) {
    std::vector<std::uint8_t> b;
    for (int v : values)
        b.push_back(static_cast<std::uint8_t>(v));
    return b;
}

// Five reads of one holding register (transaction ids 1-5, a second apart), each answered 2 ms later.
inline Conversation five_reads() {
    Conversation c;
    for (std::uint16_t t = 1; t <= 5; ++t) {
        const auto at = mb::Timestamp(std::int64_t{t} * 1'000'000'000);
        c.send(true, bytes({0, t, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1}), at);
        c.send(false, bytes({0, t, 0, 0, 0, 5, 1, 3, 2, 0, t}), at + mb::Timestamp(2'000'000));
    }
    return c;
}

// `command` run by the shell: its exit code and standard output.
inline std::pair<int, std::string> run_command(const std::string& command) {
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe) return {-1, ""};
    std::string out;
    char buf[4096];
    for (std::size_t n; (n = fread(buf, 1, sizeof buf, pipe)) > 0;)
        out.append(buf, n);
    return {WEXITSTATUS(pclose(pipe)), out};
}

// `content` written to `name` in the test's temporary directory; its path.
inline std::string write_temp(const std::string& name, const std::string& content) {
    const std::string path = ::testing::TempDir() + name;
    std::ofstream(path, std::ios::binary) << content;
    return path;
}
inline std::string write_temp(const std::string& name, const std::vector<std::uint8_t>& content) {
    return write_temp(name, std::string(content.begin(), content.end()));
}

}  // namespace mbscope::test
