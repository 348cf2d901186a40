#include "modbus/ascii_deframer.hpp"

#include <gtest/gtest.h>

#include "deframer_util.hpp"
#include "test_util.hpp"

namespace test_modbus_ascii_deframer_test {

using namespace mbscope::test;
namespace mb = mbscope::modbus;
using namespace std::chrono_literals;

namespace {

const std::string appendix_b = ":11100060000204000A01026C\r\n";  // 000:4330
const std::string fc3_request = ":11030060000389\r\n";           // MK-ASC-02
const std::string fc3_response = ":110306022B0000006455\r\n";    // MK-ASC-02

mb::DeframeEvents run(const std::string& text, const std::vector<std::size_t>& sizes) {
    mb::AsciiDeframer d;
    mb::DeframeEvents out;
    std::size_t pos = 0;
    for (auto n : sizes) {
        d.feed({reinterpret_cast<const std::uint8_t*>(text.data()) + pos, n}, out);
        pos += n;
    }
    d.finish(out);
    return out;
}

}  // namespace

TEST(AsciiDeframer, ManualFramesInEveryChunking) {
    const std::string text = fc3_request + fc3_response + appendix_b;
    for (const auto& sizes : chunkings(text.size(), 40, 3)) {
        auto events = run(text, sizes);
        expect_every_byte_accounted(events, text.size());
        ASSERT_EQ(events.size(), 3u);
        for (const auto& e : events) {
            const auto& f = std::get<mb::Frame>(e);
            EXPECT_TRUE(f.checksum_ok);
            EXPECT_EQ(f.unit_id(), 0x11);
        }
        EXPECT_EQ(std::get<mb::Frame>(events[2]).wire_length, appendix_b.size());
    }
}

TEST(AsciiDeframer, NoiseOutsideFramesIsReported) {
    const std::string text = "xx\r\n" + fc3_request + "  " + appendix_b + "zz";
    auto events = run(text, {text.size()});
    expect_every_byte_accounted(events, text.size());
    ASSERT_EQ(events.size(), 5u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::NoStart);
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).length, 4u);
}

TEST(AsciiDeframer, NewColonBeforeCrLfAbandonsTheFrame) {
    const std::string text = ":110300" + appendix_b;
    auto events = run(text, {text.size()});
    expect_every_byte_accounted(events, text.size());
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::MissingEnd);
    EXPECT_TRUE(std::get<mb::Frame>(events[1]).checksum_ok);
}

TEST(AsciiDeframer, InterCharacterTimeoutAbandonsTheFrame) {
    // MK-ASC-03 (000:304): ":1103006", a pause of 1.5 s, then "0000389\r\n" → neither piece is a frame.
    mb::AsciiDeframer d;
    mb::DeframeEvents out;
    const std::string a = ":1103006", b = "0000389\r\n";
    d.feed({reinterpret_cast<const std::uint8_t*>(a.data()), a.size()}, mb::Timestamp(10s), out);
    d.feed({reinterpret_cast<const std::uint8_t*>(b.data()), b.size()}, mb::Timestamp(11500ms), out);
    d.finish(out);
    expect_every_byte_accounted(out, a.size() + b.size());
    for (const auto& e : out)
        EXPECT_TRUE(std::holds_alternative<mb::Unparsed>(e));
    EXPECT_EQ(std::get<mb::Unparsed>(out[0]).reason, mb::UnparsedReason::Timeout);
}

TEST(AsciiDeframer, PauseUnderTheTimeoutKeepsTheFrame) {
    mb::AsciiDeframer d;
    mb::DeframeEvents out;
    const std::string a = ":1103006", b = "0000389\r\n";
    d.feed({reinterpret_cast<const std::uint8_t*>(a.data()), a.size()}, mb::Timestamp(10s), out);
    d.feed({reinterpret_cast<const std::uint8_t*>(b.data()), b.size()}, mb::Timestamp(10500ms), out);
    d.finish(out);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_TRUE(std::get<mb::Frame>(out[0]).checksum_ok);
}

TEST(AsciiDeframer, BadLrcAndLowerCaseStillGiveFrames) {
    const std::string text = ":11100060000204000A01026D\r\n:11030060000389\r\n:11100060000204000a01026c\r\n";
    auto events = run(text, {text.size()});
    ASSERT_EQ(events.size(), 3u);
    EXPECT_TRUE(std::get<mb::Frame>(events[0]).findings.contains(mb::FindingCode::AsciiLrcMismatch));
    EXPECT_TRUE(std::get<mb::Frame>(events[1]).findings.empty());
    EXPECT_TRUE(std::get<mb::Frame>(events[2]).findings.contains(mb::FindingCode::AsciiLowercaseHex));
}

TEST(AsciiDeframer, BadCharactersOddLengthAndTruncation) {
    const std::string text = ":11G3\r\n:110\r\n:1103";
    auto events = run(text, {text.size()});
    expect_every_byte_accounted(events, text.size());
    ASSERT_EQ(events.size(), 3u);
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::BadCharacter);
    EXPECT_EQ(std::get<mb::Unparsed>(events[1]).reason, mb::UnparsedReason::OddLength);
    EXPECT_EQ(std::get<mb::Unparsed>(events[2]).reason, mb::UnparsedReason::Truncated);
}

TEST(AsciiDeframer, OverlongFrameIsCut) {
    std::string text = ":" + std::string(600, '0') + "\r\n" + fc3_request;
    auto events = run(text, {text.size()});
    expect_every_byte_accounted(events, text.size());
    EXPECT_EQ(std::get<mb::Unparsed>(events[0]).reason, mb::UnparsedReason::TooLong);
    EXPECT_TRUE(std::get<mb::Frame>(events.back()).checksum_ok);
}

}  // namespace test_modbus_ascii_deframer_test
