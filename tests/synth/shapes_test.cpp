// Procedural shapes and presets: well-formed meshes (no degenerate triangles,
// unit normals that agree with the winding, outward orientation), albedo and
// lobes in their stated ranges.
#include "core/error.h"
#include "synth/presets.h"
#include "synth/shapes.h"

#include <gtest/gtest.h>

#include <cmath>

namespace specula::synth {
namespace {

// Signed volume (divergence theorem): positive when triangles wind outward.
double signed_volume(const Mesh& m) {
    double v = 0.0;
    for (const glm::uvec3& t : m.triangles)
        v += glm::dot(glm::dvec3(m.positions[t.x]), glm::cross(glm::dvec3(m.positions[t.y]), glm::dvec3(m.positions[t.z]))) / 6.0;
    return v;
}

void expect_well_formed(const Mesh& m, const std::string& name) {
    ASSERT_FALSE(m.triangles.empty()) << name;
    ASSERT_EQ(m.normals.size(), m.positions.size()) << name;
    ASSERT_TRUE(m.has_texcoords()) << name;
    std::size_t disagree = 0;
    for (const glm::uvec3& t : m.triangles) {
        ASSERT_LT(std::max({t.x, t.y, t.z}), m.positions.size()) << name;
        const glm::vec3 c = glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x]);
        ASSERT_GT(glm::length(c), 0.0f) << name << ": degenerate triangle";
        if (glm::dot(c, m.normals[t.x] + m.normals[t.y] + m.normals[t.z]) <= 0.0f) ++disagree;
    }
    EXPECT_EQ(disagree, 0u) << name << ": triangles wound against their normals";
    for (const glm::vec3& n : m.normals) ASSERT_NEAR(glm::length(n), 1.0f, 1e-4f) << name;
    for (const glm::vec2& uv : m.texcoords) ASSERT_TRUE(std::isfinite(uv.x) && std::isfinite(uv.y) && uv.y >= 0.0f && uv.y <= 1.0f) << name;
}

TEST(Shapes, UvSphereHasExactRadialNormalsAndEnclosesItsVolume) {
    const Mesh m = make_uv_sphere(glm::vec3(1.0f, 2.0f, 3.0f), 0.5f, 64, 32);
    expect_well_formed(m, "sphere");
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        EXPECT_NEAR(glm::length(m.positions[i] - glm::vec3(1, 2, 3)), 0.5f, 1e-5f);
        EXPECT_LT(glm::length(m.normals[i] - (m.positions[i] - glm::vec3(1, 2, 3)) / 0.5f), 1e-4f);
    }
    // Volume about the origin is the same for a closed mesh; the tessellation is a bit smaller than the sphere.
    const double v = signed_volume(m), exact = 4.0 / 3.0 * M_PI * 0.125;
    EXPECT_LT(v, exact);
    EXPECT_GT(v, 0.98 * exact);
}

TEST(Shapes, RoundedBoxIsClosedAndOutward) {
    const Mesh m = make_rounded_box({0.4f, 0.5f, 0.2f}, 0.05f, 8, 4, UvRect{}, 0.01f);
    expect_well_formed(m, "rounded box");
    const double v = signed_volume(m);
    // Rounded box: inner box A x B x C grown by r: ABC + 2r(AB + BC + CA) + pi r^2 (A + B + C) + 4/3 pi r^3.
    const double r = 0.05, a = 2 * (0.4 - r), b = 2 * (0.5 - r), c = 2 * (0.2 - r);
    const double exact = a * b * c + 2 * r * (a * b + b * c + c * a) + M_PI * r * r * (a + b + c) + 4.0 / 3.0 * M_PI * r * r * r;
    EXPECT_LT(v, exact);
    EXPECT_GT(v, 0.999 * exact);
}

TEST(Presets, AreWellFormedWithAlbedoAndLobesInRange) {
    for (const PresetInfo& info : list_presets()) {
        SCOPED_TRACE(info.name);
        const Preset p = make_preset(info.name);
        expect_well_formed(p.mesh, info.name);
        EXPECT_GT(signed_volume(p.mesh), 0.0) << "inside out";
        const Image& a = p.material.albedo_texture;
        ASSERT_FALSE(a.empty());
        for (float v : a.pixels) {
            ASSERT_GE(v, 0.05f);
            ASSERT_LE(v, 0.9f);
        }
        // Near the thesis's table 5.2: Cx in [-1.5, -0.85], Cz in [-0.8, 1.2], N in [9, 21].
        for (int c = 0; c < 3; ++c) {
            EXPECT_GE(p.material.lobe.cx[c], -1.5f);
            EXPECT_LE(p.material.lobe.cx[c], -0.85f);
            EXPECT_GE(p.material.lobe.cz[c], -0.8f);
            EXPECT_LE(p.material.lobe.cz[c], 1.2f);
            EXPECT_GE(p.material.lobe.n[c], 9.0f);
            EXPECT_LE(p.material.lobe.n[c], 21.0f);
        }
        std::printf("preset %-10s %8zu triangles %8zu vertices\n", info.name.c_str(), p.mesh.triangle_count(), p.mesh.positions.size());
    }
    EXPECT_LT(make_preset("woodenpot").material.lobe.cz.x, 0.0f);
    EXPECT_GE(make_preset("knot_hd").mesh.triangle_count(), 100000u);
    EXPECT_TRUE(make_preset("can", /*lambertian=*/true).material.lobe.is_zero());
    EXPECT_THROW((void)make_preset("teapot"), UsageError);
}

} // namespace
} // namespace specula::synth
