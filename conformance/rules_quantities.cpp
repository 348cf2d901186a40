// Quantities: 1, the maximum and the maximum + 1 for every read and write function (the manual's limit when
// it states one, else the specification's), and 0, which the specification refuses with exception 03.
#include <algorithm>
#include <memory>

#include "conformance/context.hpp"

namespace mbscope::conformance {

using modbus::Table;

namespace {

bool supports(const modbus::Profile& p, std::uint8_t fc) {
    return p.functions.supports(fc);
}

// A run of `n` consecutive writable points (registers or coils) whose current values can be written back.
std::optional<std::uint16_t> writable_run(const Context& c, Table t, std::uint32_t n) {
    if (c.profile.open_address_space) return c.facts(t).run_of(n);
    std::uint32_t length = 0;
    std::optional<std::uint16_t> start;
    std::optional<std::uint16_t> previous;
    for (const auto& p : c.profile.table(t)) {
        // A point read-only while another holds some value (a loop output in automatic mode, 000:961) is
        // refused with 02 then, as access.*.read_only_when expects: a run across it failed .max.
        const bool ok = p.access == modbus::Access::ReadWrite && !p.reserved && !p.momentary &&
                        !p.fixed_value && !p.read_only_when;
        for (int w = 0; w < p.encoding.words; ++w) {
            const auto a = static_cast<std::uint16_t>(p.address + w);
            if (ok && previous && a == *previous + 1 && length > 0) {
                ++length;
            } else if (ok) {
                start = a;
                length = 1;
            } else {
                length = 0;
            }
            previous = a;
            if (length >= n) return start;
        }
    }
    return std::nullopt;
}

}  // namespace

void check_quantities(Context& c) {
    const auto bad_quantity = modbus::exception_for(c.profile, "bad_quantity", 0x03);
    for (std::uint8_t fc : {1, 2, 3, 4}) {
        if (!supports(c.profile, fc)) continue;
        const Table t = *modbus::table_of_function(fc);
        const TableFacts& f = c.facts(t);
        const int max = c.profile.functions.max_for(fc);
        const bool manual =
            c.profile.functions.max_quantity.count(std::to_string(fc)) && !c.profile.open_address_space;
        const std::string src = spec_section(fc) + (manual ? "; " + c.profile.source : "");
        const std::string id = "quantity.fc" + std::to_string(fc);
        const auto fcode = static_cast<modbus::FunctionCode>(fc);
        c.run({id + ".one", "quantities", spec_section(fc), "Reading one item answers with exactly one item.",
               Authority::Specification, false},
              [&](RuleResult& r) {
                  if (f.lacks_address(r)) return;
                  expect_normal(r,
                                c.session.request(
                                    modbus::encode_pdu(modbus::make_read_request(fcode, *f.first_valid(), 1)),
                                    "quantity 1"),
                                fc);
              });
        c.run({id + ".max", "quantities", src,
               "Reading the maximum quantity (" + std::to_string(max) + ") is answered normally.",
               manual ? Authority::Manual : Authority::Specification, false},
              [&](RuleResult& r) {
                  const bool first_only = c.profile.functions.address_check == modbus::AddressCheck::First;
                  auto start = first_only ? f.first_valid() : f.run_of(static_cast<std::uint32_t>(max));
                  if (start && *start + max > 65536) start.reset();
                  if (!start && f.lacks_address(r)) return;
                  if (!start) {
                      r.outcome = Outcome::Skip;
                      r.reason = "the map has no run of " + std::to_string(max) +
                                 " consecutive valid addresses" +
                                 (f.end_unknown.empty() ? std::string() : " known (" + f.end_unknown + ")");
                      return;
                  }
                  const auto ex = c.session.request(modbus::encode_pdu(modbus::make_read_request(
                                                        fcode, *start, static_cast<std::uint16_t>(max))),
                                                    "maximum quantity");
                  expect_normal(r, ex, fc);
              });
        c.run({id + ".max_plus_one", "quantities", src,
               "Reading the maximum quantity + 1 (" + std::to_string(max + 1) + ") gets " +
                   exception_text(bad_quantity) + ".",
               manual ? authority_for(c.profile, "bad_quantity") : Authority::Specification, false},
              [&](RuleResult& r) {
                  if (f.lacks_address(r)) return;
                  const auto ex =
                      c.session.request(modbus::encode_pdu(modbus::make_read_request(
                                            fcode, *f.first_valid(), static_cast<std::uint16_t>(max + 1))),
                                        "maximum quantity + 1");
                  expect_exception(r, ex, fc, bad_quantity);
              });
        c.run({id + ".zero", "quantities", spec_section(fc), "Reading quantity 0 gets exception 03.",
               Authority::Specification, false},
              [&](RuleResult& r) {
                  const auto ex = c.session.request(
                      modbus::encode_pdu(modbus::make_read_request(fcode, f.first_valid().value_or(0), 0)),
                      "quantity 0");
                  expect_exception(r, ex, fc, 0x03);
              });
    }
    for (std::uint8_t fc : {15, 16}) {
        if (!supports(c.profile, fc)) continue;
        const Table t = fc == 15 ? Table::Coils : Table::HoldingRegisters;
        const int max = c.profile.functions.max_for(fc);
        const int read_max = std::max(1, c.profile.functions.max_for(fc == 15 ? 1 : 3));
        const bool manual =
            c.profile.functions.max_quantity.count(std::to_string(fc)) && !c.profile.open_address_space;
        const std::string src = spec_section(fc) + (manual ? "; " + c.profile.source : "");
        const std::string id = "quantity.fc" + std::to_string(fc);
        // Writes a block of the values it holds now (nothing changes on a conforming device).
        const auto write_current = [&](RuleResult& r, std::uint16_t start, std::uint16_t n,
                                       const char* note) {
            // Only valid addresses hold anything to keep; the rest of the block is written as zero.
            const TableFacts& f = c.facts(t);
            for (std::uint32_t i = 0; i < n;) {
                const auto a = static_cast<std::uint16_t>(start + i);
                if (!f.valid(a)) {
                    ++i;
                    continue;
                }
                std::uint16_t len = 0;
                while (i + len < n && f.valid(static_cast<std::uint16_t>(a + len)))
                    ++len;
                if (!c.session.remember(t, a, len, static_cast<std::uint16_t>(read_max))) {
                    r.outcome = Outcome::Error;
                    r.reason = "the current values could not be read, so nothing was written";
                    return std::optional<modbus::transport::Exchange>{};
                }
                i += len;
            }
            std::vector<std::uint16_t> values;
            for (std::uint16_t i = 0; i < n; ++i) {
                const auto it = c.session.touched().find({t, static_cast<std::uint16_t>(start + i)});
                values.push_back(it == c.session.touched().end() ? 0 : it->second.original);
            }
            std::vector<std::uint8_t> pdu;
            if (fc == 16) {
                pdu = modbus::encode_pdu(modbus::make_write_multiple_registers(start, values));
            } else {
                std::unique_ptr<bool[]> bits(new bool[n]);
                for (std::uint16_t i = 0; i < n; ++i)
                    bits[i] = values[i] != 0;
                pdu = modbus::encode_pdu(
                    modbus::make_write_multiple_coils(start, std::span<const bool>(bits.get(), n)));
            }
            return std::optional<modbus::transport::Exchange>(c.session.request(pdu, note));
        };
        c.run({id + ".max", "quantities", src,
               "Writing the maximum quantity (" + std::to_string(max) + ") is answered normally.",
               manual ? Authority::Manual : Authority::Specification, true},
              [&](RuleResult& r) {
                  const auto start = writable_run(c, t, static_cast<std::uint32_t>(max));
                  if (!start) {
                      r.outcome = Outcome::Skip;
                      r.reason =
                          "the map has no run of " + std::to_string(max) + " consecutive writable points";
                      return;
                  }
                  if (auto ex = write_current(r, *start, static_cast<std::uint16_t>(max),
                                              "maximum quantity, current values"))
                      expect_normal(r, *ex, fc);
              });
        c.run({id + ".max_plus_one", "quantities", src,
               "Writing the maximum quantity + 1 (" + std::to_string(max + 1) + ") gets " +
                   exception_text(bad_quantity) + " and writes nothing.",
               manual ? authority_for(c.profile, "bad_quantity") : Authority::Specification, true},
              [&](RuleResult& r) {
                  const std::size_t pdu_bytes = 6 + (fc == 16 ? 2u * (max + 1) : (max + 1 + 7u) / 8);
                  if (pdu_bytes > 253) {
                      r.outcome = Outcome::Skip;
                      r.reason = "the request needs a PDU of " + std::to_string(pdu_bytes) +
                                 " bytes, more than the specification's 253 (AP §4.1): no frame carries it";
                      return;
                  }
                  auto start = writable_run(c, t, 1);
                  if (!start || *start + max + 1 > 65536) {
                      r.outcome = Outcome::Skip;
                      r.reason = "no writable point to start at";
                      return;
                  }
                  if (auto ex = write_current(r, *start, static_cast<std::uint16_t>(max + 1),
                                              "maximum quantity + 1"))
                      expect_exception(r, *ex, fc, bad_quantity);
              });
        c.run({id + ".zero", "quantities", spec_section(fc), "Writing quantity 0 gets exception 03.",
               Authority::Specification, false},
              [&](RuleResult& r) {
                  // Quantity 0 with byte count 0: nothing to write even on a device that accepts it.
                  const std::vector<std::uint8_t> pdu = {fc, 0x00, 0x00, 0x00, 0x00, 0x00};
                  expect_exception(r, c.session.request(pdu, "quantity 0"), fc, 0x03);
              });
    }
}

}  // namespace mbscope::conformance
