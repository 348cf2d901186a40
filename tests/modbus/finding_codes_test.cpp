#include "modbus/finding_codes.hpp"

#include <gtest/gtest.h>

#include <set>

namespace test_modbus_finding_codes_test {

namespace mb = mbscope::modbus;

TEST(FindingCodes, NamesAreStableDottedAndUnique) {
    std::set<std::string_view> names;
    std::set<std::uint16_t> codes;
    // area "." snake_case (std::regex is avoided: GCC 12 warns inside <regex> under the sanitizers)
    auto well_formed = [](std::string_view name) {
        const auto dot = name.find('.');
        if (dot == std::string_view::npos || dot + 1 == name.size()) return false;
        const std::set<std::string_view> areas{"pdu",  "rtu",    "ascii",   "tcp",
                                               "pair", "timing", "profile", "stream"};
        if (!areas.count(name.substr(0, dot))) return false;
        for (char c : name.substr(dot + 1))
            if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
        return true;
    };
    for (const auto& f : mb::all_findings()) {
        EXPECT_TRUE(well_formed(f.name)) << f.name;
        EXPECT_TRUE(names.insert(f.name).second) << "duplicate name " << f.name;
        EXPECT_TRUE(codes.insert(static_cast<std::uint16_t>(f.code)).second) << "duplicate code " << f.name;
        EXPECT_FALSE(f.summary.empty()) << f.name;
        EXPECT_FALSE(f.rule.empty()) << f.name;
        EXPECT_EQ(mb::finding_from_name(f.name), f.code);
        EXPECT_EQ(&mb::info(f.code), &f);
    }
}

TEST(FindingCodes, SmallListKeepsOrderAndDeduplicates) {
    mb::FindingList l;
    l.add(mb::FindingCode::RtuCrcMismatch);
    l.add(mb::FindingCode::RtuGapInsideFrame);
    l.add(mb::FindingCode::RtuCrcMismatch);
    EXPECT_EQ(l.size(), 2u);
    EXPECT_EQ(*l.begin(), mb::FindingCode::RtuCrcMismatch);
}

}  // namespace test_modbus_finding_codes_test
