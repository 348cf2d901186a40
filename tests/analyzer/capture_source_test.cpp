// Capture files are read ahead by a thread of their own, in batches; memory is read in the caller's thread.
// Both must give the same packets, in the same order, with the same damage reports: these tests read one
// file both ways, with enough packets and bytes for many batches and a ring that fills up.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "analyzer/capture_source.hpp"
#include "test_packets.hpp"

namespace test_analyzer_capture_source_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;

namespace {

// 6,000 records of 1 to 1,500 bytes (several batches by count and by size), each filled from its number.
std::vector<std::uint8_t> many_records() {
    std::vector<mbscope::test::PcapRecord> records;
    for (std::uint32_t i = 0; i < 6000; ++i) {
        std::vector<std::uint8_t> data(1 + (i * 7919) % 1500);
        for (std::size_t k = 0; k < data.size(); ++k)
            data[k] = static_cast<std::uint8_t>(i * 31 + k);
        records.push_back({mb::Timestamp(1'700'000'000'000'000'000 + i * 1'000'003), std::move(data)});
    }
    return mbscope::test::pcap_file(mbscope::test::link_raw, records);
}

struct Seen {
    std::uint64_t number;
    mb::Timestamp time;
    int linktype;
    std::vector<std::uint8_t> data;
    std::uint32_t original_length;
    std::uint64_t offset;
    bool operator==(const Seen&) const = default;
};

std::vector<Seen> read_all(an::CaptureSource& source) {
    std::vector<Seen> seen;
    while (auto p = source.next())
        seen.push_back({p->number,
                        p->time,
                        p->linktype,
                        {p->data.begin(), p->data.end()},
                        p->original_length,
                        source.offset()});
    return seen;
}

// The same bytes as a file (read ahead) and from memory (read in this thread), each read to its end.
struct ReadBothWays {
    std::string path;
    std::unique_ptr<an::CaptureSource> file, memory;
    std::vector<Seen> from_file, from_memory;
    ReadBothWays(const std::vector<std::uint8_t>& bytes, const std::string& name)
        : path(mbscope::test::write_temp(name + ".pcap", bytes)) {
        std::string error;
        file = an::CaptureSource::open_file(path, error);
        EXPECT_TRUE(file) << error;
        memory = an::CaptureSource::open_memory(bytes, error);
        EXPECT_TRUE(memory) << error;
        if (file) from_file = read_all(*file);
        if (memory) from_memory = read_all(*memory);
        std::filesystem::remove(path);
    }
};

}  // namespace

TEST(CaptureSource, FileReadAheadGivesWhatMemoryGives) {
    const auto bytes = many_records();
    const ReadBothWays read(bytes, "mbscope-read-ahead");
    ASSERT_TRUE(read.file && read.memory);
    const auto& [path, file, memory, from_file, from_memory] = read;
    EXPECT_EQ(file->linktype(), memory->linktype());  // DLT_RAW: libpcap names LINKTYPE_RAW by its DLT
    ASSERT_EQ(from_file.size(), 6000u);
    EXPECT_TRUE(from_file == from_memory);
    EXPECT_EQ(from_file.back().offset, bytes.size());  // where each packet ends, the last at the file's end
    EXPECT_EQ(from_file.front().offset, 24u + 16u + 1u);
    EXPECT_TRUE(file->error().empty()) << file->error();
    EXPECT_FALSE(file->next());  // the end stays the end
}

TEST(CaptureSource, DamageFarIntoAFileIsReportedAfterEveryPacketBeforeIt) {
    auto bytes = many_records();
    // cut inside record 4,001: 4,000 whole records, then a header that promises more than is left
    std::size_t at = 24;
    for (int i = 0; i < 4000; ++i)
        at += 16 + (bytes[at + 8] | bytes[at + 9] << 8);
    const std::size_t record_4001 = at;
    bytes.resize(at + 16 + 1);
    const ReadBothWays read(bytes, "mbscope-read-ahead-cut");
    ASSERT_TRUE(read.file && read.memory);
    const auto& [path, file, memory, from_file, from_memory] = read;
    EXPECT_EQ(from_file.size(), 4000u);
    EXPECT_TRUE(from_file == from_memory);
    const std::string where = ": packet 4001 at byte offset " + std::to_string(record_4001) + ": truncated";
    EXPECT_EQ(file->error().rfind(path + where, 0), 0u) << file->error();
    EXPECT_EQ(memory->error().rfind("memory" + where, 0), 0u) << memory->error();
    EXPECT_EQ(file->error().substr(path.size()), memory->error().substr(6));
}

TEST(CaptureSource, ClosingBeforeTheEndStopsTheReader) {
    const auto bytes = many_records();
    const auto path = mbscope::test::write_temp("mbscope-read-ahead-stop.pcap", bytes);
    for (int read = 0; read < 3000; read += 700) {  // stopped at the start, inside and between batches
        std::string error;
        auto file = an::CaptureSource::open_file(path, error);
        ASSERT_TRUE(file) << error;
        for (int i = 0; i < read; ++i)
            ASSERT_TRUE(file->next()) << i;
        file.reset();  // joins the reading thread, which may be waiting for room in its ring
    }
    std::filesystem::remove(path);
}

}  // namespace test_analyzer_capture_source_test
