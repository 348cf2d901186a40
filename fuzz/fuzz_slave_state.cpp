// The slave's state file reader (slave/state_file.hpp, `mbscope slave --state FILE`) on hostile bytes: a file
// damaged on disk, edited by hand or left by another version. The input is the file. It is applied to four
// devices that cover what the image shares between tables: unit 1 an MK instrument (FC3 and FC4 one
// table), 2 a Walchem controller (coils are views of its registers), 3 the CTH2265I (fixed read values),
// 4 the generic profile (every address exists). Properties: no crash and no exception; a refused file
// changes no device and its error starts with the file's name; an accepted file holds bits as 0 or 1, and
// saving what it made (with the units it holds for no device) and applying that to the devices as made gives
// the same image, the same other units and the same text.
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fuzz/bundled_profiles.hpp"
#include "fuzz/fuzz_support.hpp"
#include "modbus/addressing.hpp"
#include "slave/device.hpp"
#include "slave/state_file.hpp"

using namespace mbscope;

namespace {

constexpr const char* target = "fuzz_slave_state";
const char* const served[] = {"mmk-2030", "walchem-w600", "cth2265i", "modbus"};

// Made once and reset when each input ends, as the slave target does: every input meets devices as made.
const std::vector<slave::Device*>& devices() {
    static std::vector<std::unique_ptr<slave::Device>> made;
    static std::vector<slave::Device*> units;
    if (made.empty()) {
        for (const char* id : served) {
            const modbus::Profile* found = nullptr;
            for (const auto& p : fuzz::bundled_profiles())
                if (p.id == id) found = &p;
            if (found == nullptr) fuzz::fail(target, std::string("bundled profile ") + id + " is missing");
            made.push_back(
                std::make_unique<slave::Device>(*found, static_cast<std::uint8_t>(made.size() + 1)));
            units.push_back(made.back().get());
        }
    }
    return units;
}

using Image = std::map<modbus::Table, std::map<std::uint16_t, std::uint16_t>>;

std::vector<Image> images(const std::vector<slave::Device*>& units) {
    std::vector<Image> out;
    for (const auto* d : units)
        out.push_back(d->image().changes());
    return out;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    (void)devices();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto& units = devices();
    const fuzz::ResetAtEnd reset{units};
    std::vector<std::uint64_t> before;
    for (const auto* d : units)
        before.push_back(d->image().modifications());
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const auto applied = slave::apply_state(text, "state.json", units);
    if (!applied) {
        if (applied.error().rfind("state.json: ", 0) != 0)
            fuzz::fail(target, "an error that does not name the file: " + applied.error());
        for (std::size_t i = 0; i < units.size(); ++i)
            if (units[i]->image().modifications() != before[i])
                fuzz::fail(target,
                           "a refused file changed unit " + std::to_string(i + 1) + ": " + applied.error());
        return 0;
    }
    const auto loaded = images(units);
    for (std::size_t i = 0; i < units.size(); ++i)
        for (const auto& [table, values] : loaded[i])
            if (modbus::is_bit_table(table))
                for (const auto& [address, value] : values)
                    if (value > 1)
                        fuzz::fail(target, "unit " + std::to_string(i + 1) + " " +
                                               std::string(modbus::to_string(table)) + "/" +
                                               std::to_string(address) + " holds " + std::to_string(value));
    const std::string saved = slave::state_text(units);
    for (auto* d : units)
        d->reset();
    const auto again = slave::apply_state(saved, "saved", units);
    if (!again) fuzz::fail(target, "the slave refuses the state it saved: " + again.error());
    if (images(units) != loaded) fuzz::fail(target, "saving and loading again changed the image:\n" + saved);
    if (slave::state_text(units) != saved)
        fuzz::fail(target, "the saved text is not a fixed point:\n" + saved);
    return 0;
}
