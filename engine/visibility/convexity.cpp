#include "visibility/convexity.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <numeric>
#include <vector>

namespace specula {

namespace {

struct DirectedEdge {
    std::uint32_t lo, hi;   // welded vertex ids, lo < hi
    std::uint32_t triangle;
    std::uint32_t opposite; // welded id of the triangle's third vertex
    bool forward;           // the triangle runs lo -> hi
};

std::uint32_t find_root(std::vector<std::uint32_t>& parent, std::uint32_t x) {
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

} // namespace

ConvexityReport analyze_convexity(const Mesh& mesh, double tolerance) {
    ConvexityReport r;
    const std::size_t nv = mesh.positions.size();
    if (mesh.triangles.empty()) {
        r.reason = "the mesh has no triangles";
        return r;
    }

    // Weld vertices with bit-identical positions (split normals or texture seams duplicate them).
    std::vector<std::uint32_t> by_pos(nv);
    std::iota(by_pos.begin(), by_pos.end(), 0u);
    auto key = [&](std::uint32_t i) { return std::array<float, 3>{mesh.positions[i].x, mesh.positions[i].y, mesh.positions[i].z}; };
    std::sort(by_pos.begin(), by_pos.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
    std::vector<std::uint32_t> weld(nv);
    std::vector<glm::dvec3> welded_pos;
    for (std::size_t k = 0; k < nv; ++k) {
        if (k == 0 || key(by_pos[k]) != key(by_pos[k - 1])) welded_pos.emplace_back(mesh.positions[by_pos[k]]);
        weld[by_pos[k]] = static_cast<std::uint32_t>(welded_pos.size() - 1);
    }
    r.welded_vertices = welded_pos.size();

    std::vector<DirectedEdge> edges;
    edges.reserve(3 * mesh.triangles.size());
    std::vector<glm::dvec3> face_normal(mesh.triangles.size());
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        const std::uint32_t v[3] = {weld[mesh.triangles[t].x], weld[mesh.triangles[t].y], weld[mesh.triangles[t].z]};
        const glm::dvec3 n = glm::cross(welded_pos[v[1]] - welded_pos[v[0]], welded_pos[v[2]] - welded_pos[v[0]]);
        const double len = glm::length(n);
        face_normal[t] = len > 0.0 ? n / len : glm::dvec3(0.0);
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = v[k], b = v[(k + 1) % 3], c = v[(k + 2) % 3];
            edges.push_back({std::min(a, b), std::max(a, b), t, c, a < b});
        }
    }
    std::sort(edges.begin(), edges.end(), [](const DirectedEdge& x, const DirectedEdge& y) {
        return x.lo != y.lo ? x.lo < y.lo : x.hi != y.hi ? x.hi < y.hi : x.triangle < y.triangle;
    });

    std::vector<std::uint32_t> parent(mesh.triangles.size());
    std::iota(parent.begin(), parent.end(), 0u);
    for (std::size_t i = 0; i < edges.size();) {
        std::size_t j = i;
        while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
        ++r.edges;
        const std::size_t uses = j - i;
        if (uses == 1) {
            ++r.boundary_edges;
        } else if (uses > 2 || edges[i].forward == edges[i + 1].forward) {
            ++r.nonmanifold_edges;
        } else {
            const DirectedEdge &e1 = edges[i], &e2 = edges[i + 1];
            parent[find_root(parent, e1.triangle)] = find_root(parent, e2.triangle);
            // Dihedral test from both sides: the neighbour's far vertex must not rise above this plane.
            const glm::dvec3 a = welded_pos[e1.lo];
            const glm::dvec3 d2 = welded_pos[e2.opposite] - a, d1 = welded_pos[e1.opposite] - a;
            const bool reflex = glm::dot(face_normal[e1.triangle], d2) > tolerance * glm::length(d2) ||
                                glm::dot(face_normal[e2.triangle], d1) > tolerance * glm::length(d1);
            if (reflex) ++r.reflex_edges;
        }
        i = j;
    }
    for (std::uint32_t t = 0; t < parent.size(); ++t)
        if (find_root(parent, t) == t) ++r.components;

    r.closed = r.boundary_edges == 0 && r.nonmanifold_edges == 0;
    r.connected = r.components == 1;
    r.convex = r.closed && r.connected && r.reflex_edges == 0;
    if (!r.closed)
        r.reason = "open or non-manifold mesh (" + std::to_string(r.boundary_edges) + " boundary, " +
                   std::to_string(r.nonmanifold_edges) + " non-manifold edges)";
    else if (!r.connected)
        r.reason = std::to_string(r.components) + " separate components";
    else if (r.reflex_edges > 0)
        r.reason = std::to_string(r.reflex_edges) + " reflex (concave) edges";
    return r;
}

} // namespace specula
