// The deframer fuzz targets' chunk buffer (fuzz/fuzz_support.hpp): chunks follow the input in order and in
// the sizes asked for, and, in an ASan build, a read one byte past a chunk or before it is caught as it would
// be with a heap buffer of the chunk's exact size (the point of the buffer).
#include <fuzzer/FuzzedDataProvider.h>
#include <gtest/gtest.h>

#include <numeric>
#include <vector>

#include "fuzz/fuzz_support.hpp"

namespace test_fuzz_exact_chunks_test {

namespace {

using Chunks = mbscope::fuzz::ExactChunks<FuzzedDataProvider>;

TEST(ExactChunks, HandsOutTheInputInOrderInTheSizesAskedFor) {
    std::vector<std::uint8_t> input(100);
    std::iota(input.begin(), input.end(), std::uint8_t{0});
    FuzzedDataProvider in(input.data(), input.size());
    Chunks chunks(64);
    std::vector<std::uint8_t> seen;
    // Asked for 1, 10, 80 and 64: given 1, 10, 64 (the largest chunk) and the 25 bytes left.
    const std::size_t asked[] = {1, 10, 80, 64};
    const std::size_t given[] = {1, 10, 64, 25};
    for (std::size_t i = 0; i < 4; ++i) {
        const auto chunk = chunks.take(in, asked[i]);
        ASSERT_EQ(chunk.size(), given[i]) << "chunk " << i;
        seen.insert(seen.end(), chunk.begin(), chunk.end());
    }
    EXPECT_EQ(seen, input);
    EXPECT_TRUE(chunks.take(in, 5).empty());
}

#if defined(__SANITIZE_ADDRESS__) || (defined(__has_feature) && __has_feature(address_sanitizer))
std::uint8_t read_at(std::span<const std::uint8_t> chunk, std::ptrdiff_t index) {
    return *static_cast<const volatile std::uint8_t*>(chunk.data() + index);
}

TEST(ExactChunksDeathTest, AReadPastTheChunkIsCaught) {
    std::vector<std::uint8_t> input(40, 0x5A);
    FuzzedDataProvider in(input.data(), input.size());
    Chunks chunks(64);
    const auto chunk = chunks.take(in, 10);
    EXPECT_EQ(read_at(chunk, 9), 0x5A);
    EXPECT_DEATH(read_at(chunk, 10), "heap-buffer-overflow");
    EXPECT_DEATH(read_at(chunk, -8), "use-after-poison");
}
#endif

}  // namespace

}  // namespace test_fuzz_exact_chunks_test
