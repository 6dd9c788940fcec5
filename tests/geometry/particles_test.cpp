// Surface particles (engine/geometry/particles.h): eq. 3.2 / 3.3, one per
// owned texel, gutters on the triangle's boundary, the appendix-B frame; on the
// patchwork atlas (the chart atlas's particles: chart_atlas_test.cpp).
#include "geometry/particles.h"

#include "test_meshes.h"

#include <gtest/gtest.h>

#include <set>

namespace specula {
namespace {

std::vector<Camera> two_cameras() {
    const Intrinsics k{256, 256, 300.0, 300.0, 128.0, 128.0};
    return {Camera(k, look_at_camera_to_world({0, 0, 3}, {0, 0, 0}, {0, 1, 0})),
            Camera(k, look_at_camera_to_world({3, 1, -1}, {0, 0, 0}, {0, 1, 0}))};
}

TEST(Particles, PositionsAndNormalsFollowEq32And33) {
    // Perturbed vertex normals, so that eq. 3.3 differs from the radial normal.
    Mesh mesh = test::sphere(1.0f, 8, 10);
    for (std::size_t i = 0; i < mesh.normals.size(); ++i)
        mesh.normals[i] = glm::normalize(mesh.normals[i] + 0.2f * glm::vec3(std::sin(float(i)), std::cos(3.0f * float(i)), 0.0f));
    const Atlas atlas = build_atlas(mesh, two_cameras(), {.mode = AtlasMode::Patchwork});
    const ParticleSet set = build_particles(mesh, atlas);
    ASSERT_FALSE(set.particles.empty());
    for (const Particle& p : set.particles) {
        const glm::uvec3 t = mesh.triangles[p.triangle];
        const float s = p.bary.x, tt = p.bary.y;
        const glm::vec3 expected_p = (1.0f - s - tt) * mesh.positions[t.x] + s * mesh.positions[t.y] + tt * mesh.positions[t.z];
        const glm::vec3 blend = (1.0f - s - tt) * mesh.normals[t.x] + s * mesh.normals[t.y] + tt * mesh.normals[t.z];
        EXPECT_LT(glm::length(p.p() - expected_p), 1e-5f);
        EXPECT_LT(glm::length(p.n() - glm::normalize(blend)), 1e-5f);
        EXPECT_NEAR(glm::length(p.n()), 1.0f, 1e-5f);
        EXPECT_EQ(p.position.w, 1.0f);
        EXPECT_EQ(p.normal.w, 0.0f);
        // Interior texels: (s, t) is the texel center's own patch coordinate.
        if (!p.is_gutter()) {
            const glm::dvec2 st = atlas.patch_bary(p.triangle, {p.texel_x() + 0.5, p.texel_y() + 0.5});
            EXPECT_NEAR(st.x, s, 1e-6);
            EXPECT_NEAR(st.y, tt, 1e-6);
        }
    }
    EXPECT_EQ(set.normal_fallbacks, 0u);
}

TEST(Particles, OneParticlePerOwnedTexel) {
    const Mesh mesh = test::sphere(1.0f, 8, 10);
    const Atlas atlas = build_atlas(mesh, two_cameras(), {.mode = AtlasMode::Patchwork});
    const ParticleSet set = build_particles(mesh, atlas);
    EXPECT_EQ(set.particles.size(), atlas.summary.interior_texels + atlas.summary.gutter_texels);
    EXPECT_EQ(set.interior, atlas.summary.interior_texels);
    EXPECT_EQ(set.gutter, atlas.summary.gutter_texels);
    std::set<std::pair<std::uint32_t, std::uint32_t>> texels;
    std::vector<int> per_triangle(mesh.triangles.size(), 0);
    for (const Particle& p : set.particles) {
        EXPECT_TRUE(texels.insert({p.texel_x(), p.texel_y()}).second) << "texel used twice";
        EXPECT_EQ(atlas.owner_at(p.texel_x(), p.texel_y()), p.triangle);
        const bool inside = in_patch(atlas.patch_bary(p.triangle, {p.texel_x() + 0.5, p.texel_y() + 0.5}));
        EXPECT_EQ(p.is_gutter(), !inside);
        ++per_triangle[p.triangle];
    }
    for (int n : per_triangle) EXPECT_GT(n, 0) << "every triangle has particles";
}

TEST(Particles, GutterParticlesLieOnTheTriangleBoundary) {
    const Mesh mesh = test::sphere(1.0f, 8, 10);
    const ParticleSet set = build_particles(mesh, build_atlas(mesh, two_cameras(), {.mode = AtlasMode::Patchwork}));
    std::size_t gutters = 0;
    for (const Particle& p : set.particles) {
        if (!p.is_gutter()) continue;
        ++gutters;
        const float s = p.bary.x, t = p.bary.y;
        EXPECT_GE(s, 0.0f);
        EXPECT_GE(t, 0.0f);
        EXPECT_LE(s + t, 1.0f + 1e-6f);
        const float to_boundary = std::min({s, t, std::abs(1.0f - s - t)});
        EXPECT_LT(to_boundary, 1e-6f);
    }
    EXPECT_GT(gutters, 0u);
}

TEST(Particles, FallsBackToTheFaceNormalWhenTheBlendVanishes) {
    Mesh mesh;
    test::add_triangle(mesh, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1});
    mesh.normals[1] = {0, 0, -1}; // n0 + n1 cancel half-way along the edge v0-v1
    const SurfacePoint mid = surface_point(mesh, 0, {0.5, 0.0});
    EXPECT_TRUE(mid.used_face_normal);
    EXPECT_LT(glm::length(mid.normal - glm::vec3(0, 0, 1)), 1e-6f);
    const SurfacePoint near_v2 = surface_point(mesh, 0, {0.1, 0.8});
    EXPECT_FALSE(near_v2.used_face_normal);
    EXPECT_NEAR(glm::length(near_v2.normal), 1.0f, 1e-6f);
}

TEST(Particles, TangentFrameHasTheNormalAsZ) {
    const Mesh mesh = test::sphere(1.0f, 6, 8);
    const ParticleSet set = build_particles(mesh, build_atlas(mesh, two_cameras(), {.mode = AtlasMode::Patchwork}));
    for (const Particle& p : set.particles) {
        const glm::vec3 z = p.to_local(p.n());
        EXPECT_NEAR(z.z, 1.0f, 1e-5f);
        EXPECT_NEAR(z.x, 0.0f, 1e-5f);
        EXPECT_NEAR(z.y, 0.0f, 1e-5f);
        // Orthonormal: lengths are preserved.
        const glm::vec3 w(0.3f, -0.5f, 0.8f);
        EXPECT_NEAR(glm::length(p.to_local(w)), glm::length(w), 1e-5f);
    }
}

TEST(Particles, TexelPackingRoundTrips) {
    Particle p;
    p.texel = pack_texel(32767, 12345, true);
    EXPECT_EQ(p.texel_x(), 32767u);
    EXPECT_EQ(p.texel_y(), 12345u);
    EXPECT_TRUE(p.is_gutter());
    p.texel = pack_texel(7, 32767, false);
    EXPECT_EQ(p.texel_x(), 7u);
    EXPECT_EQ(p.texel_y(), 32767u);
    EXPECT_FALSE(p.is_gutter());
}

} // namespace
} // namespace specula
