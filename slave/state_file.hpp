#pragma once
// The slave's memory across restarts (--state FILE): every register and coil that differs from the
// profile's initial image, per unit, as JSON. Saved atomically: written to FILE.tmp, fsync'ed, renamed over
// FILE and the directory fsync'ed, so a kill at any instant leaves either the old or the new image, never
// a torn one. The server saves before it sends the acknowledgement of a write, so an acknowledged write is
// on disk.

#include <string>
#include <vector>

#include "modbus/result.hpp"
#include "slave/device.hpp"

namespace mbscope::slave {

// Writes the changes of every device. Errors name the file and the system call that failed.
modbus::Result<void, std::string> save_state(const std::string& path, const std::vector<Device*>& devices);
// Applies a saved image to the devices with the same unit id and profile. A missing file is not an error
// (first start); a damaged one is, naming the file and what is wrong.
modbus::Result<void, std::string> load_state(const std::string& path, const std::vector<Device*>& devices);

}  // namespace mbscope::slave
