#pragma once
// residual_term: terms 2..K of the multi-term factorization (issue 5)
//     F(h, d) ~ sum_k G_k(h) H_k(d),   rendered as max(0, sum)
// Why: for a Phong-like lobe f ~ Cz^N exp(-2 N sin^2(theta_h) m(d)), m(d) = cos^2 theta_d +
// sin^2 theta_d cos^2 phi_d: the width along h depends on d, so one product G(h) H(d) (the
// thesis's normalized decomposition, term 1) leaves ~50% relative RMS on the presets' lobes.
// A truncated SVD-like expansion by deflation removes most of it: term k is the rank-1
// least-squares fit of the residual R_k = F - sum_{j<k} G_j H_j over the valid entries of F
// (a weighted low-rank fit with 0/1 weights), found by alternating least squares from the
// column RMS of R_k (kResidualIterations iterations of power iteration):
//     H(d) = sqrt(mean_h R^2);  repeat: G(h) = sum_d R H / sum_d H^2,  H(d) = sum_h R G / sum_h G^2
// G_k and H_k take either sign. Sums are blocked by kGshdSumBlock as in the other kernels.
// Reference in double (residual_term_cpu.cpp); Vulkan: shaders/factorization/residual_term.comp.
#include "factorization/brdf_matrix.h"
#include "factorization/normalized_decomposition.h"
#include "material/material.h"

#include <cstdint>
#include <optional>
#include <vector>

namespace specula::factorization {

inline constexpr uint32_t kResidualIterations = 12; ///< ALS iterations per residual term
inline constexpr double kDefaultTermTarget = 0.03;  ///< automatic K: matrix relative RMS to reach
/// Residual terms are left out when the lobe's height max(|Cx|, |Cz|)^N exceeds this (float sums
/// of products of F with G and H could overflow; the normalized decomposition scales, these do not).
inline constexpr double kResidualMaxValue = 1.0e15;

struct ResidualTermsInputs {
    const BrdfMatrix* matrix = nullptr;
    const Decomposition* first = nullptr; ///< term 1 (normalized decomposition) on the same grids
    uint32_t terms = 2;                   ///< K, total including term 1; 2..kMaxFactorTerms
    uint32_t iterations = kResidualIterations;
    unsigned threads = 1; ///< the C++ path's workers (the result is the same for any count)
};

void residual_terms_validate(const ResidualTermsInputs& in);

/// Terms 2..K (K - 1 decompositions), in double, results rounded to float after each term
/// (the next term's residual uses the rounded values, as the shader does).
[[nodiscard]] std::vector<Decomposition> residual_terms_cpu(const ResidualTermsInputs& in);

/// Term 1 refined by `iterations` alternating least-squares (G, H) pairs over the valid
/// entries of F, from its own H (warm: the normalized decomposition's): the passes above with
/// R = F. Why: the normalized decomposition's G(h) is a norm over the row's valid entries, and
/// the valid set changes from row to row, so on a matrix that is exactly rank 1 over its valid
/// entries (the warped parametrization, shared/gshd.h part 5) term 1 keeps ~34% relative RMS;
/// the least-squares fit has none. Non-negative F and a non-negative start stay non-negative.
[[nodiscard]] Decomposition refine_first_term_cpu(const BrdfMatrix& m, const Decomposition& first, uint32_t iterations,
                                                   unsigned threads = 1);

/// The Vulkan kernel: per term, 1 + 2 iterations dispatches separated by compute->compute
/// barriers. g and h hold all K terms, term-major (term 0 already written at offset 0).
class ResidualTermsVk {
public:
    explicit ResidualTermsVk(gpu::Context& ctx, uint32_t workgroup_size = 64);
    /// Records terms 2..terms, each in a timing span "residual_term_<k>" (k = 2..terms).
    void record(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                uint32_t res_h, uint32_t res_d, uint32_t terms, uint32_t iterations) const;
    /// Records refine_first_term_cpu's passes on term 0 of g and h (timing span "first_term_als").
    void record_refine_first(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                             uint32_t res_h, uint32_t res_d, uint32_t iterations) const;
    /// Uploads F and term 1, refines term 1 (refine_first_term_cpu), downloads it.
    [[nodiscard]] Decomposition run_refine_first(const BrdfMatrix& m, const Decomposition& first, uint32_t iterations);
    /// Uploads F and term 1, runs, downloads terms 2..K.
    [[nodiscard]] std::vector<Decomposition> run(const ResidualTermsInputs& in);

private:
    /// `iterations` (G, H) pass pairs on term `term`, each pass after a compute->compute barrier.
    void record_als(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                    uint32_t rows, uint32_t cols, uint32_t term, uint32_t iterations) const;
    gpu::Context* m_ctx;
    gpu::ComputePipeline m_pipeline;
};

} // namespace specula::factorization
