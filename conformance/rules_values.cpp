// Values and access: every writable point accepts its documented limits and refuses one past them
// (exception 03) where the manual gives limits; enumerations refuse a value they do not list; read-only
// points refuse writes; FC5 accepts only FF00/0000; FC15/FC16 refuse a byte count that disagrees with the
// quantity. Every value written is restored afterwards.
#include <algorithm>
#include <cctype>

#include "conformance/context.hpp"

namespace mbscope::conformance {

using modbus::Table;

namespace {

constexpr std::size_t max_points_per_rule = 48;  // keeps a run to seconds; the choice is spread over the map

// Up to `limit` points chosen evenly across the list, so big maps are sampled from end to end.
std::vector<const modbus::Point*> spread(const std::vector<const modbus::Point*>& all, std::size_t limit) {
    if (all.size() <= limit) return all;
    std::vector<const modbus::Point*> out;
    for (std::size_t i = 0; i < limit; ++i)
        out.push_back(all[i * all.size() / limit]);
    return out;
}

bool is_signed(const modbus::Point& p) {
    return p.encoding.type == modbus::EncodingType::S16 || p.encoding.is_signed;
}

std::string point_label(const modbus::Point& p) {
    return std::to_string(p.address) + " (" + (p.name_en.empty() ? p.name : p.name_en) + ")";
}

}  // namespace

void check_values(Context& c) {
    if (!c.profile.functions.supports(6) || c.profile.open_address_space) return;
    const auto bad_value = modbus::exception_for(c.profile, "bad_value", 0x03);
    const Authority value_authority = authority_for(c.profile, "bad_value");
    std::vector<const modbus::Point*> ranged, enums, read_only;
    for (const auto& p : c.profile.table(Table::HoldingRegisters)) {
        if (p.access == modbus::Access::Read && !p.reserved && !p.fixed_value && p.encoding.words == 1) {
            read_only.push_back(&p);
        } else if (freely_writable(p)) {
            if (p.encoding.type == modbus::EncodingType::Enum && !p.encoding.values.empty())
                enums.push_back(&p);
            else if (p.min || p.max)
                ranged.push_back(&p);
        }
    }
    const auto write = [&](const modbus::Point& p, std::uint16_t v, const std::string& note) {
        return c.session.request(modbus::encode_pdu(modbus::make_write_single_register(p.address, v)), note);
    };
    const auto remember = [&](RuleResult& r, const modbus::Point& p) {
        if (c.session.remember(Table::HoldingRegisters, p.address, 1)) return true;
        r.outcome = Outcome::Error;
        r.reason = "the point's value could not be read, so nothing was written";
        return false;
    };
    for (const modbus::Point* p : spread(ranged, max_points_per_rule)) {
        const std::int64_t lo = p->min.value_or(is_signed(*p) ? -32768 : 0);
        const std::int64_t hi = p->max.value_or(is_signed(*p) ? 32767 : 65535);
        const std::string src = p->source.empty() ? c.profile.source : p->source;
        const std::string id = "value.hr" + std::to_string(p->address);
        c.run({id + ".limits", "values and access", src,
               "Register " + point_label(*p) + " accepts its limits " + std::to_string(lo) + " and " +
                   std::to_string(hi) + ", and each reads back as written.",
               Authority::Manual, true},
              [&](RuleResult& r) {
                  if (!remember(r, *p)) return;
                  r.expected = "both written, echoed and read back";
                  r.outcome = Outcome::Pass;
                  // A write-only point has nothing to read back (the manuals do not say what it reads).
                  const bool readable = p->access != modbus::Access::Write;
                  for (const auto& [v, what] : {std::pair{lo, "the minimum"}, std::pair{hi, "the maximum"}}) {
                      const auto raw = static_cast<std::uint16_t>(v);
                      const auto ex = write(*p, raw, what);
                      r.observed += (r.observed.empty() ? "" : "; ") + describe(ex);
                      if (!is_normal(ex, 6)) {
                          r.outcome = Outcome::Fail;
                          continue;
                      }
                      if (!readable) continue;
                      const auto back = c.session.read_registers(Table::HoldingRegisters, p->address, 1,
                                                                 std::string("read back ") + what);
                      if (!back || (*back)[0] != raw) {
                          r.outcome = Outcome::Fail;
                          r.observed += back ? ", reads back " + std::to_string((*back)[0]) + " instead of " +
                                                   std::to_string(raw)
                                             : ", could not be read back";
                      }
                  }
              });
        const bool below = is_signed(*p) ? lo > -32768 : lo > 0;
        const bool above = is_signed(*p) ? hi < 32767 : hi < 65535;
        if (!below && !above) continue;
        c.run({id + ".outside", "values and access", src,
               "Register " + point_label(*p) + " refuses a value one past its limits with " +
                   exception_text(bad_value) + ".",
               value_authority, true},
              [&](RuleResult& r) {
                  if (!remember(r, *p)) return;
                  std::vector<modbus::transport::Exchange> ex;
                  if (below)
                      ex.push_back(write(*p, static_cast<std::uint16_t>(lo - 1), "one below the minimum"));
                  if (above)
                      ex.push_back(write(*p, static_cast<std::uint16_t>(hi + 1), "one above the maximum"));
                  r.expected = exception_text(bad_value);
                  r.outcome = Outcome::Pass;
                  for (const auto& e : ex) {
                      r.observed += (r.observed.empty() ? "" : "; ") + describe(e);
                      if (!is_exception(e, 6, bad_value)) r.outcome = Outcome::Fail;
                  }
              });
    }
    for (const modbus::Point* p : spread(enums, max_points_per_rule)) {
        std::int64_t unlisted = 0;
        for (const auto& v : p->encoding.values)
            unlisted = std::max(unlisted, v.value + 1);
        if (unlisted > 65535) continue;
        c.run({"value.hr" + std::to_string(p->address) + ".enumeration", "values and access",
               p->source.empty() ? c.profile.source : p->source,
               "Register " + point_label(*p) + " refuses " + std::to_string(unlisted) +
                   ", which its enumeration does not list, with " + exception_text(bad_value) + ".",
               value_authority, true},
              [&](RuleResult& r) {
                  if (!remember(r, *p)) return;
                  expect_exception(
                      r, write(*p, static_cast<std::uint16_t>(unlisted), "a value the enumeration lacks"), 6,
                      bad_value);
              });
        // Values the manual lists and marks as not allowed ("não permitido", 000:1097).
        std::vector<const modbus::EnumValue*> forbidden;
        std::string which;
        for (const auto& v : p->encoding.values)
            if (v.forbidden && v.value >= 0 && v.value <= 65535) {
                forbidden.push_back(&v);
                which += (which.empty() ? "" : ", ") + std::to_string(v.value);
            }
        if (forbidden.empty()) continue;
        c.run({"value.hr" + std::to_string(p->address) + ".forbidden", "values and access",
               p->source.empty() ? c.profile.source : p->source,
               "Register " + point_label(*p) + " refuses " + which +
                   ", which the manual lists as not allowed, with " + exception_text(bad_value) + ".",
               value_authority, true},
              [&](RuleResult& r) {
                  if (!remember(r, *p)) return;
                  r.expected = exception_text(bad_value) + " to each";
                  r.outcome = Outcome::Pass;
                  for (const modbus::EnumValue* v : forbidden) {
                      const auto e = write(*p, static_cast<std::uint16_t>(v->value), "a value not allowed");
                      r.observed += (r.observed.empty() ? "" : "; ") + describe(e);
                      if (!is_exception(e, 6, bad_value)) r.outcome = Outcome::Fail;
                  }
              });
    }
    const auto read_only_code = modbus::exception_for(c.profile, "write_read_only", 0x02);
    for (const modbus::Point* p : spread(read_only, 8)) {
        c.run({"access.hr" + std::to_string(p->address) + ".read_only", "values and access",
               p->source.empty() ? c.profile.source : p->source,
               "Read-only register " + point_label(*p) + " refuses a write with " +
                   exception_text(read_only_code) + ".",
               authority_for(c.profile, "write_read_only"), true},
              [&](RuleResult& r) {
                  // The write carries the value the point holds, so even a device that wrongly accepts it
                  // changes nothing: nothing to restore (a process value moves on its own and could not be
                  // restored anyway).
                  const auto now =
                      c.session.read_registers(Table::HoldingRegisters, p->address, 1, "its value");
                  if (!now) {
                      r.outcome = Outcome::Error;
                      r.reason = "the point could not be read";
                      return;
                  }
                  expect_exception(r, write(*p, (*now)[0], "its own value"), 6, read_only_code);
              });
    }
    // Read-only while another point holds certain values (conditional_access, MK-RO-02: a loop's output in
    // automatic mode): the condition is set, the point written with its own value (a device that wrongly
    // takes it changes nothing), and the condition set back at once (the ledger restores it again). The
    // manual states the condition (the specification knows nothing of it): graded against the manual.
    for (const auto& p : c.profile.table(Table::HoldingRegisters)) {
        if (!p.read_only_when || p.reserved) continue;
        const auto& when = p.read_only_when->when;
        const modbus::Point* condition = c.profile.find(when.table, when.address);
        const bool coil = when.table == Table::Coils;
        if (!condition || condition->access != modbus::Access::ReadWrite || condition->reserved ||
            !c.profile.functions.supports(coil ? 5 : 6))
            continue;
        const std::uint16_t set_to = p.read_only_when->values.front();
        const std::string condition_text =
            (coil ? "coil " : "register ") + std::to_string(when.address) + " := " + std::to_string(set_to);
        c.run({"access.hr" + std::to_string(p.address) + ".read_only_when", "values and access",
               p.source.empty() ? c.profile.source : p.source,
               "Register " + point_label(p) + " refuses a write with " + exception_text(read_only_code) +
                   " while " + condition_text + ".",
               Authority::Manual, true},
              [&, set_to, coil](RuleResult& r) {
                  if (!c.session.remember(when.table, when.address, 1) ||
                      !c.session.remember(Table::HoldingRegisters, p.address, 1)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the points' values could not be read, so nothing was written";
                      return;
                  }
                  const auto original = c.session.touched().at({when.table, when.address}).original;
                  const auto own = c.session.touched().at({Table::HoldingRegisters, p.address}).original;
                  const auto set_condition = [&](std::uint16_t v, const std::string& note) {
                      const auto pdu = coil ? modbus::make_write_single_coil(when.address, v != 0)
                                            : modbus::make_write_single_register(when.address, v);
                      return c.session.request(modbus::encode_pdu(pdu), note);
                  };
                  const auto set = set_condition(set_to, condition_text);
                  if (!is_normal(set, coil ? 5 : 6)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the condition (" + condition_text + ") was not taken: " + describe(set);
                      return;
                  }
                  expect_exception(r, write(p, own, "its own value, " + condition_text), 6, read_only_code);
                  (void)set_condition(original, "the condition set back");
              });
    }
}

void check_write_encoding(Context& c) {
    if (c.profile.functions.supports(5)) {
        c.run({"value.fc5.invalid", "values and access", "AP §6.5",
               "FC5 with a value other than FF00 or 0000 gets exception 03.", Authority::Specification, true},
              [&](RuleResult& r) {
                  // A device that takes 0x1234 for a value changes the coil: it is read first and written
                  // back at the end (it ran under --read-only and was never restored). A device with no coil
                  // to read (the CTH2265I's map has none: the read is refused) still gets the request: the
                  // value is judged before the address (AP §6.5), and there is nothing there to restore. A
                  // read that went unanswered says nothing of the kind: the coil may be there, unkept.
                  auto start = c.facts(Table::Coils).first_valid().value_or(0);
                  // Not at a momentary command (a device that takes the value would act on it): at the
                  // first coil that is none.
                  if (const auto* there = c.profile.find(Table::Coils, start); there && there->momentary)
                      for (const auto& p : c.profile.table(Table::Coils))
                          if (!p.momentary) {
                              start = p.address;
                              break;
                          }
                  if (!c.session.remember(Table::Coils, start, 1) && !c.session.last_read_refused()) {
                      r.outcome = Outcome::Error;
                      r.reason = "the coil's value could not be read, so nothing was written";
                      return;
                  }
                  const std::vector<std::uint8_t> pdu = {0x05, static_cast<std::uint8_t>(start >> 8),
                                                         static_cast<std::uint8_t>(start), 0x12, 0x34};
                  expect_exception(r, c.session.request(pdu, "value 0x1234"), 5, 0x03);
              });
    }
    if (c.profile.functions.supports(16)) {
        c.run(
            {"value.fc16.byte_count", "values and access", "AP §6.12",
             "FC16 whose byte count disagrees with the quantity gets exception 03 and writes nothing.",
             Authority::Specification, true},
            [&](RuleResult& r) {
                // A register the run may write (a process value or a read-only point would refuse for
                // another reason, and could not be restored), carrying a value other than its own, so an
                // executed write shows on reading back.
                const modbus::Point* wp = nullptr;
                for (const auto& p : c.profile.table(Table::HoldingRegisters))
                    if (!wp && freely_writable(p)) wp = &p;
                const auto first = c.facts(Table::HoldingRegisters).first_valid();
                if (!wp && !(c.profile.open_address_space && first)) {
                    r.outcome = Outcome::Skip;
                    r.reason = "the map has no register this run may write";
                    return;
                }
                const std::uint16_t start = wp ? wp->address : *first;
                if (!c.session.remember(Table::HoldingRegisters, start, 1)) {
                    r.outcome = Outcome::Error;
                    r.reason = "the register's value could not be read, so nothing was written";
                    return;
                }
                // The value now (an earlier rule may have changed it; the ledger keeps the first one).
                const auto current =
                    c.session.read_registers(Table::HoldingRegisters, start, 1, "its value now");
                if (!current) {
                    r.outcome = Outcome::Error;
                    r.reason = "the register's value could not be read";
                    return;
                }
                const std::uint16_t original = (*current)[0];
                const std::uint16_t other =
                    wp ? valid_alternative(wp, original).value_or(original ^ 1u) : original ^ 1u;
                // Quantity 1, byte count 3, three data bytes: consistent framing, inconsistent count.
                const std::vector<std::uint8_t> pdu = {
                    0x10, static_cast<std::uint8_t>(start >> 8), static_cast<std::uint8_t>(start), 0x00, 0x01,
                    0x03, static_cast<std::uint8_t>(other >> 8), static_cast<std::uint8_t>(other), 0x00};
                expect_exception(r, c.session.request(pdu, "quantity 1, byte count 3"), 16, 0x03);
                const auto back =
                    c.session.read_registers(Table::HoldingRegisters, start, 1, "read it back: unchanged");
                if (!back || (*back)[0] != original) {
                    r.outcome = Outcome::Fail;
                    r.observed += back ? "; the register now reads " + std::to_string((*back)[0])
                                       : "; could not be read back";
                }
            });
    }
    if (c.profile.functions.supports(15)) {
        c.run({"value.fc15.byte_count", "values and access", "AP §6.11",
               "FC15 whose byte count disagrees with the quantity gets exception 03 and writes nothing.",
               Authority::Specification, true},
              [&](RuleResult& r) {
                  // A coil the run may write where the map has one, carrying the opposite of its value, so
                  // an executed write shows on reading back.
                  const modbus::Point* wc = nullptr;
                  for (const auto& p : c.profile.table(Table::Coils))
                      if (!wc && p.access == modbus::Access::ReadWrite && !p.reserved && !p.momentary)
                          wc = &p;
                  const auto first = c.facts(Table::Coils).first_valid();
                  const std::uint16_t start = wc ? wc->address : first.value_or(0);
                  // The first coil when none is freely writable: a momentary command there is sent 0, which a
                  // device that wrongly executes the write takes as no command.
                  const auto* at_start = c.profile.find(Table::Coils, start);
                  const bool pressed_if_executed = !wc && at_start && at_start->momentary;
                  std::optional<bool> now;
                  if (wc || first) {
                      if (!c.session.remember(Table::Coils, start, 1)) {
                          r.outcome = Outcome::Error;
                          r.reason = "the coil's value could not be read, so nothing was written";
                          return;
                      }
                      if (auto b = c.session.read_bits(Table::Coils, start, 1, "its value now"))
                          now = (*b)[0];
                  }
                  // Quantity 1 needs 1 byte; 2 are announced and sent.
                  const std::vector<std::uint8_t> pdu = {
                      0x0F,
                      static_cast<std::uint8_t>(start >> 8),
                      static_cast<std::uint8_t>(start),
                      0x00,
                      0x01,
                      0x02,
                      static_cast<std::uint8_t>(now && !*now && !pressed_if_executed ? 0x01 : 0x00),
                      0x00};
                  expect_exception(r, c.session.request(pdu, "quantity 1, byte count 2"), 15, 0x03);
                  if (!now) return;
                  const auto back = c.session.read_bits(Table::Coils, start, 1, "read it back: unchanged");
                  if (!back || (*back)[0] != *now) {
                      r.outcome = Outcome::Fail;
                      r.observed += back ? "; the coil changed" : "; could not be read back";
                  }
              });
    }
}

}  // namespace mbscope::conformance
