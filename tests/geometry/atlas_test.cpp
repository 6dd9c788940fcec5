// The patchwork atlas (engine/geometry/atlas.h, AtlasMode::Patchwork, the thesis's
// reference): bilinear filtering never crosses patches, shared edges agree, patch sizes
// follow the footprint and the budget clips as documented. (The chart atlas, the default:
// chart_atlas_test.cpp.)
#include "geometry/atlas.h"
#include "geometry/particles.h"

#include "core/error.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

namespace specula {
namespace {

Camera make_camera(glm::dvec3 eye, glm::dvec3 target, int size = 256, double fl = 300.0) {
    return Camera(Intrinsics{size, size, fl, fl, size / 2.0, size / 2.0}, look_at_camera_to_world(eye, target, {0, 1, 0}));
}

std::vector<Camera> ring_of_cameras(int count, double distance, int size = 256) {
    std::vector<Camera> cams;
    for (int i = 0; i < count; ++i) {
        const double a = 2.0 * 3.14159265358979 * i / count;
        cams.push_back(make_camera({distance * std::cos(a), 0.7 * distance * std::sin(3.0 * a), distance * std::sin(a)}, {0, 0, 0}, size));
    }
    return cams;
}

/// The patchwork, with the budget and other options of `o`.
AtlasOptions patchwork(AtlasOptions o = {}) {
    o.mode = AtlasMode::Patchwork;
    return o;
}

/// Texel coordinates of patch point (s, t) of a triangle.
glm::dvec2 patch_point(const Atlas& atlas, std::uint32_t tri, double s, double t) {
    const glm::dvec2 c0 = atlas.corner_texel(tri, 0), c1 = atlas.corner_texel(tri, 1), c2 = atlas.corner_texel(tri, 2);
    return c0 + s * (c1 - c0) + t * (c2 - c0);
}

/// The four texels bilinear filtering reads at texel-space point p (all four,
/// including those with zero weight). Returns false when one lies outside the atlas.
bool bilinear_taps_owned_by(const Atlas& atlas, glm::dvec2 p, std::uint32_t tri) {
    const double fx = std::floor(p.x - 0.5), fy = std::floor(p.y - 0.5);
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const double x = fx + dx, y = fy + dy;
            if (x < 0 || y < 0 || x >= atlas.width || y >= atlas.height) return false;
            if (atlas.owner_at(std::uint32_t(x), std::uint32_t(y)) != tri) return false;
        }
    return true;
}

void expect_no_bleeding(const Atlas& atlas, double margin) {
    std::size_t checked = 0, failures = 0;
    for (std::uint32_t tri = 0; tri < atlas.patches.size(); ++tri) {
        const int steps = int(4 * atlas.patches[tri].size) + 4; // finer than a texel
        for (int i = 0; i <= steps; ++i)
            for (int j = 0; i + j <= steps; ++j) {
                const glm::dvec2 p = patch_point(atlas, tri, double(i) / steps, double(j) / steps);
                for (const glm::dvec2 d : {glm::dvec2(0, 0), glm::dvec2(margin, margin), glm::dvec2(-margin, margin),
                                           glm::dvec2(margin, -margin), glm::dvec2(-margin, -margin)}) {
                    ++checked;
                    if (!bilinear_taps_owned_by(atlas, p + d, tri) && ++failures < 10)
                        ADD_FAILURE() << "triangle " << tri << " (leg " << atlas.patches[tri].size << ", half "
                                      << atlas.patches[tri].half << ") reads a foreign texel at (" << p.x + d.x << ", " << p.y + d.y << ")";
                }
            }
    }
    EXPECT_EQ(failures, 0u) << "of " << checked << " bilinear lookups";
}

TEST(Atlas, BilinearInsideAPatchReadsOnlyItsOwnTexels) {
    // Patch legs from 1 texel up, both halves of a block, blocks of different sizes side by side.
    const Mesh mesh = test::sphere(1.0f, 8, 12);
    for (const int size : {64, 256, 1024}) {
        const Atlas atlas = build_atlas(mesh, ring_of_cameras(3, 4.0, size), patchwork());
        SCOPED_TRACE("image size " + std::to_string(size) + ": " + describe(atlas.summary));
        expect_no_bleeding(atlas, 0.0);
        // The footprints keep 0.25 texel from every foreign texel: survive GPU sub-texel rounding.
        expect_no_bleeding(atlas, 0.2);
    }
}

TEST(Atlas, SmallestPatchesDoNotBleedEither) {
    const Mesh mesh = test::sphere(1.0f, 6, 8);
    for (std::uint32_t leg : {1u, 2u, 3u}) {
        AtlasOptions o;
        o.min_patch = o.max_patch = leg;
        const Atlas atlas = build_atlas(mesh, {}, patchwork(o));
        for (const PatchPlacement& p : atlas.patches) EXPECT_EQ(p.size, leg);
        expect_no_bleeding(atlas, 0.2);
    }
}

TEST(Atlas, BlocksHoldTwoHalvesSeparatedAcrossTheDiagonal) {
    const Mesh mesh = test::box({0, 0, 0}, {1, 1, 1});
    AtlasOptions o;
    o.min_patch = o.max_patch = 6;
    const Atlas atlas = build_atlas(mesh, {}, patchwork(o));
    ASSERT_EQ(atlas.summary.blocks, 6u);
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> halves;
    for (const PatchPlacement& p : atlas.patches) halves[{p.block_x, p.block_y}] += 1 << p.half;
    for (const auto& [origin, mask] : halves) EXPECT_EQ(mask, 3) << "each block holds a lower and an upper half";
    // Along the block's anti-diagonal band x + y = n + 4 no texel is owned.
    const PatchPlacement& p = atlas.patches[0];
    for (std::uint32_t i = 0; i < p.size + Atlas::kBlockPadding; ++i) {
        const std::int64_t j = std::int64_t(p.size) + 3 - i; // centers (i + .5) + (j + .5) = n + 4
        if (j < 0 || j >= std::int64_t(p.size + Atlas::kBlockPadding)) continue;
        EXPECT_EQ(atlas.owner_at(p.block_x + i, p.block_y + std::uint32_t(j)), Atlas::kEmpty);
    }
}

TEST(Atlas, CornerUvsAreNormalizedCornerTexels) {
    const Mesh mesh = test::sphere(1.0f, 6, 8);
    const Atlas atlas = build_atlas(mesh, ring_of_cameras(2, 3.0), patchwork());
    ASSERT_EQ(atlas.corner_uv.size(), 3 * mesh.triangles.size());
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const glm::vec2 uv = atlas.corner_uv[3 * t + k];
            const glm::dvec2 c = atlas.corner_texel(t, k);
            EXPECT_GT(uv.x, 0.0f);
            EXPECT_LT(uv.x, 1.0f);
            EXPECT_GT(uv.y, 0.0f);
            EXPECT_LT(uv.y, 1.0f);
            EXPECT_NEAR(uv.x * atlas.width, c.x, 1e-3);
            EXPECT_NEAR(uv.y * atlas.height, c.y, 1e-3);
        }
    // Corners map to the vertices: (s, t) of corner k is (0,0), (1,0), (0,1).
    const glm::dvec2 expected[3] = {{0, 0}, {1, 0}, {0, 1}};
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 st = atlas.patch_bary(t, atlas.corner_texel(t, k));
            EXPECT_NEAR(st.x, expected[k].x, 1e-12);
            EXPECT_NEAR(st.y, expected[k].y, 1e-12);
        }
}

TEST(Atlas, SharedEdgesMapToTheSamePointsFromBothSides) {
    const Mesh mesh = test::sphere(1.0f, 10, 14); // shared vertex indices
    const Atlas atlas = build_atlas(mesh, ring_of_cameras(4, 3.0), patchwork());
    std::map<std::pair<unsigned, unsigned>, std::vector<std::pair<std::uint32_t, int>>> edges; // -> (triangle, local edge)
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const unsigned a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
            edges[{std::min(a, b), std::max(a, b)}].push_back({t, k});
        }
    std::size_t shared = 0;
    for (const auto& [key, uses] : edges) {
        ASSERT_EQ(uses.size(), 2u);
        ++shared;
        for (double lambda : {0.0, 0.125, 0.5, 0.8, 1.0}) {
            glm::vec3 points[2];
            for (int side = 0; side < 2; ++side) {
                const auto [t, k] = uses[side];
                // Walk the edge from the vertex key.first to key.second in this triangle's patch.
                int from = k, to = (k + 1) % 3;
                if (mesh.triangles[t][from] != key.first) std::swap(from, to);
                const glm::dvec2 p = (1.0 - lambda) * atlas.corner_texel(t, from) + lambda * atlas.corner_texel(t, to);
                points[side] = surface_point(mesh, t, clamp_to_triangle(atlas.patch_bary(t, p))).position;
            }
            EXPECT_LT(glm::length(points[0] - points[1]), 1e-6f) << "edge " << key.first << "-" << key.second << " at " << lambda;
        }
    }
    EXPECT_GT(shared, 100u);
}

/// Four triangles facing +Z at z = 0: two with legs `big`, two with legs `small`.
Mesh four_triangles(float big, float small) {
    Mesh m;
    test::add_triangle(m, {-3, 0, 0}, {-3 + big, 0, 0}, {-3, big, 0}, {0, 0, 1});
    test::add_triangle(m, {-1, 0, 0}, {-1 + big, 0, 0}, {-1, big, 0}, {0, 0, 1});
    test::add_triangle(m, {1, 0, 0}, {1 + small, 0, 0}, {1, small, 0}, {0, 0, 1});
    test::add_triangle(m, {2, 0, 0}, {2 + small, 0, 0}, {2, small, 0}, {0, 0, 1});
    return m;
}

TEST(Atlas, PatchSizeFollowsThePixelFootprint) {
    const Mesh mesh = four_triangles(0.4f, 0.2f); // the big ones cover 4x the pixels
    const std::vector<Camera> cams = {make_camera({0, 0, 5}, {0, 0, 0}, 512, 400.0)};
    const std::vector<double> pixels = best_pixel_footprint(mesh, cams);
    // Orthographic-like estimate: leg 0.4 at distance 5 with fl 400 -> 32 pixels, area 512.
    EXPECT_NEAR(pixels[0], 0.5 * 32.0 * 32.0, 0.5 * 32.0 * 32.0 * 0.02);
    EXPECT_NEAR(pixels[0] / pixels[2], 4.0, 0.05);

    const Atlas atlas = build_atlas(mesh, cams, patchwork());
    EXPECT_EQ(atlas.summary.size_source, "cameras");
    EXPECT_FALSE(atlas.summary.budget_clipped);
    // n^2 / 2 texels = pixels (texels_per_pixel 1): leg = sqrt(2 * pixels).
    EXPECT_EQ(atlas.patches[0].size, std::uint32_t(std::lround(std::sqrt(2.0 * pixels[0]))));
    EXPECT_EQ(atlas.patches[2].size, std::uint32_t(std::lround(std::sqrt(2.0 * pixels[2]))));
    EXPECT_GT(atlas.patches[0].size, atlas.patches[2].size);
    EXPECT_NEAR(double(atlas.patches[0].size) / atlas.patches[2].size, 2.0, 0.1);

    // A texel per 4 pixels halves the legs.
    AtlasOptions coarse;
    coarse.texels_per_pixel = 0.25;
    const Atlas half = build_atlas(mesh, cams, patchwork(coarse));
    EXPECT_NEAR(double(half.patches[0].size), atlas.patches[0].size / 2.0, 1.0);

    // A triangle no camera sees gets the minimum patch and is counted.
    const std::vector<Camera> behind = {make_camera({0, 0, -5}, {0, 0, 0}, 512, 400.0)};
    const Atlas unseen = build_atlas(mesh, behind, patchwork());
    EXPECT_EQ(unseen.summary.triangles_seen_by_no_camera, 4u);
    for (const PatchPlacement& p : unseen.patches) EXPECT_EQ(p.size, 1u);
}

TEST(Atlas, BudgetScalesAllPatchesDownAndSaysSo) {
    const Mesh mesh = four_triangles(0.4f, 0.2f);
    const std::vector<Camera> cams = {make_camera({0, 0, 5}, {0, 0, 0}, 512, 400.0)};
    const Atlas free = build_atlas(mesh, cams, patchwork());
    ASSERT_FALSE(free.summary.budget_clipped);
    EXPECT_EQ(free.summary.budget_scale, 1.0);
    EXPECT_TRUE(free.summary.notes.empty());

    AtlasOptions tight;
    tight.max_width = 40;
    tight.max_height = 40;
    const Atlas clipped = build_atlas(mesh, cams, patchwork(tight));
    EXPECT_TRUE(clipped.summary.budget_clipped);
    EXPECT_LT(clipped.summary.budget_scale, 1.0);
    EXPECT_LE(clipped.width, 40u);
    EXPECT_LE(clipped.height, 40u);
    ASSERT_FALSE(clipped.summary.notes.empty());
    EXPECT_NE(clipped.summary.notes[0].find("budget"), std::string::npos);
    EXPECT_NE(describe(clipped.summary).find("CLIPPED"), std::string::npos);
    // Every leg is the desired one times the same factor (up to rounding): the big ones stay twice the small ones.
    EXPECT_LT(clipped.patches[0].size, free.patches[0].size);
    EXPECT_NEAR(double(clipped.patches[0].size), clipped.summary.budget_scale * std::sqrt(2.0 * best_pixel_footprint(mesh, cams)[0]), 0.5 + 1e-9);
    EXPECT_GT(clipped.patches[0].size, clipped.patches[2].size);
    expect_no_bleeding(clipped, 0.2);

    AtlasOptions impossible;
    impossible.max_width = impossible.max_height = 8;
    EXPECT_THROW((void)build_atlas(test::sphere(1.0f, 20, 20), cams, patchwork(impossible)), Error);
}

TEST(Atlas, WithoutCamerasPatchAreaFollowsSurfaceArea) {
    const Mesh mesh = four_triangles(0.4f, 0.2f);
    AtlasOptions o;
    o.max_width = o.max_height = 256;
    const Atlas atlas = build_atlas(mesh, {}, patchwork(o));
    EXPECT_EQ(atlas.summary.size_source, "surface area");
    EXPECT_FALSE(atlas.summary.budget_clipped);
    EXPECT_LE(atlas.width, 256u);
    EXPECT_LE(atlas.height, 256u);
    EXPECT_NEAR(double(atlas.patches[0].size) / atlas.patches[2].size, 2.0, 0.1);
    // It fills a good part of the budget.
    EXPECT_GT(double(atlas.width) * atlas.height, 0.5 * 256 * 256);
}

TEST(Atlas, SummaryCountsTexels) {
    const Mesh mesh = test::sphere(1.0f, 8, 12);
    const Atlas atlas = build_atlas(mesh, ring_of_cameras(3, 4.0), patchwork());
    const AtlasSummary& s = atlas.summary;
    std::size_t owned = 0;
    for (std::uint32_t o : atlas.owner) owned += o != Atlas::kEmpty;
    EXPECT_EQ(owned, s.interior_texels + s.gutter_texels);
    EXPECT_NEAR(s.fill_ratio, double(owned) / (double(atlas.width) * atlas.height), 1e-12);
    EXPECT_LE(s.patch_min, s.patch_median);
    EXPECT_LE(s.patch_median, s.patch_max);
    EXPECT_EQ(s.triangles, mesh.triangles.size());
    EXPECT_EQ(s.blocks, (mesh.triangles.size() + 1) / 2);
    EXPECT_FALSE(describe(s).empty());
}

TEST(Atlas, ClampToTriangleIsTheClosestPoint) {
    EXPECT_EQ(clamp_to_triangle({0.2, 0.3}), glm::dvec2(0.2, 0.3));
    EXPECT_EQ(clamp_to_triangle({-0.5, 0.3}), glm::dvec2(0.0, 0.3));
    EXPECT_EQ(clamp_to_triangle({0.4, -1.0}), glm::dvec2(0.4, 0.0));
    EXPECT_EQ(clamp_to_triangle({-1.0, -1.0}), glm::dvec2(0.0, 0.0));
    const glm::dvec2 h = clamp_to_triangle({0.8, 0.6});
    EXPECT_NEAR(h.x, 0.6, 1e-12);
    EXPECT_NEAR(h.y, 0.4, 1e-12);
    EXPECT_EQ(clamp_to_triangle({2.0, -0.5}), glm::dvec2(1.0, 0.0));
}

} // namespace
} // namespace specula
