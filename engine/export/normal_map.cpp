#include "export/normal_map.h"

#include "core/error.h"

#include <cmath>

namespace specula {

namespace {

// A unit vector orthogonal to unit n.
glm::vec3 any_orthogonal(const glm::vec3& n) {
    const glm::vec3 axis = std::abs(n.x) < 0.9f ? glm::vec3(1.0f, 0.0f, 0.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
    return glm::normalize(glm::cross(axis, n));
}

glm::vec3 normalized_or(const glm::vec3& v, const glm::vec3& fallback) {
    const float len = glm::length(v);
    return len > 1e-20f && std::isfinite(len) ? v / len : fallback;
}

} // namespace

std::vector<glm::vec4> vertex_tangents(const Mesh& mesh) {
    if (!mesh.has_texcoords()) throw Error("vertex_tangents: the mesh has no texture coordinates (one per vertex)");
    const std::vector<glm::vec3> normals = gltf_unit_normals(mesh);
    const std::size_t n = mesh.positions.size();
    std::vector<glm::dvec3> tan(n, glm::dvec3(0.0)), bit(n, glm::dvec3(0.0));
    for (const glm::uvec3& t : mesh.triangles) {
        const glm::dvec3 p0(mesh.positions[t.x]), p1(mesh.positions[t.y]), p2(mesh.positions[t.z]);
        const glm::dvec2 w0(mesh.texcoords[t.x]), w1(mesh.texcoords[t.y]), w2(mesh.texcoords[t.z]);
        const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
        const glm::dvec2 d1 = w1 - w0, d2 = w2 - w0;
        const double det = d1.x * d2.y - d2.x * d1.y;
        if (!(std::abs(det) > 0.0)) continue;
        // The directions of dp/du and dp/dv, weighted by the triangle's area.
        const double weight = glm::length(glm::cross(e1, e2));
        const glm::dvec3 dpdu = (e1 * d2.y - e2 * d1.y) / det, dpdv = (e2 * d1.x - e1 * d2.x) / det;
        for (int c = 0; c < 3; ++c) {
            tan[t[c]] += weight * glm::normalize(dpdu);
            bit[t[c]] += weight * glm::normalize(dpdv);
        }
    }
    std::vector<glm::vec4> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        const glm::vec3 nn = normals[i];
        const glm::vec3 t = glm::vec3(tan[i] - glm::dot(tan[i], glm::dvec3(nn)) * glm::dvec3(nn)); // Gram-Schmidt
        const glm::vec3 unit = normalized_or(t, any_orthogonal(nn));
        const float w = glm::dot(glm::cross(nn, unit), glm::vec3(bit[i])) < 0.0f ? -1.0f : 1.0f;
        out[i] = glm::vec4(unit, w);
    }
    return out;
}

TangentFrame tangent_frame_at(const Mesh& mesh, std::span<const glm::vec3> normals, std::span<const glm::vec4> tangents,
                              std::uint32_t tri, glm::vec2 bary) {
    const glm::uvec3 t = mesh.triangles[tri];
    const float w0 = 1.0f - bary.x - bary.y, w1 = bary.x, w2 = bary.y;
    // Per vertex, as a viewer's vertex shader passes them on: N, T and B = cross(N, T) w.
    glm::vec3 n(0.0f), tg(0.0f), b(0.0f);
    const float w[3] = {w0, w1, w2};
    for (int c = 0; c < 3; ++c) {
        const glm::vec3 vn = normals[t[c]];
        const glm::vec3 vt = glm::vec3(tangents[t[c]]);
        n += w[c] * vn;
        tg += w[c] * vt;
        b += w[c] * glm::cross(vn, vt) * tangents[t[c]].w;
    }
    TangentFrame f;
    f.n = normalized_or(n, f.n);
    f.t = normalized_or(tg, any_orthogonal(f.n));
    f.b = normalized_or(b, glm::cross(f.n, f.t));
    return f;
}

glm::vec3 encode_tangent_normal(const TangentFrame& frame, const glm::vec3& world) {
    const glm::mat3 m(frame.t, frame.b, frame.n); // columns
    const float det = glm::determinant(m);
    glm::vec3 c = std::abs(det) > 1e-6f ? glm::inverse(m) * world : glm::transpose(m) * world;
    c = normalized_or(c, glm::vec3(0.0f, 0.0f, 1.0f));
    return glm::clamp(0.5f * (c + 1.0f), 0.0f, 1.0f);
}

glm::vec3 decode_tangent_normal(const TangentFrame& frame, const glm::vec3& encoded) {
    const glm::vec3 c = 2.0f * encoded - 1.0f;
    return normalized_or(frame.t * c.x + frame.b * c.y + frame.n * c.z, frame.n);
}

} // namespace specula
