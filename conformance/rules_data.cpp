// Echoes and data: FC5, FC6 and FC8/00 echo the request exactly; a written value reads back; 32-bit values
// travel in the profile's word order; a reply to FC1 or FC2 pads its last byte with zeros; reserved registers
// read their documented fixed value.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include "conformance/context.hpp"
#include "modbus/describe.hpp"

namespace mbscope::conformance {

using modbus::Table;

namespace {

const modbus::Point* first_writable(const modbus::Profile& p, Table t, int words) {
    for (const auto& pt : p.table(t)) {
        if (words == 1 && freely_writable(pt)) return &pt;
        if (words == 2 && pt.access == modbus::Access::ReadWrite && !pt.reserved && !pt.momentary &&
            pt.encoding.words == 2)
            return &pt;
    }
    return nullptr;
}

// An echo counts only in the request's envelope (its transaction and unit identifiers, protocol 0): the
// same PDU from another unit or for another transaction answers nothing that was asked.
bool echoes(const modbus::transport::Exchange& ex, std::span<const std::uint8_t> pdu) {
    if (!ex.response || !ex.response->checksum_ok || !envelope_fault(ex).empty()) return false;
    const auto got = ex.response->pdu();
    return std::equal(got.begin(), got.end(), pdu.begin(), pdu.end());
}

}  // namespace

void check_data(Context& c) {
    const bool generic = c.profile.open_address_space;
    const auto coil = generic ? c.facts(Table::Coils).first_valid() : std::optional<std::uint16_t>{};
    const modbus::Point* wc = first_writable(c.profile, Table::Coils, 1);
    if (c.profile.functions.supports(5) && (wc || coil)) {
        const std::uint16_t address = wc ? wc->address : *coil;
        c.run({"echo.fc5", "echoes and data", "AP §6.5", "FC5 is answered with an exact echo of the request.",
               Authority::Specification, true},
              [&](RuleResult& r) {
                  if (!c.session.remember(Table::Coils, address, 1)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the coil could not be read, so nothing was written";
                      return;
                  }
                  const bool now = c.session.touched().at({Table::Coils, address}).original != 0;
                  const auto pdu = modbus::encode_pdu(modbus::make_write_single_coil(address, !now));
                  const auto ex = c.session.request(pdu, "write the opposite value");
                  r.expected = "the request's PDU, byte for byte";
                  r.observed = describe(ex);
                  r.outcome = echoes(ex, pdu) ? Outcome::Pass : Outcome::Fail;
                  if (r.outcome == Outcome::Pass) {
                      auto back = c.session.read_bits(Table::Coils, address, 1, "read it back");
                      if (!back || (*back)[0] == now) {
                          r.outcome = Outcome::Fail;
                          r.observed += back ? "; reads back unchanged" : "; could not be read back";
                      }
                  }
              });
    }
    const modbus::Point* wr = first_writable(c.profile, Table::HoldingRegisters, 1);
    const auto reg =
        generic ? c.facts(Table::HoldingRegisters).first_valid() : std::optional<std::uint16_t>{};
    if (c.profile.functions.supports(6) && (wr || reg)) {
        const std::uint16_t address = wr ? wr->address : *reg;
        c.run({"echo.fc6", "echoes and data", "AP §6.6",
               "FC6 is answered with an exact echo, and the value written reads back.",
               Authority::Specification, true},
              [&](RuleResult& r) {
                  if (!c.session.remember(Table::HoldingRegisters, address, 1)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the register could not be read, so nothing was written";
                      return;
                  }
                  const auto now = c.session.touched().at({Table::HoldingRegisters, address}).original;
                  const auto alternative = valid_alternative(wr, now);
                  if (!alternative) {
                      r.outcome = Outcome::Skip;
                      r.reason = "the point documents no other valid value";
                      return;
                  }
                  const std::uint16_t value = *alternative;
                  const auto pdu = modbus::encode_pdu(modbus::make_write_single_register(address, value));
                  const auto ex = c.session.request(pdu, "write a different value in range");
                  r.expected = "an exact echo, then " + std::to_string(value) + " on read-back";
                  r.observed = describe(ex);
                  // The generic profile guessed the register: one the device reads but keeps read-only (a
                  // process value) is refused with 02, and there is no echo to judge.
                  if (generic && is_exception(ex, 6, 0x02)) {
                      r.outcome = Outcome::Skip;
                      r.reason = "register " + std::to_string(address) +
                                 ", the first the device reads, is not writable (exception 02): the generic "
                                 "profile knows no writable one";
                      return;
                  }
                  r.outcome = echoes(ex, pdu) ? Outcome::Pass : Outcome::Fail;
                  auto back = c.session.read_registers(Table::HoldingRegisters, address, 1, "read it back");
                  r.observed +=
                      back ? "; reads back " + std::to_string((*back)[0]) : "; could not be read back";
                  if (!back || (*back)[0] != value) r.outcome = Outcome::Fail;
              });
    }
    const auto& diag = c.profile.functions.diagnostics;
    if (c.profile.functions.supports(8) && std::find(diag.begin(), diag.end(), 0) != diag.end()) {
        c.run(
            {"echo.fc8.0", "echoes and data", "AP §6.8.1 (sub-function 00)",
             "FC8 sub-function 0 returns the query data unchanged.", Authority::Specification, false},
            [&](RuleResult& r) {
                const std::uint8_t data[4] = {0xA5, 0x5A, 0x00, 0xFF};
                const auto pdu = modbus::encode_pdu(modbus::make_diagnostics(0, data));
                const auto ex = c.session.request(pdu, "echo four bytes");
                r.expected = "the request's PDU, byte for byte";
                r.observed = describe(ex);
                r.outcome = echoes(ex, pdu) ? Outcome::Pass : Outcome::Fail;
                // A device the generic profile knows nothing of may not implement FC8 (a serial-line
                // function, AP §6.8): refused as AP §7 says, there is nothing to judge. Any other answer (a
                // connection closed, a wrong echo) is still a failure.
                if (c.profile.open_address_space && r.outcome == Outcome::Fail && is_exception(ex, 8, 0x01)) {
                    r.outcome = Outcome::Skip;
                    r.reason = "the device does not implement FC8 (exception 01, as AP §7 allows)";
                }
            });
    }
    // 32-bit values in the profile's word order.
    const modbus::Point* w32 = first_writable(c.profile, Table::HoldingRegisters, 2);
    if (w32 && c.profile.functions.supports(16)) {
        const auto order = w32->encoding.word_order;
        c.run({"data.word_order.hr" + std::to_string(w32->address), "echoes and data",
               w32->source.empty() ? c.profile.source : w32->source,
               "A 32-bit value written with FC16 in the profile's word order (" +
                   std::string(modbus::to_string(order)) + ") reads back as the same value.",
               Authority::Manual, true},
              [&](RuleResult& r) {
                  if (!c.session.remember(Table::HoldingRegisters, w32->address, 2, 2)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the point could not be read, so nothing was written";
                      return;
                  }
                  std::uint32_t u = 0;
                  std::string shown;
                  const double lo = w32->min ? static_cast<double>(*w32->min) : 0,
                               hi = w32->max ? static_cast<double>(*w32->max) : 1000;
                  if (w32->encoding.type == modbus::EncodingType::F32) {
                      const float f = static_cast<float>(lo + (hi - lo) * 0.25) +
                                      0.5f;  // not a round number: words differ
                      std::memcpy(&u, &f, sizeof u);
                      shown = std::to_string(f);
                  } else {
                      u = static_cast<std::uint32_t>(std::llround(lo + (hi - lo) / 3));
                      if (u < 65536 && hi >= 65536 + lo)
                          u += 65536;  // both words non-zero when the range allows
                      shown = std::to_string(u);
                  }
                  const auto words = modbus::split_words(u, order);
                  const auto ex = c.session.request(
                      modbus::encode_pdu(modbus::make_write_multiple_registers(w32->address, words)),
                      "write " + shown);
                  auto back = c.session.read_registers(Table::HoldingRegisters, w32->address, 2,
                                                       "read both registers back");
                  r.expected = "normal response, then the words " + std::to_string(words[0]) + ", " +
                               std::to_string(words[1]);
                  r.observed = describe(ex) + (back ? "; reads " + std::to_string((*back)[0]) + ", " +
                                                          std::to_string((*back)[1])
                                                    : std::string("; could not be read back"));
                  r.outcome = is_normal(ex, 16) && back && (*back)[0] == words[0] && (*back)[1] == words[1]
                                  ? Outcome::Pass
                                  : Outcome::Fail;
              });
    }
    // A reply to FC1 or FC2 pads the bits of its last byte past the quantity asked with zeros (AP §6.1,
    // §6.2; the MK manual's example answers 21 coils with 1B, 000:343). Asked for the longest run of valid
    // points the device's limit allows, cut to leave a byte part-used.
    for (const std::uint8_t fc : {std::uint8_t{1}, std::uint8_t{2}}) {
        const Table t = fc == 1 ? Table::Coils : Table::DiscreteInputs;
        if (!c.profile.functions.supports(fc) || !c.facts(t).present) continue;
        c.run({"data.padding.fc" + std::to_string(fc), "echoes and data", fc == 1 ? "AP §6.1" : "AP §6.2",
               "The bits of a reply's last byte past the quantity asked are zero.", Authority::Specification,
               false},
              [&, fc, t](RuleResult& r) {
                  std::pair<std::uint16_t, std::uint32_t> longest{0, 0};  // start, length
                  for (const auto& [first, last] : c.facts(t).runs)
                      if (std::uint32_t{last} - first + 1 > longest.second)
                          longest = {first, last - first + 1u};
                  std::uint32_t quantity = std::min<std::uint32_t>(
                      longest.second, static_cast<std::uint32_t>(c.profile.functions.max_for(fc)));
                  if (quantity % 8 == 0 && quantity > 0) --quantity;
                  if (quantity == 0) {
                      r.outcome = Outcome::Skip;
                      r.reason = "no valid point known in this table";
                      return;
                  }
                  const auto pdu = modbus::encode_pdu(
                      modbus::make_read_request(static_cast<modbus::FunctionCode>(fc), longest.first,
                                                static_cast<std::uint16_t>(quantity)));
                  const auto ex = c.session.request(pdu, "read " + std::to_string(quantity) + " points");
                  const auto rsp = response_pdu(ex);
                  const auto* bits = rsp ? std::get_if<modbus::ReadBitsResponse>(&rsp->body) : nullptr;
                  r.expected = "bits " + std::to_string(quantity % 8) + " to 7 of the last byte zero";
                  if (!bits || bits->values.size() != (quantity + 7) / 8) {
                      r.outcome = Outcome::Error;
                      r.reason = "the read of " + std::to_string(quantity) +
                                 " points was not answered with " + std::to_string((quantity + 7) / 8) +
                                 " bytes of them: " + describe(ex);
                      return;
                  }
                  const std::uint8_t last = bits->values.back();
                  r.observed =
                      "last byte " + modbus::hex8(last) + " for " + std::to_string(quantity) + " points";
                  r.outcome = modbus::padding_bits_set(bits->values, static_cast<std::uint16_t>(quantity))
                                  ? Outcome::Fail
                                  : Outcome::Pass;
              });
    }
    // Reserved registers with a documented read value (the CTH2265I's 0x55AA, 003:574).
    for (const auto& p : c.profile.table(Table::HoldingRegisters)) {
        if (!p.fixed_value || !c.profile.functions.supports(3)) continue;
        c.run({"data.fixed.hr" + std::to_string(p.address), "echoes and data",
               p.source.empty() ? c.profile.source : p.source,
               "Register " + std::to_string(p.address) + " reads its documented fixed value " +
                   std::to_string(*p.fixed_value) + ".",
               Authority::Manual, false},
              [&](RuleResult& r) {
                  auto v =
                      c.session.read_registers(Table::HoldingRegisters, p.address, 1, "read the fixed value");
                  r.expected = std::to_string(*p.fixed_value);
                  r.observed = v ? std::to_string((*v)[0]) : "no normal reply";
                  r.outcome = v && (*v)[0] == *p.fixed_value ? Outcome::Pass : Outcome::Fail;
              });
    }
    // Registers that mirror the line settings (MK-CFG-01: ENDER, PROT, BAUD, PARID; CTH-ADR-01: 3999) read
    // what the runner is using: its unit, its framing, and on a serial line its speed and parity.
    const auto line = modbus::transport::line_state(c.session.client().endpoint(), c.session.options().unit);
    for (const auto& p : c.profile.table(Table::HoldingRegisters)) {
        if (!p.mirrors || !c.profile.functions.supports(3)) continue;
        const std::string setting(modbus::to_string(*p.mirrors));
        c.run({"data.mirror.hr" + std::to_string(p.address), "echoes and data",
               p.source.empty() ? c.profile.source : p.source,
               "Register " + std::to_string(p.address) + " reads back the line's " + setting +
                   " the runner is using.",
               Authority::Manual, false},
              [&](RuleResult& r) {
                  // Over Modbus/TCP unit 255 asks whichever device serves the connection (TCP §4.4.1), not a
                  // device by its address, which 255 never is on a serial line (SL §2.2: 1 to 247).
                  if (*p.mirrors == modbus::LineSetting::UnitId && !c.serial_framing() &&
                      c.session.options().unit == 255) {
                      r.outcome = Outcome::Skip;
                      r.reason =
                          "unit 255 over Modbus/TCP addresses the device on the connection, not by "
                          "an address it holds (TCP §4.4.1)";
                      return;
                  }
                  const auto expected = modbus::mirrored_value(p, line);
                  if (!expected) {
                      // Framing over Modbus/TCP, speed and parity over any network scheme: the device's line
                      // is on the far side of a gateway, its settings are not the runner's.
                      const bool known =
                          *p.mirrors == modbus::LineSetting::Framing ? c.serial_framing() : c.true_serial();
                      r.outcome = Outcome::Skip;
                      r.reason = known ? "the map has no code for this line's " + setting
                                       : "over " +
                                             std::string(modbus::transport::to_string(
                                                 c.session.client().endpoint().scheme)) +
                                             " the device's " + setting + " is a gateway's, not the runner's";
                      return;
                  }
                  auto v =
                      c.session.read_registers(Table::HoldingRegisters, p.address, 1, "read the " + setting);
                  const auto named = [&](std::uint16_t value) {
                      for (const auto& e : p.encoding.values)
                          if (e.value == value)
                              return std::to_string(value) + " (" + (e.text_en.empty() ? e.text : e.text_en) +
                                     ")";
                      return std::to_string(value);
                  };
                  r.expected = named(*expected);
                  r.observed = v ? named((*v)[0]) : "no normal reply";
                  r.outcome = v && (*v)[0] == *expected ? Outcome::Pass : Outcome::Fail;
              });
    }
    check_alternative_maps(c);
}

namespace {

// "Sensor 1 (sensor-1-1)" of "Sensor 1 (sensor-1-1): Valor primário".
std::string object_of(const modbus::Point& p) {
    const auto end = p.name.find("): ");
    return end == std::string::npos ? p.name : p.name.substr(0, end + 1);
}

std::string words_text(const std::vector<std::uint16_t>& words) {
    std::string out;
    for (const auto w : words) {
        char b[8];
        std::snprintf(b, sizeof b, "%04X", w);
        out += (out.empty() ? "" : " ") + std::string(b);
    }
    return out;
}

}  // namespace

// Walchem's alternative maps (5.3.9, 002:750-776): each address reads what its object's own field holds
// (Point::same_value_as). One rule per map (its points share the line they cite), for its first and last
// object: the object's fields read in one request, each alternative address, and the fields again. A value
// that did not move between the two reads of its field must be the alternative address's; one that moved (a
// live sensor, or the slave's simulated one, when the reads are paced seconds apart) is not judged. Which
// field a column reads the manual does not say (the profile takes the one of the same name): a failure is a
// warning.
void check_alternative_maps(Context& c) {
    if (!c.profile.functions.supports(3)) return;
    std::map<std::string, std::vector<const modbus::Point*>> maps;  // by the line they cite
    for (const auto& p : c.profile.table(Table::HoldingRegisters))
        if (p.same_value_as && !p.reserved) maps[p.source].push_back(&p);
    for (const auto& [source, points] : maps) {
        std::vector<std::string> objects;  // in their numbering: the first column is in object order
        for (const auto* p : points)
            if (std::find(objects.begin(), objects.end(), object_of(*p)) == objects.end())
                objects.push_back(object_of(*p));
        std::vector<std::vector<const modbus::Point*>> checked(objects.size() > 1 ? 2 : 1);
        for (const auto* p : points) {
            if (object_of(*p) == objects.front()) checked.front().push_back(p);
            if (objects.size() > 1 && object_of(*p) == objects.back()) checked.back().push_back(p);
        }
        const std::string first = std::to_string(points.front()->address);
        c.run(
            {"data.alternative.hr" + first, "echoes and data", source,
             "The alternative map from holding register " + first +
                 " reads what its objects' own fields hold (" + objects.front() +
                 (objects.size() > 1 ? " and " + objects.back() : std::string()) + ").",
             Authority::Implied, false},
            [&c, checked](RuleResult& r) {
                std::size_t judged = 0, moved = 0;
                for (const auto& object : checked) {
                    // The object's fields: one block of its map (36 registers), read whole.
                    std::uint32_t lo = 0xFFFF, hi = 0;
                    for (const auto* p : object) {
                        lo = std::min<std::uint32_t>(lo, *p->same_value_as);
                        hi = std::max<std::uint32_t>(hi, *p->same_value_as + p->encoding.words);
                    }
                    const auto start = static_cast<std::uint16_t>(lo);
                    const auto count = static_cast<std::uint16_t>(hi - lo);
                    const std::string fields = std::to_string(lo) + "-" + std::to_string(hi - 1);
                    const auto before = c.session.read_registers(Table::HoldingRegisters, start, count,
                                                                 "the object's fields " + fields);
                    std::vector<std::pair<const modbus::Point*, std::vector<std::uint16_t>>> alts;
                    for (const auto* p : object)
                        if (auto v =
                                c.session.read_registers(Table::HoldingRegisters, p->address,
                                                         static_cast<std::uint16_t>(p->encoding.words),
                                                         std::to_string(p->address) + " (" + p->name + ")"))
                            alts.emplace_back(p, std::move(*v));
                    const auto after = c.session.read_registers(Table::HoldingRegisters, start, count,
                                                                "the object's fields " + fields + " again");
                    if (!before || !after || alts.size() != object.size()) {
                        r.outcome = Outcome::Fail;
                        r.expected =
                            "normal replies to reads of the object's fields and of its alternative addresses";
                        r.observed = "no normal reply to one of them (see the evidence)";
                        return;
                    }
                    for (const auto& [p, alt] : alts) {
                        const auto at = static_cast<std::ptrdiff_t>(*p->same_value_as - lo);
                        const std::vector<std::uint16_t> was(before->begin() + at,
                                                             before->begin() + at + p->encoding.words);
                        const std::vector<std::uint16_t> is(after->begin() + at,
                                                            after->begin() + at + p->encoding.words);
                        if (was != is) {
                            ++moved;
                            continue;
                        }
                        ++judged;
                        if (alt != was) {
                            r.outcome = Outcome::Fail;
                            r.expected = "holding register " + std::to_string(p->address) + " (" + p->name +
                                         ") reads what " + std::to_string(*p->same_value_as) + " holds (" +
                                         words_text(was) + ")";
                            r.observed = words_text(alt);
                            return;
                        }
                    }
                }
                if (judged == 0) {
                    r.outcome = Outcome::Skip;
                    r.reason = "every value moved between the two reads of its field (" +
                               std::to_string(moved) + "): none could be compared";
                    return;
                }
                r.outcome = Outcome::Pass;
                r.observed =
                    std::to_string(judged) + " addresses read their objects' values" +
                    (moved ? "; " + std::to_string(moved) + " that moved while read not judged" : "");
            });
    }
}

}  // namespace mbscope::conformance
