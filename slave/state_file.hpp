#pragma once
// The slave's memory across restarts (--state FILE): every register and coil that differs from the
// profile's initial image, per unit (named by the address it was made with, `--unit`, also when a write
// moved it: the address written is in the image and taken again on loading), as JSON. Saved atomically:
// written to FILE.tmp, fsync'ed, renamed over FILE and the directory fsync'ed, so a kill at any instant
// leaves either the old or the new image, never a torn one. The server saves before it sends the
// acknowledgement of a write, so an acknowledged write is on disk. Units the file holds that a run does not
// serve are written back as they were saved, so serving fewer units for a while loses none of the others'
// values.

#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "modbus/result.hpp"
#include "modbus/transport/unique_fd.hpp"
#include "slave/device.hpp"

namespace mbscope::slave {

// The units of a state file that no device of this run is: a JSON object, unit id -> the unit as saved
// (null when there are none).
using OtherUnits = nlohmann::json;

// Writes the changes of every device, and the other units as they were. Errors name the file and the
// system call that failed.
modbus::Result<void, std::string> save_state(const std::string& path, const std::vector<Device*>& devices,
                                             const OtherUnits& others = {});
// Takes FILE.lock (flock, exclusive, not waiting) for as long as the descriptor returned lives: two slaves
// saving one state file would each write back their own view of it, and the one saving last would drop the
// writes the other acknowledged. Errors say the file is in use, or why the lock could not be taken. The lock
// file stays beside the state file (its content is nothing; holding it is what counts).
modbus::Result<modbus::transport::UniqueFd, std::string> lock_state(const std::string& path);
// Applies a saved image to the devices with the same configured unit id and profile and returns the units it
// holds for no device. A missing file is not an error (first start); one that exists and cannot be read, or a
// damaged one, is, naming the file and what is wrong.
modbus::Result<OtherUnits, std::string> load_state(const std::string& path,
                                                   const std::vector<Device*>& devices);

// The two halves without the file system (the fuzz target's way in): the text save_state writes, and the
// check and application of such a text. A text is applied whole or not at all: every entry is checked
// before the first is stored, so a refused file leaves every device as it was. Errors start with `name`.
std::string state_text(const std::vector<Device*>& devices, const OtherUnits& others = {});
modbus::Result<OtherUnits, std::string> apply_state(std::string_view text, const std::string& name,
                                                    const std::vector<Device*>& devices);

}  // namespace mbscope::slave
