#pragma once
// brdf_matrix: the specular model (any family: shared/material.h material_specular, the one
// evaluation every kernel shares) sampled as the matrix F[h, d] (thesis appendix A, step 1), with
// the GSHD reparametrization and the hemispherical octahedral grids of shared/gshd.h.
// Row = cell of the h grid (res_h x res_h), column = cell of the d grid (res_d x res_d).
// Layout, channel-planar (what the shader writes): values[(c * rows + row) * cols + col].
// Entries outside the BRDF's domain (u or v below the horizon) are kGshdInvalid (-1).
// `param` picks the parametrization of the pairs (shared/gshd.h parts 4 and 5): the thesis's
// GSHD of (u, v), the mirrored GSHD of (r(u), v), or the warped GSHD of (w(u), v) with the
// warp `warp` = (s, k_r, k_g, k_b) (channel c's pairs in its own warp (s, k_c)), whose F is
// the lobe over its radial factor |C u|^N (in [0, 1]): the lafortune family only, whose lobe
// has that factor (the coated family is factorized plain or mirrored).
//
// Weighted entries (weight_q != 0): every valid entry is the model times w(h, d) = (h.z d.z)^q,
// h.z = n.h and d.z = u.h of the cell centres. The steps after it (the normalized decomposition,
// the residual terms' alternating least squares) minimize the plain squared error of their
// input, so on the weighted F they minimize sum w^2 (G H - f)^2: the weighted least-squares fit,
// exact because w is separable (a(h) b(d)), after which G is divided by a = h.z^q and H by
// b = d.z^q (normalized_decomposition.h unweight_decomposition). Why (the coated family, factorization.h): its model
// grows without bound towards grazing pairs (1 / (4 n.u n.v) with the Fresnel factor near 1)
// that a render shows on few pixels and dimmed by n.u, and the plain fit spends its terms there.
#include "material/factor_param.h"
#include "material/lafortune.h"
#include "material/material.h"
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
    SpecularModel model; ///< any family; FactorParam::Warped: LafortuneRgb only
    uint32_t res_h = 32;
    uint32_t res_d = 32;
    FactorParam param = FactorParam::Gshd;
    glm::vec4 warp{1.0f}; ///< (s, k_r, k_g, k_b), FactorParam::Warped only (warp_for_lobe)
    float weight_q = 0.0f; ///< entries times (h.z d.z)^weight_q; 0: the model itself (in [0, 8])
    unsigned threads = 1;  ///< brdf_matrix_cpu's workers (each entry is computed alone: the same for any count)
};

static_assert(static_cast<uint32_t>(FactorParam::Gshd) == shared::kGshdPlain &&
              static_cast<uint32_t>(FactorParam::Mirrored) == shared::kGshdMirrored &&
              static_cast<uint32_t>(FactorParam::Warped) == shared::kGshdWarped);

struct BrdfMatrix {
    uint32_t res_h = 0;
    uint32_t res_d = 0;
    FactorParam param = FactorParam::Gshd;
    glm::vec4 warp{1.0f};
    float weight_q = 0.0f;     // the entries' weight (h.z d.z)^weight_q
    std::vector<float> values; // 3 * rows() * cols()
    [[nodiscard]] std::size_t rows() const noexcept { return std::size_t{res_h} * res_h; }
    [[nodiscard]] std::size_t cols() const noexcept { return std::size_t{res_d} * res_d; }
    [[nodiscard]] float at(uint32_t c, std::size_t row, std::size_t col) const {
        return values[(c * rows() + row) * cols() + col];
    }
};

/// Throws specula::Error for a resolution below 2, a matrix over 2^32 entries, the warped
/// parametrization of a model that is not of the lafortune family, or weight_q outside [0, 8].
void brdf_matrix_validate(const BrdfMatrixInputs& in);

/// The reference: directions and model in double (shared::f64), each entry rounded to float.
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
