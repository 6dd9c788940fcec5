#pragma once
// cubemaps: a hemisphere grid (G or H of the decomposition) resampled into a cube-map
// (thesis appendix A, Algorithm 2): every face texel takes the direction through its
// centre; texels below the horizon (z < 0) are 0, except the horizon gutter (the row just
// below it, shared/gshd.h cube_texel_kept), the others the bilinear interpolation of the
// grid at that direction (shared/gshd.h: gshd_grid_bilinear). Why the gutter: without it a
// lookup at a grazing h or d blends the zeros in (half the value at the horizon); measured on
// the vase lobe in the warped parametrization (h 16, d 72, K = 1), relative RMS against the
// lobe through the cube-maps 5.9% with the whole lower hemisphere 0, 1.2% with the gutter
// (0.7% through the grids).
// Layout: texels[(face * res + row) * res + col], faces +X, -X, +Y, -Y, +Z, -Z in Vulkan's
// orientation, rgb float: uploads as-is into a VK_IMAGE_CREATE_CUBE_COMPATIBLE_BIT image
// of format R32G32B32_SFLOAT (or converted to RGBA16F / stored in a glTF bundle).
#include "gpu/buffer.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "shared/factorization.h"
#include "material/material.h"
#include "shared/gshd.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace specula::factorization {

struct CubemapInputs {
    std::span<const glm::vec3> grid; // grid_res^2 cells, rgb
    uint32_t grid_res = 0;
    uint32_t cube_res = 0; // face size
};

void cubemap_validate(const CubemapInputs& in);

/// The reference: directions and interpolation weights in double, results rounded to float.
[[nodiscard]] CubeMap cubemaps_cpu(const CubemapInputs& in);

/// Bilinear lookup of a cube-map along direction w (CPU; within the face that w selects,
/// clamped at the face's edge texels: a seamless GPU sampler blends across edges instead).
[[nodiscard]] glm::dvec3 cubemap_sample(const CubeMap& cube, glm::dvec3 w);

/// Bilinear lookup of a hemisphere grid along w (shared/gshd.h gshd_grid_bilinear, in double).
[[nodiscard]] glm::dvec3 grid_sample(std::span<const glm::vec3> grid, uint32_t grid_res, glm::dvec3 w);

/// The Vulkan kernel (shaders/factorization/cubemaps.comp).
class CubemapsVk {
public:
    explicit CubemapsVk(gpu::Context& ctx, uint32_t workgroup_size = 64);
    /// Records one dispatch reading `grid` (rgb float triples) and writing `cube`.
    void record(gpu::Sequence& seq, const gpu::Buffer& grid, const gpu::Buffer& cube, uint32_t grid_res,
                uint32_t cube_res, std::string_view label) const;
    [[nodiscard]] CubeMap run(const CubemapInputs& in);
    [[nodiscard]] std::optional<double> last_gpu_ns() const noexcept { return m_last_gpu_ns; }

private:
    gpu::Context* m_ctx;
    gpu::ComputePipeline m_pipeline;
    std::optional<double> m_last_gpu_ns;
};

} // namespace specula::factorization
