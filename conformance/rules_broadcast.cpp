// Broadcast (SL §2.1, AP §4.1): a write to unit 0 takes effect and gets no reply; a read to unit 0 gets no
// reply; a function the manual does not allow in broadcast is not executed. Modbus/TCP has no broadcast
// (TCP §4.4.1.2) unless the manual gives unit 0 that meaning (Walchem 002:213, contradicted at 211, 215).
#include <algorithm>

#include "conformance/context.hpp"

namespace mbscope::conformance {

using modbus::Table;

void check_broadcast(Context& c) {
    const bool tcp = !c.serial_framing();
    const auto& allowed = c.profile.functions.broadcast;
    const auto& transports = c.profile.line.transports;
    const bool manual_says_tcp_broadcast =
        tcp && !c.profile.open_address_space && !allowed.empty() &&
        std::find(transports.begin(), transports.end(), "tcp") != transports.end();
    if (tcp && !manual_says_tcp_broadcast) {
        c.run({"broadcast", "broadcast", "TCP §4.4.1.2", "Broadcast rules apply to serial lines only.",
               Authority::Specification, false},
              [](RuleResult& r) {
                  r.outcome = Outcome::Skip;
                  r.reason = "Modbus/TCP has no broadcast and the profile gives unit 0 no such meaning";
              });
        return;
    }
    const Authority authority = tcp ? Authority::Implied : Authority::Specification;
    const std::string src = tcp ? "002:211-215 (contradictory)" : "SL §2.1, AP §4.1";
    const auto timeout = std::max(c.session.options().timeout, std::chrono::milliseconds(300));
    c.run(
        {"broadcast.read.silent", "broadcast", src, "A read sent to unit 0 gets no reply.", authority, false},
        [&](RuleResult& r) {
            const auto start = c.facts(Table::HoldingRegisters).first_valid().value_or(0);
            const auto ex = c.session.request(modbus::encode_pdu(modbus::make_read_request(
                                                  modbus::FunctionCode::ReadHoldingRegisters, start, 1)),
                                              "FC3 to unit 0", 0, timeout);
            expect_silence(r, ex);
        });
    // A writable register and a new value for it inside its range.
    const modbus::Point* target = nullptr;
    for (const auto& p : c.profile.table(Table::HoldingRegisters))
        if (freely_writable(p)) {
            target = &p;
            break;
        }
    std::optional<std::uint16_t> generic_target;
    if (!target && c.profile.open_address_space)
        generic_target = c.facts(Table::HoldingRegisters).first_valid();
    if (!target && !generic_target) return;
    const std::uint16_t address = target ? target->address : *generic_target;
    for (std::uint8_t fc : {6, 16}) {
        if (!c.profile.functions.supports(fc)) continue;
        const bool in_broadcast = std::find(allowed.begin(), allowed.end(), fc) != allowed.end();
        c.run({"broadcast.fc" + std::to_string(fc) + (in_broadcast ? ".executed" : ".refused"), "broadcast",
               src,
               in_broadcast ? "FC" + std::to_string(fc) + " sent to unit 0 takes effect and gets no reply."
                            : "FC" + std::to_string(fc) +
                                  ", which the manual does not allow in broadcast, sent to unit 0 "
                                  "is not executed and gets no reply.",
               authority, true},
              [&](RuleResult& r) {
                  // Every device on the line takes a broadcast write, and what the others held is neither
                  // known nor put back: the run changed devices it did not test while its ledger said
                  // every point written was restored.
                  if (!c.options.broadcast_writes) {
                      r.outcome = Outcome::Skip;
                      r.reason =
                          "a write to unit 0 is executed by every device on the line and only the "
                          "device under test is put back: --broadcast-writes for a device alone on "
                          "its line";
                      return;
                  }
                  if (!c.session.remember(Table::HoldingRegisters, address, 1)) {
                      r.outcome = Outcome::Error;
                      r.reason = "the register could not be read, so nothing was written";
                      return;
                  }
                  // The value it holds now, not the one before the run: an earlier rule (echo.fc6) may have
                  // written the very value this one would pick, and a device that ignored the broadcast
                  // would then read back as having taken it.
                  const auto held = c.session.read_registers(Table::HoldingRegisters, address, 1,
                                                             "read the value it holds now");
                  if (!held) {
                      r.outcome = Outcome::Error;
                      r.reason = "the register could not be read, so nothing was written";
                      return;
                  }
                  const auto alternative = valid_alternative(target, (*held)[0]);
                  if (!alternative) {
                      r.outcome = Outcome::Skip;
                      r.reason = "the register documents no other valid value";
                      return;
                  }
                  const std::uint16_t value = *alternative;
                  const std::uint16_t values[1] = {value};
                  const auto pdu =
                      fc == 6 ? modbus::encode_pdu(modbus::make_write_single_register(address, value))
                              : modbus::encode_pdu(modbus::make_write_multiple_registers(address, values));
                  const auto ex =
                      c.session.request(pdu, "write " + std::to_string(value) + " to unit 0", 0, timeout);
                  auto now = c.session.read_registers(Table::HoldingRegisters, address, 1,
                                                      "read it back from the unit");
                  const bool changed = now && (*now)[0] == value;
                  r.expected =
                      std::string("no reply, and the register ") + (in_broadcast ? "changed" : "unchanged");
                  r.observed = describe(ex) + (now ? "; register reads " + std::to_string((*now)[0])
                                                   : "; register unreadable");
                  r.outcome = ex.own_received().empty() && now && changed == in_broadcast ? Outcome::Pass
                                                                                          : Outcome::Fail;
              });
    }
}

}  // namespace mbscope::conformance
