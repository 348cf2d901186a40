#pragma once
// The bundled device profiles, loaded once per fuzzing process, for the targets that serve or annotate by a
// profile. Looked up in $MBSCOPE_PROFILE_PATH, then a `profiles` folder beside the binary (where a
// ClusterFuzzLite build puts them), then the source tree this binary was built from.

#include <vector>

#include "modbus/profile.hpp"

namespace mbscope::fuzz {

// Every profile of every bundled file (Walchem devices in their default configuration); never empty (a
// missing profile folder aborts with a message: a target that silently serves nothing would fuzz nothing).
const std::vector<modbus::Profile>& bundled_profiles();

}  // namespace mbscope::fuzz
