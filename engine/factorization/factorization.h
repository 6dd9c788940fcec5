#pragma once
/// \file
/// Stage 6, the Kautz-McCool factorization (pipeline.md section 6; thesis appendix A):
/// the fitted specular model (any family of material/material.h: a Lafortune lobe or the coated
/// family's GGX reflection, evaluated by shared/material.h material_specular) sampled as F[h, d]
/// over the GSHD parametrization (brdf_matrix), the
/// normalized decomposition F ~ G(h) H(d) (normalized_decomposition), and G and H
/// resampled into two cube-maps (cubemaps). Math shared with the shaders: shared/gshd.h.
///
///   auto f = factorize(model, {}, Backend::Vulkan, &ctx);   // model: SpecularModel (or a LafortuneRgb)
///   f.cubes                            // material/material.h FactorizedSpecular: what the
///                                      // renderer draws and the bundle stores, as it is
///   f.cubes.terms[k].g.texels          // term k's G: 6 x res x res rgb, Vulkan face order
///   f.grids[k]                         // term k's G and H on the hemisphere grids
///   f.resolution.reason                // why these resolutions
///   f.terms.count, f.terms.reason      // K, and why (issue 5: sum of K separable terms)
///
/// A renderer evaluates f_s(u, v) ~ R(u) max(0, sum_k G_k(h) H_k(d)) with
/// (h, d) = gshd_from_uv_warped(u, v, f.cubes.param, f.cubes.warp), R = 1 except in the warped
/// parametrization (R = lafortune_radial); K = 1 is the thesis's single term (terms 2..K:
/// residual_term.h).
///
/// The parametrization f.cubes.param (shared/gshd.h parts 4 and 5): the thesis's GSHD of (u, v),
/// the mirrored GSHD of (r(u), v) with r(u) = (-ux, -uy, uz), or the warped GSHD of (w(u), v)
/// with F the lobe over R. A lobe with Cx < 0 peaks about the mirror direction, and the
/// mirrored F is exactly rank 1 when Cx = -Cz; the plain one is when Cx = +Cz; the warped one
/// for every lobe in the channel its warp fits. By default each is factorized and the one with
/// the least error against the lobe through the cube-maps is kept (f.param_choice says which,
/// why, and every error).
///
/// The coated family (shared/coated.h): the warped parametrization is not offered, since F there
/// is the model over the Lafortune lobe's radial factor |C u|^N, which the GGX reflection does
/// not have. The plain GSHD suits it: h is the half vector, so D(n.h) is a function of h alone
/// and the Fresnel factor F(u.h) = F(d.z) of d alone, leaving only the masking and 1 / (4 n.u n.v)
/// to the residual terms. The automatic choice takes it alone: the mirrored GSHD (which can be
/// forced) kept 2.5 to 23 times its error against the model through the cube-maps (alpha 0.25:
/// 2.9% plain, 67.5% mirrored). Its grids come from alpha (resolution.h) and its
/// entries are weighted where the lobe is rough (default_weight_exponent).
#include "factorization/brdf_matrix.h"
#include "factorization/cubemaps.h"
#include "core/backend.h"
#include "material/lafortune.h"
#include "material/material.h"
#include "shared/lafortune.h"
#include "factorization/normalized_decomposition.h"
#include "factorization/residual_term.h"
#include "factorization/resolution.h"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula::factorization {


struct FactorizationOptions {
    /// 0 = default_resolution(model) for that field.
    uint32_t grid_h = 0;
    uint32_t grid_d = 0;
    uint32_t cube_g = 0;
    uint32_t cube_h = 0;
    float p = 2.0f;           ///< exponent of the normalized decomposition (normalized_decomposition.h)
    DecompositionWeighting weighting = DecompositionWeighting::Energy;
    bool keep_matrix = false; ///< return F too (error measurement)
    /// Number of separable terms K: 0 = automatic (the smallest K <= max_terms whose matrix
    /// relative RMS is <= term_target, else the K of least error), 1 = the thesis, 2..kMaxFactorTerms forced.
    uint32_t terms = 0;
    uint32_t max_terms = kMaxFactorTerms;
    double term_target = kDefaultTermTarget;
    uint32_t iterations = kResidualIterations; ///< ALS iterations per residual term
    /// ALS iterations refining term 1 (refine_first_term_cpu) after the normalized
    /// decomposition: nullopt = kResidualIterations in the warped parametrization (exactly rank 1
    /// there, where the normalized decomposition alone keeps ~34%), 0 (the thesis's term 1) in
    /// the others. Left out, as the residual terms are, for a lobe over kResidualMaxValue.
    std::optional<uint32_t> first_iterations;
    /// Parametrization of the pairs: nullopt = automatic (both factorized, ParamChoice's rule),
    /// else forced (FactorParam::Gshd is the thesis). Zero grid fields take each one's default rule.
    std::optional<FactorParam> param;
    /// The warped parametrization: nullopt = automatic (one warp shared by the three channels,
    /// shared_warp_of, where that keeps the error within kSharedWarpGoodEnough with no more lookups
    /// than a warp per channel; else a warp per channel), true / false forced.
    std::optional<bool> shared_warp;
    /// Exponent q of the entries' weight (h.z d.z)^q (brdf_matrix.h: a weighted least-squares fit):
    /// nullopt = default_weight_exponent(model), 0 for every lafortune lobe.
    std::optional<float> weight_q;
    /// The C++ path's workers (0: the hardware's); the result is the same for any count.
    unsigned threads = 0;
};

/// The coated family's weight exponent (default_weight_exponent): 0 up to alpha
/// kCoatedWeightAlphaLow, kCoatedWeightExponent from kCoatedWeightAlphaHigh on, linear between.
inline constexpr float kCoatedWeightExponent = 2.0f;
inline constexpr float kCoatedWeightAlphaLow = 0.12f;
inline constexpr float kCoatedWeightAlphaHigh = 0.25f;

/// The weight exponent q of the factorization of `model` (FactorizationOptions::weight_q).
/// Lafortune lobes: 0, the thesis's plain fit (their height is bounded by the peak). Coated: F
/// grows without bound towards grazing pairs (1 / (4 n.u n.v), the Fresnel factor near 1, limited
/// only by the masking), which a render shows on few pixels and dimmed by n.u; the plain fit
/// spends its terms there, and a rough lobe's peak is low enough that they dominate F's norm.
/// Measured on the presets' meshes (eta 1.5; masked PSNR factorized vs analytic over the spread
/// and the thesis's ring rigs, worst near-camera frame / worst far-light frame / lowest mean; the
/// far-light figures before render/terms.glsl cut the coated factorized term at the view's
/// horizon, which lifted the knot's worst from 39.3 to 52 dB at alpha 0.4), alpha
/// 0.4 on 32 x 64 grids: q = 0 33.1 / 39.3 / 48.7 dB, q = 2 56.8 / 39.3 / 58.9 dB; alpha 0.25
/// on 48 x 64: q = 0 42.7 / 45.0 / 54.1, q = 2 49.1 / 44.3 / 57.4. A sharp lobe's peak dominates
/// F already and the weight costs its far-light frames (alpha 0.12 on 64 x 48: q = 0 43.3 / 43.3 /
/// 56.5, q = 2 42.2 / 36.7 / 55.6; alpha 0.05 on 96 x 32: q = 0 40.8 / 40.2 / 53.7, q = 2
/// 40.8 / 30.7 / 52.2): hence no weight below alpha 0.12, the full weight from 0.25.
[[nodiscard]] float default_weight_exponent(const SpecularModel& model);

/// Wall-clock seconds per step (host side, including the submit and wait on Vulkan) and,
/// on Vulkan, each dispatch's GPU time from timestamps (nullopt where there are none).
struct FactorizationTimings {
    double matrix_s = 0.0;
    double decomposition_s = 0.0;
    double cubemaps_s = 0.0;
    double residual_s = 0.0; ///< terms 2..K (CPU path; on Vulkan inside total_s)
    double total_s = 0.0;
    std::optional<double> matrix_gpu_ns;
    std::optional<double> decomposition_g_gpu_ns;
    std::optional<double> decomposition_h_gpu_ns;
    std::optional<double> cube_g_gpu_ns;
    std::optional<double> cube_h_gpu_ns;
    std::optional<double> residual_gpu_ns; ///< all residual terms computed (nullopt for K_max = 1)
    std::optional<double> first_refine_gpu_ns; ///< term 1's ALS refinement (nullopt without one)
    [[nodiscard]] std::optional<double> gpu_total_ns() const;
};

/// How K was chosen. matrix_rms[k - 1]: matrix relative RMS of the first k terms (clamped sum),
/// for every k computed (up to max_terms when automatic, K when forced).
struct TermChoice {
    uint32_t count = 1;
    std::vector<double> matrix_rms;
    double target = kDefaultTermTarget;
    bool forced = false;
    std::string reason;
};

/// One parametrization's factorization, as the choice saw it.
struct ParamCandidate {
    bool computed = false;
    FactorizationResolution resolution; ///< its grids (default_resolution per parametrization)
    TermChoice terms;                   ///< its K and matrix errors
    /// Relative RMS against the lobe of its K terms through the cube-maps (direct_relative_rms,
    /// kParamChoicePairs pairs): the error of what the renderer draws.
    double direct_rms = 0.0;
};

/// Pairs of the direct error that decides the parametrization, and the relative difference
/// within which two direct errors tie (the same pairs, looked up at different (h, d): equal
/// matrices, Cx = 0, differ by ~0.1% in their interpolation errors).
inline constexpr uint32_t kParamChoicePairs = 1u << 16;
inline constexpr double kParamTieMargin = 0.02;
/// The warped parametrization's error against the lobe through the cube-maps at or below which
/// the automatic choice keeps it without factorizing the other two (the presets' lobes: 0.2% to
/// 0.4%; the factorization stage then takes ~1 s instead of 4 to 14 s on lavapipe).
inline constexpr double kWarpedGoodEnough = 0.01;
/// The error against the lobe through the cube-maps at or below which the automatic choice keeps
/// one warp shared by the channels (FactorizationOptions::shared_warp) instead of one per channel:
/// TermChoice's default target. Measured on knot_hd's lobe (channels' k 0.932, 0.960, 0.991):
/// 2.3% against 0.4%, and the factorized render of its 256 px capture 34.31 / 37.77 dB test /
/// train against 34.34 / 37.84 dB, for a factorized shading pass of 6.9 ms instead of 11.1 ms.
inline constexpr double kSharedWarpGoodEnough = kDefaultTermTarget;

/// How the parametrization was chosen. Automatic: the warped one first where it fits the model
/// (warp_for_model: a Lafortune lobe warp_for_lobe accepts), kept when its error is within
/// kWarpedGoodEnough; else every one that fits is factorized (each on its own default grids, each with its own K by TermChoice's rule) and
/// the one whose K terms have the least relative RMS against the lobe through the cube-maps
/// (ParamCandidate::direct_rms) is kept; within kParamTieMargin the one with fewer terms
/// (cheaper to render), then the thesis's GSHD. Not the matrix error: the two matrices sample the (u, v) pairs differently (and on
/// different grids), and a grid that misses a narrow peak has a small matrix error (measured at
/// the default grids: woodenpot's lobe has matrix RMS 2.7% plain vs 4.8% mirrored at K = 4, but
/// 30% vs 14% against the lobe; with one 16 x 16 grid for both, the N = 1000 mirror lobe's
/// mirrored matrix RMS is 0.0% and its error against the lobe 99.98%).
struct ParamChoice {
    FactorParam param = FactorParam::Gshd;
    bool forced = false;
    std::string reason;
    /// The warped parametrization with a warp per channel, where the one shared by the channels
    /// was kept instead (its candidate is candidates[Warped]); nullopt otherwise.
    std::optional<ParamCandidate> warped_per_channel;
    /// index = FactorParam's value; only the forced one when forced, and warped only for a model
    /// warp_for_model accepts
    std::array<ParamCandidate, kFactorParamCount> candidates{};
    [[nodiscard]] const ParamCandidate& of(FactorParam p) const { return candidates[static_cast<std::size_t>(p)]; }
};

struct Factorization {
    FactorizationResolution resolution;
    float weight_q = 0.0f; ///< the entries' weight exponent (FactorizationOptions::weight_q); the grids are unweighted
    /// The K terms' cube-maps (terms[0] is term 1) with how (h, d) come from (u, v)
    /// (shared/gshd.h parts 4, 5). FactorParam::Warped: cubes.warp is (s, k_r, k_g, k_b)
    /// (warp_for_lobe; channel c looks up at the coordinates of its warp (s, k_c)), and the terms
    /// approximate the lobe over its radial factor: f ~ lafortune_radial(u) max(0, sum_k G_k H_k);
    /// (1, 1, 1, 1) otherwise.
    FactorizedSpecular cubes;
    std::vector<Decomposition> grids; ///< per term (same order): G on the h grid, H on the d grid
    ParamChoice param_choice;
    TermChoice terms;
    float p = 2.0f;
    DecompositionWeighting weighting = DecompositionWeighting::Energy;
    [[nodiscard]] uint32_t term_count() const noexcept { return static_cast<uint32_t>(cubes.terms.size()); }
    std::optional<BrdfMatrix> matrix; // with keep_matrix (weighted when weight_q != 0, as the terms were fitted)
    FactorizationTimings timings;
};

/// The warp of the warped parametrization for `model` (warp_for_lobe for the lafortune family);
/// nullopt, with the reason in *why, for a lobe warp_for_lobe refuses and for every other family
/// (the warped F divides by the Lafortune lobe's radial factor, which they do not have).
[[nodiscard]] std::optional<glm::vec4> warp_for_model(const SpecularModel& model, std::string* why = nullptr);


/// The options' resolutions with zeros replaced by the default rule of parametrization `param`
/// (reason says which were forced).
[[nodiscard]] FactorizationResolution resolve_resolution(const SpecularModel& model, const FactorizationOptions& options,
                                                         FactorParam param = FactorParam::Gshd);

/// The reference path (all steps on the CPU, double accumulation).
[[nodiscard]] Factorization factorize_cpu(const SpecularModel& model, const FactorizationOptions& options = {});

/// The Vulkan path: the three kernels recorded in one Sequence (F, G and H stay on the
/// device; only the grids and cube-maps, and F with keep_matrix, are read back).
class FactorizeVk {
public:
    explicit FactorizeVk(gpu::Context& ctx);
    [[nodiscard]] Factorization run(const SpecularModel& model, const FactorizationOptions& options = {});

private:
    /// One parametrization; F is read back when keep_matrix or errors (the automatic choice needs them).
    [[nodiscard]] Factorization run_param(const SpecularModel& model, const FactorizationOptions& options, FactorParam param,
                                          bool errors);
    gpu::Context* m_ctx;
    BrdfMatrixVk m_matrix;
    NormalizedDecompositionVk m_decomposition;
    ResidualTermsVk m_residual;
    CubemapsVk m_cubemaps;
};

/// Either path; ctx is required for Vulkan.
[[nodiscard]] Factorization factorize(const SpecularModel& model, const FactorizationOptions& options,
                                      Backend backend, gpu::Context* ctx = nullptr);

// ---- approximation error -------------------------------------------------------------

/// sqrt(sum (G H - F)^2 / sum F^2) over the valid entries of F, all channels (in double).
[[nodiscard]] double matrix_relative_rms(const BrdfMatrix& matrix, const Decomposition& decomposition);
/// The same for max(0, sum_k G_k H_k) over the given terms (all on F's grids).
[[nodiscard]] double matrix_relative_rms(const BrdfMatrix& matrix, std::span<const Decomposition* const> terms);

struct DirectError {
    double grid = 0.0; ///< G, H interpolated bilinearly from the grids
    double cube = 0.0; ///< G, H looked up bilinearly in the cube-maps (NaN without them)
    uint32_t pairs = 0;
};
/// Relative RMS of G(h) H(d) against the model (material_specular(u, v)) for `pairs` pairs (u, v)
/// drawn uniformly (in solid angle) from the upper hemisphere with a fixed seed: the sampling,
/// decomposition and interpolation errors together. (h, d) in the decomposition's param.
[[nodiscard]] DirectError direct_relative_rms(const SpecularModel& model, const Decomposition& decomposition,
                                              const CubeMap* cube_g, const CubeMap* cube_h, uint32_t pairs = 1u << 18,
                                              uint32_t seed = 1);
/// The same for max(0, sum_k G_k H_k) over the first `terms` terms of f (0 = all of them).
[[nodiscard]] DirectError direct_relative_rms(const SpecularModel& model, const Factorization& f, uint32_t terms = 0,
                                              uint32_t pairs = 1u << 18, uint32_t seed = 1);

} // namespace specula::factorization
