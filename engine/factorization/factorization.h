#pragma once
/// \file
/// Stage 6, the Kautz-McCool factorization (pipeline.md section 6; thesis appendix A):
/// the fitted lobe sampled as F[h, d] over the GSHD parametrization (brdf_matrix), the
/// normalized decomposition F ~ G(h) H(d) (normalized_decomposition), and G and H
/// resampled into two cube-maps (cubemaps). Math shared with the shaders: shared/gshd.h.
///
///   auto f = factorize(lobe, {}, FactorizationBackend::Vulkan, &ctx);
///   f.cube_g.texels, f.cube_h.texels   // 6 x res x res rgb, Vulkan face order
///   f.resolution.reason                // why these resolutions
///
/// A renderer evaluates f_s(u, v) ~ G(h) H(d) with (h, d) = gshd_from_uv(u, v).
#include "factorization/brdf_matrix.h"
#include "factorization/cubemaps.h"
#include "factorization/lobe.h"
#include "factorization/normalized_decomposition.h"
#include "factorization/resolution.h"

#include <cstdint>
#include <optional>
#include <string>

namespace specula::factorization {

enum class FactorizationBackend { Cpu, Vulkan };
[[nodiscard]] const char* to_string(FactorizationBackend backend) noexcept;

struct FactorizationOptions {
    /// 0 = default_resolution(lobe) for that field.
    uint32_t grid_h = 0;
    uint32_t grid_d = 0;
    uint32_t cube_g = 0;
    uint32_t cube_h = 0;
    float p = 2.0f;           ///< exponent of the normalized decomposition (normalized_decomposition.h)
    DecompositionWeighting weighting = DecompositionWeighting::Energy;
    bool keep_matrix = false; ///< return F too (error measurement)
};

/// Wall-clock seconds per step (host side, including the submit and wait on Vulkan) and,
/// on Vulkan, each dispatch's GPU time from timestamps (nullopt where there are none).
struct FactorizationTimings {
    double matrix_s = 0.0;
    double decomposition_s = 0.0;
    double cubemaps_s = 0.0;
    double total_s = 0.0;
    std::optional<double> matrix_gpu_ns;
    std::optional<double> decomposition_g_gpu_ns;
    std::optional<double> decomposition_h_gpu_ns;
    std::optional<double> cube_g_gpu_ns;
    std::optional<double> cube_h_gpu_ns;
    [[nodiscard]] std::optional<double> gpu_total_ns() const;
};

struct Factorization {
    FactorizationResolution resolution;
    float p = 2.0f;
    DecompositionWeighting weighting = DecompositionWeighting::Energy;
    Decomposition decomposition; // G on the h grid, H on the d grid
    Cubemap cube_g;
    Cubemap cube_h;
    std::optional<BrdfMatrix> matrix; // with keep_matrix
    FactorizationTimings timings;
};

/// The options' resolutions with zeros replaced by the default rule (reason says which were forced).
[[nodiscard]] FactorizationResolution resolve_resolution(const LafortuneRgb& lobe, const FactorizationOptions& options);

/// The reference path (all steps on the CPU, double accumulation).
[[nodiscard]] Factorization factorize_cpu(const LafortuneRgb& lobe, const FactorizationOptions& options = {});

/// The Vulkan path: the three kernels recorded in one Sequence (F, G and H stay on the
/// device; only the grids and cube-maps, and F with keep_matrix, are read back).
class FactorizeVk {
public:
    explicit FactorizeVk(gpu::Context& ctx);
    [[nodiscard]] Factorization run(const LafortuneRgb& lobe, const FactorizationOptions& options = {});

private:
    gpu::Context* m_ctx;
    BrdfMatrixVk m_matrix;
    NormalizedDecompositionVk m_decomposition;
    CubemapsVk m_cubemaps;
};

/// Either path; ctx is required for Vulkan.
[[nodiscard]] Factorization factorize(const LafortuneRgb& lobe, const FactorizationOptions& options,
                                      FactorizationBackend backend, gpu::Context* ctx = nullptr);

// ---- approximation error -------------------------------------------------------------

/// sqrt(sum (G H - F)^2 / sum F^2) over the valid entries of F, all channels (in double).
[[nodiscard]] double matrix_relative_rms(const BrdfMatrix& matrix, const Decomposition& decomposition);

struct DirectError {
    double grid = 0.0; ///< G, H interpolated bilinearly from the grids
    double cube = 0.0; ///< G, H looked up bilinearly in the cube-maps (NaN without them)
    uint32_t pairs = 0;
};
/// Relative RMS of G(h) H(d) against lafortune_eval(u, v) for `pairs` pairs (u, v) drawn
/// uniformly (in solid angle) from the upper hemisphere with a fixed seed: the sampling,
/// decomposition and interpolation errors together.
[[nodiscard]] DirectError direct_relative_rms(const LafortuneRgb& lobe, const Decomposition& decomposition,
                                              const Cubemap* cube_g, const Cubemap* cube_h, uint32_t pairs = 1u << 18,
                                              uint32_t seed = 1);

} // namespace specula::factorization
