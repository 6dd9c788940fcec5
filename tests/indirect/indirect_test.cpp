// Indirect light (engine/indirect): the transfer against closed-form form factors, the bounces
// against the closed sphere's interior, the images against the particles, determinism.
#include "indirect/indirect.h"

#include "core/error.h"
#include "shared/lafortune.h"
#include "synth/shapes.h"

#include <gtest/gtest.h>

#include <glm/gtc/constants.hpp>

#include <cmath>
#include <cstdio>
#include <numeric>

namespace specula {
namespace {

// Form factor from a point to a parallel rectangle [0, a] x [0, b] at height h whose corner is
// straight above the point (Howell's catalogue, C-11): odd in a and in b, so signed extents
// add up to any rectangle above any point.
double corner_form_factor(double a, double b, double h) {
    const double x = a / h, y = b / h;
    const double sx = std::sqrt(1.0 + x * x), sy = std::sqrt(1.0 + y * y);
    return (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy)) / (2.0 * glm::pi<double>());
}
double rectangle_form_factor(glm::dvec2 p, glm::dvec2 lo, glm::dvec2 hi, double h) {
    return corner_form_factor(hi.x - p.x, hi.y - p.y, h) - corner_form_factor(lo.x - p.x, hi.y - p.y, h) -
           corner_form_factor(hi.x - p.x, lo.y - p.y, h) + corner_form_factor(lo.x - p.x, lo.y - p.y, h);
}

struct Scene {
    Mesh mesh;
    Atlas atlas;
    ParticleSet particles;
    RayScene rays;
    // A 256 x 256 atlas: some 40,000 particles, enough to resolve the light, quick to gather.
    explicit Scene(Mesh m)
        : mesh(std::move(m)), atlas(build_atlas(mesh, {}, AtlasOptions{.max_width = 256, .max_height = 256})),
          particles(build_particles(mesh, atlas)), rays(mesh) {}
};

// A floor (z = 0, facing up) under a square plate (z = h, facing down).
constexpr float kFloor = 2.0f, kPlate = 0.5f, kHeight = 0.5f;
Mesh floor_and_plate() {
    Mesh m = synth::make_quad({-kFloor, -kFloor, 0.0f}, {2 * kFloor, 0, 0}, {0, 2 * kFloor, 0});
    synth::append_mesh(m, synth::make_quad({-kPlate, -kPlate, kHeight}, {0, 2 * kPlate, 0}, {2 * kPlate, 0, 0}));
    return m;
}

TEST(IndirectTransfer, MatchesTheFormFactorOfAParallelRectangle) {
    const Scene s(floor_and_plate());
    TransferStats stats;
    const IndirectTransfer t = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 256, .block = 1}, &stats);
    validate_transfer(t);
    ASSERT_EQ(t.rows, s.particles.particles.size());
    EXPECT_TRUE(t.row_of.empty());
    EXPECT_EQ(t.rays_per_row, 256u);
    EXPECT_EQ(stats.back_faces, 0u);
    // The plate's particles shine (radiosity 1), the floor's do not.
    const std::size_t n = s.particles.particles.size();
    std::vector<glm::vec4> b(n, glm::vec4(0.0f));
    std::size_t plate = 0;
    for (std::size_t j = 0; j < n; ++j)
        if (s.particles.particles[j].n().z < -0.5f) {
            b[j] = glm::vec4(1.0f, 2.0f, 3.0f, 0.0f);
            ++plate;
        }
    ASSERT_GT(plate, 100u);
    std::vector<glm::vec4> e(n);
    gather_indirect_cpu(t, b, 1, e);
    double sum_error = 0.0, sum_square = 0.0, sum_truth = 0.0;
    std::size_t checked = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const Particle& p = s.particles.particles[i];
        if (p.n().z < 0.5f || p.is_gutter()) continue;
        const double f = rectangle_form_factor({p.p().x, p.p().y}, {-kPlate, -kPlate}, {kPlate, kPlate}, kHeight);
        // Per particle: 256 rays on a 16 x 16 grid of strata. The plate is a sharp-edged target:
        // the strata its edge crosses (up to about 4 x 16) each hit or miss by chance, a standard
        // deviation of up to sqrt(64 / 4) / 256 = 0.016; 0.07 is over 4 of them.
        EXPECT_NEAR(e[i].x, f, 0.07) << "floor particle at (" << p.p().x << ", " << p.p().y << ")";
        EXPECT_FLOAT_EQ(e[i].y, 2.0f * e[i].x);
        EXPECT_FLOAT_EQ(e[i].z, 3.0f * e[i].x);
        sum_error += e[i].x - f;
        sum_square += (e[i].x - f) * (e[i].x - f);
        sum_truth += f;
        ++checked;
    }
    ASSERT_GT(checked, 1000u);
    // Unbiased: over the floor the errors cancel to well under 1% of the light received, and
    // their spread stays within that bound on the standard deviation.
    EXPECT_LT(std::abs(sum_error) / sum_truth, 0.01);
    EXPECT_LT(std::sqrt(sum_square / static_cast<double>(checked)), 0.016);
}

// Blocks of 2 x 2 texels: each row holds the particles of one block of one chart, and its
// gathered light is the mean of what its particles gather on their own.
TEST(IndirectTransfer, ABlockGathersTheMeanOfItsParticles) {
    const Scene s(floor_and_plate());
    const std::span<const Particle> particles = s.particles.particles;
    const std::size_t n = particles.size();
    const IndirectTransfer fine = build_transfer(particles, s.mesh, s.rays, s.atlas, {.rays = 1024, .block = 1});
    const IndirectTransfer blocks = build_transfer(particles, s.mesh, s.rays, s.atlas, {.rays = 1024, .block = 2});
    validate_transfer(blocks);
    ASSERT_EQ(blocks.row_of.size(), n);
    // Between a quarter and all of the particles' count: blocks at a chart's edge hold fewer.
    EXPECT_GE(blocks.rows, n / 4);
    EXPECT_LT(blocks.rows, n / 2);
    std::vector<std::uint32_t> first(blocks.rows, Atlas::kEmpty), members(blocks.rows, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t r = blocks.row_of[i];
        ++members[r];
        if (first[r] == Atlas::kEmpty) {
            first[r] = static_cast<std::uint32_t>(i);
            continue;
        }
        const Particle &a = particles[first[r]], &b = particles[i];
        EXPECT_EQ(s.atlas.chart_of[a.triangle], s.atlas.chart_of[b.triangle]) << "particle " << i;
        EXPECT_EQ(a.texel_x() / 2, b.texel_x() / 2) << "particle " << i;
        EXPECT_EQ(a.texel_y() / 2, b.texel_y() / 2) << "particle " << i;
    }
    for (std::uint32_t r = 0; r < blocks.rows; ++r) EXPECT_LE(members[r], 4u) << "row " << r;
    // The rows' stand-ins for the light rays (complete_lit): each particle's row's first particle.
    const std::vector<std::uint32_t> stand_in = row_stand_ins(blocks);
    ASSERT_EQ(stand_in.size(), n);
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(stand_in[i], first[blocks.row_of[i]]) << "particle " << i;
    EXPECT_TRUE(row_stand_ins(fine).empty());
    // The plate shines: per particle on the fine transfer, per block on the other.
    std::vector<glm::vec4> b_fine(n, glm::vec4(0.0f)), b_block(blocks.rows, glm::vec4(0.0f));
    for (std::size_t j = 0; j < n; ++j)
        if (particles[j].n().z < -0.5f) {
            b_fine[j] = glm::vec4(1.0f);
            b_block[blocks.row_of[j]] += glm::vec4(1.0f / static_cast<float>(members[blocks.row_of[j]]));
        }
    std::vector<glm::vec4> e_fine(n), e_block(blocks.rows);
    gather_indirect_cpu(fine, b_fine, 1, e_fine);
    gather_indirect_cpu(blocks, b_block, 1, e_block);
    std::vector<double> mean(blocks.rows, 0.0);
    for (std::size_t i = 0; i < n; ++i) mean[blocks.row_of[i]] += e_fine[i].x / members[blocks.row_of[i]];
    double square = 0.0;
    std::size_t checked = 0;
    for (std::uint32_t r = 0; r < blocks.rows; ++r) {
        if (particles[first[r]].n().z < 0.5f) continue; // the floor's blocks
        // Both sides hold 1024 rays a row (a block's: 256 from each of 4 particles); the plate's
        // edge crosses up to about 4 x 32 of a row's strata: a deviation of up to sqrt(128 / 4) /
        // 1024 = 0.006 each, 0.03 is over 3 of both together.
        EXPECT_NEAR(e_block[r].x, mean[r], 0.03) << "row " << r;
        square += (e_block[r].x - mean[r]) * (e_block[r].x - mean[r]);
        ++checked;
    }
    ASSERT_GT(checked, 1000u);
    EXPECT_LT(std::sqrt(square / static_cast<double>(checked)), 0.006);
}

TEST(IndirectTransfer, IsTheSameForAnyThreadCount) {
    const Scene s(floor_and_plate());
    const IndirectTransfer a = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 16, .threads = 1});
    const IndirectTransfer b = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 16, .threads = 3});
    EXPECT_EQ(a.row_begin, b.row_begin);
    ASSERT_EQ(a.entries.size(), b.entries.size());
    for (std::size_t k = 0; k < a.entries.size(); ++k) {
        EXPECT_EQ(a.entries[k].source, b.entries[k].source);
        EXPECT_EQ(a.entries[k].weight, b.entries[k].weight);
    }
    // Another seed draws other rays.
    const IndirectTransfer c = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 16, .seed = 2});
    EXPECT_NE(a.row_begin, c.row_begin);
}

// The inside of a closed sphere of albedo rho, lit by a point light of intensity I at its centre:
// every point gets E0 = I / R^2, and every point sees the whole sphere, so each bounce is uniform:
// E_b = rho^b E0 (the geometric series of the sphere's form factor, 1 to the whole sphere).
Mesh inside_of_sphere(float radius) {
    Mesh m = synth::make_uv_sphere({0, 0, 0}, radius, 48, 24);
    for (glm::uvec3& t : m.triangles) std::swap(t.y, t.z);
    for (glm::vec3& n : m.normals) n = -n;
    return m;
}

Visibility all_lit(std::size_t particles, std::uint32_t frames) {
    Visibility v;
    v.particle_count = static_cast<std::uint32_t>(particles);
    v.frame_count = frames;
    v.view_count = 1;
    v.frame_words = (frames + 31) / 32;
    v.lit.assign(particles * v.frame_words, 0xFFFFFFFFu);
    v.seen.assign(particles, 1u);
    return v;
}

TEST(IndirectLight, BouncesInsideAClosedSphereAddUpToTheGeometricSeries) {
    const float radius = 2.0f;
    const Scene s(inside_of_sphere(radius));
    TransferStats stats;
    const IndirectTransfer t = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 16}, &stats);
    const std::size_t n = s.particles.particles.size();
    // Nearly every ray reaches a particle (a few land on the texels between charts).
    EXPECT_GT(static_cast<double>(stats.hits), 0.999 * static_cast<double>(stats.rays))
        << stats.rays << " rays, " << stats.hits << " hits, " << stats.unmapped << " unmapped, " << stats.back_faces
        << " back faces, " << stats.below_surface << " below";
    const Visibility vis = all_lit(n, 1);
    const std::vector<PointLight> lights = {PointLight{glm::dvec3(0.0), glm::dvec3(8.0, 4.0, 2.0), std::nullopt}};
    const std::vector<std::uint32_t> frame_view = {0};
    const std::vector<ViewAtlasMap> maps(1);
    const IndirectScene scene{.particles = s.particles.particles, .visibility = &vis, .lights = lights, .frame_view = frame_view,
                              .atlas = &s.atlas, .transfer = &t, .view_maps = maps};
    const glm::vec3 rho(0.6f, 0.5f, 0.4f);
    const std::vector<glm::vec3> albedo(n, rho);
    const std::size_t frame[] = {0};
    for (std::uint32_t bounces = 1; bounces <= 3; ++bounces) {
        const std::vector<glm::vec4> e = indirect_irradiance(scene, frame, albedo, std::nullopt, {.bounces = bounces});
        glm::dvec3 series(0.0), power(1.0);
        for (std::uint32_t b = 1; b <= bounces; ++b) {
            power *= glm::dvec3(rho);
            series += power;
        }
        const glm::dvec3 expected = series * glm::dvec3(8.0, 4.0, 2.0) / double(radius * radius);
        std::size_t off = 0;
        for (std::size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c)
                if (std::abs(e[i][c] - expected[c]) > 0.02 * expected[c]) ++off;
        // A uniform radiosity gathers exactly whatever the rays; what is left is the faceted
        // sphere's own: its flat triangles sit up to 0.2% inside the radius, with interpolated
        // normals a little off the centre, so E0 varies by about 1% over the particles.
        EXPECT_EQ(off, 0u) << bounces << " bounces";
        // The ratio of indirect to direct irradiance (r + g + b) the pipeline's rounds damp by.
        std::vector<float> ratio;
        indirect_images(scene, frame, albedo, std::nullopt, {.bounces = bounces}, [](std::size_t, const Image&) {}, &ratio);
        ASSERT_EQ(ratio.size(), n);
        const double expected_ratio = (expected.x + expected.y + expected.z) / (14.0 / double(radius * radius));
        std::size_t ratio_off = 0;
        for (const float r : ratio)
            if (std::abs(r - expected_ratio) > 0.02 * expected_ratio) ++ratio_off;
        EXPECT_EQ(ratio_off, 0u) << bounces << " bounces: ratio " << ratio[0] << ", expected " << expected_ratio;
    }
    // A frame whose lit bits hold only the particles its view sees (VisibilityOptions::
    // lit_seen_only, before complete_lit) is refused, not read as unlit emitters.
    Visibility partial = vis;
    partial.lit_complete.assign(1, 0);
    const IndirectScene incomplete{.particles = s.particles.particles, .visibility = &partial, .lights = lights,
                                   .frame_view = frame_view, .atlas = &s.atlas, .transfer = &t, .view_maps = maps};
    EXPECT_THROW((void)indirect_irradiance(incomplete, frame, albedo, std::nullopt, {.bounces = 1}), Error);
    partial.lit_complete.assign(1, 1);
    EXPECT_NO_THROW((void)indirect_irradiance(incomplete, frame, albedo, std::nullopt, {.bounces = 1}));
}

// The lobe's directional albedo at cosine c, by an independent quadrature: uniform random
// directions over the hemisphere (pdf 1 / 2 pi), the lobe evaluated in the tangent frame.
glm::dvec3 lobe_albedo(const LafortuneRgb& lobe, double c) {
    const glm::vec3 u(static_cast<float>(std::sqrt(1.0 - c * c)), 0.0f, static_cast<float>(c));
    glm::dvec3 sum(0.0);
    std::uint64_t state = 12345;
    const auto next = [&] {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return static_cast<double>(state >> 11) * (1.0 / 9007199254740992.0);
    };
    constexpr int kSamples = 400000;
    for (int i = 0; i < kSamples; ++i) {
        const double z = next(), phi = 2.0 * glm::pi<double>() * next(), r = std::sqrt(1.0 - z * z);
        const glm::vec3 w(static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
        sum += glm::dvec3(shared::lafortune_eval_rgb(lobe.cx, lobe.cz, lobe.n, u, w)) * z;
    }
    return sum * (2.0 * glm::pi<double>() / kSamples);
}

// With a lobe, each source also reflects its lobe's directional albedo a_s (spread diffusely):
// inside the sphere, lit from the centre (N.u = 1), B1 = (rho + a_s(1)) E0 and each later bounce
// multiplies by rho + a_s(2/3).
TEST(IndirectLight, ASourcesLobeAddsItsDirectionalAlbedo) {
    const float radius = 2.0f;
    const Scene s(inside_of_sphere(radius));
    const IndirectTransfer t = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 16});
    const std::size_t n = s.particles.particles.size();
    const Visibility vis = all_lit(n, 1);
    const std::vector<PointLight> lights = {PointLight{glm::dvec3(0.0), glm::dvec3(4.0), std::nullopt}};
    const std::vector<std::uint32_t> frame_view = {0};
    const std::vector<ViewAtlasMap> maps(1);
    const IndirectScene scene{.particles = s.particles.particles, .visibility = &vis, .lights = lights, .frame_view = frame_view,
                              .atlas = &s.atlas, .transfer = &t, .view_maps = maps};
    const LafortuneRgb lobe{.cx = glm::vec3(-1.0f), .cz = glm::vec3(0.8f, 0.85f, 0.9f), .n = glm::vec3(8.0f)};
    const double rho = 0.4;
    const std::vector<glm::vec3> albedo(n, glm::vec3(static_cast<float>(rho)));
    const std::size_t frame[] = {0};
    const std::vector<glm::vec4> e = indirect_irradiance(scene, frame, albedo, SpecularModel(lobe), {.bounces = 2});
    const glm::dvec3 a1 = lobe_albedo(lobe, 1.0), a23 = lobe_albedo(lobe, 2.0 / 3.0);
    ASSERT_GT(a1.x, 0.05); // the lobe reflects a fair share: the check can see it
    const glm::dvec3 e0(4.0 / (radius * radius));
    const glm::dvec3 expected = e0 * (glm::dvec3(rho) + a1) * (glm::dvec3(1.0) + glm::dvec3(rho) + a23);
    glm::dvec3 mean(0.0);
    for (std::size_t i = 0; i < n; ++i) mean += glm::dvec3(e[i]) / static_cast<double>(n);
    // The table's quadrature and interpolation against 400,000 random directions: within 1%; the
    // faceted sphere's E0 varies by about 1% (above), which the mean averages.
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], expected[c], 0.01 * expected[c]) << "channel " << c;
}

TEST(IndirectLight, ImagesShowTheLightOfTheSurfaceEachPixelSees) {
    const Scene s(floor_and_plate());
    const IndirectTransfer t = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 256});
    const std::size_t n = s.particles.particles.size();
    // A light far under the plate gives its underside a uniform irradiance E0 (it faces the light
    // at 1e4 times the plate's size: cos and distance are constant to 1e-4); the floor faces away
    // from it. So the floor gets rho E0 F from the plate, F the form factor above.
    const Visibility vis = all_lit(n, 1);
    const double e0 = 1.0;
    const std::vector<PointLight> lights = {PointLight{glm::dvec3(0.0, 0.0, -1e4), glm::dvec3(e0 * 1e8), std::nullopt}};
    const std::vector<std::uint32_t> frame_view = {0};
    const Camera camera(Intrinsics{64, 64, 60.0, 60.0, 32.0, 32.0},
                        look_at_camera_to_world({1.2, 0.3, 0.35}, {0.0, 0.0, 0.0}, {0, 0, 1}));
    const std::vector<ViewAtlasMap> maps = {build_view_atlas_map(camera, s.mesh, s.rays, s.atlas, s.particles.particles)};
    const IndirectScene scene{.particles = s.particles.particles, .visibility = &vis, .lights = lights, .frame_view = frame_view,
                              .atlas = &s.atlas, .transfer = &t, .view_maps = maps};
    const float rho = 0.5f;
    const std::vector<glm::vec3> albedo(n, glm::vec3(rho));
    const std::size_t frame[] = {0};
    Image image;
    indirect_images(scene, frame, albedo, std::nullopt, {.bounces = 1}, [&](std::size_t f, const Image& im) {
        EXPECT_EQ(f, 0u);
        image = im;
    });
    ASSERT_EQ(image.width, 64);
    // Each pixel that sees the floor shows rho / pi rho E0 F at the point its centre ray hits.
    std::size_t checked = 0;
    double sum_error = 0.0, sum_truth = 0.0;
    for (int y = 0; y < 64; y += 2)
        for (int x = 0; x < 64; x += 2) {
            const glm::dvec3 dir = camera.ray_direction(x + 0.5, y + 0.5);
            const std::optional<RayHit> hit = s.rays.intersect(glm::vec3(camera.center()), glm::vec3(dir), 0.0f, 1e30f);
            const std::size_t k = static_cast<std::size_t>(y) * 64 + static_cast<std::size_t>(x);
            EXPECT_EQ(hit.has_value(), maps[0].texel[k].x >= 0.0f);
            if (!hit) {
                EXPECT_EQ(image.at(x, y, 0), 0.0f);
                continue;
            }
            const glm::dvec3 point = camera.center() + static_cast<double>(hit->t) * dir;
            if (point.z > 0.1) continue; // the plate's top: nothing above it
            const double f = rectangle_form_factor({point.x, point.y}, {-kPlate, -kPlate}, {kPlate, kPlate}, kHeight);
            const double expected = rho / glm::pi<double>() * rho * e0 * f;
            // The form factor test's bound on a particle's F (0.07), in radiance; the 4 particles a
            // pixel mixes are nearer the truth than one.
            EXPECT_NEAR(image.at(x, y, 0), expected, rho / glm::pi<double>() * rho * e0 * 0.07) << "pixel " << x << ", " << y;
            sum_error += image.at(x, y, 0) - expected;
            sum_truth += expected;
            ++checked;
        }
    EXPECT_GT(checked, 200u);
    EXPECT_LT(std::abs(sum_error) / sum_truth, 0.02);
}

// A mirror-like lobe (Lafortune Cx = -1, Cz = 1: f_s = (r.v)^N, r the mirror of u) on the
// plate, lit straight up from far below (E0 = 1, u the plate's normal, so f_s = cos^N of the
// angle off it), and no diffuse part: the floor right under the plate gets its light, the floor
// that sees the plate at a slant little. A floor point at (x, y) gets
//     E = integral over the plate of (h / r)^N E0 (h / r) (h / r) / r^2 dA
// (cos at the plate = cos at the floor = h / r): the directed first bounce follows it; the
// spread one (a_s(1) E0 times the form factor) does not.
double mirror_lobe_irradiance(glm::dvec2 p, double exponent) {
    constexpr int kSteps = 200;
    const double step = 2.0 * kPlate / kSteps;
    double sum = 0.0;
    for (int i = 0; i < kSteps; ++i)
        for (int j = 0; j < kSteps; ++j) {
            const double x = -kPlate + (i + 0.5) * step - p.x, y = -kPlate + (j + 0.5) * step - p.y;
            const double r2 = x * x + y * y + double(kHeight) * kHeight, c = kHeight / std::sqrt(r2);
            sum += std::pow(c, exponent + 2.0) / r2 * step * step;
        }
    return sum;
}

TEST(IndirectLight, AGlossySourceSendsItsFirstBounceWhereItsLobePoints) {
    const Scene s(floor_and_plate());
    const IndirectTransfer t = build_transfer(s.particles.particles, s.mesh, s.rays, s.atlas, {.rays = 1024, .block = 2});
    ASSERT_EQ(t.entry_direction.size(), t.entries.size());
    const std::size_t n = s.particles.particles.size();
    const Visibility vis = all_lit(n, 1);
    const std::vector<PointLight> lights = {PointLight{glm::dvec3(0.0, 0.0, -1e4), glm::dvec3(1e8), std::nullopt}};
    const std::vector<std::uint32_t> frame_view = {0};
    const std::vector<ViewAtlasMap> maps(1);
    const IndirectScene scene{.particles = s.particles.particles, .visibility = &vis, .lights = lights, .frame_view = frame_view,
                              .atlas = &s.atlas, .transfer = &t, .view_maps = maps};
    constexpr float kExponent = 20.0f;
    const LafortuneRgb lobe{.cx = glm::vec3(-1.0f), .cz = glm::vec3(1.0f), .n = glm::vec3(kExponent)};
    const std::vector<glm::vec3> albedo(n, glm::vec3(0.0f));
    const std::size_t frame[] = {0};
    const std::vector<glm::vec4> directed = indirect_irradiance(scene, frame, albedo, SpecularModel(lobe), {.bounces = 1});
    const std::vector<glm::vec4> spread =
        indirect_irradiance(scene, frame, albedo, SpecularModel(lobe), {.bounces = 1, .lobe_directions = false});
    double directed_square = 0.0, spread_square = 0.0, truth_square = 0.0, directed_sum = 0.0, truth_sum = 0.0;
    std::size_t checked = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const Particle& p = s.particles.particles[i];
        if (p.n().z < 0.5f || p.is_gutter() || glm::length(glm::vec2(p.p())) > 1.0f || i % 8 != 0) continue;
        const double truth = mirror_lobe_irradiance({p.p().x, p.p().y}, kExponent);
        directed_square += (directed[i].x - truth) * (directed[i].x - truth);
        spread_square += (spread[i].x - truth) * (spread[i].x - truth);
        truth_square += truth * truth;
        directed_sum += directed[i].x;
        truth_sum += truth;
        ++checked;
    }
    ASSERT_GT(checked, 200u);
    const double directed_rms = std::sqrt(directed_square / truth_square), spread_rms = std::sqrt(spread_square / truth_square);
    std::printf("relative RMS error of the floor's irradiance: directed %.3f, spread %.3f\n", directed_rms, spread_rms);
    // The directed light is where the integral puts it: its total within 3%, and each point within
    // what 1024 rays a block leave (the lobe fills about 1/20 of a floor point's hemisphere, some 50
    // of its rays: ~15% each); the spread light, all of the lobe's over the form factor, is not.
    EXPECT_NEAR(directed_sum / truth_sum, 1.0, 0.03);
    EXPECT_LT(directed_rms, 0.2);
    EXPECT_GT(spread_rms, 2.0 * directed_rms);
}

} // namespace
} // namespace specula
