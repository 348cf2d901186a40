// Text files read with bounds (modbus/storage/text_file.hpp): lines cut at the bound and read past, whole
// files refused over their limit, so a hostile file is an error naming it rather than all the memory there
// is.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "modbus/storage/text_file.hpp"

namespace test_modbus_text_file_test {

namespace st = mbscope::modbus::storage;

namespace {

struct Line {
    std::string text;
    std::uint64_t number;
    bool too_long;
    std::uint64_t length;
};

std::vector<Line> read_all(const std::string& text, std::size_t bound) {
    std::istringstream in(text);
    st::LineReader reader(in, bound);
    std::vector<Line> out;
    for (std::string line; reader.next(line);)
        out.push_back({line, reader.number(), reader.too_long(), reader.length()});
    return out;
}

std::string temp_file(const std::string& name, const std::string& text) {
    const auto path = (std::filesystem::temp_directory_path() / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

}  // namespace

TEST(LineReader, ReadsLinesAsGetlineDoesWithinTheBound) {
    const auto lines = read_all("one\n\ntwo\r\nlast", 8);
    ASSERT_EQ(lines.size(), 4u);
    EXPECT_EQ(lines[0].text, "one");
    EXPECT_EQ(lines[1].text, "");
    EXPECT_EQ(lines[2].text, "two\r");  // CR is the caller's to trim, as with std::getline
    EXPECT_EQ(lines[3].text, "last");   // a last line without LF counts
    for (std::size_t i = 0; i < lines.size(); ++i) {
        EXPECT_EQ(lines[i].number, i + 1);
        EXPECT_FALSE(lines[i].too_long);
        EXPECT_EQ(lines[i].length, lines[i].text.size());
    }
    EXPECT_TRUE(read_all("", 8).empty());
    EXPECT_EQ(read_all("\n", 8).size(), 1u);
    EXPECT_EQ(read_all("a\n", 8).size(), 1u);  // the LF ends the line, it starts none
}

TEST(LineReader, ALineOfExactlyTheBoundIsWhole) {
    const auto lines = read_all("12345678\n12345678", 8);
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_EQ(lines[0].text, "12345678");
    EXPECT_FALSE(lines[0].too_long);
    EXPECT_EQ(lines[1].text, "12345678");
    EXPECT_FALSE(lines[1].too_long);
}

TEST(LineReader, ALongerLineIsCutMeasuredAndReadPast) {
    // One over the bound, several times the bound (the rest read past a bound at a time, ending exactly on
    // a multiple of it), then lines that must come out as they are, with their numbers.
    const std::string over(9, 'a'), many(32, 'b');
    const auto lines = read_all(over + "\n" + many + "\nnext\n" + many + "c\nend", 8);
    ASSERT_EQ(lines.size(), 5u);
    EXPECT_TRUE(lines[0].too_long);
    EXPECT_EQ(lines[0].text, std::string(8, 'a'));
    EXPECT_EQ(lines[0].length, 9u);
    EXPECT_TRUE(lines[1].too_long);
    EXPECT_EQ(lines[1].length, 32u);
    EXPECT_EQ(lines[2].text, "next");
    EXPECT_FALSE(lines[2].too_long);
    EXPECT_EQ(lines[2].number, 3u);
    EXPECT_TRUE(lines[3].too_long);
    EXPECT_EQ(lines[3].length, 33u);
    EXPECT_EQ(lines[4].text, "end");
    EXPECT_EQ(lines[4].number, 5u);
}

TEST(LineReader, ALongLineThatEndsTheInputIsMeasuredToItsEnd) {
    for (std::size_t n : {9u, 16u, 17u, 100u}) {
        const auto lines = read_all("x\n" + std::string(n, 'z'), 8);
        ASSERT_EQ(lines.size(), 2u) << n;
        EXPECT_TRUE(lines[1].too_long) << n;
        EXPECT_EQ(lines[1].length, n);
    }
    const auto message = [] {
        std::istringstream in(std::string(20, 'q'));
        st::LineReader reader(in, 8);
        std::string line;
        reader.next(line);
        return st::too_long_line_message(reader);
    }();
    EXPECT_EQ(message, "line of 20 bytes is longer than the 8 a line may hold: skipped");
}

// Lines are read a piece at a time (4 KiB): lines around and across the pieces' size come out whole, and
// the bound cuts across pieces.
TEST(LineReader, LinesLongerThanAPieceComeOutWhole) {
    std::string text;
    const std::size_t sizes[] = {4094, 4095, 4096, 4097, 8190, 8191, 9000, 12000};
    for (std::size_t n : sizes)
        text += std::string(n, static_cast<char>('a' + n % 26)) + "\n";
    text += std::string(8191, 'z');  // the last, without LF, a piece's multiple less one
    const auto lines = read_all(text, 10000);
    ASSERT_EQ(lines.size(), std::size(sizes) + 1);
    for (std::size_t i = 0; i < std::size(sizes); ++i) {
        EXPECT_EQ(lines[i].length, sizes[i]);
        EXPECT_EQ(lines[i].too_long, sizes[i] > 10000) << sizes[i];
        EXPECT_EQ(lines[i].text, std::string(std::min<std::size_t>(sizes[i], 10000),
                                             static_cast<char>('a' + sizes[i] % 26)));
        EXPECT_EQ(lines[i].number, i + 1);
    }
    EXPECT_EQ(lines.back().text, std::string(8191, 'z'));
}

TEST(ReadTextFile, ReadsWithinTheLimitAndRefusesBeyondIt) {
    const auto path = temp_file("mbscope-text-file-test.txt", std::string(100, 'x'));
    std::string error;
    const auto whole = st::read_text_file(path, error, 100);
    ASSERT_TRUE(whole.has_value()) << error;
    EXPECT_EQ(whole->size(), 100u);
    EXPECT_FALSE(st::read_text_file(path, error, 99).has_value());
    EXPECT_EQ(error, "larger than 99 bytes, the most a document may hold (not read)");
    EXPECT_FALSE(st::read_text_file(path + ".missing", error).has_value());
    EXPECT_EQ(error, "cannot open");
    std::remove(path.c_str());
}

}  // namespace test_modbus_text_file_test
