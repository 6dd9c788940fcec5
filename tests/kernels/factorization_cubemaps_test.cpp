// cubemaps: CPU reference (double) vs Vulkan (float), lower hemisphere, and lookups.
//
// Tolerance, per texel. The float texel direction and hemi-oct encoding put the map
// coordinate e off by ~8 eps32, i.e. the cell coordinate x = (e + 1) R/2 - 0.5 off by
// ~4 R eps32 in each axis; bilinear interpolation is continuous (also across cell
// boundaries and at the clamped edge), so the value moves by at most 8 R eps32 times the
// largest step between neighbouring cells; the two lerps add ~6 eps32 of the largest value:
//     |c_vk - c_ref| <= kSafety (8 R eps32 max_step + 6 eps32 max_abs)
// Texels below the horizon must be exactly 0 on both sides, but for the horizon gutter
// (shared/gshd.h cube_texel_kept), which holds the grid at the horizon point of its azimuth.
#include "factorization/cubemaps.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace specula::factorization {
namespace {

constexpr double kEps32 = 5.96e-8;
constexpr double kSafety = 4.0;

std::vector<glm::vec3> random_grid(uint32_t res, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 3.0f);
    std::vector<glm::vec3> g(std::size_t{res} * res);
    for (auto& v : g) v = {uni(rng), uni(rng), uni(rng)};
    return g;
}

// A field linear in the map coordinates (e.x, e.y) of each cell centre: bilinear
// interpolation reproduces it exactly away from the clamped edge cells.
std::vector<glm::vec3> linear_grid(uint32_t res) {
    std::vector<glm::vec3> g(std::size_t{res} * res);
    for (uint32_t i = 0; i < g.size(); ++i) {
        const glm::dvec2 e = shared::f64::gshd_grid_center(i, res);
        g[i] = glm::vec3(2.0 + e.x + 0.5 * e.y, 3.0 - e.y, 1.0 + 0.25 * e.x);
    }
    return g;
}

double max_step(const std::vector<glm::vec3>& g, uint32_t res) {
    double s = 0.0;
    for (uint32_t j = 0; j < res; ++j)
        for (uint32_t i = 0; i < res; ++i)
            for (int c = 0; c < 3; ++c) {
                const float v = g[j * res + i][c];
                if (i + 1 < res) s = std::max(s, static_cast<double>(std::abs(g[j * res + i + 1][c] - v)));
                if (j + 1 < res) s = std::max(s, static_cast<double>(std::abs(g[(j + 1) * res + i][c] - v)));
            }
    return s;
}

class CubemapsConformance : public test::VulkanTest {};

TEST_F(CubemapsConformance, VulkanMatchesReference) {
    CubemapsVk kernel(ctx());
    struct Size { uint32_t grid, cube; };
    for (const Size s : {Size{7, 5}, Size{16, 18}, Size{2, 33}, Size{32, 64}}) {
        for (int kind = 0; kind < 2; ++kind) {
            const auto grid = kind == 0 ? random_grid(s.grid, s.cube) : linear_grid(s.grid);
            const CubemapInputs in{.grid = grid, .grid_res = s.grid, .cube_res = s.cube};
            const CubeMap ref = cubemaps_cpu(in);
            const CubeMap vk = kernel.run(in);
            ASSERT_EQ(vk.texels.size(), ref.texels.size());
            double max_abs = 0.0;
            for (const auto& v : grid) max_abs = std::max<double>(max_abs, glm::max(v.x, glm::max(v.y, v.z)));
            const double tol = kSafety * (8.0 * s.grid * kEps32 * max_step(grid, s.grid) + 6.0 * kEps32 * max_abs);
            double worst = 0.0;
            for (uint32_t f = 0; f < 6; ++f)
                for (uint32_t r = 0; r < s.cube; ++r)
                    for (uint32_t c = 0; c < s.cube; ++c) {
                        const glm::dvec3 dir = shared::f64::cube_texel_dir(f, c, r, s.cube);
                        const glm::vec3 a = ref.at(f, r, c), b = vk.at(f, r, c);
                        if (!shared::f64::cube_texel_kept(dir, s.cube)) {
                            EXPECT_LT(dir.z, 0.0);
                            EXPECT_EQ(a, glm::vec3(0.0f));
                            EXPECT_EQ(b, glm::vec3(0.0f)) << "lower hemisphere texel not 0";
                            continue;
                        }
                        if (dir.z < 0.0) { // the horizon gutter: the grid at the horizon point of its azimuth
                            EXPECT_GT(dir.z, -1.5 / s.cube);
                            const glm::dvec3 horizon = grid_sample(grid, s.grid, glm::dvec3(dir.x, dir.y, 0.0));
                            for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], horizon[k], 1e-6 * (1.0 + std::abs(horizon[k])));
                        }
                        for (int k = 0; k < 3; ++k) {
                            worst = std::max<double>(worst, std::abs(a[k] - b[k]));
                            EXPECT_LE(std::abs(a[k] - b[k]), tol) << "face " << f << " row " << r << " col " << c;
                        }
                    }
            std::printf("[ grid %u cube %u %s ] worst |vk - ref| %.3g (tol %.3g)\n", s.grid, s.cube,
                        kind == 0 ? "random" : "linear", worst, tol);
        }
    }
}

// Looking the grid up at a cell centre's direction returns that cell's value; a field
// linear in the map coordinates comes back exactly in every cube-map texel whose
// direction falls between cell centres (thesis Algorithm 2's bilinear step).
TEST(Cubemaps, LookupAlongGridDirectionsReproducesGrid) {
    const uint32_t res = 12;
    const auto grid = random_grid(res, 9);
    for (uint32_t i = 0; i < grid.size(); ++i) {
        const glm::dvec3 w = shared::f64::gshd_grid_dir(i, res);
        const glm::dvec3 v = grid_sample(grid, res, w);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], grid[i][c], 1e-6 * grid[i][c] + 1e-7) << "cell " << i;
    }
    const auto lin = linear_grid(res);
    const CubeMap cube = cubemaps_cpu({.grid = lin, .grid_res = res, .cube_res = 24});
    const double inner = 1.0 - 1.0 / res; // outside this the lookup clamps to the edge cells
    std::size_t checked = 0;
    for (uint32_t f = 0; f < 6; ++f)
        for (uint32_t r = 0; r < cube.resolution; ++r)
            for (uint32_t c = 0; c < cube.resolution; ++c) {
                const glm::dvec3 dir = shared::f64::cube_texel_dir(f, c, r, cube.resolution);
                if (dir.z <= 0.0) continue;
                const glm::dvec2 e = shared::f64::hemi_oct_encode(dir);
                if (std::abs(e.x) > inner || std::abs(e.y) > inner) continue;
                const glm::dvec3 expect(2.0 + e.x + 0.5 * e.y, 3.0 - e.y, 1.0 + 0.25 * e.x);
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(cube.at(f, r, c)[k], expect[k], 1e-5);
                // and a cube-map lookup along that texel's direction returns the texel
                const glm::dvec3 back = cubemap_sample(cube, dir);
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], cube.at(f, r, c)[k], 1e-5);
                ++checked;
            }
    EXPECT_GT(checked, cube.texels.size() / 4);
}

} // namespace
} // namespace specula::factorization
