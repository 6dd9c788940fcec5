// Reference for cubemaps (thesis Algorithm 2): shared/gshd.h in double.
#include "factorization/cubemaps.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace specula::factorization {

void cubemap_validate(const CubemapInputs& in) {
    if (in.grid_res < 2) throw Error("cubemaps: grid resolution must be >= 2");
    if (in.cube_res < 1) throw Error("cubemaps: cube-map resolution must be >= 1");
    if (in.grid.size() != std::size_t{in.grid_res} * in.grid_res)
        throw Error("cubemaps: grid holds " + std::to_string(in.grid.size()) + " cells, expected " +
                    std::to_string(std::size_t{in.grid_res} * in.grid_res));
    if (uint64_t{6} * in.cube_res * in.cube_res * 3 >= (uint64_t{1} << 32))
        throw Error("cubemaps: cube-map too large for 32-bit indexing");
}

glm::dvec3 grid_sample(std::span<const glm::vec3> grid, uint32_t grid_res, glm::dvec3 w) {
    const shared::f64::GshdBilinear b = shared::f64::gshd_grid_bilinear(w, grid_res);
    return shared::f64::gshd_bilinear_mix(b, glm::dvec3(grid[b.i00]), glm::dvec3(grid[b.i10]), glm::dvec3(grid[b.i01]),
                                          glm::dvec3(grid[b.i11]));
}

CubeMap cubemaps_cpu(const CubemapInputs& in) {
    cubemap_validate(in);
    CubeMap out{.resolution = in.cube_res, .texels = {}};
    out.texels.assign(std::size_t{6} * in.cube_res * in.cube_res, glm::vec3(0.0f));
    for (uint32_t face = 0; face < shared::kCubeFaces; ++face)
        for (uint32_t row = 0; row < in.cube_res; ++row)
            for (uint32_t col = 0; col < in.cube_res; ++col) {
                const glm::dvec3 dir = shared::f64::cube_texel_dir(face, col, row, in.cube_res);
                if (!shared::f64::cube_texel_kept(dir, in.cube_res)) continue; // lower hemisphere: 0
                out.texels[(std::size_t{face} * in.cube_res + row) * in.cube_res + col] =
                    glm::vec3(grid_sample(in.grid, in.grid_res, dir));
            }
    return out;
}

glm::dvec3 cubemap_sample(const CubeMap& cube, glm::dvec3 w) {
    // Vulkan face selection: the major axis, ties to x then y (spec table; ties do not matter here).
    const glm::dvec3 a = glm::abs(w);
    uint32_t face = 0;
    double sc = 0.0, tc = 0.0, ma = 1.0;
    if (a.x >= a.y && a.x >= a.z) {
        face = w.x >= 0.0 ? 0u : 1u;
        sc = w.x >= 0.0 ? -w.z : w.z;
        tc = -w.y;
        ma = a.x;
    } else if (a.y >= a.z) {
        face = w.y >= 0.0 ? 2u : 3u;
        sc = w.x;
        tc = w.y >= 0.0 ? w.z : -w.z;
        ma = a.y;
    } else {
        face = w.z >= 0.0 ? 4u : 5u;
        sc = w.z >= 0.0 ? w.x : -w.x;
        tc = -w.y;
        ma = a.z;
    }
    const double r = cube.resolution;
    const double s = std::clamp(0.5 * (sc / ma + 1.0) * r - 0.5, 0.0, r - 1.0);
    const double t = std::clamp(0.5 * (tc / ma + 1.0) * r - 0.5, 0.0, r - 1.0);
    const uint32_t c0 = std::min(static_cast<uint32_t>(s), cube.resolution > 1 ? cube.resolution - 2 : 0u);
    const uint32_t r0 = std::min(static_cast<uint32_t>(t), cube.resolution > 1 ? cube.resolution - 2 : 0u);
    const uint32_t c1 = std::min(c0 + 1, cube.resolution - 1);
    const uint32_t r1 = std::min(r0 + 1, cube.resolution - 1);
    const double fx = s - c0;
    const double fy = t - r0;
    const auto v = [&](uint32_t row, uint32_t col) { return glm::dvec3(cube.at(face, row, col)); };
    return (1.0 - fy) * ((1.0 - fx) * v(r0, c0) + fx * v(r0, c1)) + fy * ((1.0 - fx) * v(r1, c0) + fx * v(r1, c1));
}

} // namespace specula::factorization
