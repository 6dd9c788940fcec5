// The pixel fit (refine/pixel_fit.h) against the preset's truth, on captures the synthetic
// renderer made (a procedural texture sampled once per pixel centre, not the fit's bilinear
// atlas): the albedo as the renderer reads it (between texel centres too: diffuse_scene.h
// surface_error) must come nearer the truth than the solve's; a uniform albedo is left as it
// is; each iteration lowers the train pixels' residual; a known coated material is taken out of
// every pixel; the result is the same for any thread count. No Vulkan device: C++ and Embree only.
#include "diffuse/albedo_texture.h"
#include "diffuse_scene.h"
#include "refine/pixel_fit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>

using namespace specula;

namespace {

struct Fitted {
    LambertOutputs solve;
    AlbedoRefineResult fit;
    PixelFitStats stats;
};

Fitted fit_scene(const test::DiffuseScene& s, const LambertOptions& o, unsigned threads = 2,
                 std::uint32_t iterations = PixelFitOptions{}.iterations, bool given_hits = false) {
    const LambertInputs in = s.inputs();
    Fitted f;
    f.solve = lambert_solve_cpu(in, o);
    const RayScene scene(s.capture.mesh);
    std::vector<PixelHits> hits; // as the visibility keeps them
    if (given_hits)
        for (const LambertView& view : in.views) hits.push_back(cast_pixel_hits(scene, view.camera, 1));
    f.fit = fit_albedo_to_pixels(s.capture.mesh, scene, s.atlas, s.particles.particles, in, f.solve, o,
                                 PixelFitOptions{.iterations = iterations, .threads = threads, .view_hits = hits}, &f.stats);
    return f;
}

// Particles the solve gave a value, not gutter texels: where both estimates are defined.
std::vector<std::uint8_t> solved_interior(const test::DiffuseScene& s, const LambertOutputs& solve) {
    std::vector<std::uint8_t> sel(s.particles.particles.size(), 0);
    for (std::size_t p = 0; p < sel.size(); ++p)
        sel[p] = (solve.particles[p].status & shared::kLambertOk) && !s.particles.particles[p].is_gutter() ? 1 : 0;
    return sel;
}

} // namespace

// The can's label (stripes and lettering finer than the pixels), Lambertian, 128 px, 8 views x
// 6 lights, png8. Measured: the albedo as rendered, RMSE over the solved texels' surface, solve
// 9.19%, pixel fit 7.72% (0.84 times); the train pixels' weighted residual 0.0736 -> 0.0434 in
// 8 iterations (0.0323 without the bounds), the last lowering it by 0.0001.
TEST(PixelFit, TheRenderedAlbedoComesNearerTheTruthThanTheSolves) {
    const test::DiffuseScene s =
        test::make_scene({.preset = "can", .lambertian = true, .size = 128, .views = 8, .format = synth::ImageFormat::Png8});
    const Fitted f = fit_scene(s, {});
    const std::vector<std::uint8_t> sel = solved_interior(s, f.solve);
    const test::AlbedoError before = test::surface_error(s, make_albedo_texture(s.atlas, s.particles.particles, f.solve).image, sel);
    const test::AlbedoError after =
        test::surface_error(s, make_albedo_texture(s.atlas, s.particles.particles, f.fit.albedo, f.fit.valid).image, sel);
    std::printf("surface RMSE over %zu texels: solve %.3f%%, pixel fit %.3f%%; %llu pixels used, residual", after.count,
                100 * before.rmse, 100 * after.rmse, static_cast<unsigned long long>(f.stats.pixels_used));
    for (double r : f.stats.rms) std::printf(" %.5f", r);
    std::printf("\n");
    ASSERT_EQ(f.stats.rms.size(), PixelFitOptions{}.iterations + 1u);
    ASSERT_EQ(f.fit.rounds.size(), PixelFitOptions{}.iterations);
    EXPECT_GT(f.stats.pixels_used, f.stats.pixels / 2);
    EXPECT_LT(after.rmse, 0.9 * before.rmse);
    // Each texel stays within what the pixels that read it show: no overshoot past the data
    // (without that bound the label's texels reached 1.79 against a truth at most 0.86).
    float fit_max = 0.0f, truth_max = 0.0f;
    for (std::size_t p = 0; p < sel.size(); ++p)
        if (sel[p]) {
            fit_max = std::max({fit_max, f.fit.albedo[p].x, f.fit.albedo[p].y, f.fit.albedo[p].z});
            truth_max = std::max({truth_max, s.truth[p].x, s.truth[p].y, s.truth[p].z});
        }
    std::printf("largest albedo: pixel fit %.3f, truth %.3f\n", fit_max, truth_max);
    EXPECT_LE(fit_max, 1.05f * truth_max);
    // Each iteration lowers the residual (a majorized step: it cannot rise), and they settle.
    for (std::size_t i = 1; i < f.stats.rms.size(); ++i) EXPECT_LE(f.stats.rms[i], f.stats.rms[i - 1] * (1 + 1e-9)) << i;
    EXPECT_LT(f.stats.rms.back(), 0.7 * f.stats.rms.front());
    EXPECT_LT(f.stats.rms[f.stats.rms.size() - 2] - f.stats.rms.back(), 0.05 * (f.stats.rms.front() - f.stats.rms.back()));
}

// A correct uniform albedo stays as it is: the fit has nothing to sharpen (knot, 128 px, 8
// views, png8: the preset whose texels that only grazing views see drifted under the undamped
// back-projection).
TEST(PixelFit, UniformAlbedoIsLeftAsItIs) {
    const test::DiffuseScene s = test::make_scene(
        {.preset = "knot", .lambertian = true, .size = 128, .views = 8, .format = synth::ImageFormat::Png8,
         .edit_preset = [](synth::Preset& p) {
             std::fill(p.material.albedo_texture.pixels.begin(), p.material.albedo_texture.pixels.end(), 0.5f);
         }});
    const Fitted f = fit_scene(s, {});
    const std::vector<std::uint8_t> sel = solved_interior(s, f.solve);
    std::vector<glm::vec3> solve_albedo(sel.size());
    for (std::size_t p = 0; p < sel.size(); ++p) solve_albedo[p] = glm::vec3(f.solve.albedo(p));
    const test::AlbedoError before = test::albedo_error(solve_albedo, s.truth, sel);
    const test::AlbedoError after = test::albedo_error(f.fit.albedo, s.truth, sel);
    std::printf("uniform: texel RMSE over %zu texels %.4f%% -> %.4f%% (max %.4f -> %.4f)\n", after.count, 100 * before.rmse,
                100 * after.rmse, before.max_abs, after.max_abs);
    // Issue 3's criterion (RMSE under 0.5% of full scale over the seen texels) still holds, and
    // the fit adds at most 0.1% to the solve's RMSE (the png8 quantization it cannot tell from
    // texture: 0.290% -> 0.305% measured) without raising the largest error.
    EXPECT_LT(after.rmse, 0.005);
    EXPECT_LE(after.rmse, before.rmse + 1e-3);
    EXPECT_LE(after.max_abs, before.max_abs + 0.01);
}

// Every particle gathers its pixels in a fixed order: one thread and two give the same bits.
TEST(PixelFit, SameResultForAnyThreadCount) {
    const test::DiffuseScene s =
        test::make_scene({.preset = "cologne", .lambertian = true, .size = 96, .views = 6, .format = synth::ImageFormat::Png8});
    const Fitted one = fit_scene(s, {}, 1, 3), two = fit_scene(s, {}, 2, 3);
    ASSERT_EQ(one.fit.albedo.size(), two.fit.albedo.size());
    EXPECT_EQ(std::memcmp(one.fit.albedo.data(), two.fit.albedo.data(), one.fit.albedo.size() * sizeof(glm::vec3)), 0);
    EXPECT_EQ(one.stats.pixels_used, two.stats.pixels_used);
    EXPECT_EQ(one.stats.samples_used, two.stats.samples_used);
    // The views' pixel hits given (the visibility's, as the pipeline passes them): the same fit.
    const Fitted given = fit_scene(s, {}, 2, 3, true);
    ASSERT_EQ(given.fit.albedo.size(), one.fit.albedo.size());
    EXPECT_EQ(std::memcmp(given.fit.albedo.data(), one.fit.albedo.data(), one.fit.albedo.size() * sizeof(glm::vec3)), 0);
    EXPECT_EQ(given.stats.pixels_used, one.stats.pixels_used);
}

// A coated truth (a Lambertian base under a dielectric coating, a GGX reflection: not the
// Lambertian albedo the fit's data term assumes unless the material is known), uniform albedo 0.5
// so that only the material can move the fit: with the true material known, its specular light
// subtracted and its Fresnel diffuse factor applied pixel by pixel, the fit keeps the solve's
// albedo or comes nearer the truth; fed the same solve but told nothing of the material, the fit
// pulls every texel toward the albedos the pixels seem to show (the coating's fall-off toward
// grazing angles, its highlights' tails). Can, 128 px, 8 views x 6 lights, png8. Measured: texel
// RMSE against 0.5: solve 2.08%, fit with the material 1.20%, fit ignoring it 4.03%.
TEST(PixelFit, AKnownCoatedMaterialIsTakenOutOfEveryPixel) {
    const test::DiffuseScene s = test::make_scene(
        {.preset = "can", .lambertian = false, .size = 128, .views = 8, .format = synth::ImageFormat::Png8,
         .edit_preset = [](synth::Preset& p) {
             p = synth::make_preset("can", false, MaterialFamily::Coated);
             std::fill(p.material.albedo_texture.pixels.begin(), p.material.albedo_texture.pixels.end(), 0.5f);
         }});
    LambertOptions known;
    known.material = s.preset.material.specular();
    ASSERT_TRUE(known.material.has_value());
    const Fitted with = fit_scene(s, known);
    // The same solve (material known) for both fits: only the fit's own use of the material differs.
    const RayScene scene(s.capture.mesh);
    const AlbedoRefineResult ignored = fit_albedo_to_pixels(s.capture.mesh, scene, s.atlas, s.particles.particles, s.inputs(),
                                                            with.solve, LambertOptions{}, PixelFitOptions{});
    const std::vector<std::uint8_t> sel = solved_interior(s, with.solve);
    std::vector<glm::vec3> solve_albedo(sel.size());
    for (std::size_t p = 0; p < sel.size(); ++p) solve_albedo[p] = glm::vec3(with.solve.albedo(p));
    const double e_solve = test::albedo_error(solve_albedo, s.truth, sel).rmse;
    const double e_known = test::albedo_error(with.fit.albedo, s.truth, sel).rmse;
    const double e_ignored = test::albedo_error(ignored.albedo, s.truth, sel).rmse;
    std::printf("coated can, uniform albedo: texel RMSE solve %.3f%%, fit with the material %.3f%%, ignoring it %.3f%%\n",
                100 * e_solve, 100 * e_known, 100 * e_ignored);
    EXPECT_LT(e_known, e_solve);
    EXPECT_GT(e_ignored, 2.5 * e_known);
}
