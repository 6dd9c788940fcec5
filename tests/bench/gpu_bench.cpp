// lsq3_solve: C++ reference (one thread, double) against Vulkan, for 1M and 4M
// elements of 8 rows each (a photometric-stereo-like input). The Vulkan figure is
// wall time per run() including uploads and downloads; the counter gpu_ms is the
// kernel time from timestamp queries. Run with the device you want to measure:
//   VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json build/tests/gpu/gpu_bench
#include "gpu/kernels/lsq3_solve.h"

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <random>

namespace {

using namespace specula;

constexpr uint32_t kRowsPerElement = 8;

struct Input {
    std::vector<uint32_t> offsets;
    std::vector<gpu::Lsq3Row> rows;
};

const Input& input(std::size_t count) {
    static std::map<std::size_t, Input> cache;
    auto [it, fresh] = cache.try_emplace(count);
    if (!fresh) return it->second;
    Input& in = it->second;
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
    in.offsets.resize(count + 1);
    in.rows.resize(count * kRowsPerElement);
    for (std::size_t e = 0; e <= count; ++e) in.offsets[e] = static_cast<uint32_t>(e * kRowsPerElement);
    for (auto& r : in.rows) r = {uni(rng), uni(rng), 1.0f + 0.5f * uni(rng), uni(rng), 1.0f};
    return in;
}

gpu::Context& context() {
    static gpu::Context ctx;
    return ctx;
}

void BM_Lsq3Cpu(benchmark::State& state) {
    const Input& in = input(static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) benchmark::DoNotOptimize(gpu::lsq3_solve_cpu({in.offsets, in.rows}));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}

void BM_Lsq3Vulkan(benchmark::State& state) {
    const Input& in = input(static_cast<std::size_t>(state.range(0)));
    gpu::Lsq3SolveVk kernel(context());
    benchmark::DoNotOptimize(kernel.run({in.offsets, in.rows})); // warm-up: buffers allocated once
    double gpu_ns = 0.0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(kernel.run({in.offsets, in.rows}));
        gpu_ns += kernel.last_gpu_ns().value_or(0.0);
    }
    state.SetItemsProcessed(state.iterations() * state.range(0));
    state.counters["gpu_ms"] = kernel.last_gpu_ns() ? gpu_ns / 1e6 / static_cast<double>(state.iterations()) : -1.0;
    state.counters["chunks"] = kernel.last_chunk_count();
    state.SetLabel(context().info().name);
}

BENCHMARK(BM_Lsq3Cpu)->Arg(1 << 20)->Arg(4 << 20)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Lsq3Vulkan)->Arg(1 << 20)->Arg(4 << 20)->Unit(benchmark::kMillisecond)->UseRealTime();

} // namespace

BENCHMARK_MAIN();
