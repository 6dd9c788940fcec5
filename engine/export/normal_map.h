#pragma once
// Tangent-space normal maps for the bundle (glTF 2.0 material.normalTexture, section
// 3.9.3): what ordinary viewers show of the refined normals of a photometric rig.
//
// glTF's normal texture holds, per texel, a unit vector c in the tangent frame of the
// surface, stored as (c + 1) / 2 in linear RGB; a viewer takes the interpolated vertex
// normal N and tangent T (the TANGENT attribute: xyz, w = +-1), B = cross(N, T) w, each
// normalized per fragment, and shades with normalize(T c.x + B c.y + N c.z) (the Khronos
// sample viewer). So a world normal n is stored as c = normalize(inverse([T B N]) n): the
// same frame, inverted. Where a texel has no refined normal it holds (0, 0, 1), the mesh's
// own normal.
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace specula {

/// Per vertex of `mesh` (one texture coordinate per vertex): the tangent along +u of its
/// texture coordinates, area-weighted over its triangles, orthogonal to the vertex's written
/// normal (gltf_unit_normals) and unit; w = +1 when +v runs along cross(N, T), else -1.
/// Where the texture coordinates give no direction (degenerate), any unit vector orthogonal
/// to the normal, w = +1. Throws Error when the mesh has no texture coordinates.
[[nodiscard]] std::vector<glm::vec4> vertex_tangents(const Mesh& mesh);

/// The frame a viewer builds at barycentrics (s, t) (weights 1 - s - t, s, t) of triangle
/// `tri`: the interpolated normal, tangent and bitangent, each normalized.
struct TangentFrame {
    glm::vec3 t{1.0f, 0.0f, 0.0f};
    glm::vec3 b{0.0f, 1.0f, 0.0f};
    glm::vec3 n{0.0f, 0.0f, 1.0f};
};
[[nodiscard]] TangentFrame tangent_frame_at(const Mesh& mesh, std::span<const glm::vec3> normals,
                                            std::span<const glm::vec4> tangents, std::uint32_t tri, glm::vec2 bary);

/// The texel value (in [0, 1]^3) that a viewer decodes to the unit world normal `world`.
[[nodiscard]] glm::vec3 encode_tangent_normal(const TangentFrame& frame, const glm::vec3& world);
/// What a viewer shades with for the texel value `encoded`: normalize(T c.x + B c.y + N c.z).
[[nodiscard]] glm::vec3 decode_tangent_normal(const TangentFrame& frame, const glm::vec3& encoded);

} // namespace specula
