#pragma once
// Shared by the analyzer tests: a sink that keeps every record, and IPv4 packets built by hand (link type
// raw IP) between a client 10.0.0.1:40000 and a server 10.0.0.2:502.

#include <cstdint>
#include <vector>

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
};

// IPv4 + TCP (or UDP) packet from client 10.0.0.1:40000 to server 10.0.0.2:502, or back.
inline std::vector<std::uint8_t> packet(bool to_server, std::uint32_t seq,
                                        const std::vector<std::uint8_t>& payload, bool udp = false,
                                        std::uint8_t flags = 0x18) {
    std::vector<std::uint8_t> p;
    const std::size_t l4 = udp ? 8 : 20;
    const std::size_t total = 20 + l4 + payload.size();
    const std::uint8_t a[4] = {10, 0, 0, 1}, b[4] = {10, 0, 0, 2};
    const std::uint8_t* src = to_server ? a : b;
    const std::uint8_t* dst = to_server ? b : a;
    p.insert(p.end(), {0x45, 0, static_cast<std::uint8_t>(total >> 8), static_cast<std::uint8_t>(total), 0, 1,
                       0x40, 0, 64, static_cast<std::uint8_t>(udp ? 17 : 6), 0, 0});
    p.insert(p.end(), src, src + 4);
    p.insert(p.end(), dst, dst + 4);
    const std::uint16_t sport = to_server ? 40000 : 502, dport = to_server ? 502 : 40000;
    p.insert(p.end(), {static_cast<std::uint8_t>(sport >> 8), static_cast<std::uint8_t>(sport),
                       static_cast<std::uint8_t>(dport >> 8), static_cast<std::uint8_t>(dport)});
    if (udp) {
        const std::size_t len = 8 + payload.size();
        p.insert(p.end(), {static_cast<std::uint8_t>(len >> 8), static_cast<std::uint8_t>(len), 0, 0});
    } else {
        p.insert(p.end(), {static_cast<std::uint8_t>(seq >> 24), static_cast<std::uint8_t>(seq >> 16),
                           static_cast<std::uint8_t>(seq >> 8), static_cast<std::uint8_t>(seq), 0, 0, 0, 0,
                           0x50, flags, 0xFF, 0xFF, 0, 0, 0, 0});
    }
    p.insert(p.end(), payload.begin(), payload.end());
    return p;
}

}  // namespace mbscope::test
