// The diffuse solve against synthetic truth, on extreme inputs, and the albedo texture.
//
// Which texels the accuracy tests measure. The truth is the preset's albedo texture at each
// particle's mesh UV; the images sample that texture once per pixel centre, and a particle's
// value is the bilinear mix of the 4 pixels around its projection. Where the texture changes
// within that footprint (text, stripes: the presets' textures are finer than 128-pixel images)
// no solve can recover the texture value: the error is the images' resampling, not the
// solve's. The accuracy figures are therefore asserted over "resolved" texels, whose truth is
// flat within 1.5 image pixels of the view that sees them best (flat_truth, diffuse_scene.h),
// and the RMSE over all seen texels is printed beside them. Over every seen texel, issue 3's
// criterion is asserted on a uniform albedo (UniformLambertianMeetsTheCriterionOverSeenTexels).
#include "diffuse_scene.h"

#include "diffuse/albedo_texture.h"
#include "diffuse/lambert_solve_detail.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <unistd.h>
#include <algorithm>
#include <filesystem>

namespace specula {
namespace {

using test::DiffuseScene;
using test::SceneOptions;

std::vector<std::uint8_t> ok_mask(const LambertOutputs& out) {
    std::vector<std::uint8_t> m(out.particles.size());
    for (std::size_t p = 0; p < m.size(); ++p) m[p] = (out.particles[p].status & shared::kLambertOk) ? 1 : 0;
    return m;
}
std::vector<std::uint8_t> both(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    std::vector<std::uint8_t> m(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) m[i] = a[i] && b[i];
    return m;
}

bool finite(const LambertParticleResult& r) {
    for (int c = 0; c < 4; ++c)
        if (!std::isfinite(r.albedo_best[c]) || !std::isfinite(r.albedo_robust[c]) || !std::isfinite(r.normal[c])) return false;
    return true;
}

// Every particle: finite, and flagged; "no sample" and "not seen" have albedo 0.
void expect_sane(const LambertOutputs& out) {
    std::size_t bad = 0;
    for (const auto& r : out.particles) {
        if (!finite(r)) ++bad;
        const bool ok = r.status & shared::kLambertOk;
        const bool none = r.status & (shared::kLambertNoSample | shared::kLambertNotSeen);
        if (ok == none) ++bad;
        if (none && (glm::vec3(r.albedo_best) != glm::vec3(0.0f) || glm::vec3(r.albedo_robust) != glm::vec3(0.0f))) ++bad;
    }
    EXPECT_EQ(bad, 0u);
    EXPECT_EQ(out.summary.ok + out.summary.no_sample + out.summary.not_seen, out.summary.particles);
}

class DiffuseSolve : public ::testing::TestWithParam<Backend> {
protected:
    void SetUp() override {
        if (GetParam() == Backend::Vulkan) SPECULA_REQUIRE_VULKAN();
    }
    LambertOutputs run(const LambertInputs& in, const LambertOptions& o) {
        return lambert_solve(in, o, GetParam(), test::vulkan_context());
    }
};

const DiffuseScene& lambertian_can() {
    static const DiffuseScene s = test::make_scene({.preset = "can", .lambertian = true, .size = 128, .views = 8});
    return s;
}

// Noise-free Lambertian can (EXR): RMSE < 0.5% of full scale on resolved texels, both modes;
// photometric normals within 1 degree of the mesh normal.
TEST_P(DiffuseSolve, LambertianRecoversAlbedo) {
    const DiffuseScene& s = lambertian_can();
    const auto flat = test::flat_truth(s, 1.5, 0.004f);
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        LambertOutputs out = run(s.inputs(), {.mode = mode});
        expect_sane(out);
        const auto seen = ok_mask(out);
        const auto e_all = test::albedo_error(s, out, seen);
        const auto e = test::albedo_error(s, out, both(seen, flat));
        out.choice = ViewChoice::Robust;
        const auto e_rob = test::albedo_error(s, out, both(seen, flat));
        std::printf("%s: RMSE resolved %.4f%% (n %zu), robust %.4f%%; all seen %.3f%% (n %zu)\n", to_string(mode),
                    100 * e.rmse, e.count, 100 * e_rob.rmse, 100 * e_all.rmse, e_all.count);
        EXPECT_GT(e.count, s.truth.size() / 10);
        EXPECT_LT(e.rmse, 0.005);
        EXPECT_LT(e_rob.rmse, 0.005);
        if (mode == LambertMode::Photometric) {
            // Refined normals on resolved interior texels solved photometrically.
            std::vector<double> angles;
            for (std::size_t p = 0; p < s.truth.size(); ++p) {
                const auto& r = out.particles[p];
                if (!flat[p] || s.particles.particles[p].is_gutter() || !(r.status & shared::kLambertOk) ||
                    (r.status & shared::kLambertFallback))
                    continue;
                angles.push_back(r.normal.w);
            }
            ASSERT_GT(angles.size(), 1000u);
            std::sort(angles.begin(), angles.end());
            double mean = 0.0;
            for (double a : angles) mean += a;
            mean /= double(angles.size());
            const double p95 = angles[angles.size() * 95 / 100];
            std::printf("  refined normals: mean %.3f deg, median %.3f, 95%% %.3f, max %.3f (n %zu)\n", mean,
                        angles[angles.size() / 2], p95, angles.back(), angles.size());
            EXPECT_LT(mean, 1.0);
            EXPECT_LT(angles[angles.size() / 2], 1.0);
        }
    }
}

// Issue 3's criterion as written: a purely Lambertian object gives RMSE < 0.5% of full scale
// over EVERY seen texel (every particle the solve gives a value: gutters, texels only grazing
// views see, texels shadowed in some frames; none left out as unresolved). The object is the
// knot (self-shadowing, self-occluding; 5% of its seen texels have no view with n.v >= 0.3)
// with a uniform albedo, 256 px, 8 views x 6 lights: the error is then the solve's own
// (irradiance, shadows, occlusion, view choice, gutters), none of it the images resampling a
// texture finer than their pixels. Measured 0.204% (best view; 0.394% before each tap got its
// own irradiance); with the shadows baked in (every frame lit) 21.7%, which the test checks too.
// On the presets' own textures (bench/seen_texels.cpp, README.md "How the albedo is
// sharpened") the error over every seen texel is mostly detail finer than a texel, which the
// atlas cannot hold. TapIrradianceMeetsTheCriterionOnCurvedRims below covers the geometry
// where the solve itself was biased.
TEST_P(DiffuseSolve, UniformLambertianMeetsTheCriterionOverSeenTexels) {
    static const DiffuseScene s = test::make_scene(
        {.preset = "knot", .lambertian = true, .size = 256, .views = 8, .edit_preset = [](synth::Preset& p) {
             std::fill(p.material.albedo_texture.pixels.begin(), p.material.albedo_texture.pixels.end(), 0.5f);
         }});
    LambertOutputs out = run(s.inputs(), {});
    expect_sane(out);
    const auto seen = ok_mask(out);
    const auto e = test::albedo_error(s, out, seen);
    out.choice = ViewChoice::Robust;
    const auto e_rob = test::albedo_error(s, out, seen);
    EXPECT_GT(out.summary.rejected_shadow, 0u);
    EXPECT_GT(e.count, s.truth.size() * 9 / 10);
    // The same capture with the shadows baked in: the measure sees it.
    DiffuseScene baked = s;
    std::fill(baked.visibility.lit.begin(), baked.visibility.lit.end(), ~0u);
    const LambertOutputs out_baked = run(baked.inputs(), {});
    const auto e_baked = test::albedo_error(baked, out_baked, ok_mask(out_baked));
    std::printf("knot, uniform albedo: RMSE over %zu seen texels (of %zu) %.3f%% (max %.3f), robust %.3f%%; shadows baked in %.2f%%\n",
                e.count, s.truth.size(), 100 * e.rmse, e.max_abs, 100 * e_rob.rmse, 100 * e_baked.rmse);
    EXPECT_LT(e.rmse, 0.005);
    EXPECT_LT(e_rob.rmse, 0.005);
    EXPECT_GT(e_baked.rmse, 0.05);
}

// The same criterion on the presets whose normals turn fastest within a pixel (the can's rim,
// the vase's lip and foot, the cologne's shoulders), uniform albedo, 256 px, 12 views x 6
// lights, every seen texel. The solve mixing the 4 taps as they are (tap_irradiance off, the
// thesis's sampling) divides by the particle's irradiance alone and is biased there; each tap
// scaled to the particle's irradiance from the view's surface map (shared/lambert.h) is not.
TEST_P(DiffuseSolve, TapIrradianceMeetsTheCriterionOnCurvedRims) {
    static std::map<std::string, DiffuseScene> scenes; // built once for both backends
    for (const char* preset : {"can", "cologne", "vase"}) {
        if (!scenes.count(preset))
            scenes.emplace(preset, test::make_scene({.preset = preset, .lambertian = true, .size = 256, .views = 12,
                                                     .edit_preset = [](synth::Preset& p) {
                                                         std::fill(p.material.albedo_texture.pixels.begin(),
                                                                   p.material.albedo_texture.pixels.end(), 0.5f);
                                                     }}));
        const DiffuseScene& s = scenes.at(preset);
        ASSERT_EQ(s.visibility.surfaces.size(), s.capture.views.size());
        const LambertOutputs with = run(s.inputs(), {});
        const LambertOutputs without = run(s.inputs(), {.tap_irradiance = false});
        expect_sane(with);
        const auto seen = ok_mask(with);
        const auto e = test::albedo_error(s, with, seen);
        const auto e_plain = test::albedo_error(s, without, both(seen, ok_mask(without)));
        std::printf("%s, uniform albedo: RMSE over %zu seen texels %.3f%% (max %.3f); taps mixed as they are %.3f%% (max %.3f)\n",
                    preset, e.count, 100 * e.rmse, e.max_abs, 100 * e_plain.rmse, e_plain.max_abs);
        EXPECT_GT(e.count, s.truth.size() / 3);
        EXPECT_LT(e.rmse, 0.005) << preset;
        EXPECT_LT(e.rmse, 0.5 * e_plain.rmse) << preset;
    }
}

// The strongest lobe of the presets (cologne: Cz = 1.12, N = 18), png8, exposure 2 so that
// highlights clip: RMSE < 1.5% on resolved texels.
TEST_P(DiffuseSolve, HighlightsAndClippingAreRejected) {
    static const DiffuseScene s = test::make_scene({.preset = "cologne", .lambertian = false, .size = 128, .views = 8,
                                                    .exposure = 2.0, .format = synth::ImageFormat::Png8});
    ASSERT_GT(s.clipped_pixels, 1000u);
    const auto flat = test::flat_truth(s, 1.5, 0.004f);
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        LambertOutputs out = run(s.inputs(), {.mode = mode, .choice = ViewChoice::Robust});
        expect_sane(out);
        const auto e = test::albedo_error(s, out, both(ok_mask(out), flat));
        out.choice = ViewChoice::BestView;
        const auto e_best = test::albedo_error(s, out, both(ok_mask(out), flat));
        std::printf("%s: RMSE resolved robust %.3f%%, best view %.3f%% (n %zu); clipped %llu, highlight %llu, outlier-view %llu samples\n",
                    to_string(mode), 100 * e.rmse, 100 * e_best.rmse, e.count,
                    static_cast<unsigned long long>(out.summary.rejected_clipped),
                    static_cast<unsigned long long>(out.summary.rejected_highlight),
                    static_cast<unsigned long long>(out.summary.rejected_view));
        EXPECT_GT(out.summary.rejected_clipped, 0u);
        EXPECT_GT(out.summary.rejected_highlight, 0u);
        EXPECT_LT(e.rmse, 0.015);
    }
}

// Self-shadowing knot (issue 3, "no baked shadows"): shadowed samples are dropped, so texels
// shadowed in some frames are no darker than the others: over the resolved ones, RMSE < 2%,
// signed mean within 1% of full scale, median absolute error under 2%. At 128 px, 8 views:
// RMSE 1.09%, signed mean -0.15%, median 0.08% (n 155601). It was 2.23% (signed mean -0.21%,
// n 162979), for two reasons:
//   - texels that only grazing views see (in the knot's crevices, n.v 0.1 to 0.3) counted as
//     resolved: their footprint was taken in a view that cannot see them. A grazing pixel
//     spreads over several texels, so the bands and the spiral blur into them (errors of both
//     signs, 5 to 17% each; 83% of the squared error came from texels whose best view has
//     n.v < 0.3). flat_truth now takes the footprint in a view that sees the texel: 4.5% of
//     the texels leave the set (1.18% with this change alone);
//   - lit samples whose bilinear taps reach past the smooth-shading terminator, where the
//     images are black but no shadow ray is occluded: the shadow map now marks those pixels
//     (2.18% with this change alone; LitSamplesReadNoBlackPixels below).
// Dropping grazing views from the solve instead (n.v < 0.2 or 0.3) lowers this figure, but
// those texels are then inpainted from atlas neighbours and the texture gets worse (texture
// RMSE over the old set 2.23% -> 2.33% and 3.52%).
TEST_P(DiffuseSolve, KnotShowsNoBakedShadows) {
    static const DiffuseScene s = test::make_scene({.preset = "knot", .lambertian = true, .size = 128, .views = 8});
    const auto flat = test::flat_truth(s, 1.5, 0.004f);
    LambertOutputs out = run(s.inputs(), {});
    expect_sane(out);
    EXPECT_GT(out.summary.rejected_shadow, 0u);
    const test::ShadowedTexelError e = test::shadowed_texel_error(s, out, flat);
    ASSERT_GT(e.count, 1000u);
    std::printf("knot, resolved texels shadowed in some frames (n %zu): signed mean %.4f, median |e| %.4f, RMSE %.4f\n",
                e.count, e.signed_mean, e.median_abs, e.rmse);
    EXPECT_LT(e.rmse, 0.02);
    EXPECT_LT(std::abs(e.signed_mean), 0.01);
    EXPECT_LT(e.median_abs, 0.02);
}

// The visibility the solve gets against the images it reads: a (particle, frame) pair that
// visibility lights and whose view sees the particle reads no black object pixel among its 4
// bilinear taps. The shadow map marks pixels in a cast shadow AND pixels whose surface faces
// away from the light (the smooth-shading terminator, where the face still faces the light
// and the shadow ray is free): without the second, 2.1% (knot), 2.0% (vase) and 1.6%
// (cologne) of these pairs read a black pixel; with it 83 of 575230, 0 and 1 (shadow rays
// from a slightly different origin than the renderer's, at grazing light) on the patchwork
// atlas, 21 of 157536, 0 of 183704 and 4 of 139192 on the chart atlas at 3 texels per pixel.
TEST(DiffuseInputs, LitSamplesReadNoBlackPixels) {
    for (const char* preset : {"knot", "vase", "cologne"}) {
        // 3 texels per pixel: the chart atlas (the default) has no gutters inside its charts,
        // so at one texel per pixel it gives a third of the patchwork's particles here.
        const DiffuseScene s = test::make_scene({.preset = preset, .lambertian = true, .size = 96, .views = 4, .texels_per_pixel = 3.0});
        const Visibility& vis = s.visibility;
        std::size_t lit_pairs = 0, dark = 0;
        for (std::size_t p = 0; p < s.particles.particles.size(); ++p)
            for (std::uint32_t v = 0; v < s.capture.views.size(); ++v) {
                if (!vis.sees(p, v)) continue;
                const Camera& cam = s.capture.views[v].camera;
                const int w = cam.intrinsics.w, h = cam.intrinsics.h;
                const glm::dvec2 q = *cam.project(glm::dvec3(s.particles.particles[p].p()));
                const int x0 = static_cast<int>(std::floor(q.x - 0.5)), y0 = static_cast<int>(std::floor(q.y - 0.5));
                for (std::size_t f : s.capture.views[v].frames) {
                    if (!vis.lights(p, f)) continue;
                    ++lit_pairs;
                    const FrameImage& im = s.capture.images[f];
                    bool black = false;
                    for (int dy = 0; dy < 2; ++dy)
                        for (int dx = 0; dx < 2; ++dx) {
                            const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
                            const float* c = &im.color.pixels[im.color.index(x, y)];
                            black = black || (!(im.flags[std::size_t(y) * std::size_t(w) + std::size_t(x)] & kOutsideMask) &&
                                              c[0] == 0.0f && c[1] == 0.0f && c[2] == 0.0f);
                        }
                    dark += black ? 1u : 0u;
                }
            }
        std::printf("%s: %zu of %zu lit pairs read a black object pixel\n", preset, dark, lit_pairs);
        EXPECT_GT(lit_pairs, 100000u);
        EXPECT_LE(double(dark), 1e-3 * double(lit_pairs)) << preset;
    }
}

// ---- extreme inputs: a value with a flag or a counted skip, never NaN ----------------------

const DiffuseScene& small_can() {
    static const DiffuseScene s = test::make_scene({.preset = "can", .lambertian = true, .size = 64, .views = 3});
    return s;
}

TEST_P(DiffuseSolve, AllSamplesClipped) {
    DiffuseScene s = small_can();
    for (auto& im : s.capture.images)
        for (auto& f : im.flags) f |= kClippedAny;
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        const LambertOutputs out = run(s.inputs(), {.mode = mode});
        expect_sane(out);
        EXPECT_EQ(out.summary.ok, 0u);
        EXPECT_GT(out.summary.no_sample, 0u);
        EXPECT_GT(out.summary.rejected_clipped, 0u);
        EXPECT_EQ(out.summary.used, 0u);
    }
}

TEST_P(DiffuseSolve, AllSamplesInShadow) {
    DiffuseScene s = small_can();
    std::fill(s.visibility.lit.begin(), s.visibility.lit.end(), 0u);
    const LambertOutputs out = run(s.inputs(), {});
    expect_sane(out);
    EXPECT_EQ(out.summary.ok, 0u);
    EXPECT_GT(out.summary.rejected_shadow, 0u);
    EXPECT_EQ(out.summary.no_sample + out.summary.not_seen, out.summary.particles);
}

TEST_P(DiffuseSolve, SingleView) {
    const DiffuseScene& s = small_can();
    LambertInputs in = s.inputs();
    for (std::size_t v = 1; v < in.views.size(); ++v) in.views[v].frames.clear();
    const LambertOutputs out = run(in, {.mode = LambertMode::Photometric});
    expect_sane(out);
    EXPECT_GT(out.summary.ok, 1000u);
    for (const auto& r : out.particles) {
        if (r.status & shared::kLambertOk) {
            ASSERT_EQ(r.best_view, 0u);
        }
    }
    const auto e = test::albedo_error(s, out, both(ok_mask(out), test::flat_truth(s, 1.5, 0.004f)));
    EXPECT_LT(e.rmse, 0.01);
}

// A photometric-stereo rig (issue 17): one view lit by 48 lights, at 10 to 55 degrees off
// the camera in 12 azimuths, noise-free EXR. Nothing limits the frames of a view: both modes
// recover the albedo of resolved texels within the 20 x 6 rig's bound (0.5% RMSE), and the
// photometric normals lie within 1 degree of the mesh's.
TEST_P(DiffuseSolve, OneViewWithManyLights) {
    static const DiffuseScene s = test::make_scene(
        {.preset = "can", .lambertian = true, .size = 128, .views = 1, .lights = 48, .light_angles_deg = {10, 25, 40, 55}});
    ASSERT_EQ(s.inputs().views.size(), 1u);
    ASSERT_EQ(s.inputs().views[0].frames.size(), 48u);
    const auto flat = test::flat_truth(s, 1.5, 0.004f);
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        const LambertOutputs out = run(s.inputs(), {.mode = mode});
        expect_sane(out);
        const auto e = test::albedo_error(s, out, both(ok_mask(out), flat));
        std::printf("%s, 1 view x 48 lights: RMSE resolved %.4f%% (n %zu), %zu samples used, %.3f s\n", to_string(mode),
                    100 * e.rmse, e.count, static_cast<std::size_t>(out.summary.used), out.summary.seconds);
        EXPECT_GT(e.count, 1000u);
        EXPECT_LT(e.rmse, 0.005);
        EXPECT_GT(out.summary.used, 30u * out.summary.ok); // most of a texel's 48 samples count (measured 38 on average)
        if (mode == LambertMode::Photometric) {
            EXPECT_LT(out.summary.fallback, out.summary.ok / 20);
            EXPECT_LT(out.summary.mean_normal_angle_deg, 1.0);
        }
    }
}

// Distant lights (issue 17): one view of 16 lights given as point lights 1000 bounding radii
// away, and the same 16 lights as directional lights (capture format 1.1; each rendered
// exactly, parallel and of one irradiance, by the synthetic renderer, and solved through its
// stand-in point light, capture.h). The two albedos agree within 0.5% (they differ by the
// far point lights' own 1e-3 spread of direction and irradiance), and the directional one
// meets the 20 x 6 rig's bound against the truth.
TEST_P(DiffuseSolve, DirectionalLightsGiveTheFarPointLightsAlbedo) {
    const auto rig_at = [](bool directional) {
        return [directional](synth::Rig& rig) {
            for (synth::RigView& v : rig.views)
                for (PointLight& l : v.lights) {
                    const glm::dvec3 dir = glm::normalize(l.position - rig.center);
                    const double d = 1000.0 * rig.radius;
                    const glm::dvec3 irradiance = l.intensity / glm::dot(l.position - rig.center, l.position - rig.center);
                    if (directional) {
                        Bounds b;
                        b.min = glm::vec3(rig.center - glm::dvec3(rig.radius));
                        b.max = glm::vec3(rig.center + glm::dvec3(rig.radius));
                        l = directional_stand_in(DirectionalLight{dir, irradiance}, b);
                    } else {
                        l = PointLight{rig.center + d * dir, irradiance * (d * d), std::nullopt};
                    }
                }
        };
    };
    const SceneOptions base{.preset = "can", .size = 128, .views = 1, .lights = 16, .light_angles_deg = {10, 25, 40, 55}};
    SceneOptions far = base, distant = base;
    far.edit_rig = rig_at(false);
    distant.edit_rig = rig_at(true);
    static const DiffuseScene point_scene = test::make_scene(far);
    static const DiffuseScene directional_scene = test::make_scene(distant);
    ASSERT_TRUE(directional_scene.capture.desc.frames[0].light.directional.has_value());
    ASSERT_FALSE(point_scene.capture.desc.frames[0].light.directional.has_value());
    const LambertOutputs a = run(point_scene.inputs(), {});
    const LambertOutputs b = run(directional_scene.inputs(), {});
    ASSERT_EQ(a.particles.size(), b.particles.size());
    double sum2 = 0.0, worst = 0.0;
    std::size_t n = 0;
    for (std::size_t p = 0; p < a.particles.size(); ++p) {
        if (!(a.particles[p].status & shared::kLambertOk) || !(b.particles[p].status & shared::kLambertOk)) continue;
        for (int c = 0; c < 3; ++c) {
            const double ra = a.particles[p].albedo_best[c], rb = b.particles[p].albedo_best[c];
            const double rel = std::abs(rb - ra) / std::max(ra, 0.02);
            sum2 += rel * rel;
            worst = std::max(worst, rel);
            ++n;
        }
    }
    const double rms = std::sqrt(sum2 / double(std::max<std::size_t>(n, 1)));
    const auto flat = test::flat_truth(directional_scene, 1.5, 0.004f);
    const auto e = test::albedo_error(directional_scene, b, both(ok_mask(b), flat));
    std::printf("16 lights, point at 1000 radii vs directional: relative albedo difference RMS %.4f%%, max %.4f%% (n %zu); "
                "directional against the truth: RMSE %.4f%% (n %zu)\n",
                100 * rms, 100 * worst, n, 100 * e.rmse, e.count);
    EXPECT_GT(n, 3000u);
    EXPECT_LT(rms, 0.005);
    EXPECT_LT(e.rmse, 0.005);
    EXPECT_GT(e.count, 1000u);
}

TEST_P(DiffuseSolve, TwoLightsPhotometricFallsBack) {
    const DiffuseScene& s = small_can();
    LambertInputs in = s.inputs();
    for (auto& v : in.views) v.frames.resize(2);
    const LambertOutputs out = run(in, {.mode = LambertMode::Photometric});
    expect_sane(out);
    EXPECT_GT(out.summary.ok, 1000u);
    EXPECT_EQ(out.summary.fallback, out.summary.ok); // fewer than 3 samples everywhere
    const auto e = test::albedo_error(s, out, both(ok_mask(out), test::flat_truth(s, 1.5, 0.004f)));
    EXPECT_LT(e.rmse, 0.01);
}

TEST_P(DiffuseSolve, GrazingLightIsRejected) {
    const DiffuseScene& s = small_can();
    const LambertOutputs base = run(s.inputs(), {});
    const LambertOutputs out = run(s.inputs(), {.min_light_cos = 0.95f});
    expect_sane(out);
    EXPECT_GT(out.summary.rejected_grazing, base.summary.rejected_grazing);
    EXPECT_LT(out.summary.ok, base.summary.ok);
    // Grazing views: particles seen only near the silhouette still give finite values (expect_sane).
}

TEST_P(DiffuseSolve, BlackPixels) {
    DiffuseScene s = small_can();
    for (auto& im : s.capture.images) std::fill(im.color.pixels.begin(), im.color.pixels.end(), 0.0f);
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        const LambertOutputs out = run(s.inputs(), {.mode = mode});
        expect_sane(out);
        EXPECT_GT(out.summary.ok, 1000u);
        for (std::size_t p = 0; p < out.particles.size(); ++p) ASSERT_EQ(out.albedo(p), glm::vec3(0.0f));
    }
}

TEST_P(DiffuseSolve, NaNPixelsAreMissing) {
    DiffuseScene s = small_can();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::size_t i = 0;
    for (auto& im : s.capture.images)
        for (std::size_t p = 0; p < im.flags.size(); ++p, ++i)
            if (i % 3 == 0) {
                for (int c = 0; c < 3; ++c) im.color.pixels[3 * p + std::size_t(c)] = nan;
                if (i % 2 == 0) im.flags[p] |= kMissing; // the others: NaN without the flag (defensive check)
            }
    for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
        const LambertOutputs out = run(s.inputs(), {.mode = mode});
        expect_sane(out);
        EXPECT_GT(out.summary.rejected_missing, 0u);
    }
}

INSTANTIATE_TEST_SUITE_P(Backends, DiffuseSolve, ::testing::Values(Backend::Cpu, Backend::Vulkan),
                         [](const auto& info) { return info.param == Backend::Cpu ? "Cpu" : "Vulkan"; });

// ---- the albedo texture -------------------------------------------------------------------

TEST(AlbedoTexture, FillsUnseenAndGutters) {
    const DiffuseScene& s = small_can();
    const LambertOutputs out = lambert_solve_cpu(s.inputs(), {});
    const AlbedoTexture tex = make_albedo_texture(s.atlas, s.particles.particles, out);
    EXPECT_EQ(tex.stats.texels, s.particles.particles.size());
    EXPECT_EQ(tex.stats.solved, out.summary.ok);
    EXPECT_EQ(tex.stats.solved + tex.stats.filled_same_patch + tex.stats.filled_across + tex.stats.filled_global,
              tex.stats.texels);
    EXPECT_GT(tex.stats.filled_same_patch + tex.stats.filled_across, 0u);
    std::printf("texture %ux%u: %zu texels, solved %zu, same patch %zu, across %zu, global %zu, %.3f s\n", s.atlas.width,
                s.atlas.height, tex.stats.texels, tex.stats.solved, tex.stats.filled_same_patch, tex.stats.filled_across,
                tex.stats.filled_global, tex.stats.seconds);
    // Every owned texel is finite and in range; solved texels hold their particle's value.
    for (const auto& part : s.particles.particles)
        for (int c = 0; c < 3; ++c) {
            const float v = tex.image.at(int(part.texel_x()), int(part.texel_y()), c);
            ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v < 2.0f);
        }
    for (std::size_t p = 0; p < s.particles.particles.size(); ++p) {
        if (!(out.particles[p].status & shared::kLambertOk)) continue;
        const auto& part = s.particles.particles[p];
        ASSERT_EQ(tex.image.at(int(part.texel_x()), int(part.texel_y()), 1), out.albedo(p).y);
    }
    // Written as linear EXR and sRGB PNG.
    const auto dir = std::filesystem::temp_directory_path() / ("specula_albedo_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    write_albedo_texture(tex, dir / "albedo");
    EXPECT_TRUE(std::filesystem::exists(dir / "albedo.exr"));
    EXPECT_TRUE(std::filesystem::exists(dir / "albedo.png"));
    std::filesystem::remove_all(dir);
}

TEST(AlbedoTexture, NothingSeenGetsGlobalMeanOrZero) {
    const DiffuseScene& s = small_can();
    std::vector<glm::vec3> albedo(s.particles.particles.size(), glm::vec3(0.25f));
    std::vector<std::uint8_t> valid(albedo.size(), 0);
    valid[0] = 1;
    const AlbedoTexture tex = make_albedo_texture(s.atlas, s.particles.particles, albedo, valid);
    EXPECT_EQ(tex.stats.solved, 1u);
    EXPECT_GT(tex.stats.filled_same_patch, 0u);
    for (const auto& part : s.particles.particles)
        ASSERT_FLOAT_EQ(tex.image.at(int(part.texel_x()), int(part.texel_y()), 0), 0.25f);
}

} // namespace
} // namespace specula
