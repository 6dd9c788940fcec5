// The albedo refinement (refine/albedo_refine.h) against the truth at the texel centres:
// the texels that only grazing views see must not drift round after round, and the rounds
// must not make the texel values much worse than the solve's. Lambertian knot (the preset
// whose grazing texels drifted most), 128 px, 8 views x 6 lights, png8: ~10 s on lavapipe.
// Measured (lavapipe), RMSE over seen texels (max |error|) after 0 / 2 / 4 rounds:
//   undamped (the update before the damping): 7.82% (1.56) / 9.24% (1.78) / 10.99% (2.32)
//   damped (the defaults):                    7.82% (1.56) / 8.12% (1.56) / 8.34% (1.56)
// At this size (a texel is 4 of the 512 px capture's) the damped rounds still raise the RMSE
// a little: the renderer-optimal albedo overshoots at edges that cover most texels here (at
// 512 px the knot's RMSE goes 2.77% -> 2.79%, README.md "How the albedo is sharpened").
// On a uniform albedo the refinement leaves the solve's values as they were.
#include "diffuse_scene.h"
#include "refine/albedo_refine.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

using namespace specula;

namespace {

class AlbedoRefine : public test::VulkanTest {
protected:
    struct Errors {
        test::AlbedoError rounds[3]; // 0, 2, 4 rounds
    };

    Errors measure(const test::DiffuseScene& s, const AlbedoRefineOptions& options) {
        const LambertInputs in = s.inputs();
        const LambertOutputs solve = lambert_solve_cpu(in, {});
        std::vector<std::uint8_t> seen(s.truth.size());
        for (std::size_t p = 0; p < seen.size(); ++p) seen[p] = (solve.particles[p].status & shared::kLambertOk) ? 1 : 0;
        Errors e;
        for (std::uint32_t i = 0; i < 3; ++i) {
            const AlbedoRefineResult r =
                refine_albedo(ctx(), s.capture, s.atlas, s.particles.particles, in, solve, LafortuneRgb{}, 2 * i,
                              [](const LambertInputs& x) { return lambert_solve_cpu(x, {}); }, options);
            e.rounds[i] = test::albedo_error(r.albedo, s.truth, seen);
        }
        return e;
    }
    static void print(const char* label, const Errors& e) {
        std::printf("%s: RMSE over %zu seen texels (max) 0 / 2 / 4 rounds: %.3f%% (%.3f) / %.3f%% (%.3f) / %.3f%% (%.3f)\n",
                    label, e.rounds[0].count, 100 * e.rounds[0].rmse, e.rounds[0].max_abs, 100 * e.rounds[1].rmse,
                    e.rounds[1].max_abs, 100 * e.rounds[2].rmse, e.rounds[2].max_abs);
    }
};

const AlbedoRefineOptions kUndamped{.step = 1.0f, .prior = 0.0f, .grazing_cos = -1.0f, .resolved_cos = -1.0f,
                                    .stop_growing = false};

} // namespace

TEST_F(AlbedoRefine, TexelValuesDoNotDriftOverRounds) {
    const test::DiffuseScene s = test::make_scene(
        {.preset = "knot", .lambertian = true, .size = 128, .views = 8, .format = synth::ImageFormat::Png8});
    const Errors damped = measure(s, {});
    const Errors undamped = measure(s, kUndamped);
    print("damped", damped);
    print("undamped", undamped);
    // The measure sees the drift of the undamped update.
    EXPECT_GT(undamped.rounds[2].rmse, 1.1 * undamped.rounds[0].rmse);
    EXPECT_GT(undamped.rounds[2].max_abs, undamped.rounds[0].max_abs + 0.2);
    EXPECT_GT(undamped.rounds[2].rmse - undamped.rounds[1].rmse, 0.01);
    // Damped: the first rounds sharpen edge texels (the largest error 0.67 -> 0.80, undamped
    // 0.67 -> 1.51), then nothing drifts: rounds 3-4 move the largest error by under 0.05 (0.80
    // -> 0.80; undamped 1.51 -> 2.35), the RMSE barely moves, and it stays within 8% of the solve's.
    EXPECT_LE(damped.rounds[1].max_abs - damped.rounds[0].max_abs,
              0.35 * (undamped.rounds[1].max_abs - undamped.rounds[0].max_abs));
    EXPECT_LE(damped.rounds[2].max_abs, damped.rounds[1].max_abs + 0.05);
    for (int i = 1; i < 3; ++i) EXPECT_LE(damped.rounds[i].rmse, 1.08 * damped.rounds[0].rmse) << 2 * i << " rounds";
    EXPECT_LT(damped.rounds[2].rmse - damped.rounds[1].rmse, 0.005);
}

// A correct uniform albedo stays as it is (the solve's own error, 0.4% here, is not the
// refinement's to amplify).
TEST_F(AlbedoRefine, UniformAlbedoIsLeftAsItIs) {
    const test::DiffuseScene s = test::make_scene(
        {.preset = "knot", .lambertian = true, .size = 128, .views = 8, .edit_preset = [](synth::Preset& p) {
             std::fill(p.material.albedo_texture.pixels.begin(), p.material.albedo_texture.pixels.end(), 0.5f);
         }});
    const Errors e = measure(s, {});
    print("uniform", e);
    for (int i = 1; i < 3; ++i) EXPECT_LE(e.rounds[i].rmse, e.rounds[0].rmse + 5e-4) << 2 * i << " rounds";
}
