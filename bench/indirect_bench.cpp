// Time of the indirect-light gather (engine/indirect/transfer.h), C++ reference vs Vulkan, on
// seeded random transfers (tests/indirect/random_transfer.h: K = 64 rays a particle, half of
// them hitting, so ~30 entries a row, sources uniform over the object: the worst case for the
// radiosity reads). Not a test. Entries/s counts entry x frame products (one multiply-add of
// an rgb value each). The Vulkan time is the whole run (uploads, dispatches, downloads); "gpu"
// is the dispatches' own time from timestamps, and the worst relative difference of the
// Vulkan values to the reference's is printed. Validation is off (it only adds host time).
// The directed lobe's first bounce (engine/indirect/lobe.h) on the same transfers, with random
// entry directions and lights (random_lobe_inputs), C++ float path (the pipeline's) vs Vulkan,
// for a Lafortune lobe (a power per channel) and a coating (GGX, Smith, Fresnel); terms/s counts
// entry x frame evaluations (those skipped included), the worst difference to the double
// reference's values is relative to its largest value.
//   indirect_bench [reps=3] [threads=2] [gather|lobe] [rows,frames ...]   (both terms by
//                  default; default sizes: 20000,1 20000,16 200000,1 200000,16 1000000,16;
//                  1M particles' entries exceed lavapipe's 128 MiB binding, so that size runs split)
#include "indirect/lobe.h"
#include "indirect/transfer.h"

#include "core/timer.h"
#include "gpu/context.h"
#include "random_transfer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <vector>

using namespace specula;

namespace {

double best_of(int reps, const std::function<void()>& fn) {
    double best = 1e30;
    for (int i = 0; i < reps; ++i) {
        const Stopwatch sw;
        fn();
        best = std::min(best, sw.seconds());
    }
    return best;
}

void bench(std::uint32_t rows, std::uint32_t frames, int reps, unsigned threads, IndirectGatherVk* vk) {
    const IndirectTransfer t = test::random_transfer({.rows = rows, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .seed = 1});
    const std::vector<glm::vec4> b = test::random_radiosity(rows, frames, 2);
    std::vector<glm::vec4> out(b.size());
    const double products = double(t.entry_count()) * frames;
    const double tc = best_of(reps, [&] { gather_indirect_cpu(t, b, frames, out, threads); });
    std::printf("%8u rows %6.1f entries/row %3u frames  cpu    %9.2f ms  %7.1f M entries/s\n", rows,
                double(t.entry_count()) / rows, frames, tc * 1e3, products / tc * 1e-6);
    if (vk == nullptr) return;
    std::vector<glm::vec4> ref = out;
    vk->run(t, b, frames, out); // warm-up, and a check against the reference (at this size the real binding cap may split)
    double worst = 0.0;
    for (std::size_t i = 0; i < out.size(); ++i)
        for (int c = 0; c < 3; ++c)
            if (ref[i][c] > 0.0f) worst = std::max(worst, std::abs(double(out[i][c]) - ref[i][c]) / ref[i][c]);
    double gpu_ms = 1e30;
    const double tv = best_of(reps, [&] {
        vk->run(t, b, frames, out);
        if (vk->last_run().gpu_ms) gpu_ms = std::min(gpu_ms, *vk->last_run().gpu_ms);
    });
    const IndirectGatherStats& s = vk->last_run();
    std::printf("%8u rows %6.1f entries/row %3u frames  vulkan %9.2f ms  %7.1f M entries/s", rows,
                double(t.entry_count()) / rows, frames, tv * 1e3, products / tv * 1e-6);
    if (s.gpu_ms) std::printf("  (gpu %.2f ms: %.1f M entries/s)", gpu_ms, products / (gpu_ms * 1e-3) * 1e-6);
    std::printf("  %u row chunks, %u frame batches; worst relative difference to the cpu %.2g\n", s.row_chunks, s.frame_batches,
                worst);
}

struct LobeMaterial {
    const char* name;
    shared::MaterialGpu m;
};

void bench_lobe(std::uint32_t rows, std::uint32_t frames, int reps, unsigned threads, IndirectLobeVk* vk) {
    IndirectTransfer t = test::random_transfer({.rows = rows, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .seed = 1});
    const test::RandomLobeInputs in = test::random_lobe_inputs(t, frames, {}, 3);
    const std::vector<glm::vec4> zero(std::size_t{rows} * frames, glm::vec4(0.0f));
    std::vector<glm::vec4> out(zero.size()), ref(zero.size());
    const double terms = double(t.entry_count()) * frames;
    const LobeMaterial materials[] = {
        {"lafortune", {.family = glm::uvec4(shared::kMaterialLafortune, 0, 0, 0), .a = glm::vec4(-1.0f, -0.9f, -1.05f, 0.0f),
                       .b = glm::vec4(0.95f, 0.9f, 1.0f, 0.0f), .c = glm::vec4(8.0f, 20.0f, 60.0f, 0.0f)}},
        {"coated", {.family = glm::uvec4(shared::kMaterialCoated, 0, 0, 0), .a = glm::vec4(1.5f, 0.3f, 0.0f, 0.0f),
                    .b = glm::vec4(1.0f, 0.9f, 0.8f, 0.0f), .c = glm::vec4(0.0f)}},
    };
    // Relative to the largest value: a lobe's tail (N = 60) reaches values that float flushes
    // to 0, so a value's own relative difference says nothing (the test's bound is the check).
    const auto worst_difference = [&] {
        double worst = 0.0, largest = 0.0;
        for (std::size_t i = 0; i < out.size(); ++i)
            for (int c = 0; c < 3; ++c) {
                worst = std::max(worst, std::abs(double(out[i][c]) - ref[i][c]));
                largest = std::max(largest, double(ref[i][c]));
            }
        return largest > 0.0 ? worst / largest : 0.0;
    };
    const bool simd = detail::lobe_simd();
    for (const LobeMaterial& lm : materials) {
        ref = zero;
        add_directed_lobe_cpu(t, lm.m, in.row_normal, in.light_geometry, in.intensity, frames, ref, threads);
        // The float path both ways where the processor has the 8-wide one (lobe.h; the lafortune family).
        for (const bool eight : {true, false}) {
            if (eight && (!simd || lm.m.family.x != shared::kMaterialLafortune)) continue;
            detail::set_lobe_simd(eight);
            // Each run adds to `out`: reset it outside the timing (a copy of rows x frames values).
            double tc = 1e30;
            for (int r = 0; r < reps; ++r) {
                out = zero;
                const Stopwatch sw;
                add_directed_lobe_float(t, lm.m, in.row_normal, in.light_geometry, in.intensity, frames, out, threads);
                tc = std::min(tc, sw.seconds());
            }
            std::printf("%8u rows %6.1f entries/row %3u frames  lobe %-9s cpu%s %9.2f ms  %7.1f M terms/s  worst difference "
                        "to the reference %.2g of its largest value\n",
                        rows, double(t.entry_count()) / rows, frames, lm.name, eight ? " x8" : "   ", tc * 1e3, terms / tc * 1e-6,
                        worst_difference());
        }
        detail::set_lobe_simd(simd);
        if (vk == nullptr) continue;
        out = zero;
        vk->run(t, lm.m, in.row_normal, in.light_geometry, in.intensity, frames, out); // warm-up
        double tv = 1e30, gpu_ms = 1e30;
        for (int r = 0; r < reps; ++r) {
            out = zero;
            const Stopwatch sw;
            vk->run(t, lm.m, in.row_normal, in.light_geometry, in.intensity, frames, out);
            tv = std::min(tv, sw.seconds());
            if (vk->last_run().gpu_ms) gpu_ms = std::min(gpu_ms, *vk->last_run().gpu_ms);
        }
        const IndirectLobeStats& s = vk->last_run();
        std::printf("%8u rows %6.1f entries/row %3u frames  lobe %-9s vulkan %9.2f ms  %7.1f M terms/s", rows,
                    double(t.entry_count()) / rows, frames, lm.name, tv * 1e3, terms / tv * 1e-6);
        if (s.gpu_ms) std::printf("  (gpu %.2f ms: %.1f M terms/s)", gpu_ms, terms / (gpu_ms * 1e-3) * 1e-6);
        std::printf("  %u row chunks, %u frame batches; worst difference to the reference %.2g of its largest value\n",
                    s.row_chunks, s.frame_batches, worst_difference());
    }
}

} // namespace

int main(int argc, char** argv) try {
    const int reps = argc > 1 ? std::atoi(argv[1]) : 3;
    const unsigned threads = argc > 2 ? unsigned(std::atoi(argv[2])) : 2u;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> sizes;
    bool gather = true, lobe = true;
    int first_size = 3;
    if (argc > 3 && (std::string(argv[3]) == "gather" || std::string(argv[3]) == "lobe")) {
        gather = std::string(argv[3]) == "gather";
        lobe = !gather;
        first_size = 4;
    }
    for (int i = first_size; i < argc; ++i) {
        unsigned rows = 0, frames = 0;
        if (std::sscanf(argv[i], "%u,%u", &rows, &frames) != 2) throw Error(std::string("not rows,frames: ") + argv[i]);
        sizes.emplace_back(rows, frames);
    }
    if (sizes.empty()) sizes = {{20000, 1}, {20000, 16}, {200000, 1}, {200000, 16}, {1000000, 16}};
    std::unique_ptr<gpu::Context> ctx;
    std::unique_ptr<IndirectGatherVk> vk;
    std::unique_ptr<IndirectLobeVk> vk_lobe;
    try {
        ctx = std::make_unique<gpu::Context>(gpu::ContextOptions{.validation = false});
        vk = std::make_unique<IndirectGatherVk>(*ctx);
        vk_lobe = std::make_unique<IndirectLobeVk>(*ctx);
        std::printf("device: %s (storage binding %llu bytes)\n", ctx->info().name.c_str(),
                    static_cast<unsigned long long>(ctx->info().max_storage_buffer_range));
    } catch (const std::exception& e) {
        std::printf("no Vulkan: %s\n", e.what());
    }
    std::printf("best of %d, cpu on %u threads\n", reps, threads);
    for (const auto& [rows, frames] : sizes) {
        if (gather) bench(rows, frames, reps, threads, vk.get());
        if (lobe) bench_lobe(rows, frames, reps, threads, vk_lobe.get());
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
