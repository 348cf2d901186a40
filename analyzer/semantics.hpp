#pragma once
// Device meaning for traffic: which profile describes which device (--profile for all, --map per unit or
// address), the manual's rules applied to each request, and raw registers turned into named, scaled values.
// Decimal-point registers seen in earlier replies are remembered per device so later values scale right,
// and so are the points that make another read-only (a loop's operating mode, MK-RO-02), so that a write the
// manual forbids in the state the traffic showed is named.

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "modbus/finding_codes.hpp"
#include "modbus/frame.hpp"
#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"

namespace mbscope::analyzer {

struct DeviceSelector {
    std::optional<std::string> host;  // IP address as printed ("10.0.0.3"); nullopt = any
    std::optional<int> unit;          // nullopt = any
};

struct RuleBreak {
    modbus::FindingCode code;
    std::string message;
};

class Semantics {
  public:
    void add(DeviceSelector selector, std::shared_ptr<const modbus::Profile> profile);
    bool empty() const noexcept { return maps_.empty(); }
    // The most specific match: host and unit, then unit, then host, then the default.
    const modbus::Profile* profile_for(const std::string& server, std::uint8_t unit) const;
    // What became of each selector, in the order added, for a user to hear of a --map that described nothing
    // (a mistyped address, a unit the capture never shows).
    enum class SelectorUse : std::uint8_t {
        Unmatched,  // no device the traffic showed matched it
        Shadowed,   // every device it matched took a more specific selector's profile
        Used,
    };
    std::vector<SelectorUse> selector_uses() const;

    // The manual's rules on a request to `device`: supported function, quantity limit, addresses, written
    // values, and writes to a point the manual makes read-only while another holds values earlier traffic
    // showed it holding (conditional_access).
    std::vector<RuleBreak> check_request(const modbus::Profile& profile, const std::string& device,
                                         const modbus::Pdu& request) const;
    // What a device's frame shows of its serial line against its manual: a framing the manual does not list
    // (the CTH2265I talks RTU only, 003:460), a unit id outside its addresses or one that disables it (MK
    // 1..99 and 0 "communication disabled", 000:220). Once per device; nothing over Modbus/TCP (gateways
    // give the devices behind them unit ids of their own) nor for a broadcast.
    std::vector<RuleBreak> check_line(const modbus::Profile& profile, const std::string& device,
                                      const modbus::Frame& frame) const;
    // The response judged against the map (an exception where the map says the request is valid). A write
    // to a conditionally read-only point refused while the condition's value is unknown is no departure:
    // the device may be in the state that forbids it.
    std::vector<RuleBreak> check_response(const modbus::Profile& profile, const std::string& device,
                                          const modbus::Pdu& request, const modbus::Pdu& response) const;
    // A write to the device's address register that it acknowledged (MK ENDER: the device obeys at once,
    // MK-CFG-01): from then on `server`'s unit at the new address is described by `profile` too. The note
    // to report, or nullopt when the transaction moved nothing.
    // What earlier traffic showed `device` holding goes with it to "server unit N" (and what was remembered
    // there, of a device that moved away, is dropped).
    std::optional<RuleBreak> follow_address(const std::string& server, const std::string& device,
                                            const modbus::Profile& profile, const modbus::Pdu& request,
                                            const modbus::Pdu& response);
    // A write to the registers mirroring the device's framing, speed or parity (MK PROT, BAUD, PARID:
    // MK-CFG-01) that it acknowledged, with codes the manual defines and, where the registers were read
    // before on `device`, other than they held: the device talks with them from then on. The note and the
    // settings written, or nullopt. Before values(), which remembers the written values.
    struct LineSettingsTold {
        RuleBreak note;
        modbus::LineState settings;  // the framing, speed and parity written; the rest unset
        std::string written;         // "PROT. (register 8) := 0"
        std::string now;             // "ASCII"
    };
    std::optional<LineSettingsTold> follow_line_settings(const std::string& device,
                                                         const modbus::Profile& profile,
                                                         const modbus::Pdu& request,
                                                         const modbus::Pdu& response) const;
    // The same for a broadcast write (no reply: SL §2.1), on a device whose manual allows the function in
    // broadcast; the written values are remembered for `device` as values() remembers acknowledged ones.
    std::optional<LineSettingsTold> follow_broadcast_line_settings(const std::string& device,
                                                                   const modbus::Profile& profile,
                                                                   const modbus::Pdu& request);
    // What a completed transaction shows the device's registers hold (reads, and writes it acknowledged),
    // kept for `device`: a later write of the same code is no change. values() does it too.
    void remember(const modbus::Profile& profile, const std::string& device, const modbus::Pdu& request,
                  const modbus::Pdu& response);
    // Named values of a completed transaction (reads: the reply's values; writes: the values written).
    std::vector<modbus::NamedValue> values(const modbus::Profile& profile, const std::string& device,
                                           const modbus::Pdu& request, const modbus::Pdu& response);

  private:
    std::optional<LineSettingsTold> line_settings_written(const std::string& device,
                                                          const modbus::Profile& profile, std::uint16_t start,
                                                          std::span<const std::uint16_t> values,
                                                          const std::string& how) const;
    std::vector<std::pair<DeviceSelector, std::shared_ptr<const modbus::Profile>>> maps_;
    mutable std::vector<SelectorUse> uses_;       // beside maps_, filled by profile_for
    mutable std::set<std::string> line_checked_;  // devices check_line has looked at
    // `words` of `table` seen at `start` on `device`: in registers_, and in holding_ when they are holding
    // registers.
    void keep(const modbus::Profile& profile, const std::string& device, modbus::Table table,
              std::uint16_t start, std::span<const std::uint16_t> words);
    std::map<std::string, modbus::RegisterContext> registers_;               // device → last values seen
    std::map<std::string, std::map<std::uint16_t, std::uint16_t>> holding_;  // the holding registers alone
    // device → (table as the profile resolves it, address) → the last value seen, bits as 0/1: what a
    // conditional access asks (registers_ keeps only what decoding asks, and no bits).
    std::map<std::string, std::map<std::pair<modbus::Table, std::uint16_t>, std::uint16_t>> state_;
    // Per profile, the points others' access depends on (read_only_when), by resolved table.
    std::map<const modbus::Profile*, std::set<std::pair<modbus::Table, std::uint16_t>>> conditions_;
    void keep_state(const modbus::Profile& profile, const std::string& device, modbus::Table table,
                    std::uint16_t start, std::span<const std::uint16_t> values);
    std::optional<std::uint16_t> known(const std::string& device, const modbus::Profile& profile,
                                       const modbus::PointRef& ref) const;
    // The conditionally read-only points a request writes: the rule break for each whose condition is
    // known to hold; `unknown` is set when one's condition was never seen.
    void check_conditional(const modbus::Profile& profile, const std::string& device, const modbus::Pdu& q,
                           std::vector<RuleBreak>& out, bool* unknown) const;
    // (host, unit) → the profile of a device that moved there (follow_address): before any --map.
    std::map<std::pair<std::string, std::uint8_t>, const modbus::Profile*> moved_;
};

// Parses "--map" keys: "17", "10.0.0.3", "10.0.0.3:17". nullopt when malformed.
std::optional<DeviceSelector> parse_selector(const std::string& text);

}  // namespace mbscope::analyzer
