// Function codes: every supported one answers with its own function code; every other one, reserved and
// user-defined ranges included, gets exception 01 (AP §7).
#include <algorithm>
#include <optional>

#include "conformance/context.hpp"
#include "modbus/function_code.hpp"
#include "modbus/pdu.hpp"

namespace mbscope::conformance {

using modbus::Table;

namespace {

// The first point of table `t` a harmless write may rewrite with its own value; on the generic profile,
// which maps nothing, the first address the device reads.
std::optional<std::uint16_t> rewritable(Context& c, Table t, bool (*may_rewrite)(const modbus::Point&)) {
    const auto& pts = c.profile.table(t);
    if (const auto it = std::find_if(pts.begin(), pts.end(), may_rewrite); it != pts.end())
        return it->address;
    if (c.profile.open_address_space) return c.facts(t).first_valid();
    return std::nullopt;
}

// The smallest request of `fc` that a conforming device must answer normally and that changes nothing:
// reads of one item at the first valid address, writes of the value already there.
std::optional<std::vector<std::uint8_t>> harmless_request(Context& c, std::uint8_t fc, std::string& why_not) {
    const auto first = [&](Table t) { return c.facts(t).first_valid(); };
    switch (fc) {
        case 1:
        case 2:
        case 3:
        case 4: {
            const Table t = *modbus::table_of_function(fc);
            // A table whose probing read of address 0 came back damaged every time: that read again, whose
            // damaged reply fails the rule (skipped, a device damaging every read passed).
            if (!first(t) && c.facts(t).damaged.empty()) {
                why_not = c.facts(t).no_address_reason();
                return std::nullopt;
            }
            return modbus::encode_pdu(
                modbus::make_read_request(static_cast<modbus::FunctionCode>(fc), first(t).value_or(0), 1));
        }
        case 5:
        case 15: {
            // Not a point read-only in some state (read_only_when): in that state the device refuses it
            // with 02, as access.*.read_only_when expects, and the function seemed unsupported.
            const auto at = rewritable(c, Table::Coils, [](const modbus::Point& p) {
                return p.access == modbus::Access::ReadWrite && !p.reserved && !p.momentary &&
                       !p.read_only_when;
            });
            if (!at) {
                why_not = "no readable and writable coil to rewrite with its own value";
                return std::nullopt;
            }
            const std::uint16_t address = *at;
            auto now =
                c.session.read_bits(Table::Coils, address, 1, "current value, to write it back unchanged");
            if (!now) {
                why_not = "the coil's current value could not be read";
                return std::nullopt;
            }
            const bool v = (*now)[0];
            if (fc == 5) return modbus::encode_pdu(modbus::make_write_single_coil(address, v));
            const bool bits[1] = {v};
            return modbus::encode_pdu(modbus::make_write_multiple_coils(address, bits));
        }
        case 6:
        case 16:
        case 22:
        case 23: {
            const auto at = rewritable(c, Table::HoldingRegisters, [](const modbus::Point& p) {
                return p.access == modbus::Access::ReadWrite && !p.reserved && !p.momentary &&
                       p.encoding.words == 1 && !p.fixed_value && !p.read_only_when;
            });
            if (!at) {
                why_not = "no readable and writable register to rewrite with its own value";
                return std::nullopt;
            }
            const std::uint16_t address = *at;
            auto now = c.session.read_registers(Table::HoldingRegisters, address, 1,
                                                "current value, to write it back unchanged");
            if (!now) {
                why_not = "the register's current value could not be read";
                return std::nullopt;
            }
            const std::uint16_t v[1] = {(*now)[0]};
            if (fc == 6) return modbus::encode_pdu(modbus::make_write_single_register(address, v[0]));
            if (fc == 16) return modbus::encode_pdu(modbus::make_write_multiple_registers(address, v));
            if (fc == 22)
                return modbus::encode_pdu(modbus::make_mask_write_register(address, 0xFFFF, 0x0000));
            return modbus::encode_pdu(modbus::make_read_write_multiple(address, 1, address, v));
        }
        case 7:
        case 11:
        case 12:
        case 17:
            return modbus::encode_pdu(modbus::make_no_data_request(static_cast<modbus::FunctionCode>(fc)));
        case 8: {
            const std::uint8_t data[2] = {0xA5, 0x37};
            return modbus::encode_pdu(modbus::make_diagnostics(0, data));
        }
        case 24: {
            if (!first(Table::HoldingRegisters)) {
                why_not = "no holding register to point the FIFO at";
                return std::nullopt;
            }
            return modbus::encode_pdu(modbus::make_read_fifo_queue(*first(Table::HoldingRegisters)));
        }
        case 43:
            return modbus::encode_pdu(modbus::make_read_device_id(1, 0));
        default:
            why_not = "no harmless request of this function is known to the runner";
            return std::nullopt;
    }
}

// A well-formed request of a public function code (so that a framing which sizes frames by their content
// can find its end), or a body shaped like a read request for any other code: a device must not guess a
// meaning for it either way. Writes aim at address 0 and are never executed by a conforming device.
std::vector<std::uint8_t> shaped_request(std::uint8_t fc) {
    using FC = modbus::FunctionCode;
    const std::uint16_t zero[1] = {0};
    const bool off[1] = {false};
    switch (fc) {
        case 1:
        case 2:
        case 3:
        case 4:
            return modbus::encode_pdu(modbus::make_read_request(static_cast<FC>(fc), 0, 1));
        case 5:
            return modbus::encode_pdu(modbus::make_write_single_coil(0, false));
        case 6:
            return modbus::encode_pdu(modbus::make_write_single_register(0, 0));
        case 7:
        case 11:
        case 12:
        case 17:
            return modbus::encode_pdu(modbus::make_no_data_request(static_cast<FC>(fc)));
        case 8:
            return modbus::encode_pdu(modbus::make_diagnostics(0, std::vector<std::uint8_t>{0x00, 0x00}));
        case 15:
            return modbus::encode_pdu(modbus::make_write_multiple_coils(0, off));
        case 16:
            return modbus::encode_pdu(modbus::make_write_multiple_registers(0, zero));
        case 20:  // one sub-request: reference type 6, file 1, record 0, length 1 (AP §6.14)
            return {0x14, 0x07, 0x06, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01};
        case 21:
            return {0x15, 0x09, 0x06, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00};
        case 22:
            return modbus::encode_pdu(modbus::make_mask_write_register(0, 0xFFFF, 0));
        case 23:
            return modbus::encode_pdu(modbus::make_read_write_multiple(0, 1, 0, zero));
        case 24:
            return modbus::encode_pdu(modbus::make_read_fifo_queue(0));
        case 43:
            return modbus::encode_pdu(modbus::make_read_device_id(1, 0));
        default:
            return {fc, 0x00, 0x00, 0x00, 0x01};
    }
}

// The table a write-type function's shaped_request() writes at address 0, were the device to execute it
// although it does not support the function; nullopt for functions that write nothing (FC21 writes a file
// record: written, but by no table this runner can read back).
std::optional<Table> written_by_shaped_request(int fc) {
    if (fc == 5 || fc == 15) return Table::Coils;
    if (fc == 6 || fc == 16 || fc == 22 || fc == 23) return Table::HoldingRegisters;
    return std::nullopt;
}

bool shaped_request_writes(int fc) {
    return written_by_shaped_request(fc) || fc == 21;
}

}  // namespace

void check_function_codes(Context& c) {
    const auto& supported = c.profile.functions.supported;
    for (std::uint8_t fc : supported) {
        const std::string name(modbus::function_name(fc).value_or("function"));
        const bool writes = fc == 5 || fc == 6 || fc == 15 || fc == 16 || fc == 22 || fc == 23;
        c.run({"fc.supported." + std::to_string(fc), "function codes",
               spec_section(fc) + "; " + c.profile.source,
               c.profile.open_address_space
                   ? "Function " + std::to_string(fc) + " (" + name +
                         ") is answered normally, or refused with exception 01 (a device need not implement "
                         "every function)."
                   : "Function " + std::to_string(fc) + " (" + name +
                         "), which the device supports, is answered normally.",
               c.profile.open_address_space ? Authority::Specification : Authority::Manual, writes},
              [&](RuleResult& r) {
                  // AP §6.7-6.10, §6.13: these functions are for serial lines only; a Modbus/TCP device
                  // of unknown make may not have them at all.
                  const bool serial_only = fc == 7 || fc == 8 || fc == 11 || fc == 12 || fc == 17;
                  if (c.profile.open_address_space && serial_only && !c.serial_framing()) {
                      r.outcome = Outcome::Skip;
                      r.reason = "a serial-line function (AP §6), and the target is not a serial line";
                      return;
                  }
                  std::string why_not;
                  auto pdu = harmless_request(c, fc, why_not);
                  if (!pdu) {
                      r.outcome = Outcome::Skip;
                      r.reason = why_not;
                      return;
                  }
                  const auto table = modbus::table_of_function(fc);
                  const bool unmapped = table && !c.facts(*table).first_valid();
                  const auto ex = c.session.request(
                      *pdu, unmapped ? "address 0 again, whose every reply came damaged while it was probed"
                                     : "a request of function " + std::to_string(fc));
                  expect_normal(r, ex, fc);
                  // Address 0 was asked for want of a known one: a refusal of the address alone (exception
                  // 02) still answers the function.
                  if (unmapped && r.outcome == Outcome::Fail && is_exception(ex, fc, 0x02)) {
                      r.outcome = Outcome::Pass;
                      r.expected += ", or exception 02 (Illegal Data Address) at address 0";
                  }
                  if (unmapped && r.outcome == Outcome::Fail) r.observed += "; " + c.facts(*table).damaged;
                  // FC24 points at any register: one that counts more than 31 is refused with 03 as AP
                  // §6.18 demands (the reference slave failed for the data it held).
                  if (fc == 24 && r.outcome == Outcome::Fail && is_exception(ex, fc, 0x03)) {
                      const auto pointer =
                          std::get<modbus::ReadFifoQueueRequest>(modbus::decode_request(*pdu)->body)
                              .fifo_pointer_address;
                      const auto count = c.session.read_registers(Table::HoldingRegisters, pointer, 1,
                                                                  "the FIFO count the pointer names");
                      if (count && (*count)[0] > 31) {
                          r.outcome = Outcome::Pass;
                          r.expected += ", or exception 03 (Illegal Data Value) for a FIFO count above 31";
                          r.observed += "; register " + std::to_string(pointer) + " counts " +
                                        std::to_string((*count)[0]) + " (AP §6.18)";
                      }
                  }
                  // The generic profile knows no device: a function the device does not implement, refused
                  // as AP §7 says, is conformant.
                  if (c.profile.open_address_space && r.outcome == Outcome::Fail &&
                      is_exception(ex, fc, 0x01)) {
                      r.outcome = Outcome::Pass;
                      r.expected = "normal response, or exception 01 (Illegal Function)";
                      c.functions_refused.set(fc);
                  }
                  // Nor does it know which register is writable: the first the device reads is written with
                  // its own value, and one read-only to the device (a process value) is refused with 02.
                  if (c.profile.open_address_space && modbus::writes_points(fc) &&
                      r.outcome == Outcome::Fail && is_exception(ex, fc, 0x02)) {
                      r.outcome = Outcome::Pass;
                      r.expected +=
                          ", or exception 02 (Illegal Data Address) for an address the device reads "
                          "but does not let be written (the generic profile knows no map)";
                  }
              });
    }
    const auto code = modbus::exception_for(c.profile, "unsupported_function", 0x01);
    // RTU over a stream (rtu-tcp) has no silence to end a frame: a device finds a request's end by its
    // function code, and one whose length no function code tells (an unassigned code, say) has no end it can
    // find. On a line the silence ends it (SL §2.5.1.1). There, silence earns a warning, not a failure, as
    // the network fuzzer's oracle allows it; any other wrong answer fails as anywhere.
    const bool rtu_stream = c.session.client().framing() == modbus::Framing::Rtu && !c.true_serial();
    for (int fc = 1; fc <= 127; ++fc) {
        if (std::find(supported.begin(), supported.end(), fc) != supported.end()) continue;
        std::string kind = modbus::is_user_defined_function(static_cast<std::uint8_t>(fc)) ? "user-defined "
                           : modbus::is_reserved_function(static_cast<std::uint8_t>(fc))   ? "reserved "
                           : modbus::is_public_function(static_cast<std::uint8_t>(fc))     ? ""
                                                                                           : "unassigned ";
        const bool endless =
            rtu_stream && modbus::predict_pdu_length(shaped_request(static_cast<std::uint8_t>(fc)),
                                                     modbus::Direction::Request)
                                  .kind != modbus::LengthPrediction::Kind::Known;
        c.run({"fc.unsupported." + std::to_string(fc), "function codes",
               "AP §7 (exception 01); " + c.profile.source,
               "The " + kind + "function code " + std::to_string(fc) +
                   ", which the device does not support, gets " + exception_text(code) + ".",
               authority_for(c.profile, "unsupported_function"), shaped_request_writes(fc)},
              [&](RuleResult& r) {
                  // A device that executes a write it says it does not support changes address 0: read
                  // first, so that the end of the run writes it back (a table whose read is refused holds
                  // nothing to restore; one whose read went unanswered may). It ran under --read-only and
                  // was never restored.
                  if (const auto table = written_by_shaped_request(fc);
                      table && !c.session.remember(*table, 0, 1) && !c.session.last_read_refused()) {
                      r.outcome = Outcome::Error;
                      r.reason =
                          "address 0 of the table it would write could not be read, so nothing was sent";
                      return;
                  }
                  const auto pdu = shaped_request(static_cast<std::uint8_t>(fc));
                  const auto ex = c.session.request(pdu, "function code " + std::to_string(fc));
                  expect_exception(r, ex, static_cast<std::uint8_t>(fc), code);
                  // Only the silence is excused: a device that answered found the request's end.
                  if (endless && r.outcome == Outcome::Fail && ex.timed_out && ex.own_received().empty()) {
                      r.rule.authority = Authority::Implied;
                      r.rule.source +=
                          "; RTU over a stream: a request of this code has no end a device can find";
                  }
              });
    }
}

}  // namespace mbscope::conformance
