#pragma once
// The bundled device profiles, loaded once per fuzzing process, for the targets that serve or annotate by a
// profile. Looked up in $MBSCOPE_PROFILE_PATH, then a `profiles` folder beside the binary (where a
// ClusterFuzzLite build puts them), then the source tree this binary was built from.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "modbus/profile.hpp"
#include "slave/device.hpp"

namespace mbscope::fuzz {

// Every profile of every bundled file (Walchem devices in their default configuration); never empty (a
// missing profile folder aborts with a message: a target that silently serves nothing would fuzz nothing).
const std::vector<modbus::Profile>& bundled_profiles();

// The reference slave's device for bundled profile `profile` (an index into bundled_profiles()) and `unit`,
// without faults: made on first use and kept. A target resets the devices it used when an input ends
// (fuzz::ResetAtEnd), so every input meets them as made without paying to make them.
slave::Device& bundled_device(std::size_t profile, std::uint8_t unit);
// The unit id nearest `preferred` that the profile's line allows (at least 1).
std::uint8_t unit_within(const modbus::Profile& profile, int preferred);

}  // namespace mbscope::fuzz
