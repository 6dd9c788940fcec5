#pragma once
// normalized_decomposition: F ~ G(h) H(d) per channel (thesis eq. A.2-A.3; Kautz and
// McCool 1999, "normalized decomposition"), over the valid entries of F only:
//     G(h) = (mean_d |F(h, d)|^p)^(1/p)
//     H(d) = mean_h F(h, d) / G(h)        over rows with G(h) > 0
// computed as G = m (mean (|F|/m)^p)^(1/p) with m the row maximum (finite for any F that
// is), and G = 0 for rows whose maximum is below kGshdMinValue. Sums are blocked by
// kGshdSumBlock on both sides (shared/gshd.h).
//
// Default weighting: Energy, a deliberate difference from eq. A.3 (pipeline.md section 6
// writes A.3's plain mean, which is kept as Uniform). With the plain mean every row with
// G > 0 pulls H towards its own normalized profile, and the many dark rows (far from the
// peak, where the lobe's profile along d is different) dominate: G H then over-shoots the
// bright rows. Measured at R = 32 (factorization_sweep): matrix relative RMS of cologne
// 1.36 (uniform) vs 0.088 (energy), pepsi 0.60 vs 0.41, mirror N=1000 1.68 vs 0.76.
// Energy weighting is the least-squares H for the given G (argmin_H sum (G H - F)^2),
// and is still exact for a separable F.
//
// p = 2 by default: G is then the RMS of the row, so G H reproduces the energy (L2 norm) of
// every row exactly where F is separable and weights the approximation towards the bright
// part of the lobe where errors show; p = 1 lets the many dark entries pull G down and
// under-shoots the peak, p -> infinity makes G the row maximum (sensitive to one noisy or
// clamped entry). With energy weighting, p = 2 makes G the row's L2 norm and H the
// least-squares fit to it: both steps minimize the same L2 error that is reported. The
// sweep measures p = 1, 2, 4 (energy weighting, R = 32, direct error): p = 2 is best for
// cologne (0.113) and within 1% of best for pepsi; p = 4 is better for vase and woodenpot
// (0.34, 0.19 vs 0.41, 0.34) and worse for the mirror lobe (0.96 vs 0.90). The best p
// depends on the lobe; 2 is the choice consistent with the L2 error that is reported.
#include "factorization/brdf_matrix.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace specula::factorization {

/// How H averages the normalized rows F(h, .) / G(h).
enum class DecompositionWeighting : uint32_t {
    Uniform = 0, ///< thesis eq. A.3: every row with G > 0 counts the same
    Energy = 1,  ///< rows weighted by G(h)^2: H(d) = sum G F / sum G^2, the least-squares H for the given G
};
[[nodiscard]] const char* to_string(DecompositionWeighting w) noexcept;

struct DecompositionInputs {
    const BrdfMatrix* matrix = nullptr; // any matrix in BrdfMatrix's layout (tests build separable ones)
    float p = 2.0f;
    DecompositionWeighting weighting = DecompositionWeighting::Energy;
};

struct Decomposition {
    uint32_t res_h = 0;
    uint32_t res_d = 0;
    std::vector<glm::vec3> g; // res_h^2 cells of the h grid, rgb
    std::vector<glm::vec3> h; // res_d^2 cells of the d grid, rgb
    FactorParam param = FactorParam::Gshd; // the decomposed matrix's: how (h, d) come from (u, v)
    glm::vec4 warp{1.0f};            // and its warp (FactorParam::Warped)
};

/// Divides a decomposition of a weighted F (BrdfMatrixInputs::weight_q = q, brdf_matrix.h) by the
/// weight's factors: G at h cell i by h_i.z^q, H at d cell j by d_j.z^q (cell centres: z > 0), so
/// that G H approximates the model itself. No-op for q = 0.
void unweight_decomposition(Decomposition& d, float q);

/// Throws specula::Error for a missing or inconsistent matrix or p not in [1, 64].
void decomposition_validate(const DecompositionInputs& in);

/// The reference: sums and powers in double, results rounded to float.
[[nodiscard]] Decomposition normalized_decomposition_cpu(const DecompositionInputs& in);

/// The Vulkan kernel (shaders/factorization/normalized_decomposition.comp): two dispatches
/// (G, then H after a compute->compute barrier).
class NormalizedDecompositionVk {
public:
    explicit NormalizedDecompositionVk(gpu::Context& ctx, uint32_t workgroup_size = 64);
    /// Records both passes reading `matrix` (layout of BrdfMatrix) and writing g, h
    /// (rgb float triples). Labels "decomposition_g" and "decomposition_h".
    void record(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                uint32_t res_h, uint32_t res_d, float p, DecompositionWeighting weighting) const;
    /// Uploads F, runs both passes, downloads G and H.
    [[nodiscard]] Decomposition run(const DecompositionInputs& in);
    /// Sum of both passes' GPU time in ns (nullopt without timestamps).
    [[nodiscard]] std::optional<double> last_gpu_ns() const noexcept { return m_last_gpu_ns; }

private:
    gpu::Context* m_ctx;
    gpu::ComputePipeline m_pipeline;
    std::optional<double> m_last_gpu_ns;
};

} // namespace specula::factorization
