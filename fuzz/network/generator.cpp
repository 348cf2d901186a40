#include "fuzz/network/generator.hpp"

#include <algorithm>
#include <array>

#include "modbus/function_code.hpp"

namespace mbscope::fuzz::network {

namespace {

using modbus::Table;

void put16(std::vector<std::uint8_t>& out, std::uint32_t v) {
    out.push_back(static_cast<std::uint8_t>(v >> 8));
    out.push_back(static_cast<std::uint8_t>(v));
}

// Public function codes and the table each reads or writes.
constexpr std::array<std::uint8_t, 19> public_functions = {1,  2,  3,  4,  5,  6,  7,  8,  11, 12,
                                                           15, 16, 17, 20, 21, 22, 23, 24, 43};
// Codes that have burned other stacks, drawn more often than their share.
constexpr std::array<std::uint8_t, 5> attention_functions = {23, 20, 21, 43, 8};

}  // namespace

Generator::Generator(const modbus::Profile& profile, GeneratorOptions options)
    : profile_(profile), options_(options), rng_(options.seed), functions_(profile.functions.supported) {
    if (functions_.empty()) functions_.assign(public_functions.begin(), public_functions.end());
    // Writes aim at the writable points, but not at momentary commands: one acts on the device, and the
    // campaign's restore cannot undo it (an address drawn at random may still reach one).
    for (const auto& p : profile.table(Table::HoldingRegisters))
        if (p.access != modbus::Access::Read && !p.momentary) writable_registers_.push_back(&p);
    for (const auto& p : profile.table(Table::Coils))
        if (p.access != modbus::Access::Read && !p.momentary) writable_coils_.push_back(&p);
}

bool Generator::allowed(const std::vector<std::uint8_t>& pdu) const {
    if (pdu.empty()) return !options_.read_only;
    const std::uint8_t fc = pdu[0] & 0x7F;
    // Diagnostics that change how the device talks would silence or garble the rest of the run (and a
    // device's line for its real master): 03 changes the ASCII delimiter, 04 forces listen-only mode.
    if (fc == 8 && pdu.size() >= 3 && pdu[1] == 0 && (pdu[2] == 3 || pdu[2] == 4)) return false;
    // File records cannot be read back and restored: written only to a device whose manual says it has
    // none (where the write must be refused).
    if (fc == 21 && profile_.functions.supports(21)) return false;
    if (!options_.read_only) return true;
    // Read-only: the public read functions, and diagnostics that only echo or return counters.
    if (modbus::is_write_function(fc)) return false;
    if (fc == 8) {
        const unsigned sub = pdu.size() >= 3 ? (pdu[1] << 8) | pdu[2] : 0xFFFF;
        return sub == 0 || sub == 2 || (sub >= 0x0B && sub <= 0x12);
    }
    return std::find(public_functions.begin(), public_functions.end(), fc) != public_functions.end();
}

std::uint8_t Generator::unit() {
    const std::uint32_t r = below(100);
    if (r < 92) return options_.unit;
    if (r < 96) return 0;  // broadcast: never answered on a serial line
    if (r < 98 && options_.framing == modbus::Framing::Tcp) return 0xFF;
    return static_cast<std::uint8_t>(below(256));
}

std::uint16_t Generator::address_in(Table t, bool write) {
    const auto& points = profile_.table(t);
    const std::uint32_t r = below(100);
    // Writes go to points a master may write half of the time: that is where a write that is lost, stuck,
    // misplaced or swapped shows when it is read back.
    const auto& writable = t == Table::Coils ? writable_coils_ : writable_registers_;
    if (write && !writable.empty() && r < 50)
        return writable[below(static_cast<std::uint32_t>(writable.size()))]->address;
    if (points.empty() || profile_.open_address_space) {
        static constexpr std::array<std::uint16_t, 6> edges = {0, 1, 0x7FFF, 0x8000, 0xFFFE, 0xFFFF};
        return r < 40 ? edges[below(edges.size())] : static_cast<std::uint16_t>(below(0x10000));
    }
    // The last point's last register: a 32-bit value at the end of the map ends a word after its address.
    const std::uint16_t first = points.front().address,
                        last = static_cast<std::uint16_t>(points.back().address +
                                                          points.back().encoding.words - 1);
    if (r < 45) return points[below(static_cast<std::uint32_t>(points.size()))].address;
    if (r < 55) return first;
    if (r < 65) return last;
    if (r < 72) return static_cast<std::uint16_t>(last + 1);
    if (r < 78) return static_cast<std::uint16_t>(first - 1);
    if (r < 85) {  // a gap inside the map, when there is one
        const auto& p = points[below(static_cast<std::uint32_t>(points.size()))];
        return static_cast<std::uint16_t>(p.address + p.encoding.words);
    }
    if (r < 90) return 0xFFFF;
    return static_cast<std::uint16_t>(below(0x10000));
}

std::uint16_t Generator::quantity_for(std::uint8_t fc, bool write_part) {
    int max = profile_.functions.max_for(fc, write_part);
    if (max <= 0) max = 125;
    const std::uint32_t r = below(100);
    if (r < 30) return 1;
    if (r < 45) return static_cast<std::uint16_t>(max);
    if (r < 60) return static_cast<std::uint16_t>(max + 1);
    if (r < 67) return 0;
    if (r < 72) return 0xFFFF;
    if (r < 77) return 2;
    return static_cast<std::uint16_t>(1 + below(static_cast<std::uint32_t>(max)));
}

std::uint16_t Generator::value_for(Table t, std::uint16_t address) {
    const modbus::Point* p = profile_.find(t, address);
    const std::uint32_t r = below(100);
    if (p && r < 70) {
        if (!p->encoding.values.empty() && r < 35) {
            const auto& v = p->encoding.values[below(static_cast<std::uint32_t>(p->encoding.values.size()))];
            return static_cast<std::uint16_t>(v.value + (r < 25 ? 0 : 1));
        }
        if (p->min && p->max) {
            switch (below(5)) {
                case 0:
                    return static_cast<std::uint16_t>(*p->min);
                case 1:
                    return static_cast<std::uint16_t>(*p->max);
                case 2:
                    return static_cast<std::uint16_t>(*p->min - 1);
                case 3:
                    return static_cast<std::uint16_t>(*p->max + 1);
                default:
                    return static_cast<std::uint16_t>(
                        *p->min +
                        below(static_cast<std::uint32_t>(std::max<std::int64_t>(1, *p->max - *p->min + 1))));
            }
        }
    }
    static constexpr std::array<std::uint16_t, 6> edges = {0, 1, 0x7FFF, 0x8000, 0xFFFF, 0x55AA};
    return r < 85 ? edges[below(edges.size())] : static_cast<std::uint16_t>(below(0x10000));
}

std::vector<std::uint8_t> Generator::read_pdu(std::uint8_t fc) {
    const Table t = *modbus::table_of_function(fc);
    std::vector<std::uint8_t> pdu{fc};
    put16(pdu, address_in(t));
    put16(pdu, quantity_for(fc));
    return pdu;
}

std::vector<std::uint8_t> Generator::write_pdu(std::uint8_t fc) {
    const Table t = fc == 5 || fc == 15 ? Table::Coils : Table::HoldingRegisters;
    const std::uint16_t address = address_in(t, true);
    std::vector<std::uint8_t> pdu{fc};
    put16(pdu, address);
    switch (fc) {
        case 5: {
            static constexpr std::array<std::uint16_t, 5> values = {0xFF00, 0x0000, 0xFF00, 0x0001, 0x00FF};
            put16(pdu, below(10) < 8 ? values[below(3)] : values[below(values.size())]);
            break;
        }
        case 6:
            put16(pdu, value_for(t, address));
            break;
        case 22:
            put16(pdu, below(2) ? 0xFFFF : static_cast<std::uint16_t>(below(0x10000)));
            put16(pdu, below(2) ? 0x0000 : static_cast<std::uint16_t>(below(0x10000)));
            break;
        default: {  // 15, 16: quantity, byte count (sometimes disagreeing), values
            const modbus::Point* point = profile_.find(t, address);
            const std::uint16_t quantity =
                point && point->encoding.words == 2 && point->address == address && below(10) < 4
                    ? 2
                    : quantity_for(fc);
            const std::size_t data = std::min<std::size_t>(fc == 15 ? (quantity + 7u) / 8u : 2u * quantity,
                                                           modbus::max_pdu_length - 6);
            put16(pdu, quantity);
            std::size_t count = data;
            if (chance(0.15)) count = below(2) ? data + 1 : (data ? data - 1 : 0);
            if (chance(0.03)) count = 0xFF;
            pdu.push_back(static_cast<std::uint8_t>(count));
            if (fc == 16)
                for (std::size_t i = 0; i + 1 < data; i += 2)
                    put16(pdu, value_for(t, static_cast<std::uint16_t>(address + i / 2)));
            else
                for (std::size_t i = 0; i < data; ++i)
                    pdu.push_back(static_cast<std::uint8_t>(below(256)));
            break;
        }
    }
    return pdu;
}

std::vector<std::uint8_t> Generator::diagnostics_pdu() {
    static constexpr std::array<std::uint16_t, 12> subs = {0,    0,    0,    1,    2,    0x0A,
                                                           0x0B, 0x0C, 0x0D, 0x0E, 0x12, 0x14};
    std::vector<std::uint8_t> pdu{8};
    const std::uint16_t sub =
        below(10) < 9 ? subs[below(subs.size())] : static_cast<std::uint16_t>(below(0x10000));
    put16(pdu, sub);
    const std::uint32_t r = below(10);
    if (sub == 0 && r < 3) {  // echo of arbitrary length
        for (std::uint32_t i = 0, n = below(40); i < n; ++i)
            pdu.push_back(static_cast<std::uint8_t>(below(256)));
    } else if (sub == 1) {
        put16(pdu, below(2) ? 0xFF00 : 0x0000);
    } else if (r < 8) {
        put16(pdu, r < 6 ? 0 : static_cast<std::uint16_t>(below(0x10000)));
    } else if (r < 9) {
        pdu.push_back(static_cast<std::uint8_t>(below(256)));  // one data byte: a wrong data length
    }
    return pdu;
}

std::vector<std::uint8_t> Generator::file_record_pdu(bool write) {
    std::vector<std::uint8_t> body;
    for (std::uint32_t i = 0, n = 1 + below(3); i < n; ++i) {
        body.push_back(below(10) < 8 ? modbus::file_reference_type : static_cast<std::uint8_t>(below(256)));
        put16(body, below(3) ? 1 + below(4) : (below(2) ? 0 : 0xFFFF));
        put16(body, below(4) ? below(10) : (below(2) ? modbus::max_file_record_number + 1 : 0xFFFF));
        const std::uint16_t length =
            static_cast<std::uint16_t>(below(4) ? 1 + below(8) : (below(2) ? 0 : 0x7F));
        put16(body, length);
        if (write)
            for (std::uint16_t w = 0; w < length && body.size() < 240; ++w)
                put16(body, below(0x10000));
    }
    std::size_t count = body.size();
    if (chance(0.2)) count = below(2) ? count + 1 : (below(2) ? 0 : 0xFF);
    // Function code and byte count in front of the sub-requests.
    body.insert(body.begin(), {static_cast<std::uint8_t>(write ? 21 : 20),
                               static_cast<std::uint8_t>(std::min<std::size_t>(count, 0xFF))});
    std::vector<std::uint8_t> pdu = std::move(body);
    if (pdu.size() > modbus::max_pdu_length) pdu.resize(modbus::max_pdu_length);
    return pdu;
}

std::vector<std::uint8_t> Generator::device_id_pdu() {
    std::vector<std::uint8_t> pdu{43};
    const std::uint32_t r = below(10);
    pdu.push_back(
        r < 7 ? modbus::mei_read_device_identification
              : (r < 8 ? modbus::mei_canopen_general_reference : static_cast<std::uint8_t>(below(256))));
    pdu.push_back(
        static_cast<std::uint8_t>(below(10) < 8 ? 1 + below(4) : below(256)));        // read device id code
    pdu.push_back(static_cast<std::uint8_t>(below(10) < 7 ? below(8) : below(256)));  // object id
    if (chance(0.1)) pdu.pop_back();
    if (chance(0.1)) pdu.push_back(static_cast<std::uint8_t>(below(256)));
    return pdu;
}

std::vector<std::uint8_t> Generator::read_write_pdu() {
    std::vector<std::uint8_t> pdu{23};
    put16(pdu, address_in(Table::HoldingRegisters));
    put16(pdu, quantity_for(23, false));
    const std::uint16_t write_start = address_in(Table::HoldingRegisters);
    const std::uint16_t write_quantity = quantity_for(23, true);
    put16(pdu, write_start);
    put16(pdu, write_quantity);
    const std::size_t data = std::min<std::size_t>(2u * write_quantity, modbus::max_pdu_length - 10);
    std::size_t count = data;
    if (chance(0.15)) count = below(2) ? data + 1 : (data ? data - 1 : 0);
    pdu.push_back(static_cast<std::uint8_t>(std::min<std::size_t>(count, 0xFF)));
    for (std::size_t i = 0; i + 1 < data; i += 2)
        put16(pdu, value_for(Table::HoldingRegisters, static_cast<std::uint16_t>(write_start + i / 2)));
    return pdu;
}

void Generator::envelope(Probe& p) {
    const std::uint32_t r = below(100);
    const bool tcp = options_.framing == modbus::Framing::Tcp;
    if (r < 4 && !tcp) {
        p.envelope = Envelope::BadChecksum;
    } else if (r < 7 && tcp) {
        p.envelope = Envelope::MbapLength;
        static constexpr std::array<std::uint16_t, 5> lengths = {0, 1, 255, 256, 0xFFFF};
        const auto true_length = static_cast<std::uint16_t>(p.pdu.size() + 1);
        p.envelope_value = below(3) ? lengths[below(lengths.size())]
                                    : static_cast<std::uint16_t>(true_length + (below(2) ? 1 : -1));
    } else if (r < 9 && tcp) {
        p.envelope = Envelope::ProtocolId;
        p.envelope_value = below(2) ? 1 : static_cast<std::uint16_t>(1 + below(0xFFFF));
    } else if (r < 11 && options_.framing == modbus::Framing::Ascii) {
        p.envelope = Envelope::LowerCaseHex;
    }
    // Splits: on a stream, pieces written apart test reassembly: up to 100 µs, long enough for a slave that
    // answers in tens of microseconds to read the first piece alone (the writes are not coalesced: the
    // client sets TCP_NODELAY), short enough to keep the slave busy (millisecond pauses made them most of
    // the fuzzer's time). On a real serial line a pause beyond t1.5 makes an RTU request void (SL §2.5.1.1);
    // an ASCII one allows a second between characters (SL §2.5.2.1). Over UDP each piece would be a datagram
    // of its own, which a device rightly drops.
    if (below(100) < 6 && !options_.datagrams) {
        p.split = static_cast<std::uint8_t>(2 + below(2));
        if (options_.serial_line) {
            const auto t = std::chrono::duration_cast<std::chrono::microseconds>(options_.t1_5 * 2);
            p.pause = std::max<std::chrono::microseconds>(t, std::chrono::milliseconds(2));
        } else {
            p.pause = std::chrono::microseconds(25 * below(5));
        }
    }
}

Probe Generator::generate() {
    Probe p;
    p.unit = unit();
    std::uint8_t fc = 0;
    const std::uint32_t r = below(100);
    if (r < 55)
        fc = functions_[below(static_cast<std::uint32_t>(functions_.size()))];
    else if (r < 75)
        fc = attention_functions[below(attention_functions.size())];
    else if (r < 95)
        fc = public_functions[below(public_functions.size())];
    else
        fc = static_cast<std::uint8_t>(below(128));
    switch (fc) {
        case 1:
        case 2:
        case 3:
        case 4:
            p.pdu = read_pdu(fc);
            break;
        case 5:
        case 6:
        case 15:
        case 16:
        case 22:
            p.pdu = write_pdu(fc);
            break;
        case 8:
            p.pdu = diagnostics_pdu();
            break;
        case 20:
        case 21:
            p.pdu = file_record_pdu(fc == 21);
            break;
        case 23:
            p.pdu = read_write_pdu();
            break;
        case 24:
            p.pdu = {24};
            put16(p.pdu, address_in(Table::HoldingRegisters));
            break;
        case 43:
            p.pdu = device_id_pdu();
            break;
        default:  // 7, 11, 12, 17 take no data; others are whatever follows
            p.pdu = {fc};
            if (fc != 7 && fc != 11 && fc != 12 && fc != 17)
                for (std::uint32_t i = 0, n = below(8); i < n; ++i)
                    p.pdu.push_back(static_cast<std::uint8_t>(below(256)));
            else if (chance(0.1))
                p.pdu.push_back(0);
            break;
    }
    p.recipe = "grammar fc" + std::to_string(fc);
    envelope(p);
    return p;
}

Probe Generator::mutate(const Probe& base) {
    Probe p = base;
    p.recipe = "mutated " + base.recipe;
    p.envelope = Envelope::Valid;
    p.split = 1;
    p.pause = {};
    for (std::uint32_t n = 1 + below(3); n > 0; --n) {
        auto& d = p.pdu;
        switch (below(8)) {
            case 0:  // flip a bit
                if (!d.empty())
                    d[below(static_cast<std::uint32_t>(d.size()))] ^=
                        static_cast<std::uint8_t>(1u << below(8));
                break;
            case 1:  // an interesting byte
                if (!d.empty()) {
                    static constexpr std::array<std::uint8_t, 6> bytes = {0x00, 0x01, 0x7F, 0x80, 0xFE, 0xFF};
                    d[below(static_cast<std::uint32_t>(d.size()))] = bytes[below(bytes.size())];
                }
                break;
            case 2:  // a 16-bit field to a boundary: addresses and quantities live at 1..4
                if (d.size() >= 5) {
                    static constexpr std::array<std::uint16_t, 6> words = {0, 1, 0x7D, 0x7E, 0x7FFF, 0xFFFF};
                    const std::size_t at = 1 + 2 * below(2);
                    const std::uint16_t w = words[below(words.size())];
                    d[at] = static_cast<std::uint8_t>(w >> 8);
                    d[at + 1] = static_cast<std::uint8_t>(w);
                }
                break;
            case 3:  // cut the end
                if (d.size() > 1)
                    d.resize(d.size() - 1 -
                             below(static_cast<std::uint32_t>(std::min<std::size_t>(d.size() - 1, 4))));
                break;
            case 4:  // insert a byte
                if (d.size() < modbus::max_pdu_length)
                    d.insert(d.begin() +
                                 static_cast<std::ptrdiff_t>(below(static_cast<std::uint32_t>(d.size() + 1))),
                             static_cast<std::uint8_t>(below(256)));
                break;
            case 5:  // another function code with the same body
                if (!d.empty()) d[0] = public_functions[below(public_functions.size())];
                break;
            case 6:  // another unit
                p.unit = unit();
                break;
            default:  // a new envelope or split
                envelope(p);
                break;
        }
    }
    if (p.pdu.empty()) p.pdu.push_back(3);
    return p;
}

Probe Generator::next() {
    for (;;) {
        Probe p = !pool_.empty() && below(100) < 45
                      ? mutate(pool_[below(static_cast<std::uint32_t>(pool_.size()))])
                      : generate();
        if (allowed(p.pdu)) return p;
    }
}

void Generator::keep(const Probe& probe) {
    constexpr std::size_t capacity = 512;
    if (pool_.size() < capacity)
        pool_.push_back(probe);
    else
        pool_[below(capacity)] = probe;
}

}  // namespace mbscope::fuzz::network
