#pragma once
// brdf_matrix: the lobe sampled as the matrix F[h, d] (thesis appendix A, step 1), with
// the GSHD reparametrization and the hemispherical octahedral grids of shared/gshd.h.
// Row = cell of the h grid (res_h x res_h), column = cell of the d grid (res_d x res_d).
// Layout, channel-planar (what the shader writes): values[(c * rows + row) * cols + col].
// Entries outside the BRDF's domain (u or v below the horizon) are kGshdInvalid (-1).
// `param` picks the parametrization of the pairs (shared/gshd.h parts 4 and 5): the thesis's
// GSHD of (u, v), the mirrored GSHD of (r(u), v), or the warped GSHD of (w(u), v) with the
// warp `warp` = (s, k_r, k_g, k_b) (channel c's pairs in its own warp (s, k_c)), whose F is
// the lobe over its radial factor |C u|^N (in [0, 1]).
#include "material/factor_param.h"
#include "material/lafortune.h"
#include "shared/lafortune.h"
#include "gpu/buffer.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "shared/factorization.h"
#include "shared/gshd.h"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace specula::factorization {

struct BrdfMatrixInputs {
    LafortuneRgb lobe;
    uint32_t res_h = 32;
    uint32_t res_d = 32;
    FactorParam param = FactorParam::Gshd;
    glm::vec4 warp{1.0f}; ///< (s, k_r, k_g, k_b), FactorParam::Warped only (warp_for_lobe)
};

static_assert(static_cast<uint32_t>(FactorParam::Gshd) == shared::kGshdPlain &&
              static_cast<uint32_t>(FactorParam::Mirrored) == shared::kGshdMirrored &&
              static_cast<uint32_t>(FactorParam::Warped) == shared::kGshdWarped);

struct BrdfMatrix {
    uint32_t res_h = 0;
    uint32_t res_d = 0;
    FactorParam param = FactorParam::Gshd;
    glm::vec4 warp{1.0f};
    std::vector<float> values; // 3 * rows() * cols()
    [[nodiscard]] std::size_t rows() const noexcept { return std::size_t{res_h} * res_h; }
    [[nodiscard]] std::size_t cols() const noexcept { return std::size_t{res_d} * res_d; }
    [[nodiscard]] float at(uint32_t c, std::size_t row, std::size_t col) const {
        return values[(c * rows() + row) * cols() + col];
    }
};

/// Throws specula::Error for a resolution below 2 or a matrix over 2^32 entries.
void brdf_matrix_validate(const BrdfMatrixInputs& in);

/// The reference: directions and lobe in double (shared::f64), each entry rounded to float.
[[nodiscard]] BrdfMatrix brdf_matrix_cpu(const BrdfMatrixInputs& in);

/// The Vulkan kernel (shaders/factorization/brdf_matrix.comp). Owns its pipeline.
class BrdfMatrixVk {
public:
    explicit BrdfMatrixVk(gpu::Context& ctx, uint32_t workgroup_size = 64);
    /// Records the dispatch writing F into `matrix` (>= 3 rows cols floats); label times it.
    void record(gpu::Sequence& seq, const gpu::Buffer& matrix, const BrdfMatrixInputs& in) const;
    /// Uploads nothing, dispatches, downloads F.
    [[nodiscard]] BrdfMatrix run(const BrdfMatrixInputs& in);
    [[nodiscard]] std::optional<double> last_gpu_ns() const noexcept { return m_last_gpu_ns; }

private:
    gpu::Context* m_ctx;
    gpu::ComputePipeline m_pipeline;
    std::optional<double> m_last_gpu_ns;
};

} // namespace specula::factorization
