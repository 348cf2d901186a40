// The network fuzzer's reproducer reader (fuzz/network/reproducer.hpp, `mbscope replay --target URI FILE`)
// on hostile bytes: reproducers travel between people (a field engineer sends one to a firmware team), so
// the file is anyone's. The input is the file. Properties: no crash and no exception escapes; a reproducer
// that loads has at least one part in every step (replaying writes the last part as the request) and pauses
// within 0..60 s; written out again and read back it is the same reproducer.
#include <string>

#include "fuzz/fuzz_support.hpp"
#include "fuzz/network/reproducer.hpp"

using namespace mbscope;

namespace {

constexpr const char* target = "fuzz_reproducer";

std::string text_of(const fuzz::network::Reproducer& r) {
    return to_json(r).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto j = nlohmann::json::parse(data, data + size, nullptr, false);
    if (j.is_discarded()) return 0;
    auto loaded = fuzz::network::reproducer_from_json(j);
    if (!loaded) {
        if (loaded.error().empty()) fuzz::fail(target, "a refusal without a reason");
        return 0;
    }
    for (std::size_t i = 0; i < loaded->steps.size(); ++i) {
        const auto& step = loaded->steps[i];
        if (step.parts.empty()) fuzz::fail(target, "step " + std::to_string(i + 1) + " has no part");
        if (step.pause.count() < 0 || step.pause.count() > 60'000'000)
            fuzz::fail(target, "step " + std::to_string(i + 1) + " pauses " +
                                   std::to_string(step.pause.count()) + " us");
    }
    const std::string written = text_of(*loaded);
    const auto again = fuzz::network::reproducer_from_json(nlohmann::json::parse(written));
    if (!again) fuzz::fail(target, "a reproducer written out is refused: " + again.error() + "\n" + written);
    if (text_of(*again) != written) fuzz::fail(target, "written and read back it changed:\n" + written);
    return 0;
}
