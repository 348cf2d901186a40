#include "fuzz/bundled_profiles.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "modbus/storage/profile_store.hpp"

namespace mbscope::fuzz {

namespace {

std::vector<std::string> candidate_directories() {
    std::vector<std::string> dirs;
    if (const char* path = std::getenv("MBSCOPE_PROFILE_PATH"))
        for (auto& d : modbus::storage::split_path_list(path))
            dirs.push_back(d);
    std::error_code ec;
    const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) dirs.push_back((exe.parent_path() / "profiles").string());
    dirs.push_back(MBSCOPE_SOURCE_DIR "/profiles");
    return dirs;
}

}  // namespace

const std::vector<modbus::Profile>& bundled_profiles() {
    static const std::vector<modbus::Profile> profiles = [] {
        std::vector<modbus::Profile> out;
        for (const auto& dir : candidate_directories()) {
            if (!std::filesystem::is_directory(dir)) continue;
            // Headers only: each profile is resolved once, by the load below.
            modbus::storage::ProfileStore store(std::vector<modbus::storage::ProfileDirectory>{
                {dir, modbus::storage::ProfileReading::headers}});
            for (const auto& entry : store.entries())
                if (auto p = store.load(entry.id); p) out.push_back(std::move(p.value()));
            if (!out.empty()) break;
        }
        if (out.empty()) {
            std::fprintf(stderr,
                         "no device profiles found (set MBSCOPE_PROFILE_PATH to the profiles folder)\n");
            std::abort();
        }
        return out;
    }();
    return profiles;
}

slave::Device& bundled_device(std::size_t profile, std::uint8_t unit) {
    static std::map<std::pair<std::size_t, std::uint8_t>, std::unique_ptr<slave::Device>> made;
    auto& device = made[{profile, unit}];
    if (!device) device = std::make_unique<slave::Device>(bundled_profiles().at(profile), unit, nullptr);
    return *device;
}

std::uint8_t unit_within(const modbus::Profile& profile, int preferred) {
    return static_cast<std::uint8_t>(
        std::clamp(preferred, std::max(1, profile.line.unit_min), std::max(1, profile.line.unit_max)));
}

}  // namespace mbscope::fuzz
