// lambert_solve: Vulkan (float) against the C++ reference (double) on a real synthetic
// capture: the cologne with its lobe (the strongest of the presets), png8 at exposure 2, so
// that clipping, highlights, shadows, grazing light and photometric fallbacks all occur.
//
// Tolerance. Per pair, the GPU differs from the reference by (a) float rounding of the sums
// of K samples: relative (K + 8) eps32 (1.4e-6 for 16, 2.9e-6 for 40), (b) the projection in float: the
// image position moves by ~1e-5 pixel at 96 px, so a bilinear sample moves by at most that
// times the local pixel difference (<= full scale 1): ~1e-5 / E in rho/pi, and (c) in
// photometric mode the 3x3 solve amplifies (a) by up to cond ~ 3 / rcond <= 3000
// (min_rcond = 1e-3): 4e-3 relative in the worst case, typically far less. Allowed:
//     albedo mode        |rho_vk - rho_ref| <= 1e-4 + 1e-4 rho_ref   per channel
//     photometric mode   |rho_vk - rho_ref| <= 1e-3 + 4e-3 rho_ref,   normal angle <= 0.05 deg
// Decisions (sample rejection against thresholds, cross-view outliers, photometric
// conditioning, the best view among nearly equal cosines) may flip when a value lies within
// rounding of a threshold; such particles are counted and must stay under 0.5% of the seen
// particles; every other particle must agree in status, best view, counts and values.
#include "diffuse_scene.h"

#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

namespace specula {
namespace {

const test::DiffuseScene& scene() { return test::conformance_scene(); }

bool same_decisions(const LambertParticleResult& a, const LambertParticleResult& b) {
    return a.status == b.status && a.best_view == b.best_view && a.views == b.views && a.used == b.used &&
           a.rejected_shadow == b.rejected_shadow && a.rejected_clipped == b.rejected_clipped &&
           a.rejected_missing == b.rejected_missing && a.rejected_grazing == b.rejected_grazing &&
           a.rejected_highlight == b.rejected_highlight && a.rejected_view == b.rejected_view &&
           a.rejected_low == b.rejected_low && a.albedo_robust.w == b.albedo_robust.w;
}

using LambertSolveConformance = test::VulkanTest;

TEST_F(LambertSolveConformance, VulkanMatchesCpuReference) {
    const test::DiffuseScene& s = scene();
    const LambertInputs in = s.inputs();
    LambertSolveVk kernel(ctx());
    // The two modes, and albedo mode with the scene's true lobe subtracted (the joint
    // estimate's later rounds; float pow(base, N) adds ~N eps32 relative to the lobe term,
    // within the same tolerance).
    // Each with per-tap irradiance (the default: the views' surface maps), and albedo mode once
    // without it (the thesis's sampling).
    // And both modes with a coated material (its GGX reflection subtracted, each sample's
    // irradiance scaled by the coating's diffuse factor k_d).
    struct Config {
        LambertMode mode;
        bool lobe;
        bool taps = true;
        bool coated = false;
    };
    ASSERT_EQ(s.visibility.surfaces.size(), in.views.size());
    for (const Config cfg : {Config{LambertMode::Albedo, false}, Config{LambertMode::Photometric, false},
                             Config{LambertMode::Albedo, true}, Config{LambertMode::Albedo, false, false},
                             Config{LambertMode::Albedo, false, true, true}, Config{LambertMode::Photometric, false, true, true}}) {
        const LambertMode mode = cfg.mode;
        LambertOptions o{.mode = mode, .tap_irradiance = cfg.taps};
        if (cfg.lobe) o.material = s.preset.material.lobe;
        if (cfg.coated) o.material = CoatedParams{.eta = 1.5f, .alpha = 0.12f};
        ASSERT_FALSE(s.preset.material.lobe.is_zero());
        const LambertOutputs ref = lambert_solve_cpu(in, o);
        const LambertOutputs vk = kernel.run(in, o);
        ASSERT_EQ(vk.particles.size(), ref.particles.size());
        EXPECT_EQ(ref.summary.tap_irradiance, cfg.taps);
        EXPECT_EQ(vk.summary.tap_irradiance, cfg.taps);
        const double abs_tol = mode == LambertMode::Albedo ? 1e-4 : 1e-3;
        const double rel_tol = mode == LambertMode::Albedo ? 1e-4 : 4e-3;
        std::size_t flips = 0, compared = 0;
        double worst = 0.0, worst_angle = 0.0;
        for (std::size_t p = 0; p < ref.particles.size(); ++p) {
            const auto& r = ref.particles[p];
            const auto& v = vk.particles[p];
            for (int c = 0; c < 4; ++c)
                ASSERT_TRUE(std::isfinite(v.albedo_best[c]) && std::isfinite(v.albedo_robust[c]) && std::isfinite(v.normal[c]))
                    << "particle " << p;
            ASSERT_EQ(v.views, r.views) << "particle " << p; // visibility is an input: pairs must agree exactly
            if (!same_decisions(r, v)) {
                ++flips;
                continue;
            }
            ++compared;
            for (int c = 0; c < 3; ++c) {
                for (const auto& [a, b] :
                     {std::pair{r.albedo_best[c], v.albedo_best[c]}, std::pair{r.albedo_robust[c], v.albedo_robust[c]}}) {
                    const double tol = abs_tol + rel_tol * std::abs(double(a));
                    const double d = std::abs(double(a) - double(b));
                    worst = std::max(worst, d / tol);
                    ASSERT_LE(d, tol) << "particle " << p << " channel " << c << ": cpu " << a << " vk " << b;
                }
            }
            if (mode == LambertMode::Photometric && (r.status & shared::kLambertOk)) {
                const double da = std::abs(double(r.normal.w) - double(v.normal.w));
                worst_angle = std::max(worst_angle, da);
                ASSERT_LE(da, 0.05) << "particle " << p;
            }
        }
        std::printf("%s%s%s: %zu particles (%zu ok, %zu fallback, %zu no sample, %zu not seen in the reference); decisions "
                    "differ on %zu; worst value error / tolerance %.3g, worst angle difference %.3g deg; GPU %.2f ms\n",
                    to_string(mode), cfg.lobe ? " (true lobe subtracted)" : cfg.coated ? " (coated material)" : "", cfg.taps ? "" : " (taps as they are)", ref.particles.size(), ref.summary.ok, ref.summary.fallback, ref.summary.no_sample,
                    ref.summary.not_seen, flips, worst, worst_angle, vk.summary.gpu_ms.value_or(-1.0));
        EXPECT_LE(flips, (ref.summary.ok + ref.summary.no_sample) / 200);
        EXPECT_GT(ref.summary.rejected_clipped, 0u);
        if (!cfg.lobe && !cfg.coated) {
            EXPECT_GT(ref.summary.rejected_highlight, 0u);
        }
        EXPECT_GT(ref.summary.rejected_shadow + ref.summary.rejected_grazing, 0u);
        if (mode == LambertMode::Photometric) {
            EXPECT_GT(ref.summary.fallback, 0u);
        }
    }
}

// Image batching and particle chunking give bit-identical results: bindings limited to 2 MiB
// (two views' images per batch), and to 448 KiB (two frames and a surface map of 96^2 x 16
// bytes per batch: every view's frames are split over several batches).
TEST_F(LambertSolveConformance, BatchedRunMatchesSingleRun) {
    const test::DiffuseScene& s = scene();
    const LambertInputs in = s.inputs();
    LambertSolveVk kernel(ctx());
    const LambertOutputs whole = kernel.run(in, {.mode = LambertMode::Photometric});
    EXPECT_EQ(whole.summary.view_batches, 1u);
    EXPECT_EQ(whole.summary.pair_chunks, 1u);
    EXPECT_EQ(whole.summary.record_groups, 1u);
    for (const std::uint64_t limit : {std::uint64_t(2) << 20, std::uint64_t(448) << 10}) {
        // The second run also holds the records of at most one chunk at a time (a group per chunk).
        const LambertOutputs batched = kernel.run(
            in, {.mode = LambertMode::Photometric, .max_binding_bytes = limit, .max_record_group_bytes = limit < (1u << 20) ? 1u : 0u});
        EXPECT_EQ(batched.summary.record_groups, limit < (1u << 20) ? batched.summary.pair_chunks : 1u);
        EXPECT_GT(batched.summary.view_batches, limit < (1u << 20) ? in.views.size() : 2u);
        EXPECT_GT(batched.summary.pair_chunks, 1u);
        ASSERT_EQ(whole.particles.size(), batched.particles.size());
        for (std::size_t p = 0; p < whole.particles.size(); ++p)
            ASSERT_EQ(std::memcmp(&whole.particles[p], &batched.particles[p], sizeof(LambertParticleResult)), 0)
                << "particle " << p << " (binding limit " << limit << " bytes)";
    }
}

// A view with many frames (issue 17: no limit on frames per view): one view lit by 40
// lights, 5 of them at 70 to 80 degrees (grazing and shadowed samples), png8 at exposure 2
// (clipped highlights), against the reference, with the same tolerances as above.
TEST_F(LambertSolveConformance, ManyFramesPerViewMatchReference) {
    static const test::DiffuseScene s = test::make_scene({.preset = "cologne",
                                                          .lambertian = false,
                                                          .size = 96,
                                                          .views = 1,
                                                          .lights = 40,
                                                          .exposure = 2.0,
                                                          .format = synth::ImageFormat::Png8,
                                                          .light_angles_deg = {10, 25, 40, 55, 30, 20, 45, 75}});
    const LambertInputs in = s.inputs();
    ASSERT_EQ(in.views[0].frames.size(), 40u);
    LambertSolveVk kernel(ctx());
    for (const LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        const LambertOutputs ref = lambert_solve_cpu(in, {.mode = mode});
        const LambertOutputs vk = kernel.run(in, {.mode = mode});
        const double abs_tol = mode == LambertMode::Albedo ? 1e-4 : 1e-3;
        const double rel_tol = mode == LambertMode::Albedo ? 1e-4 : 4e-3;
        std::size_t flips = 0;
        for (std::size_t p = 0; p < ref.particles.size(); ++p) {
            const auto& r = ref.particles[p];
            const auto& v = vk.particles[p];
            if (!same_decisions(r, v)) {
                ++flips;
                continue;
            }
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(v.albedo_best[c], r.albedo_best[c], abs_tol + rel_tol * std::abs(double(r.albedo_best[c])))
                    << "particle " << p << " channel " << c;
        }
        std::printf("%s, 1 view x 40 lights: %zu ok, used %llu, highlight %llu, clipped %llu, grazing %llu, shadow %llu; "
                    "decisions differ on %zu\n",
                    to_string(mode), ref.summary.ok, static_cast<unsigned long long>(ref.summary.used),
                    static_cast<unsigned long long>(ref.summary.rejected_highlight),
                    static_cast<unsigned long long>(ref.summary.rejected_clipped),
                    static_cast<unsigned long long>(ref.summary.rejected_grazing),
                    static_cast<unsigned long long>(ref.summary.rejected_shadow), flips);
        EXPECT_GT(ref.summary.ok, 1000u);
        EXPECT_GT(ref.summary.used, 20u * ref.summary.ok);
        EXPECT_GT(ref.summary.rejected_highlight, 0u);
        EXPECT_GT(ref.summary.rejected_clipped, 0u);
        EXPECT_LE(flips, ref.summary.ok / 200);
    }
}

} // namespace
} // namespace specula
