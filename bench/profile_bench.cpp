// Loading every bundled profile (what the analyzer does at start-up) next to parsing the same files with
// nlohmann::json and nothing else, and next to reading them: ratios in bench/README.md.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "modbus/storage/profile_store.hpp"

namespace fs = std::filesystem;

namespace {

const std::string dir = MBSCOPE_SOURCE_PROFILES;

std::vector<fs::path> files() {
    std::vector<fs::path> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".json") out.push_back(e.path());
    return out;
}

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::int64_t total_bytes() {
    std::int64_t n = 0;
    for (const auto& f : files())
        n += static_cast<std::int64_t>(fs::file_size(f));
    return n;
}

void BM_ReadProfileFiles(benchmark::State& state) {
    for (auto _ : state)
        for (const auto& f : files())
            benchmark::DoNotOptimize(slurp(f));
    state.SetBytesProcessed(state.iterations() * total_bytes());
}
BENCHMARK(BM_ReadProfileFiles)->Unit(benchmark::kMillisecond);

void BM_ParseProfileJsonOnly(benchmark::State& state) {
    for (auto _ : state)
        for (const auto& f : files())
            benchmark::DoNotOptimize(nlohmann::json::parse(slurp(f)));
    state.SetBytesProcessed(state.iterations() * total_bytes());
}
BENCHMARK(BM_ParseProfileJsonOnly)->Unit(benchmark::kMillisecond);

void BM_LoadEveryProfile(benchmark::State& state) {
    std::size_t profiles = 0;
    for (auto _ : state) {
        mbscope::modbus::storage::ProfileStore store({dir});
        profiles = store.entries().size();
        benchmark::DoNotOptimize(store.entries().data());
    }
    state.SetBytesProcessed(state.iterations() * total_bytes());
    state.counters["profiles"] = static_cast<double>(profiles);
}
BENCHMARK(BM_LoadEveryProfile)->Unit(benchmark::kMillisecond);

// What a command that names one device does: list the directory from the files' headers, then resolve the
// one profile (the largest MK file's first model, and the largest Walchem controller).
void BM_ListHeadersAndLoadOne(benchmark::State& state, const char* id) {
    using mbscope::modbus::storage::ProfileDirectory;
    using mbscope::modbus::storage::ProfileReading;
    std::size_t points = 0;
    for (auto _ : state) {
        mbscope::modbus::storage::ProfileStore store(
            std::vector<ProfileDirectory>{{dir, ProfileReading::headers}});
        auto p = store.load(id);
        if (!p) {
            state.SkipWithError("the profile does not load");
            return;
        }
        points = p->table(mbscope::modbus::Table::HoldingRegisters).size();
        benchmark::DoNotOptimize(points);
    }
    state.SetBytesProcessed(state.iterations() * total_bytes());
    state.counters["registers"] = static_cast<double>(points);
}
BENCHMARK_CAPTURE(BM_ListHeadersAndLoadOne, mmk_2015_ma, "mmk-2015-ma")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ListHeadersAndLoadOne, walchem_w900, "walchem-w900")->Unit(benchmark::kMillisecond);

// The same with every profile resolved first, as every command did before the headers.
void BM_LoadEveryAndLoadOne(benchmark::State& state, const char* id) {
    for (auto _ : state) {
        mbscope::modbus::storage::ProfileStore store({dir});
        auto p = store.load(id);
        if (!p) {
            state.SkipWithError("the profile does not load");
            return;
        }
        benchmark::DoNotOptimize(p->table(mbscope::modbus::Table::HoldingRegisters).size());
    }
    state.SetBytesProcessed(state.iterations() * total_bytes());
}
BENCHMARK_CAPTURE(BM_LoadEveryAndLoadOne, mmk_2015_ma, "mmk-2015-ma")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LoadEveryAndLoadOne, walchem_w900, "walchem-w900")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
