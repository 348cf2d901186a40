#pragma once
// Shared checks for deframer tests: every byte fed is in exactly one frame or unparsed record.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "modbus/frame.hpp"

namespace mbscope::test {

struct Piece {
    std::uint64_t offset;
    std::uint64_t length;
    bool frame;
};

inline std::vector<Piece> pieces(const modbus::DeframeEvents& events) {
    std::vector<Piece> out;
    for (const auto& e : events) {
        if (const auto* f = std::get_if<modbus::Frame>(&e))
            out.push_back({f->offset, f->wire_length, true});
        else {
            const auto& u = std::get<modbus::Unparsed>(e);
            out.push_back({u.offset, u.length, false});
        }
    }
    return out;
}

// Asserts the events tile [0, total) exactly, in order.
inline void expect_every_byte_accounted(const modbus::DeframeEvents& events, std::uint64_t total) {
    std::uint64_t next = 0;
    for (const auto& p : pieces(events)) {
        ASSERT_EQ(p.offset, next) << "hole or overlap before offset " << p.offset;
        ASSERT_GT(p.length, 0u);
        next = p.offset + p.length;
    }
    EXPECT_EQ(next, total) << "bytes lost at the end";
}

inline std::vector<std::vector<std::uint8_t>> frames_bytes(const modbus::DeframeEvents& events) {
    std::vector<std::vector<std::uint8_t>> out;
    for (const auto& e : events)
        if (const auto* f = std::get_if<modbus::Frame>(&e))
            out.emplace_back(f->adu().begin(), f->adu().end());
    return out;
}

// Splits `data` into chunks: size 1, whole, and `random_splits` random chunkings.
inline std::vector<std::vector<std::size_t>> chunkings(std::size_t size, int random_splits, unsigned seed) {
    std::vector<std::vector<std::size_t>> all;
    all.push_back(std::vector<std::size_t>(size, 1));
    all.push_back({size});
    std::mt19937 rng(seed);
    for (int i = 0; i < random_splits; ++i) {
        std::vector<std::size_t> sizes;
        std::size_t left = size;
        while (left) {
            std::size_t n = std::min<std::size_t>(left, 1 + rng() % 40);
            sizes.push_back(n);
            left -= n;
        }
        all.push_back(sizes);
    }
    return all;
}

}  // namespace mbscope::test
