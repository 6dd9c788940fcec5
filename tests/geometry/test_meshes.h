#pragma once
// Small procedural meshes for the geometry and visibility tests (outward,
// counter-clockwise triangles; unit normals per vertex).
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <cmath>
#include <numbers>

namespace specula::test {

/// Appends a flat quad a-b-c-d (a polygon in order) with outward normal n; the
/// triangles are wound counter-clockwise about n whichever way the corners run.
inline void add_quad(Mesh& m, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, glm::vec3 n) {
    if (glm::dot(glm::cross(b - a, c - a), n) < 0.0f) std::swap(b, d);
    const auto base = static_cast<unsigned>(m.positions.size());
    for (const glm::vec3& p : {a, b, c, d}) {
        m.positions.push_back(p);
        m.normals.push_back(glm::normalize(n));
    }
    m.triangles.emplace_back(base, base + 1, base + 2);
    m.triangles.emplace_back(base, base + 2, base + 3);
}

/// Appends a flat triangle with normal n (wound counter-clockwise about n).
inline void add_triangle(Mesh& m, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 n) {
    if (glm::dot(glm::cross(b - a, c - a), n) < 0.0f) std::swap(b, c);
    const auto base = static_cast<unsigned>(m.positions.size());
    for (const glm::vec3& p : {a, b, c}) {
        m.positions.push_back(p);
        m.normals.push_back(glm::normalize(n));
    }
    m.triangles.emplace_back(base, base + 1, base + 2);
}

/// Closed axis-aligned box, 12 triangles, face normals (24 vertices).
inline Mesh box(glm::vec3 lo, glm::vec3 hi) {
    Mesh m;
    const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                            {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
    add_quad(m, c[0], c[3], c[2], c[1], {0, 0, -1});
    add_quad(m, c[4], c[5], c[6], c[7], {0, 0, 1});
    add_quad(m, c[0], c[1], c[5], c[4], {0, -1, 0});
    add_quad(m, c[3], c[7], c[6], c[2], {0, 1, 0});
    add_quad(m, c[0], c[4], c[7], c[3], {-1, 0, 0});
    add_quad(m, c[1], c[2], c[6], c[5], {1, 0, 0});
    return m;
}

/// UV sphere: poles plus (rings - 1) rings of `segments` shared vertices;
/// 2 * segments * (rings - 1) triangles, closed and convex, normals = radial.
inline Mesh sphere(float radius, int rings, int segments, glm::vec3 center = glm::vec3(0.0f)) {
    Mesh m;
    const double pi = std::numbers::pi;
    m.positions.push_back(center + glm::vec3(0, radius, 0));
    m.normals.emplace_back(0, 1, 0);
    for (int r = 1; r < rings; ++r) {
        const double theta = pi * r / rings;
        for (int s = 0; s < segments; ++s) {
            const double phi = 2.0 * pi * s / segments;
            const glm::vec3 n(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)), float(-std::sin(theta) * std::sin(phi)));
            m.positions.push_back(center + radius * n);
            m.normals.push_back(n);
        }
    }
    m.positions.push_back(center + glm::vec3(0, -radius, 0));
    m.normals.emplace_back(0, -1, 0);
    const auto south = static_cast<unsigned>(m.positions.size() - 1);
    auto ring = [&](int r, int s) { return static_cast<unsigned>(1 + (r - 1) * segments + (s % segments)); };
    for (int s = 0; s < segments; ++s) m.triangles.emplace_back(0u, ring(1, s), ring(1, s + 1));
    for (int r = 1; r + 1 < rings; ++r)
        for (int s = 0; s < segments; ++s) {
            m.triangles.emplace_back(ring(r, s), ring(r + 1, s), ring(r + 1, s + 1));
            m.triangles.emplace_back(ring(r, s), ring(r + 1, s + 1), ring(r, s + 1));
        }
    for (int s = 0; s < segments; ++s) m.triangles.emplace_back(south, ring(rings - 1, s + 1), ring(rings - 1, s));
    return m;
}

/// Torus around +Y: 2 * nu * nv triangles, closed, not convex.
inline Mesh torus(float major, float minor, int nu, int nv) {
    Mesh m;
    const double pi = std::numbers::pi;
    for (int i = 0; i < nu; ++i) {
        const double u = 2.0 * pi * i / nu;
        const glm::dvec3 dir(std::cos(u), 0.0, -std::sin(u));
        for (int j = 0; j < nv; ++j) {
            const double v = 2.0 * pi * j / nv;
            const glm::dvec3 n = std::cos(v) * dir + glm::dvec3(0.0, std::sin(v), 0.0);
            m.positions.emplace_back(double(major) * dir + double(minor) * n);
            m.normals.emplace_back(n);
        }
    }
    auto id = [&](int i, int j) { return static_cast<unsigned>((i % nu) * nv + (j % nv)); };
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
            m.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
        }
    return m;
}

/// Square plane y = 0, |x|, |z| <= half, `cells` x `cells` quads, normal +Y.
inline Mesh plane(float half, int cells) {
    Mesh m;
    for (int i = 0; i < cells; ++i)
        for (int j = 0; j < cells; ++j) {
            const float x0 = -half + 2.0f * half * float(i) / float(cells), x1 = -half + 2.0f * half * float(i + 1) / float(cells);
            const float z0 = -half + 2.0f * half * float(j) / float(cells), z1 = -half + 2.0f * half * float(j + 1) / float(cells);
            add_quad(m, {x0, 0, z0}, {x1, 0, z0}, {x1, 0, z1}, {x0, 0, z1}, {0, 1, 0});
        }
    return m;
}

/// Concatenation of two meshes.
inline Mesh merge(Mesh a, const Mesh& b) {
    const auto base = static_cast<unsigned>(a.positions.size());
    a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
    a.normals.insert(a.normals.end(), b.normals.begin(), b.normals.end());
    for (const glm::uvec3& t : b.triangles) a.triangles.push_back(t + glm::uvec3(base));
    return a;
}

/// A 4x4 plane with a unit box standing on it (x, z in [-0.5, 0.5], y in [0, 1]).
inline Mesh plane_with_box() { return merge(plane(2.0f, 16), box({-0.5f, 0.0f, -0.5f}, {0.5f, 1.0f, 0.5f})); }

/// An L-shaped prism: the L (0,0)-(2,0)-(2,1)-(1,1)-(1,2)-(0,2) in x, y extruded over z in [0, 1].
/// Closed, one reflex edge (the inner corner at x = y = 1).
inline Mesh l_shape() {
    Mesh m;
    const glm::vec2 l[6] = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
    const int caps[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 5}, {3, 4, 5}};
    for (const auto& c : caps) {
        add_triangle(m, {l[c[0]], 1.0f}, {l[c[1]], 1.0f}, {l[c[2]], 1.0f}, {0, 0, 1});
        add_triangle(m, {l[c[0]], 0.0f}, {l[c[1]], 0.0f}, {l[c[2]], 0.0f}, {0, 0, -1});
    }
    for (int i = 0; i < 6; ++i) {
        const glm::vec2 a = l[i], b = l[(i + 1) % 6];
        const glm::vec2 e = b - a;
        add_quad(m, {a, 0.0f}, {b, 0.0f}, {b, 1.0f}, {a, 1.0f}, glm::normalize(glm::vec3(e.y, -e.x, 0.0f)));
    }
    return m;
}

} // namespace specula::test
