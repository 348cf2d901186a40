// The profile loader on hostile JSON: structure, ranges, references between points, simulation blocks and
// modular-device configurations. The include callback offers one shared map file so the Walchem path is
// reachable. Properties: no crash, no exception escapes, every problem is an error record with a pointer;
// a profile that loads is self-consistent enough to be queried over its whole address space, and every
// point's value can be shown. And the header scan a store lists profiles from agrees with the parser: on a
// document the parser takes without an error, it gives the same ids, names, aliases and line, and no error.
#include <string>
#include <string_view>

#include "fuzz/fuzz_support.hpp"
#include "modbus/profile_headers.hpp"
#include "modbus/profile_loader.hpp"

using namespace mbscope;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    // The include file is the same document: cheap, and it makes "maps_file" reach a real parse.
    const modbus::IncludeFn include = [&](const std::string&) { return std::optional<std::string>(text); };
    const auto loaded = modbus::parse_profiles(text, "fuzz.json", include);
    for (const auto& e : loaded.errors)
        if (e.message.empty())
            fuzz::fail("fuzz_profile", "an error without a message at '" + e.pointer + "'");
    const auto headers = modbus::scan_profile_headers(text, "fuzz.json");
    for (const auto& e : headers.errors)
        if (e.message.empty()) fuzz::fail("fuzz_profile", "a header error without a message");
    if (loaded.errors.empty()) {
        if (!headers.errors.empty())
            fuzz::fail("fuzz_profile",
                       "the header scan refuses what the parser takes: " + headers.errors[0].message);
        if (headers.is_profile != loaded.is_profile)
            fuzz::fail("fuzz_profile",
                       "the header scan and the parser disagree on whether this is a profile");
        if (headers.models.size() != loaded.profiles.size())
            fuzz::fail("fuzz_profile", "the header scan lists " + std::to_string(headers.models.size()) +
                                           " models, the parser " + std::to_string(loaded.profiles.size()));
        for (std::size_t i = 0; i < headers.models.size() && i < loaded.profiles.size(); ++i) {
            const auto& h = headers.models[i];
            const auto& p = loaded.profiles[i];
            if (h.id != p.id || h.name != p.name || h.aliases != p.aliases || headers.vendor != p.vendor ||
                headers.family != p.family || headers.transports != p.line.transports ||
                headers.modular != p.modular)
                fuzz::fail("fuzz_profile", "the header scan says another model " + std::to_string(i) + " ('" +
                                               h.id + "') than the parser ('" + p.id + "')");
        }
    }
    for (const auto& p : loaded.profiles) {
        for (int t : {0, 1, 3, 4}) {
            const auto table = static_cast<modbus::Table>(t);
            for (const auto& point : p.table(table)) {
                if (p.find(table, point.address) == nullptr)
                    fuzz::fail("fuzz_profile", "point '" + point.name + "' at " +
                                                   std::to_string(point.address) +
                                                   " is not found at its own address");
                // Every encoding shows a value, its formula evaluated and its decimal point looked up.
                (void)modbus::decode_registers(p, table, point.address, {0x8001, 0xFFFF},
                                               {{{point.address, 0x0003}}, {{point.address, 0x0003}}});
            }
            (void)modbus::check_read(p, table, 0, 125);
            (void)modbus::check_writes(p, table, 0, std::vector<std::uint16_t>(16, 0xFFFF));
        }
    }
    return 0;
}
