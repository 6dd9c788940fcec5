#pragma once
// Can the mesh occlude or shadow itself? (pipeline.md section 9: no occlusion
// rays where the mesh cannot shadow or occlude itself.)
//
// A mesh is convex here when it is
//   - closed: after welding vertices with identical positions, every edge is
//     shared by exactly two triangles, traversed in opposite directions
//     (consistently oriented);
//   - connected: one edge-connected component;
//   - convex at every edge: the far vertex of each neighbour lies on or
//     behind the triangle's plane, signed distance <= kTolerance times its
//     distance from the edge (a fold of less than ~1e-5 rad counts as flat,
//     so coplanar triangles of a cube face pass despite float rounding).
// A closed, connected surface that is convex at every edge bounds a convex
// body (Hadamard / Tietze), so a point on it is unoccluded from any external
// point in front of its face's plane: the front-facing test is exact. An
// inward-oriented mesh fails the edge test (every edge looks reflex): the
// answer errs on the side of casting rays.
#include "capture/mesh.h"

#include <cstddef>
#include <string>

namespace specula {

struct ConvexityReport {
    bool convex = false;
    bool closed = false;
    bool connected = false;
    std::size_t welded_vertices = 0;
    std::size_t edges = 0;
    std::size_t boundary_edges = 0;     ///< used by one triangle
    std::size_t nonmanifold_edges = 0;  ///< used by more than two, or twice in the same direction
    std::size_t reflex_edges = 0;
    std::size_t components = 0;
    std::string reason;                 ///< why it is not convex (empty when convex)
};

/// Relative tolerance of the dihedral test (see above).
inline constexpr double kConvexityTolerance = 1e-5;

[[nodiscard]] ConvexityReport analyze_convexity(const Mesh& mesh, double tolerance = kConvexityTolerance);

} // namespace specula
