#pragma once
// What every fuzz target shares: the libFuzzer entry point's signature, a way to fail that names the
// property that broke (libFuzzer and the replay runner both stop on abort), and the accounting check of the
// deframers: every byte fed comes out exactly once, as part of a frame or of an unparsed run, in order.

#include <sanitizer/asan_interface.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <span>
#include <streambuf>
#include <string>
#include <variant>

#include "modbus/frame.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
// Defined by the targets that prepare something once per process (libFuzzer calls it before fuzzing).
extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv);

namespace mbscope::fuzz {

[[noreturn]] inline void fail(const char* target, const std::string& property) {
    std::fprintf(stderr, "%s: property violated: %s\n", target, property.c_str());
    std::fflush(stderr);
    std::abort();
}

// A stream buffer that discards: the output sinks run in full, nothing is kept.
struct NullBuffer : std::streambuf {
    int overflow(int c) override { return c; }
    std::streamsize xsputn(const char*, std::streamsize n) override { return n; }
};

// The deframer targets' event list, emptied and handed out again for every input: it keeps its capacity, so
// an input does not grow a new list of frames (over 300 bytes each) by reallocation. libFuzzer's leak check
// (an input that allocates more than it frees) sees only the first input that allocates it: growing it later
// frees the smaller list.
inline modbus::DeframeEvents& reused_events() {
    static modbus::DeframeEvents events;
    events.clear();
    return events;
}

// Chunks of the input handed to a parser in a buffer that ends where the chunk ends and is poisoned before
// it begins (to ASan's granularity of 8 bytes), so that a read past either end is caught as with a heap
// buffer of the chunk's exact size, without allocating one per chunk (with ASan an allocation fills and
// faults in fresh memory: a vector per chunk was a tenth of the deframer targets' time). The chunk is copied
// to the end of one buffer of the largest chunk's size, whose heap redzone follows it. Without ASan the
// poisoning does nothing.
template <class Provider>  // FuzzedDataProvider (a template parameter: not every includer has the header)
class ExactChunks {
  public:
    explicit ExactChunks(std::size_t max_chunk) : max_(max_chunk), storage_(new std::uint8_t[max_chunk]) {}
    ~ExactChunks() { ASAN_UNPOISON_MEMORY_REGION(storage_.get(), max_); }
    ExactChunks(const ExactChunks&) = delete;
    ExactChunks& operator=(const ExactChunks&) = delete;

    // The next `size` bytes of the input (fewer at its end, at most the largest chunk).
    std::span<const std::uint8_t> take(Provider& in, std::size_t size) {
        const std::size_t n = std::min({size, max_, in.remaining_bytes()});
        std::uint8_t* const begin = storage_.get() + (max_ - n);
        ASAN_UNPOISON_MEMORY_REGION(storage_.get(), max_);
        in.ConsumeData(begin, n);
        ASAN_POISON_MEMORY_REGION(storage_.get(), max_ - n);
        return {begin, n};
    }

  private:
    std::size_t max_;
    std::unique_ptr<std::uint8_t[]> storage_;
};

// Events must tile the stream [0, end): contiguous, in order, nothing twice, nothing missing. `skipped`
// are stream ranges the caller declared lost (TCP holes), which no event covers.
class StreamAccount {
  public:
    explicit StreamAccount(const char* target) : target_(target) {}
    void skip(std::uint64_t missing) { next_ += missing; }
    void take(const modbus::DeframeEvents& events) {
        for (const auto& e : events) {
            const auto [offset, length] = std::visit(
                [](const auto& v) {
                    return std::pair<std::uint64_t, std::uint64_t>{v.offset, length_of(v)};
                },
                e);
            if (offset != next_)
                fail(target_, "event at stream offset " + std::to_string(offset) + " where " +
                                  std::to_string(next_) + " was expected (bytes lost or reported twice)");
            if (length == 0) fail(target_, "empty event at offset " + std::to_string(offset));
            next_ = offset + length;
        }
    }
    void finish(std::uint64_t total) const {
        if (next_ != total)
            fail(target_, std::to_string(total) + " bytes fed, " + std::to_string(next_) + " accounted for");
    }

  private:
    static std::uint64_t length_of(const modbus::Frame& f) { return f.wire_length; }
    static std::uint64_t length_of(const modbus::Unparsed& u) { return u.length; }
    const char* target_;
    std::uint64_t next_ = 0;
};

// Resets the objects a target reuses across inputs (devices made once per process) when an input ends, not
// when the next one begins: what an input allocated (register pages it wrote) is freed within the input, so
// libFuzzer's leak check (more mallocs than frees in one run) is not set off, and the next input meets the
// objects as made.
template <class Objects>  // a range of pointers to objects with reset()
struct ResetAtEnd {
    const Objects& objects;
    ~ResetAtEnd() {
        for (auto* o : objects)
            o->reset();
    }
};
template <class Objects>
ResetAtEnd(const Objects&) -> ResetAtEnd<Objects>;  // clang before 17 deduces no aggregate's arguments

}  // namespace mbscope::fuzz
