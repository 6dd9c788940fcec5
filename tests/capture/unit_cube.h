#pragma once
// The unit cube as a mesh, for tests and the fuzz seeds.
#include "capture/mesh.h"

namespace specula::test {

// Eight corners of [-0.5, 0.5]^3, twelve triangles (outward winding), vertex normals.
inline Mesh unit_cube_mesh() {
    Mesh m;
    for (int i = 0; i < 8; ++i)
        m.positions.emplace_back((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f);
    m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                   {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    m.normals = compute_vertex_normals(m.positions, m.triangles);
    return m;
}

} // namespace specula::test
