#include "geometry/particles.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace specula {

namespace {

/// Below this length the blended normal of eq. 3.3 is taken as vanished.
constexpr double kMinBlendLength = 1e-6;

} // namespace

SurfacePoint surface_point(const Mesh& mesh, std::uint32_t triangle, const glm::dvec2& st) {
    const glm::uvec3 t = mesh.triangles[triangle];
    const double w0 = 1.0 - st.x - st.y, w1 = st.x, w2 = st.y;
    const glm::dvec3 p0(mesh.positions[t.x]), p1(mesh.positions[t.y]), p2(mesh.positions[t.z]);
    SurfacePoint sp;
    sp.position = glm::vec3(w0 * p0 + w1 * p1 + w2 * p2); // eq. 3.2
    glm::dvec3 n(0.0);
    if (mesh.normals.size() == mesh.positions.size())
        n = w0 * glm::dvec3(mesh.normals[t.x]) + w1 * glm::dvec3(mesh.normals[t.y]) + w2 * glm::dvec3(mesh.normals[t.z]); // eq. 3.3
    const double len = glm::length(n);
    if (len > kMinBlendLength && std::isfinite(len)) {
        sp.normal = glm::vec3(n / len);
    } else {
        const glm::dvec3 face = glm::cross(p1 - p0, p2 - p0);
        const double face_len = glm::length(face);
        sp.normal = face_len > 0.0 ? glm::vec3(face / face_len) : glm::vec3(0.0f, 0.0f, 1.0f);
        sp.used_face_normal = true;
    }
    return sp;
}

ParticleSet build_particles(const Mesh& mesh, const Atlas& atlas) {
    const std::size_t tri_count = mesh.triangles.size();
    if (atlas.corners.size() != 3 * tri_count) throw Error("particles: the atlas was built for another mesh");
    ParticleSet set;
    set.particles.reserve(std::size_t(double(atlas.width) * atlas.height * atlas.summary.fill_ratio) + 16);
    const auto emit = [&](std::uint32_t tri, std::uint32_t x, std::uint32_t y) {
        const glm::dvec2 center(x + 0.5, y + 0.5);
        const glm::dvec2 st_raw = atlas.patch_bary(tri, center);
        const bool gutter = !in_patch(st_raw);
        const glm::dvec2 st = gutter ? atlas.closest_bary(tri, center) : st_raw;
        const SurfacePoint sp = surface_point(mesh, tri, st);
        Particle particle;
        particle.position = glm::vec4(sp.position, 1.0f);
        particle.normal = glm::vec4(sp.normal, 0.0f);
        particle.bary = glm::vec2(st);
        particle.triangle = tri;
        particle.texel = pack_texel(x, y, gutter);
        set.particles.push_back(particle);
        ++(gutter ? set.gutter : set.interior);
        if (sp.used_face_normal) ++set.normal_fallbacks;
    };
    if (atlas.mode == AtlasMode::Charts) {
        // Chart by chart in placement order, rows then columns of its rectangle (a small
        // chart may sit in another's rectangle: a texel belongs to the chart of its owner).
        if (atlas.chart_of.size() != tri_count) throw Error("particles: the atlas was built for another mesh");
        for (std::uint32_t c = 0; c < atlas.charts.size(); ++c) {
            const ChartPlacement& r = atlas.charts[c];
            for (std::uint32_t y = r.y; y < r.y + r.height; ++y)
                for (std::uint32_t x = r.x; x < r.x + r.width; ++x) {
                    const std::uint32_t tri = atlas.owner_at(x, y);
                    if (tri != Atlas::kEmpty && atlas.chart_of[tri] == c) emit(tri, x, y);
                }
        }
        return set;
    }
    if (atlas.patches.size() != tri_count) throw Error("particles: the atlas was built for another mesh");
    std::vector<std::uint32_t> order(tri_count);
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
        const PatchPlacement &pa = atlas.patches[a], &pb = atlas.patches[b];
        if (pa.block_y != pb.block_y) return pa.block_y < pb.block_y;
        if (pa.block_x != pb.block_x) return pa.block_x < pb.block_x;
        return pa.half < pb.half;
    });
    for (std::uint32_t tri : order) {
        const PatchPlacement& p = atlas.patches[tri];
        const std::uint32_t w = p.size + Atlas::kBlockPadding;
        for (std::uint32_t y = p.block_y; y < p.block_y + w; ++y)
            for (std::uint32_t x = p.block_x; x < p.block_x + w; ++x)
                if (atlas.owner_at(x, y) == tri) emit(tri, x, y);
    }
    return set;
}

} // namespace specula
