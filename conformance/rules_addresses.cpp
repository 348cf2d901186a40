// Addresses: first and last valid address of every table, one past the end, a range that starts valid and
// runs past the end, holes in the map (exception 02, or the manual's nuance: Walchem checks only the first
// address of a request, 002:390), and the specification's order of checks when a request breaks several
// rules at once (AP §6 diagrams: quantity and value, exception 03, before address, exception 02).
#include "conformance/context.hpp"

namespace mbscope::conformance {

using modbus::Table;

void check_addresses(Context& c) {
    const auto bad_address = modbus::exception_for(c.profile, "bad_address", 0x02);
    const bool first_only = c.profile.functions.address_check == modbus::AddressCheck::First;
    const Authority address_authority = authority_for(c.profile, "bad_address");
    for (std::uint8_t fc : {1, 2, 3, 4}) {
        if (!c.profile.functions.supports(fc)) continue;
        const Table t = *modbus::table_of_function(fc);
        const TableFacts& f = c.facts(t);
        const auto fcode = static_cast<modbus::FunctionCode>(fc);
        const std::string id = "address.fc" + std::to_string(fc);
        const std::string table_name(modbus::to_string(t));
        const auto read = [&](std::uint16_t start, std::uint16_t n, const std::string& note) {
            return c.session.request(modbus::encode_pdu(modbus::make_read_request(fcode, start, n)), note);
        };
        // Whose map says these addresses are valid: the manual's, or (the generic profile) the device's own
        // answers while it was probed, judged by the specification alone.
        const Authority map_authority =
            c.profile.open_address_space ? Authority::Specification : Authority::Manual;
        const auto need_map = [&](RuleResult& r) { return !f.lacks_address(r); };
        // A map, and room after its last address (a map reaching 65535 has no "past the end").
        const auto need_end = [&](RuleResult& r) {
            if (!need_map(r)) return false;
            if (*f.last_valid() != 0xFFFF && f.end_unknown.empty()) return true;
            r.outcome = Outcome::Skip;
            r.reason = f.end_unknown.empty() ? "the map reaches address 65535" : f.end_unknown;
            return false;
        };
        c.run({id + ".first", "addresses", spec_section(fc) + "; " + c.profile.source,
               "The first valid address of " + table_name + " is read normally.", map_authority, false},
              [&](RuleResult& r) {
                  if (need_map(r)) expect_normal(r, read(*f.first_valid(), 1, "first valid address"), fc);
              });
        c.run({id + ".last", "addresses", spec_section(fc) + "; " + c.profile.source,
               "The last valid address of " + table_name + " is read normally.", map_authority, false},
              [&](RuleResult& r) {
                  if (need_map(r)) expect_normal(r, read(*f.last_valid(), 1, "last valid address"), fc);
              });
        c.run({id + ".past_end", "addresses", spec_section(fc) + "; " + c.profile.source,
               "One past the last valid address of " + table_name + " gets " + exception_text(bad_address) +
                   ".",
               address_authority, false},
              [&](RuleResult& r) {
                  if (!need_end(r)) return;
                  expect_exception(
                      r, read(static_cast<std::uint16_t>(*f.last_valid() + 1), 1, "one past the end"), fc,
                      bad_address);
              });
        c.run({id + ".runs_past_end", "addresses", spec_section(fc) + "; " + c.profile.source,
               first_only ? "A range that starts at the last valid address and runs past the end is answered "
                            "(the device checks only the first address)."
                          : "A range that starts at the last valid address and runs past the end gets " +
                                exception_text(bad_address) + ".",
               first_only ? Authority::Manual : address_authority, false},
              [&](RuleResult& r) {
                  if (!need_end(r)) return;
                  const auto ex = read(*f.last_valid(), 2, "last valid address, quantity 2");
                  if (first_only)
                      expect_normal(r, ex, fc);
                  else
                      expect_exception(r, ex, fc, bad_address);
              });
        if (auto hole = f.hole()) {
            c.run({id + ".hole", "addresses", spec_section(fc) + "; " + c.profile.source,
                   "Address " + std::to_string(*hole) + ", a hole in the " + table_name + " map, gets " +
                       exception_text(bad_address) + ".",
                   address_authority, false},
                  [&, h = *hole](RuleResult& r) {
                      expect_exception(r, read(h, 1, "a hole in the map"), fc, bad_address);
                  });
        }
        c.run({id + ".overflow", "addresses", spec_section(fc),
               "A range beyond address 65535 (start 65535, quantity 2) gets exception 02.",
               Authority::Specification, false},
              [&](RuleResult& r) {
                  expect_exception(r, read(0xFFFF, 2, "start 65535, quantity 2"), fc, 0x02);
              });
        // Precedence: quantity 0 at an address outside the map breaks two rules; AP §6 checks the quantity
        // first.
        if (f.first_valid() && *f.last_valid() < 0xFFFF && f.end_unknown.empty()) {
            c.run({"precedence.fc" + std::to_string(fc) + ".quantity_before_address", "exception precedence",
                   spec_section(fc) + " (state diagram)",
                   "Quantity 0 at an address outside the map gets exception 03, the quantity being checked "
                   "first.",
                   Authority::Specification, false},
                  [&](RuleResult& r) {
                      expect_exception(r,
                                       read(static_cast<std::uint16_t>(*f.last_valid() + 1), 0,
                                            "quantity 0, invalid address"),
                                       fc, 0x03);
                  });
        }
    }
}

}  // namespace mbscope::conformance
