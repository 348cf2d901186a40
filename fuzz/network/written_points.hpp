#pragma once
// The points a request may write, and their original values kept for restoring: the campaign reads them
// before a write it sends, and a replay before it sends the steps of a reproducer (which may write), so
// that the target is left holding what it held before (conformance::Session::restore).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "conformance/session.hpp"
#include "fuzz/network/reproducer.hpp"
#include "modbus/profile.hpp"

namespace mbscope::fuzz::network {

// What a request may write, read from its header bytes whether or not the rest is well formed: a device
// that executes a malformed write writes there. The count is bounded by the function's limit.
struct WriteRange {
    modbus::Table table = modbus::Table::HoldingRegisters;
    std::uint16_t start = 0;
    std::uint16_t count = 0;
    // One past the last address, clipped at the end of the address space (a count from a hostile header may
    // run past it).
    std::uint32_t end() const noexcept {
        return std::min<std::uint32_t>(0x10000, std::uint32_t{start} + count);
    }
};
std::optional<WriteRange> write_range(std::span<const std::uint8_t> pdu);
// Whether `reply_pdu` acknowledges the write `request_pdu`: a normal response of its function.
inline bool acknowledges(std::span<const std::uint8_t> request_pdu, std::span<const std::uint8_t> reply_pdu) {
    return !request_pdu.empty() && !reply_pdu.empty() && reply_pdu[0] == request_pdu[0];
}

// Rewrites a write request so that the holding registers for which `held` gives a value keep it: the value
// an FC6, FC16 or FC23 request would store there becomes that value, and an FC22 mask there becomes the one
// that changes nothing (AND FFFF, OR 0000). Values the PDU is too short to carry are left alone. Returns how
// many registers it rewrote.
std::size_t keep_registers(std::vector<std::uint8_t>& pdu,
                           const std::function<std::optional<std::uint16_t>(std::uint16_t)>& held);

// A point read after a write that drew no reply (a broadcast, never answered on a serial line, or a write
// left unanswered) had reached it before its value could be read: whether the device executed the write is
// unknown, and the point may hold the write's value.
struct HeldPoint {
    modbus::Table table = modbus::Table::HoldingRegisters;
    std::uint16_t address = 0;
    std::uint16_t value = 0;  // a bit as 0/1
};
// What the points writes without a reply reached hold when read (read_held).
struct HeldReading {
    std::vector<HeldPoint> held;  // the points the device answered for, with what they hold
    // The points no read could tell about: the device gave neither their values nor an exception (silence,
    // a malformed or foreign reply), or stopped answering before they were read. Whether the write changed
    // them is unknown.
    std::vector<WriteRange> unread;
    // Ranges the device refused to read as a whole and that were not read point by point (the budget of
    // single reads was spent): taken, as the map says, for points it does not hold. A device holding some of
    // them would have those left out; listed so that this is said, not assumed silently.
    std::vector<WriteRange> refused;
    bool interrupted = false;  // ReadHeldLimits::interrupted said so: the points not read yet are in `unread`
};
// What read_held may spend. The single reads after a refusal are bounded for their time on a slow line or at
// a manual's polling interval; `interrupted`, asked before each read, ends the reading when true (a person
// interrupted it): the points not read yet are unread, without a request each.
struct ReadHeldLimits {
    unsigned single_reads = 256;
    std::function<bool()> interrupted;
};
// The single reads that fit in about a minute at a polling interval (a manual's: Walchem asks 5 s between
// requests, where 256 would take over 21 minutes after the run), at most 256 and at least one.
unsigned single_reads_within_a_minute(std::chrono::milliseconds interval);
// Reads `points` through `session`, each contiguous range in as few requests as the function's limit allows.
// A range the device refuses as a whole (an exception) is read again point by point, while
// `limits.single_reads` allow: a strict device refuses a range where any point is missing and may
// hold the others; a point it refuses alone it does not hold. The budget bounds what this costs on a slow
// line (a strict device refuses every single read of the thousands of coils a few broadcasts reach: at 9600
// baud 256 exceptions take about 6 s). After `silent_reads_before_giving_up` reads in a row that waited
// --timeout for nothing usable (silence, a reply cut short, a closed connection) the device is taken to be
// gone: the points not read yet are `unread` without a request each waiting --timeout. A prompt reply that
// tells nothing (malformed, another function's) leaves its points unread but is no sign of a device gone.
inline constexpr unsigned silent_reads_before_giving_up = 3;
HeldReading read_held(conformance::Session& session,
                      const std::set<std::pair<modbus::Table, std::uint16_t>>& points,
                      const ReadHeldLimits& limits = {});
// [{"table", "address", "value"}, ...]
nlohmann::json to_json(const std::vector<HeldPoint>& points);

// The ranges that hold `points` (each a table and an address), contiguous runs joined.
std::vector<WriteRange> ranges_of(const std::set<std::pair<modbus::Table, std::uint16_t>>& points);
// [{"table", "start", "count"}, ...]
nlohmann::json to_json(const std::vector<WriteRange>& ranges);
// "holding_registers 5000 (3 points)"
std::string to_string(const WriteRange& range);

// The reads that tell the original values of the points of `range` that exist on the device: runs of
// consecutive points of the profile's map, each as long as the table's read function allows, or blocks of
// 100 of an open address space. A write-only point is not read: what a read returns there is not what it
// holds (the reference slave answers 0), and writing it is a command (an alarm acknowledge), not a value to
// put back. One read a point cost minutes where a manual asks for slow polling (Walchem: a request every
// 5 s, and one write of 60 registers reaches some 50 points).
std::vector<WriteRange> read_blocks(const modbus::Profile& profile, const WriteRange& range);
// Reads, through `session`, the original values of the points of `range` (read_blocks); a block the device
// refuses as a whole is read point by point. False when a read failed (the points read before it are kept).
bool remember_range(conformance::Session& session, const modbus::Profile& profile, const WriteRange& range);
// How many reads remember_range would send now: the blocks holding a point `session` has no original of.
std::size_t reads_to_remember(const conformance::Session& session, const modbus::Profile& profile,
                              const WriteRange& range);
// The points of `range` a write may change whose values `session` holds no original of: outside the map of
// a closed one, or a read that failed. Write-only points are not among them (remember_range).
std::vector<std::pair<modbus::Table, std::uint16_t>> points_not_read(const conformance::Session& session,
                                                                     const modbus::Profile& profile,
                                                                     const WriteRange& range);

// Before a replay: the requests in every step's bytes, read as a lax device reads them (whatever their
// checksum; over Modbus/TCP one request a header, or the rest after a header whose length field is wrong; a
// step may hold several), and the points of each write remembered (remember_range) when it can land:
// addressed to the session's unit or broadcast, or to any unit over Modbus/TCP, where devices that ignore
// the unit id are common. Bytes that hold no request write nothing a device would execute.
struct UncheckedWrite {
    std::size_t step = 0;            // index into the steps
    std::uint8_t function = 0;       // the write's function code
    std::vector<WriteRange> points;  // the points a write may change that were not read (points_not_read)
};
struct RememberedWrites {
    std::vector<WriteRange> unread;  // ranges whose read failed: not restored, whatever the device does
    std::vector<UncheckedWrite> unchecked;  // outside the map: they changed if the device acknowledged them
};
RememberedWrites remember_writes(conformance::Session& session, const modbus::Profile& profile,
                                 const std::vector<Step>& steps);
// After a step was sent (a campaign's probe, a replay's step, a minimisation's): every write its bytes hold
// that can land (as remember_writes reads them) is told to `session` with the device's answer to it
// (conformance::Session::note_write, under watch_writes()): among what came for the step and its late
// replies, over Modbus/TCP the reply carrying the write's transaction id, over RTU and ASCII the first that
// could answer it. The restore then writes back only the points the steps changed, and leaves a point the
// device changed itself after a write it refused or did not acknowledge.
void note_step_writes(conformance::Session& session, const Step& step, const ReplayedStep& replayed);
// A reply to the write `request_pdu` that came after its step was noted unanswered (the campaign's late
// replies): an acknowledgement makes the write acknowledged (Session::note_write's `late`).
void note_late_answer(conformance::Session& session, std::span<const std::uint8_t> request_pdu,
                      const modbus::Frame& reply);

// After the replay: the points of the unchecked writes whose step drew a normal reply of their function
// (an acknowledgement, as a lax device gives to a write outside the map it holds after all). They may hold
// the steps' values now and are not restored.
std::vector<WriteRange> acknowledged_unchecked(const std::vector<UncheckedWrite>& unchecked,
                                               modbus::Framing framing,
                                               const std::vector<ReplayedStep>& steps);
// The points of the unchecked writes whose step drew neither an acknowledgement nor an exception of their
// function (a broadcast, or a write left unanswered): whether the device executed them is unknown, and they
// are read after the replay (read_held).
std::set<std::pair<modbus::Table, std::uint16_t>> unanswered_unchecked(
    const std::vector<UncheckedWrite>& unchecked, modbus::Framing framing,
    const std::vector<ReplayedStep>& steps);

}  // namespace mbscope::fuzz::network
