// The reference slave's Device against the rules of each profile's manual (../shared/spec/manual-rules.md
// gives the rule ids and lines; the manuals are ../shared/seeds/). Every case drives slave::Device in
// process with request PDU bytes and checks the reply PDU bytes exactly; "" means no answer.
//
//  - EveryProfile: rules derived from each of the bundled profiles (all 48 ids of the profile store):
//    unsupported function codes, quantity limits, unmapped addresses, broadcast, read-only points, ranges,
//    enumerations, FC5 values, FC8.
//  - Manual: hand-written exchanges citing the manual's lines and rule ids (the manuals' worked frames
//    where they exist), one instantiation per manual, plus the generic profile's specification examples.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <functional>
#include <utility>

#include "modbus/function_code.hpp"
#include "tests/slave/slave_test_support.hpp"

namespace mbscope::slave::test::test_slave_rules_test {
namespace {

using mb::Table;

std::uint8_t u8(int v) {
    return static_cast<std::uint8_t>(v);
}

std::string exception_hex(int fc, int code) {
    const std::uint8_t pdu[] = {u8(fc | 0x80), u8(code)};
    return hex(pdu);
}

using test::ask;
std::string ask(Device& d, const std::vector<std::uint8_t>& pdu, bool broadcast = false) {
    return hex(d.handle({pdu, broadcast}).pdu);
}

std::string zeros(std::size_t n) {
    std::string out;
    for (std::size_t i = 0; i < n; ++i)
        out += i ? " 00" : "00";
    return out;
}

Table table_of(int fc) {
    switch (fc) {
        case 1:
        case 5:
        case 15:
            return Table::Coils;
        case 2:
            return Table::DiscreteInputs;
        case 4:
            return Table::InputRegisters;
        default:
            return Table::HoldingRegisters;
    }
}

bool mapped(const mb::Profile& p, Table t, std::uint32_t a) {
    return p.open_address_space || p.find(t, static_cast<std::uint16_t>(a)) != nullptr;
}

// The lowest address the map does not hold at or after `from` (65536 when there is none).
std::uint32_t first_unmapped(const mb::Profile& p, Table t, std::uint32_t from = 0) {
    while (from < 65536 && mapped(p, t, from))
        ++from;
    return from;
}

std::uint16_t first_point(const mb::Profile& p, Table t) {
    const auto& points = p.table(t);
    return points.empty() ? 0 : points.front().address;
}

std::uint16_t word(std::uint16_t v, std::vector<std::uint8_t>& out) {
    out.push_back(u8(v >> 8));
    out.push_back(u8(v));
    return v;
}

std::vector<std::uint8_t> write_single(int fc, std::uint16_t address, std::uint16_t value) {
    std::vector<std::uint8_t> pdu{u8(fc)};
    word(address, pdu);
    word(value, pdu);
    return pdu;
}

std::vector<std::uint8_t> write_registers(std::uint16_t start, const std::vector<std::uint16_t>& values) {
    std::vector<std::uint8_t> pdu{16};
    word(start, pdu);
    word(static_cast<std::uint16_t>(values.size()), pdu);
    pdu.push_back(u8(2 * values.size()));
    for (auto v : values)
        word(v, pdu);
    return pdu;
}

std::vector<std::uint16_t> float_words(float f, mb::WordOrder order) {
    std::uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    const auto w = mb::split_words(u, order);
    return {w[0], w[1]};
}

bool is_signed(const mb::Point& p) {
    return p.encoding.type == mb::EncodingType::S16 || p.encoding.is_signed;
}

// The first point of the holding registers that satisfies `want`, nullptr when none does.
const mb::Point* find_point(const mb::Profile& p, const std::function<bool(const mb::Point&)>& want) {
    for (const auto& pt : p.table(Table::HoldingRegisters))
        if (want(pt)) return &pt;
    return nullptr;
}

bool writable_word(const mb::Point& pt) {
    return pt.access != mb::Access::Read && !pt.reserved && !pt.fixed_value && pt.encoding.words == 1 &&
           !pt.min_from && !pt.max_from;
}

// ---------------------------------------------------------------------------------------------------------
// Rules derived from every bundled profile.

// Runs `check` on a fresh device of every bundled profile that `has` accepts, the profile named in any
// failure. One test per rule, its table the bundled profiles: a test process per profile and rule would
// spend more on starting (every process loads every profile) than on the checks.
template <typename Has, typename Check>
void for_profiles(Has has, Check check) {
    for (const auto& id : profile_ids()) {
        const mb::Profile& p = profile(id);
        if (!has(p)) continue;
        SCOPED_TRACE(id);
        Device device{p, 1};
        check(p, device);
    }
}

// Some rules have a subject only in some profiles (a read-only register, a range, FC8, ...): each runs over
// the bundled profiles that have it, and RulesWithoutASubjectLeaveOutOnlyTheseProfiles names the others.

// A read-only single register, nullptr when the map has none.
const mb::Point* read_only_register(const mb::Profile& p) {
    return find_point(p, [](const mb::Point& pt) {
        return pt.access == mb::Access::Read && !pt.reserved && pt.encoding.words == 1;
    });
}

// A writable single register with a range that FC6 can step past, nullptr when none.
const mb::Point* ranged_register(const mb::Profile& p) {
    return find_point(p, [](const mb::Point& x) {
        if (!writable_word(x) || !x.max || x.encoding.type == mb::EncodingType::Enum) return false;
        return *x.max + 1 <= (is_signed(x) ? 32767 : 65535);
    });
}

// A writable 32-bit float with a range, nullptr when none.
const mb::Point* ranged_float(const mb::Profile& p) {
    return find_point(p, [](const mb::Point& x) {
        return x.access != mb::Access::Read && x.encoding.type == mb::EncodingType::F32 && x.max;
    });
}

// A writable enumeration, nullptr when none.
const mb::Point* enumerated_register(const mb::Profile& p) {
    return find_point(p, [](const mb::Point& x) {
        return writable_word(x) && x.encoding.type == mb::EncodingType::Enum && !x.encoding.values.empty();
    });
}

// The subjects the rules below need, each a predicate on a profile.
bool every_profile(const mb::Profile&) {
    return true;
}
bool has_unmapped_addresses(const mb::Profile& p) {
    return !p.open_address_space;
}
bool maps_every_address(const mb::Profile& p) {
    return p.open_address_space;
}
bool has_read_only_register(const mb::Profile& p) {
    return read_only_register(p) != nullptr;
}
bool has_range(const mb::Profile& p) {
    return ranged_register(p) || ranged_float(p);
}
bool has_enumeration(const mb::Profile& p) {
    return enumerated_register(p) != nullptr;
}
bool has_fc5(const mb::Profile& p) {
    return p.functions.supports(5);
}
bool has_fc8(const mb::Profile& p) {
    return p.functions.supports(8);
}

// MK-FC-01 (000:287, 313), WA-FC-01 (002:226-238), CTH-FC-01 (003:498), AP §7: a function the device does
// not list is answered with exception 01 — every profile's manual (or the specification) says 01.
TEST(EveryProfile, UnsupportedFunctionIsException01) {
    for_profiles(every_profile, [&](const mb::Profile& p, Device& device) {
        for (int fc = 1; fc < 0x80; ++fc) {
            if (p.functions.supports(u8(fc))) continue;
            SCOPED_TRACE("FC" + std::to_string(fc));
            EXPECT_EQ(ask(device, {u8(fc), 0x00, 0x00, 0x00, 0x01}), exception_hex(fc, 0x01));
        }
    });
}

// MK-FC01-02, MK-FC03-01, MK-FC15-01, MK-FC16-01 (000:325, 351, 431, 451), WA-FC01-01..WA-FC16-01
// (002:232-238), CTH-FC03-01/CTH-FC16-01 (003:518, 560), AP §6: one more than the profile's limit, and
// zero, are exception 03 — checked before the address (AP §6 state diagrams), so the start is a valid one.
TEST(EveryProfile, QuantityAboveTheLimitOrZeroIsException03) {
    for_profiles(every_profile, [&](const mb::Profile& p, Device& device) {
        for (int fc : {1, 2, 3, 4, 15, 16}) {
            if (!p.functions.supports(u8(fc))) continue;
            const int limit = p.functions.max_for(u8(fc));
            const std::uint16_t start = first_point(p, table_of(fc));
            for (std::uint32_t q : {static_cast<std::uint32_t>(limit + 1), 0u}) {
                SCOPED_TRACE("FC" + std::to_string(fc) + " quantity " + std::to_string(q));
                // A write of one more than FC16's 123 registers (or Walchem's 125) needs a PDU longer than
                // the device takes (AP §4.1: 253): no frame carries it, an overrun (device.hpp). Sent with
                // the byte count of one register, it is refused all the same.
                const auto request = quantity_request(u8(fc), start, q);
                if (request.size() > p.line.pdu_max_bytes) {
                    EXPECT_EQ(ask(device, request), "");
                    EXPECT_EQ(ask(device, {u8(fc), u8(start >> 8), u8(start), u8(q >> 8), u8(q), 2, 0, 0}),
                              exception_hex(fc, 0x03));
                    continue;
                }
                EXPECT_EQ(ask(device, request), exception_hex(fc, 0x03));
            }
        }
        if (p.functions.supports(23)) {  // AP §6.17: read part 125, write part 121
            const int read_limit = p.functions.max_for(23), write_limit = p.functions.max_for(23, true);
            std::vector<std::uint8_t> over_read{
                23, 0, 0, u8((read_limit + 1) >> 8), u8(read_limit + 1), 0, 0, 0, 1, 2, 0, 0};
            EXPECT_EQ(ask(device, over_read), exception_hex(23, 0x03));
            std::vector<std::uint8_t> over_write{
                23, 0, 0, 0, 1, 0, 0, 0, u8(write_limit + 1), u8(2 * (write_limit + 1))};
            over_write.insert(over_write.end(), 2 * (write_limit + 1), 0);
            // 122 registers to write need a PDU of 254 bytes, more than the specification's 253.
            EXPECT_EQ(ask(device, over_write),
                      over_write.size() > p.line.pdu_max_bytes ? "" : exception_hex(23, 0x03));
            over_write.resize(10);
            over_write.back() = 2;
            over_write.insert(over_write.end(), 2, 0);
            EXPECT_EQ(ask(device, over_write), exception_hex(23, 0x03));
        }
    });
}

// The limit itself is not a quantity error: a read of exactly the maximum is answered with data, or with 02
// when the map has a hole in the range (AP §6: the quantity check passes, the address check decides).
TEST(EveryProfile, QuantityAtTheLimitIsNotRefusedForItsSize) {
    for_profiles(every_profile, [&](const mb::Profile& p, Device& device) {
        for (int fc : {1, 2, 3, 4}) {
            if (!p.functions.supports(u8(fc))) continue;
            const auto limit = static_cast<std::uint32_t>(p.functions.max_for(u8(fc)));
            SCOPED_TRACE("FC" + std::to_string(fc) + " quantity " + std::to_string(limit));
            const std::string reply =
                ask(device, quantity_request(u8(fc), first_point(p, table_of(fc)), limit));
            EXPECT_NE(reply, exception_hex(fc, 0x03));
            if (reply.substr(0, 2) == hex(std::vector<std::uint8_t>{u8(fc)})) {
                const std::size_t data = fc <= 2 ? (limit + 7) / 8 : 2 * limit;
                EXPECT_EQ(bytes(reply).size(), 2 + data);
            }
        }
    });
}

// MK-EXC-03/05 (000:476, 481-484), WA-EXC-03 (002:390), CTH-EXC-01 (003:566-574), MK-MODEL-01: an address
// the map lacks is exception 02, for reads and writes, at the first hole and one past the last point.
TEST(MappedProfile, UnmappedAddressIsException02) {
    for_profiles(has_unmapped_addresses, [&](const mb::Profile& p, Device& device) {
        for (int fc : {1, 2, 3, 4, 5, 6, 15, 16}) {
            if (!p.functions.supports(u8(fc))) continue;
            const Table t = table_of(fc);
            const auto& points = p.table(t);
            std::vector<std::uint32_t> holes{first_unmapped(p, t)};
            if (!points.empty()) holes.push_back(first_unmapped(p, t, points.back().address + 1u));
            for (std::uint32_t a : holes) {
                if (a > 65535) continue;
                SCOPED_TRACE("FC" + std::to_string(fc) + " address " + std::to_string(a));
                const auto address = static_cast<std::uint16_t>(a);
                std::vector<std::uint8_t> request;
                if (fc == 5)
                    request = write_single(5, address, 0xFF00);
                else if (fc == 6)
                    request = write_single(6, address, 0);
                else
                    request = quantity_request(u8(fc), address, 1);
                EXPECT_EQ(ask(device, request), exception_hex(fc, 0x02));
            }
        }
    });
}

// AP §6 (every address of the range must exist) against WA-EXC-03 (002:390: "only if the first requested
// register is not valid"): a read that starts on the last mapped address before a hole and runs into it is
// 02 on devices that check every address, answered with data on devices that check the first only.
TEST(MappedProfile, ReadRunningIntoAHoleFollowsTheAddressCheck) {
    for_profiles(has_unmapped_addresses, [&](const mb::Profile& p, Device& device) {
        const Table t = Table::HoldingRegisters;
        const std::uint32_t hole = first_unmapped(p, t, first_point(p, t));
        ASSERT_GT(hole, 0u);
        ASSERT_LT(hole, 65536u);
        const std::string reply = ask(device, quantity_request(3, static_cast<std::uint16_t>(hole - 1), 2));
        if (p.functions.address_check == mb::AddressCheck::First)
            EXPECT_EQ(bytes(reply).size(), 6u) << reply;
        else
            EXPECT_EQ(reply, "83 02");
    });
}

// AP §4.3: a device may map every address of every table; the generic profile does, so no address is 02,
// from the first to the last, and a read running over the top of the space is still answered with data.
TEST(OpenProfile, EveryAddressIsAnswered) {
    for_profiles(maps_every_address, [&](const mb::Profile&, Device& device) {
        for (int fc : {1, 2, 3, 4}) {
            for (std::uint16_t a : {0x0000, 0x7FFF, 0xFFFF}) {
                SCOPED_TRACE("FC" + std::to_string(fc) + " address " + std::to_string(a));
                EXPECT_EQ(bytes(ask(device, quantity_request(u8(fc), a, 1))).size(), fc <= 2 ? 3u : 4u);
            }
            EXPECT_EQ(bytes(ask(device, quantity_request(u8(fc), 0xFFF0, 16))).size(), fc <= 2 ? 4u : 34u);
        }
        EXPECT_EQ(ask(device, write_single(6, 0xFFFF, 0x1234)), hex(write_single(6, 0xFFFF, 0x1234)));
        EXPECT_EQ(ask(device, write_single(5, 0xFFFF, 0xFF00)), hex(write_single(5, 0xFFFF, 0xFF00)));
        EXPECT_EQ(device.image().reg(Table::HoldingRegisters, 0xFFFF), 0x1234);
    });
}

// MK-BC-02 (000:313), CTH-BC-02 (003:498), SL §2.1: a read sent to unit 0 is neither executed nor answered.
TEST(EveryProfile, BroadcastReadIsNeverAnswered) {
    for_profiles(every_profile, [&](const mb::Profile& p, Device& device) {
        for (int fc : {1, 2, 3, 4}) {
            if (!p.functions.supports(u8(fc))) continue;
            SCOPED_TRACE("FC" + std::to_string(fc));
            EXPECT_EQ(ask(device, quantity_request(u8(fc), first_point(p, table_of(fc)), 1), true), "");
        }
        EXPECT_EQ(ask(device, {0x08, 0x00, 0x00, 0xA5, 0x37}, true), "");  // even where FC8 is supported
    });
}

// MK-BC-01 (000:248, 285), CTH-BC-01 (003:452, 479), WA-MBAP-05 (002:213, the reading the profile follows):
// a write the profile allows in broadcast is executed and never answered, even when it is refused.
TEST(EveryProfile, BroadcastWriteIsExecutedAndNeverAnswered) {
    for_profiles(every_profile, [&](const mb::Profile& p, Device& device) {
        std::uint16_t address = 0, value = 0x1234;
        if (!p.open_address_space) {
            const mb::Point* target = nullptr;
            for (const auto& pt : p.table(Table::HoldingRegisters)) {
                if (!writable_word(pt)) continue;
                const std::uint16_t current = device.image().reg(Table::HoldingRegisters, pt.address);
                std::vector<std::int64_t> candidates;
                for (const auto& ev : pt.encoding.values)
                    candidates.push_back(ev.value);
                if (pt.min) candidates.push_back(*pt.min);
                if (pt.max) candidates.push_back(*pt.max);
                candidates.insert(candidates.end(), {1, 0x61});
                for (std::int64_t c : candidates) {
                    const auto raw = static_cast<std::uint16_t>(c);
                    if (raw != current && !mb::check_write(p, Table::HoldingRegisters, pt.address, raw)) {
                        target = &pt;
                        value = raw;
                        break;
                    }
                }
                if (target) break;
            }
            ASSERT_NE(target, nullptr) << "no writable register";
            address = target->address;
        }
        const auto& allowed = p.functions.broadcast;
        const bool executes = std::find(allowed.begin(), allowed.end(), 6) != allowed.end();
        const std::uint16_t before = device.image().reg(Table::HoldingRegisters, address);
        EXPECT_EQ(ask(device, write_single(6, address, value), true), "");
        EXPECT_EQ(device.image().reg(Table::HoldingRegisters, address), executes ? value : before);
        EXPECT_EQ(ask(device, write_single(6, 0xFFFF, 0), true), "");  // refused, still silent
    });
}

// MK-RO-01 (000:493 "Somente leitura"), CTH-MAP-02 (003:598-610), WA-GEN-04 (002:172): a read-only point is
// not written. No manual gives the code; every profile leaves it to the specification's 02.
TEST(ProfileWithReadOnly, WriteToReadOnlyPointIsException02) {
    for_profiles(has_read_only_register, [&](const mb::Profile& p, Device& device) {
        const mb::Point* ro = read_only_register(p);
        ASSERT_NE(ro, nullptr);
        const std::uint16_t before = device.image().reg(Table::HoldingRegisters, ro->address);
        SCOPED_TRACE(ro->source);
        EXPECT_EQ(ask(device, write_single(6, ro->address, static_cast<std::uint16_t>(before + 1))), "86 02");
        EXPECT_EQ(device.image().reg(Table::HoldingRegisters, ro->address), before);
    });
}

// MK-RNG-01 (every "Faixa de valores"), WA-EXC-04 (002:391), CTH-EXC-01 (003:566-574): a value outside the
// point's range is exception 03 and not kept; the range's own bound is accepted. 32-bit floats are written
// whole with FC16 in the profile's word order (WA-ADR-04, 002:499).
TEST(ProfileWithRange, ValueOutsideTheRangeIsException03) {
    for_profiles(has_range, [&](const mb::Profile& p, Device& device) {
        if (const mb::Point* pt = ranged_register(p)) {
            SCOPED_TRACE(pt->source + " " + pt->name_en);
            const auto above = static_cast<std::uint16_t>(*pt->max + 1);
            EXPECT_EQ(ask(device, write_single(6, pt->address, above)), "86 03");
            EXPECT_NE(device.image().reg(Table::HoldingRegisters, pt->address), above);
            const auto top = static_cast<std::uint16_t>(*pt->max);
            EXPECT_EQ(ask(device, write_single(6, pt->address, top)), hex(write_single(6, pt->address, top)));
            return;
        }
        const mb::Point* f = ranged_float(p);
        ASSERT_NE(f, nullptr);
        SCOPED_TRACE(f->source + " " + f->name_en);
        const auto order = f->encoding.word_order;
        EXPECT_EQ(
            ask(device, write_registers(f->address, float_words(static_cast<float>(*f->max) + 1, order))),
            "90 03");
        const std::vector<std::uint8_t> ok =
            write_registers(f->address, float_words(static_cast<float>(*f->max), order));
        EXPECT_EQ(ask(device, ok), hex(std::span(ok).first(5)));
        EXPECT_EQ(device.image().f32(Table::HoldingRegisters, f->address, order),
                  static_cast<float>(*f->max));
    });
}

// MK-ENC-05 (000:1360), MK-CFG-01 (000:218-226), WA-ENC-06: a value outside an enumeration is exception 03.
TEST(ProfileWithEnumeration, ValueOutsideTheEnumerationIsException03) {
    for_profiles(has_enumeration, [&](const mb::Profile& p, Device& device) {
        const mb::Point* pt = enumerated_register(p);
        ASSERT_NE(pt, nullptr);
        SCOPED_TRACE(pt->source + " " + pt->name_en);
        std::int64_t top = 0;
        for (const auto& v : pt->encoding.values)
            top = std::max(top, v.value);
        EXPECT_EQ(ask(device, write_single(6, pt->address, static_cast<std::uint16_t>(top + 1))), "86 03");
        const auto listed = static_cast<std::uint16_t>(pt->encoding.values.back().value);
        EXPECT_EQ(ask(device, write_single(6, pt->address, listed)),
                  hex(write_single(6, pt->address, listed)));
    });
}

// AP §6.5, MK-FC05-01 (000:371), WA-FC05-01 (002:330): FC5 values other than FF00/0000 are exception 03,
// checked before the address (so also at an address the map lacks).
TEST(ProfileWithFc5, Fc5OtherValueIsException03BeforeTheAddress) {
    for_profiles(has_fc5, [&](const mb::Profile&, Device& device) {
        for (std::uint16_t v : {0x1234, 0x0001, 0x00FF, 0xFFFF}) {
            SCOPED_TRACE(v);
            EXPECT_EQ(ask(device, write_single(5, 0xFFFF, v)), "85 03");
        }
    });
}

// MK-FC08-01 (000:411-425), CTH-FC08-01 (003:540-546), AP §6.8.1: sub-function 0 echoes the request, any
// data; a sub-function the device lacks is exception 01 (the MK and CTH manuals are silent on the code: their
// profiles take the specification's).
TEST(ProfileWithFc8, Fc8ReturnQueryDataEchoesAndUnknownSubFunctionIs01) {
    for_profiles(has_fc8, [&](const mb::Profile&, Device& device) {
        for (const char* echo : {"08 00 00 A5 37", "08 00 00 00 00", "08 00 00 FF FF"})
            EXPECT_EQ(ask(device, bytes(echo)), echo);
        EXPECT_EQ(ask(device, bytes("08 00 63 A5 37")), "88 01");
    });
}

// The profiles each rule above leaves out, named: a profile that loses its subject (a transcription that
// drops a range, FC8 removed) shows here instead of silently running fewer cases.
TEST(EveryProfileList, RulesWithoutASubjectLeaveOutOnlyTheseProfiles) {
    const auto without = [](auto has) {
        std::vector<std::string> out;
        for (const auto& id : profile_ids())
            if (!has(profile(id))) out.push_back(id);
        return out;
    };
    using V = std::vector<std::string>;
    EXPECT_EQ(without(has_unmapped_addresses), V{"modbus"});
    EXPECT_EQ(without(has_read_only_register), V{"modbus"});
    EXPECT_EQ(without(has_range), (V{"cth2265i", "modbus"}));
    EXPECT_EQ(without(has_enumeration), (V{"cth2265i", "modbus"}));
    EXPECT_EQ(without(has_fc5), V{});
    EXPECT_EQ(without(has_fc8), (V{"walchem-intuition9", "walchem-w600", "walchem-w900"}));
}

TEST(EveryProfileList, HoldsTheFortyEightBundledDevices) {
    EXPECT_EQ(profile_ids().size(), 48u);  // README: 43 MK Controle models, 3 Walchem, CTH2265I, generic
}

// The tests name their cases from bundled_profiles (slave_test_support.hpp) rather than from the store; the
// two must agree on every id and on the file that defines it.
TEST(EveryProfileList, IsTheStoresList) {
    EXPECT_TRUE(store().errors().empty());
    std::vector<std::pair<std::string, std::string>> listed, stored;
    for (const auto& b : bundled_profiles)
        listed.emplace_back(b.id, b.file);
    for (const auto& e : store().entries())
        stored.emplace_back(
            e.id, std::filesystem::path(e.file).lexically_relative(profiles_dir()).generic_string());
    EXPECT_EQ(listed, stored)
        << "profiles/ changed: bring bundled_profiles in slave_test_support.hpp up to date";
}

// ---------------------------------------------------------------------------------------------------------
// Hand-written cases from the manuals.

struct Exchange {
    std::string request;
    std::string reply;  // "" = no answer
    bool broadcast = false;
};

struct ManualCase {
    std::string name;    // the rule id first
    std::string source;  // manual lines
    std::string profile;
    std::vector<Exchange> exchanges;
    std::function<void(RegisterImage&)> setup = {};
};

void PrintTo(const ManualCase& c, std::ostream* os) {
    *os << c.name;
}

class Manual : public ::testing::TestWithParam<ManualCase> {};

TEST_P(Manual, DeviceAnswersAsTheManualSays) {
    const ManualCase& c = GetParam();
    SCOPED_TRACE(c.source);
    Device device(profile(c.profile), 0x11);
    if (c.setup) c.setup(device.image());
    for (const auto& e : c.exchanges) {
        SCOPED_TRACE((e.broadcast ? "broadcast " : "") + e.request);
        EXPECT_EQ(ask(device, e.request, e.broadcast), e.reply);
    }
}

std::string case_name(const ::testing::TestParamInfo<ManualCase>& info) {
    return info.param.name;
}

constexpr Table HR = Table::HoldingRegisters;
constexpr Table Coils = Table::Coils;

mb::WordOrder order_at(const RegisterImage& image, std::uint16_t address) {
    return image.profile().find(HR, address)->encoding.word_order;
}

const std::vector<ManualCase> mk_cases = {
    {"MK_FC01_01_E1E2_Mmk2030_ReadCoils19To39",
     "000:325-343 (E1, E2)",
     "mmk-2030",
     {{"01 00 13 00 15", "01 03 B2 0E 1B"}},
     [](RegisterImage& i) {
         for (int c : {20, 23, 24, 26, 28, 29, 30, 35, 36, 38, 39})
             i.set_bit(Coils, static_cast<std::uint16_t>(c), true);
     }},
    {"MK_FC01_02_Mmk2030_MaxCoilsIs30",
     "000:325",
     "mmk-2030",
     {{"01 00 01 00 1E", "01 04 00 00 00 00"}, {"01 00 01 00 1F", "81 03"}}},
    {"MK_FC03_01_Mmk2030_MaxRegistersIs15",
     "000:351",
     "mmk-2030",
     {{"03 00 00 00 0F",
       "03 1E 00 00 00 01 00 02 00 03 00 04 00 05 00 06 00 07 00 08 00 09 00 0A 00 0B 00 0C 00 0D 00 0E"},
      {"03 00 00 00 10", "83 03"},
      {"04 00 00 00 10", "84 03"}},
     [](RegisterImage& i) {
         for (std::uint16_t a = 0; a < 15; ++a)
             i.set_reg(HR, a, a);
     }},
    {"MK_FC04_01_E3E4_Mmk2030_Fc3AndFc4ReadOneMap",
     "000:345-365 (E3, E4)",
     "mmk-2030",
     {{"03 00 60 00 03", "03 06 02 2B 00 00 00 64"}, {"04 00 60 00 03", "04 06 02 2B 00 00 00 64"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 96, 555);
         i.set_reg(HR, 97, 0);
         i.set_reg(HR, 98, 100);
     }},
    {"MK_FC05_01_E5E6_Mmk2030Tot_CoilOnAndOffEchoed",
     "000:371-385 (E5, E6); coil 84 000:1479",
     "mmk-2030-tot",
     {{"05 00 54 FF 00", "05 00 54 FF 00"},
      {"01 00 54 00 01", "01 01 01"},
      {"05 00 54 00 00", "05 00 54 00 00"},
      {"01 00 54 00 01", "01 01 00"},
      {"05 00 54 12 34", "85 03"}}},
    // AP §6.5: the output value is checked before the address.
    {"MK_FC05_01_Mmk2030_ValueCheckedBeforeAddress",
     "000:371; AP §6.5",
     "mmk-2030",
     {{"05 FF F0 12 34", "85 03"}, {"05 FF F0 FF 00", "85 02"}}},
    {"MK_FC06_01_E7E8_Mmk2030_WriteEchoedAndKept",
     "000:391-405 (E7, E8)",
     "mmk-2030",
     {{"06 00 54 03 9E", "06 00 54 03 9E"}, {"03 00 54 00 01", "03 02 03 9E"}}},
    // The manual does not say what answers another sub-function ("01 or 03"): the profile leaves it to the
    // specification's 01 (fc8_unknown_sub_function null).
    {"MK_FC08_01_E9E10_Mmk2030_OnlySubFunction0",
     "000:411-425 (E9, E10)",
     "mmk-2030",
     {{"08 00 00 A5 37", "08 00 00 A5 37"}, {"08 00 01 A5 37", "88 01"}, {"08 00 04 00 00", "88 01"}}},
    // E11's data contradicts its prose (manual-rules I-3); used here as written, and read back as sent.
    {"MK_FC15_01_E11E12_Mmk2030_WriteCoilsMax30",
     "000:431-445 (E11, E12)",
     "mmk-2030",
     {{"0F 00 13 00 0A 02 CD 00", "0F 00 13 00 0A"},
      {"01 00 13 00 0A", "01 02 CD 00"},
      {"0F 00 00 00 1F 04 00 00 00 00", "8F 03"}}},
    {"MK_FC16_01_E13E14_Mmk2030_WriteRegistersMax15",
     "000:451-465 (E13, E14)",
     "mmk-2030",
     {{"10 00 60 00 02 04 00 0A 01 02", "10 00 60 00 02"},
      {"03 00 60 00 02", "03 04 00 0A 01 02"},
      {"10 00 00 00 10 20 " + zeros(32), "90 03"}}},
    {"MK_EXC_03_Mmk2030_Register200", "000:476", "mmk-2030", {{"03 00 C8 00 01", "83 02"}}},
    // The example's prose says "read a register (function 1)"; FC1 reads coils, as the frame does.
    {"MK_EXC_05_E15_Mmk2030_Fc1BeyondTheLastCoil",
     "000:481-484 (E15)",
     "mmk-2030",
     {{"01 00 50 00 01", "81 02"}, {"01 00 00 00 01", "81 02"}}},
    {"MK_ADR_01_Mmk2030_EnderAbove99",
     "000:220, 477, 500",
     "mmk-2030",
     {{"06 00 07 00 64", "86 03"}, {"06 00 07 00 63", "06 00 07 00 63"}}},
    {"MK_BC_01_Mmk2030Tot_BroadcastWriteExecutedSilently",
     "000:248, 285",
     "mmk-2030-tot",
     {{"05 00 54 FF 00", "", true}, {"01 00 54 00 01", "01 01 01"}}},
    {"MK_BC_02_Mmk2030_BroadcastOnlyForFc5Fc6Fc15Fc16",
     "000:313",
     "mmk-2030",
     {{"03 00 60 00 03", "", true},
      {"01 00 01 00 01", "", true},
      {"08 00 00 A5 37", "", true},
      {"06 00 54 03 9E", "", true},
      {"03 00 54 00 01", "03 02 03 9E"},
      {"10 00 60 00 01 02 00 0A", "", true},
      {"03 00 60 00 01", "03 02 00 0A"},
      {"0F 00 01 00 02 01 03", "", true},
      {"01 00 01 00 02", "01 01 03"},
      {"06 00 07 00 64", "", true}}},
    {"MK_FC_01_Mmk2030_EightFunctionsOnly",
     "000:287, 313",
     "mmk-2030",
     {{"02 00 00 00 01", "82 01"},
      {"07", "87 01"},
      {"11", "91 01"},
      {"17 00 00 00 01 00 00 00 01 02 00 00", "97 01"},
      {"2B 0E 01 00", "AB 01"}}},
    {"MK_ENC_03_Mmk2030_TagCharacters",
     "000:495, 618; 001:251",
     "mmk-2030",
     {{"06 00 02 00 61", "06 00 02 00 61"},
      {"06 00 02 00 2E", "06 00 02 00 2E"},
      {"06 00 02 00 6D", "86 03"},
      {"06 00 02 00 41", "86 03"}}},
    {"MK_ENC_02_Mmk2030_NegativeRangeIsTwosComplement",
     "000:315, 581",
     "mmk-2030",
     {{"06 00 54 FC 19", "06 00 54 FC 19"}, {"03 00 54 00 01", "03 02 FC 19"}, {"06 00 54 FC 0E", "86 03"}}},
    {"MK_ENC_01_Mmk2030_FixedPointTravelsAsInteger",
     "000:517, 617",
     "mmk-2030",
     {{"06 00 17 00 0A", "06 00 17 00 0A"},
      {"06 00 17 00 FA", "06 00 17 00 FA"},
      {"06 00 17 00 FB", "86 03"}}},
    // The code for a read-only register is not stated: the profile leaves it to the specification's 02.
    {"MK_RO_01_Mmk2030_ProcessValueIsReadOnly", "000:493", "mmk-2030", {{"06 00 00 00 00", "86 02"}}},
    // Read-only by condition (MK-RO-02): a loop's output signal only in manual mode (coil 0: 0 manual,
    // 1 automatic, 000:918, 731), a program's repetitions only while it is off (register 6: 0 off, 1 on,
    // 2 suspended, 000:736-737); refused as a read-only register is (02, code not stated), kept as before.
    {"MK_RO_02_Dcy2050_ReadOnlyInAutomaticModeAndWhileAProgramRuns",
     "000:731, 736-737, 918",
     "dcy-2050",
     {{"06 00 02 01 F4", "06 00 02 01 F4"},
      {"05 00 00 FF 00", "05 00 00 FF 00"},
      {"06 00 02 00 64", "86 02"},
      {"10 00 02 00 02 04 00 64 00 64", "90 02"},
      {"03 00 02 00 01", "03 02 01 F4"},
      {"05 00 00 00 00", "05 00 00 00 00"},
      {"06 00 02 00 64", "06 00 02 00 64"},
      {"06 00 08 00 05", "06 00 08 00 05"},
      {"06 00 06 00 02", "06 00 06 00 02"},
      {"06 00 08 00 07", "86 02"},
      {"06 00 09 00 07", "06 00 09 00 07"},
      {"06 00 06 00 00", "06 00 06 00 00"},
      {"06 00 08 00 07", "06 00 08 00 07"}}},
    // (i) read-only coils refuse FC5 (02, code not stated); (ii) write-only coils read as 0 (not stated).
    {"MK_COIL_01_Mmk2030_ReadOnlyAndWriteOnlyCoils",
     "000:694, 702, 719-720",
     "mmk-2030",
     {{"05 00 3A FF 00", "85 02"}, {"05 00 42 FF 00", "05 00 42 FF 00"}, {"01 00 42 00 01", "01 01 00"}}},
    {"MK_COIL_02_Mmk2030_ReservedCoilRows",
     "000:668",
     "mmk-2030",
     {{"01 00 20 00 03", "01 01 00"}, {"05 00 21 FF 00", "85 02"}}},
    {"MK_MODEL_01_Ty2090_Register45Absent", "000:612-615", "ty-2090", {{"03 00 2D 00 01", "83 02"}}},
    {"MK_MODEL_01_Dcy2050F_Coil22Absent", "000:941, 948", "dcy-2050-f", {{"01 00 16 00 01", "81 02"}}},
    {"MK_MODEL_01_Dcy2050_Coil22Present", "000:941", "dcy-2050", {{"01 00 16 00 01", "01 01 00"}}},
    {"MK_ENC_04_Mmk2030Tot_EightDigitHalvesAre0To9999",
     "000:1243-1250, 1362",
     "mmk-2030-tot",
     {{"06 00 81 27 10", "86 03"}, {"06 00 81 27 0F", "06 00 81 27 0F"}}},
    {"MK_ENC_05_Mmk2030Tot_PredeterminationCodes0To16",
     "000:1360",
     "mmk-2030-tot",
     {{"06 00 7F 00 11", "86 03"}, {"06 00 7F 00 10", "06 00 7F 00 10"}}},
    // LIM LOW (87, 88) must not exceed LIM HIGH (89, 90); in one FC16 block the block's own values count.
    {"MK_RNG_02_Mmk2030_LowerInputLimitNotAboveUpper",
     "000:584-587, 623",
     "mmk-2030",
     {{"06 00 59 01 F4", "06 00 59 01 F4"},
      {"06 00 57 02 58", "86 03"},
      {"06 00 57 01 90", "06 00 57 01 90"},
      {"06 00 59 01 2C", "86 03"},
      {"10 00 57 00 04 08 03 84 00 00 03 20 00 00", "90 03"},
      {"10 00 57 00 04 08 01 F4 01 F4 03 E8 03 E8", "10 00 57 00 04"},
      {"03 00 57 00 04", "03 08 01 F4 01 F4 03 E8 03 E8"}}},
};

const std::vector<ManualCase> walchem_cases = {
    // A 32-bit value's halves written one at a time (002:499 tells clients to write a 32-bit set-point with
    // FC6): each write must leave the whole value a number within range (002:391, Ajuste Fino 0-90 %,
    // 002:880). Before, 589 := 4316 made it 150.0 and 7FC0 NaN, both acknowledged.
    {"WA_32_01_W600_AHalfWriteKeepsTheValueInRange",
     "002:391, 454, 463, 499, 880",
     "walchem-w600",
     {{"06 02 4C 00 00", "06 02 4C 00 00"},
      {"06 02 4D 43 16", "86 03"},
      {"10 02 4D 00 01 02 7F C0", "90 03"},
      {"06 02 4D 42 20", "06 02 4D 42 20"},
      {"03 02 4C 00 02", "03 04 00 00 42 20"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 588, 0);
         i.set_reg(HR, 589, 0);
     }},
    // A boolean in a register is its least significant bit (002:424-429): 0 or 1. Before, 0xFFFF was
    // acknowledged and read back.
    {"WA_BOOL_01_W600_ABooleanRegisterTakesZeroOrOne",
     "002:391, 424-429",
     "walchem-w600",
     {{"06 23 00 FF FF", "86 03"}, {"06 23 00 00 02", "86 03"}, {"06 23 00 00 01", "06 23 00 00 01"}}},
    {"WA_FC_01_W600_SevenFunctionsOnly",
     "002:226-238",
     "walchem-w600",
     {{"0F 00 00 00 01 01 00", "8F 01"},
      {"08 00 00 00 00", "88 01"},
      {"17 00 00 00 01 00 00 00 01 02 00 00", "97 01"},
      {"2B 0E 01 00", "AB 01"},
      {"07", "87 01"}}},
    // The manual does not give the code for a bad quantity: the profile takes the specification's 03.
    {"WA_FC01_01_WA_FC02_01_W600_Max2000Bits",
     "002:232-233, 250-254",
     "walchem-w600",
     {{"01 02 5C 07 D1", "81 03"}, {"02 02 5C 07 D1", "82 03"}}},
    {"WA_FC03_01_WA_FC04_01_W600_Max125Registers",
     "002:234-235",
     "walchem-w600",
     {{"03 00 24 00 7E", "83 03"}, {"04 00 24 00 7E", "84 03"}}},
    // 125 is the manual's FC16 limit, beyond the specification's 123 (D6); 126 is refused. 126 registers
    // written whole need a PDU of 258 bytes, more than the 256 the manual allows (002:219): not taken.
    {"WA_FC16_01_W600_Over125RegistersIs03",
     "002:219, 238, 362-381",
     "walchem-w600",
     {{"10 00 94 00 7E 02 00 00", "90 03"}, {"10 00 94 00 7E FC " + zeros(252), ""}}},
    {"WA_FC12_01_W600_Fc1AndFc2Interchangeable",
     "002:242",
     "walchem-w600",
     {{"01 02 5C 00 06", "01 01 0A"}, {"02 02 5C 00 06", "02 01 0A"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 605, 1);
         i.set_reg(HR, 607, 1);
     }},
    {"WA_FC34_01_W600_Fc3AndFc4Interchangeable",
     "002:244",
     "walchem-w600",
     {{"03 02 4A 00 04", "03 08 00 00 3F C0 00 00 42 34"},
      {"04 02 4A 00 04", "04 08 00 00 3F C0 00 00 42 34"}},
     [](RegisterImage& i) {
         i.set_f32(HR, 586, 1.5f, order_at(i, 586));
         i.set_f32(HR, 588, 45.0f, order_at(i, 588));
     }},
    // Only the first address is checked (a contradiction with AP §6, D9): a read from the last word of I/O
    // board 2's temperature running into the W900's boards 3 and 4, which the W600 has not (002:908), is
    // answered; a write from sensor 1-1's high-high set-point into the W900's 24-hour statistics likewise
    // keeps what is mapped.
    {"WA_EXC_03_W600_FirstAddressOnly",
     "002:390",
     "walchem-w600",
     {{"03 00 00 00 01", "83 02"},
      {"03 00 34 00 01", "83 02"},
      {"03 00 33 00 04", "03 08 00 00 00 00 00 00 00 00"},
      {"01 00 26 00 01", "81 02"},
      {"10 02 54 00 06 0C 00 00 40 E0 00 00 00 00 00 00 00 00", "10 02 54 00 06"},
      {"03 02 54 00 02", "03 04 00 00 40 E0"},
      {"03 02 56 00 01", "83 02"}}},
    {"WA_EXC_04_W600_FineAdjustmentAbove90Percent",
     "002:391",
     "walchem-w600",
     {{"10 02 4C 00 02 04 00 00 43 16", "90 03"}, {"10 02 4C 00 02 04 00 00 42 B4", "10 02 4C 00 02"}}},
    // 7.0 = 0x40E00000 travels low word first (CDAB): 00 00 40 E0 (002:466).
    {"WA_ENC_09_W600_FloatLowWordFirst",
     "002:461-468",
     "walchem-w600",
     {{"10 00 94 00 02 04 00 00 40 E0", "10 00 94 00 02"}, {"03 00 94 00 02", "03 04 00 00 40 E0"}}},
    {"WA_ENC_08_W600_Integer32LowWordFirst",
     "002:452-459",
     "walchem-w600",
     {{"04 00 24 00 02", "04 04 56 78 12 34"}},
     [](RegisterImage& i) { i.set_u32(HR, 36, 0x12345678, order_at(i, 36)); }},
    {"WA_ADR_02_W600_FirmwareVersionAt30039",
     "002:481-485, 495",
     "walchem-w600",
     {{"04 00 26 00 02", "04 04 0A 3D 40 47"}},
     [](RegisterImage& i) { i.set_f32(HR, 38, 3.11f, order_at(i, 38)); }},
    // Coils are views of the registers at the same address (002:244, 493).
    {"WA_FC05_01_W600_ResetCoilIsItsRegister",
     "002:324-341, 417-420, 493",
     "walchem-w600",
     {{"05 01 40 FF 00", "05 01 40 FF 00"},
      {"03 01 40 00 01", "03 02 00 01"},
      {"01 01 40 00 01", "01 01 01"},
      {"05 01 40 00 00", "05 01 40 00 00"},
      {"01 01 40 00 01", "01 01 00"},
      {"05 01 40 12 34", "85 03"}}},
    {"WA_MAP_05_W600_AlarmBitFieldReadAsCoil",
     "002:431-436, 995",
     "walchem-w600",
     {{"01 01 43 00 01", "01 01 01"}, {"03 01 43 00 01", "03 02 00 AA"}},
     [](RegisterImage& i) { i.set_reg(HR, 323, 0x00AA); }},
    {"WA_MAP_02_W600_ReadOnlyCoilRefusesFc5", "002:493", "walchem-w600", {{"05 01 41 FF 00", "85 02"}}},
    // Unit 0 contradicts itself (002:211, 213, 215; D7): the profile follows line 213, processed, no reply.
    {"WA_MBAP_05_W600_UnitZeroProcessedNotAnswered",
     "002:211-215",
     "walchem-w600",
     {{"06 01 40 00 01", "", true}, {"03 01 40 00 01", "03 02 00 01"}, {"03 01 40 00 01", "", true}}},
    {"WA_ADR_01_W600_FiveDigitAddressesOnly", "002:174, 246", "walchem-w600", {{"03 27 0F 00 01", "83 02"}}},
};

const std::vector<ManualCase> cth_cases = {
    {"CTH_FC_01_EightFunctions", "003:498", "cth2265i", {{"02 0F 9F 00 01", "82 01"}, {"07", "87 01"}}},
    {"CTH_FC03_01_MaxRegistersIs15",
     "003:512-522",
     "cth2265i",
     {{"03 0F A0 00 10", "83 03"}, {"04 0F A0 00 10", "84 03"}, {"03 0F A0 00 02", "03 04 00 00 00 00"}}},
    {"CTH_FC04_01_Fc3AndFc4ReadOneTable",
     "003:512-514",
     "cth2265i",
     {{"03 0F A0 00 01", "03 02 12 34"}, {"04 0F A0 00 01", "04 02 12 34"}},
     [](RegisterImage& i) { i.set_reg(HR, 4000, 0x1234); }},
    // Marked "Leitura / Escrita" but reserved: what a write does is not stated; the profile refuses it (02)
    // and the registers keep reading 0x55AA.
    {"CTH_RES_01_ReservedRegistersRead55AA",
     "003:639-643",
     "cth2265i",
     {{"03 0F C5 00 05", "03 0A 55 AA 55 AA 55 AA 55 AA 55 AA"},
      {"06 0F C5 12 34", "86 02"},
      {"10 0F C4 00 02 04 00 00 12 34", "90 02"},
      {"03 0F C5 00 01", "03 02 55 AA"}}},
    {"CTH_EXC_01_Register4122Absent", "003:566-574", "cth2265i", {{"03 10 1A 00 01", "83 02"}}},
    {"CTH_MAP_02_ReadOnly3999To4010", "003:598-610", "cth2265i", {{"06 0F A0 00 00", "86 02"}}},
    {"CTH_MAP_03_ReadWrite4011To4121",
     "003:611-727",
     "cth2265i",
     {{"06 0F AC 00 05", "06 0F AC 00 05"}, {"03 0F AC 00 01", "03 02 00 05"}}},
    {"CTH_FC08_01_OnlySubFunction0",
     "003:540-546",
     "cth2265i",
     {{"08 00 00 A5 37", "08 00 00 A5 37"}, {"08 00 01 00 00", "88 01"}}},
    // The register table's last row, BOBINA 0 at 1000 (read-only; bits 0, 1, 5, 6 alarms, 7 the display
    // overflow), is the coils 1000-1007, one byte to FC1: read whole or in part, not past 1007 nor below
    // 1000, and never written (no writable coil).
    {"CTH_COIL_01_AlarmCoilsAt1000ReadOnly",
     "003:498-510, 728",
     "cth2265i",
     {{"01 03 E8 00 08", "01 01 00"},
      {"01 03 EF 00 01", "01 01 00"},
      {"01 03 E8 00 09", "81 02"},
      {"01 00 00 00 01", "81 02"},
      {"05 03 E8 FF 00", "85 02"},
      {"0F 03 E8 00 01 01 01", "8F 02"}}},
    // No FC1 maximum is stated: the specification's 2000 applies (profile note, 003:502-510).
    {"CTH_FC01_01_NoMaximumStated",
     "003:502-510",
     "cth2265i",
     {{"01 00 00 07 D1", "81 03"}, {"01 00 00 07 D0", "81 02"}}},
    {"CTH_FC15_01_MaxCoilsIs30", "003:548-554", "cth2265i", {{"0F 00 00 00 1F 04 00 00 00 00", "8F 03"}}},
    {"CTH_FC16_01_MaxRegistersIs15",
     "003:556-564",
     "cth2265i",
     {{"10 0F AC 00 10 20 " + zeros(32), "90 03"}}},
    {"CTH_BC_01_BC_02_BroadcastWritesOnly",
     "003:452, 479, 498",
     "cth2265i",
     {{"06 0F AC 00 07", "", true}, {"03 0F AC 00 01", "03 02 00 07"}, {"03 0F 9F 00 01", "", true}}},
};

// The generic profile: the specification's own examples (AP V1.1b3).
const std::vector<ManualCase> generic_cases = {
    {"AP_6_16_Fc22MaskWriteRegister",
     "AP §6.16 example",
     "modbus",
     {{"16 00 04 00 F2 00 25", "16 00 04 00 F2 00 25"}, {"03 00 04 00 01", "03 02 00 17"}},
     [](RegisterImage& i) { i.set_reg(HR, 4, 0x0012); }},
    {"AP_6_17_Fc23ReadWriteMultipleRegisters",
     "AP §6.17 example",
     "modbus",
     {{"17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF", "17 0C 00 FE 0A CD 00 01 00 03 00 0D 00 FF"},
      {"03 00 0E 00 03", "03 06 00 FF 00 FF 00 FF"},
      {"17 00 00 00 01 00 00 00 01 02 AB CD", "17 02 AB CD"},  // the write is performed before the read
      {"17 00 00 00 7E 00 00 00 01 02 00 00", "97 03"},
      {"17 00 00 00 01 00 00 00 7A 02 00 00", "97 03"},
      // 122 registers written whole need a PDU of 254 bytes (AP §4.1: 253): no frame carries it.
      {"17 00 00 00 01 00 00 00 7A F4 " + zeros(244), ""}},
     [](RegisterImage& i) {
         const std::uint16_t v[] = {0x00FE, 0x0ACD, 0x0001, 0x0003, 0x000D, 0x00FF};
         for (std::uint16_t k = 0; k < 6; ++k)
             i.set_reg(HR, static_cast<std::uint16_t>(3 + k), v[k]);
     }},
    {"AP_6_18_Fc24ReadFifoQueue",
     "AP §6.18 example",
     "modbus",
     {{"18 04 DE", "18 00 06 00 02 01 B8 12 84"}, {"18 01 00", "98 03"}},
     [](RegisterImage& i) {
         i.set_reg(HR, 0x04DE, 2);
         i.set_reg(HR, 0x04DF, 0x01B8);
         i.set_reg(HR, 0x04E0, 0x1284);
         i.set_reg(HR, 0x0100, 32);  // more than 31 queued values
     }},
    {"AP_6_7_Fc7ReadExceptionStatus", "AP §6.7", "modbus", {{"07", "07 00"}}},
    // FC11 counts successful completions other than FC8/FC11/FC12 (AP §6.9).
    {"AP_6_9_Fc11CommEventCounter",
     "AP §6.9",
     "modbus",
     {{"03 00 00 00 01", "03 02 00 00"}, {"08 00 00 12 34", "08 00 00 12 34"}, {"0B", "0B 00 00 00 01"}}},
    // "mbscope modbus" after the unit id and the run indicator ON.
    {"AP_6_13_Fc17ReportServerId",
     "AP §6.13",
     "modbus",
     {{"11", "11 10 11 FF 6D 62 73 63 6F 70 65 20 6D 6F 64 62 75 73"}}},
    {"AP_6_14_Fc20FileRecordsNotServed",
     "AP §6.14; profile lists FC20",
     "modbus",
     {{"14 07 06 00 04 00 01 00 02", "94 01"}}},
    {"AP_6_21_Fc43UnknownCodeOrObject",
     "AP §6.21",
     "modbus",
     {{"2B 0E 05 00", "AB 03"}, {"2B 0E 04 07", "AB 02"}, {"2B 0D 00 00", "AB 01"}}},
    {"AP_6_3_OpenAddressSpaceEndsAt65535",
     "AP §6.3",
     "modbus",
     {{"03 FF FF 00 01", "03 02 00 00"}, {"03 FF FF 00 02", "83 02"}}},
    // SL §2.1 and the profile's broadcast list: FC22 is executed in broadcast, FC23 (a read) is not.
    {"SL_2_1_BroadcastFc22ExecutedFc23Not",
     "SL §2.1; modbus.json functions.broadcast",
     "modbus",
     {{"16 00 04 00 F2 00 25", "", true},
      {"03 00 04 00 01", "03 02 00 17"},
      {"17 00 00 00 01 00 05 00 01 02 AB CD", "", true},
      {"03 00 05 00 01", "03 02 00 00"}},
     [](RegisterImage& i) { i.set_reg(HR, 4, 0x0012); }},
};

INSTANTIATE_TEST_SUITE_P(MkControle, Manual, ::testing::ValuesIn(mk_cases), case_name);
INSTANTIATE_TEST_SUITE_P(Walchem, Manual, ::testing::ValuesIn(walchem_cases), case_name);
INSTANTIATE_TEST_SUITE_P(Cth2265i, Manual, ::testing::ValuesIn(cth_cases), case_name);
INSTANTIATE_TEST_SUITE_P(Generic, Manual, ::testing::ValuesIn(generic_cases), case_name);

// ---------------------------------------------------------------------------------------------------------
// Cases whose replies are too long to write out: their shape and the values that matter.

// WA-FC16-01 (002:238, 362-381): 125 registers in one FC16, two more than AP §6.12 allows (123); the manual
// wins for this device (D6), so the write is answered and kept. Values: what the device holds, with the
// Fluent update rate (148, f32 1..1440) set to 7.0 in the profile's word order.
TEST(WalchemRules, WA_FC16_01_W600_Writes125Registers) {
    Device device(profile("walchem-w600"), 1);
    const std::string read = ask(device, quantity_request(3, 148, 125));
    ASSERT_EQ(bytes(read).size(), 252u) << read;
    const auto data = bytes(read);
    std::vector<std::uint16_t> values;
    for (std::size_t i = 2; i + 1 < data.size(); i += 2)
        values.push_back(static_cast<std::uint16_t>(data[i] << 8 | data[i + 1]));
    const auto seven = float_words(7.0f, mb::WordOrder::Cdab);
    values[0] = seven[0];
    values[1] = seven[1];
    const auto request = write_registers(148, values);
    ASSERT_EQ(request.size(), 256u);  // WA-PDU-01: a 256-byte PDU (AP: at most 253)
    EXPECT_EQ(ask(device, request), "10 00 94 00 7D");
    EXPECT_EQ(device.image().f32(Table::HoldingRegisters, 148, mb::WordOrder::Cdab), 7.0f);
}

// WA-FC01-02 (002:256-260): 2000 coils take 250 bytes although the reply table says "1-125 bytes"; the
// profile keeps 2000 (and so 250 bytes, as in the specification).
TEST(WalchemRules, WA_FC01_02_W600_2000CoilsAre250Bytes) {
    Device device(profile("walchem-w600"), 1);
    for (const char* fc : {"01", "02"}) {
        const auto reply = bytes(ask(device, std::string(fc) + " 02 5C 07 D0"));
        ASSERT_EQ(reply.size(), 252u) << fc;
        EXPECT_EQ(reply[1], 0xFA);
    }
}

// WA-FC03-01 (002:234, 286-303): 125 registers are 250 data bytes.
TEST(WalchemRules, WA_FC03_01_W600_125RegistersAre250Bytes) {
    Device device(profile("walchem-w600"), 1);
    for (const char* fc : {"03", "04"}) {
        const auto reply = bytes(ask(device, std::string(fc) + " 00 24 00 7D"));
        ASSERT_EQ(reply.size(), 252u) << fc;
        EXPECT_EQ(reply[1], 0xFA);
    }
}

// AP §6.21: the basic identification objects, stream and individual access; an object id the device lacks
// restarts the stream at the first object.
TEST(GenericRules, AP_6_21_Fc43ReadDeviceIdentification) {
    Device device(profile("modbus"), 1);
    const auto object = [](int id, const std::string& text) {
        std::vector<std::uint8_t> out{u8(id), u8(text.size())};
        for (char ch : text)  // (not insert(): GCC 12 warns a false -Warray-bounds on it)
            out.push_back(static_cast<std::uint8_t>(ch));
        return out;
    };
    std::vector<std::uint8_t> all = bytes("2B 0E 01 81 00 00 03");
    for (const auto& o :
         {object(0, "Modbus Organization"), object(1, "Generic Modbus device"), object(2, MBSCOPE_VERSION)})
        all.insert(all.end(), o.begin(), o.end());
    EXPECT_EQ(ask(device, "2B 0E 01 00"), hex(all));
    EXPECT_EQ(ask(device, "2B 0E 01 07"), hex(all));
    std::vector<std::uint8_t> one = bytes("2B 0E 04 81 00 00 01");
    const auto product = object(1, "Generic Modbus device");
    one.insert(one.end(), product.begin(), product.end());
    EXPECT_EQ(ask(device, "2B 0E 04 01"), hex(one));
}

// WA-ADR-04 (002:499): a 32-bit set-point written "as FC6" takes two writes, each a lone half. Each is judged
// with the other half the device holds: a write that leaves the whole value out of range is refused, as FC16
// writing it whole is (002:391). Before, a lone half was not range-checked, and 2000.0 was taken.
TEST(WalchemRules, WA_ADR_04_W600_HalfAFloatIsCheckedWithTheOtherHalfHeld) {
    Device device(profile("walchem-w600"), 1);
    device.image().set_reg(Table::HoldingRegisters, 148, 0);
    // 2000.0 (above the 1440 maximum) = 0x44FA0000: CDAB words 0000 44FA.
    EXPECT_EQ(ask(device, "10 00 94 00 02 04 00 00 44 FA"), "90 03");
    EXPECT_EQ(ask(device, "06 00 95 44 FA"), "86 03");
    // 1000.0 = 0x447A0000: within range, taken.
    EXPECT_EQ(ask(device, "06 00 95 44 7A"), "06 00 95 44 7A");
    EXPECT_EQ(device.image().f32(Table::HoldingRegisters, 148, mb::WordOrder::Cdab), 1000.0f);
}

}  // namespace
}  // namespace mbscope::slave::test::test_slave_rules_test

namespace mbscope::slave::test::test_slave_rules_test {

// MK-CFG-01 (000:218-226, 500-503): ENDER, PROT, BAUD and PARID mirror the settings the device is on;
// CTH-ADR-01 (003:435, 599): register 3999 holds the configured address. The slave served them as 0.
TEST(LineMirrors, MK_CFG_01_RegistersReadTheLineTheDeviceIsOn) {
    mb::LineState rtu{17, mb::Framing::Rtu, 9600, mb::Parity::Even};
    Device on_rtu(profile("mmk-2030"), rtu);
    EXPECT_EQ(ask(on_rtu, "03 00 07 00 04"), "03 08 00 11 00 01 00 05 00 01");  // 17, RTU, 9600, even
    mb::LineState ascii{5, mb::Framing::Ascii, 300, mb::Parity::Odd};
    Device on_ascii(profile("mmk-2030"), ascii);
    EXPECT_EQ(ask(on_ascii, "03 00 07 00 04"), "03 08 00 05 00 00 00 00 00 02");  // 5, ASCII, 300, odd
    // A speed the map has no code for, and a line reached over TCP: those registers keep their start value.
    mb::LineState fast{1, mb::Framing::Rtu, 38400, mb::Parity::None};
    Device on_fast(profile("mmk-2030"), fast);
    EXPECT_EQ(ask(on_fast, "03 00 07 00 04"), "03 08 00 01 00 01 00 00 00 00");
    Device cth(profile("cth2265i"), mb::LineState{200, mb::Framing::Rtu, 9600, mb::Parity::None});
    EXPECT_EQ(ask(cth, "03 0F 9F 00 01"), "03 02 00 C8");
    // The image's start: what a state file compares with, so the mirrors are not saved as changes.
    EXPECT_TRUE(on_rtu.image().changes().empty());
}

}  // namespace mbscope::slave::test::test_slave_rules_test
