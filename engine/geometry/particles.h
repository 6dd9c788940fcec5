#pragma once
// Surface particles (thesis section 3.1.2): one per used atlas texel, interior
// and gutter. A texel with patch coordinates (s, t) (clamped to the triangle
// for gutter texels, see atlas.h) is the particle
//     P = (1 - s - t) v0 + s v1 + t v2                       (eq. 3.2)
//     N = normalize((1 - s - t) n0 + s n1 + t n2)            (eq. 3.3)
// with the face normal as fallback where the blend vanishes (opposed vertex
// normals). The tangent frame is shared::to_tangent_frame(N, .) (appendix B,
// shaders/shared/tangent_frame.h), so the GPU computes the same one.
#include "geometry/atlas.h"

#include "shared/tangent_frame.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace specula {

/// One particle, laid out for a std430 storage buffer (array stride 48 bytes):
///   struct Particle { vec4 position; vec4 normal; vec2 bary; uint triangle; uint texel; };
struct Particle {
    glm::vec4 position{0.0f, 0.0f, 0.0f, 1.0f}; ///< xyz: eq. 3.2 (world); w = 1
    glm::vec4 normal{0.0f, 0.0f, 1.0f, 0.0f};   ///< xyz: eq. 3.3, unit; w = 0
    glm::vec2 bary{0.0f};                       ///< (s, t) used for eq. 3.2/3.3 (clamped for gutter texels)
    std::uint32_t triangle = 0;                 ///< index into Mesh::triangles
    std::uint32_t texel = 0;                    ///< bits 0-14: x, 15-29: y, 31: gutter (see pack_texel)

    static constexpr std::uint32_t kGutterBit = 1u << 31;

    [[nodiscard]] std::uint32_t texel_x() const noexcept { return texel & 0x7FFFu; }
    [[nodiscard]] std::uint32_t texel_y() const noexcept { return (texel >> 15) & 0x7FFFu; }
    [[nodiscard]] bool is_gutter() const noexcept { return (texel & kGutterBit) != 0; }
    [[nodiscard]] glm::vec3 p() const noexcept { return glm::vec3(position); }
    [[nodiscard]] glm::vec3 n() const noexcept { return glm::vec3(normal); }
    /// A world direction in the particle's tangent frame (appendix B; z = normal).
    [[nodiscard]] glm::vec3 to_local(const glm::vec3& w) const { return shared::to_tangent_frame(n(), w); }
};
static_assert(sizeof(Particle) == 48, "std430 array stride of Particle");
static_assert(offsetof(Particle, normal) == 16 && offsetof(Particle, bary) == 32 && offsetof(Particle, triangle) == 40 &&
              offsetof(Particle, texel) == 44, "std430 offsets of Particle");

[[nodiscard]] constexpr std::uint32_t pack_texel(std::uint32_t x, std::uint32_t y, bool gutter) noexcept {
    return (x & 0x7FFFu) | ((y & 0x7FFFu) << 15) | (gutter ? Particle::kGutterBit : 0u);
}

struct ParticleSet {
    std::vector<Particle> particles; ///< patchwork: triangle by triangle in placement order (shelf, block, half), then texel
                                     ///< row, column; charts: chart by chart in placement order, then texel row, column
    std::size_t interior = 0;
    std::size_t gutter = 0;
    std::size_t normal_fallbacks = 0; ///< particles whose blended normal vanished (face normal used)
};

/// Eq. 3.2 and 3.3 for one point (s, t) of one triangle. Returns the position and the unit normal.
struct SurfacePoint {
    glm::vec3 position;
    glm::vec3 normal;
    bool used_face_normal = false;
};
[[nodiscard]] SurfacePoint surface_point(const Mesh& mesh, std::uint32_t triangle, const glm::dvec2& st);

/// One particle per owned texel of the atlas. Uses the mesh's vertex normals
/// when present (one per position), else the face normals.
[[nodiscard]] ParticleSet build_particles(const Mesh& mesh, const Atlas& atlas);

} // namespace specula
