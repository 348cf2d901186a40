// Runs a fuzz target over files and folders (the target's seed corpus, its saved regressions) without the
// fuzzing engine, so every build replays what fuzzing found once: a crash, an oracle violation or a
// sanitizer report stops the test. A path that does not exist is named, not skipped silently.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "fuzz/fuzz_support.hpp"

namespace fs = std::filesystem;

namespace {

bool replay(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "cannot read %s\n", file.c_str());
        return false;
    }
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    // An exact-size heap copy, as libFuzzer gives it: a read past the input is caught.
    auto* copy = new std::uint8_t[bytes.size() ? bytes.size() : 1];
    std::copy(bytes.begin(), bytes.end(), copy);
    LLVMFuzzerTestOneInput(copy, bytes.size());
    delete[] copy;
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    std::size_t count = 0;
    bool ok = true;
    for (int i = 1; i < argc; ++i) {
        const fs::path path(argv[i]);
        std::error_code ec;
        if (fs::is_directory(path, ec)) {
            std::vector<fs::path> files;
            for (const auto& e : fs::recursive_directory_iterator(path))
                if (e.is_regular_file() && e.path().filename().string().front() != '.')
                    files.push_back(e.path());
            std::sort(files.begin(), files.end());
            for (const auto& f : files) {
                ok &= replay(f);
                ++count;
            }
        } else if (fs::is_regular_file(path, ec)) {
            ok &= replay(path);
            ++count;
        } else {
            std::printf("%s: not present (nothing to replay there)\n", path.c_str());
        }
    }
    std::printf("replayed %zu inputs\n", count);
    return ok ? 0 : 1;
}
