#pragma once
// Default grid and cube-map resolutions of the factorization, chosen from the lobe's
// width (pipeline.md section 9: "a factorization grid no finer than the lobe's width needs").
//
// The rule (derivation in resolution.cpp):
//   h grid:  R_h = ceil(kCellsPerHalfWidth * sqrt(N_max)),   clamped to [16, 128]
//   d grid:  R_d = ceil(kCellsPerHalfWidth * sqrt(N_d)),     clamped to [16, 64],
//            N_d = max over channels of N |Cx + Cz| / max(|Cx|, |Cz|)
//   and R_h R_d <= kMaxGridProduct (F must fit one storage binding: 3 R_h^2 R_d^2 floats);
//   cube faces: R_cube = ceil(R * pi / (2 sqrt 2)) rounded up to a multiple of 8.
// In the mirrored and warped parametrizations (shared/gshd.h parts 4, 5) the two axes swap roles (derivation
// in resolution.cpp): R_h is the rule's d value ([16, 64]) and R_d resolves the peak, with
// kMirroredPeakCellsPerHalfWidth instead of kCellsPerHalfWidth:
//   R_d = ceil(kMirroredPeakCellsPerHalfWidth * sqrt(N_max)),  clamped to [16, 128]
// (finer: there the separability floor is gone and the rendered highlights' tails need it).
// The coated family (shared/coated.h; no warped parametrization) has its own rule, from the GGX
// roughness alpha instead of the lobe's N (derivation and measurements in resolution.cpp):
//   grazing axis (d plain, h mirrored): R_g = ceil(kCoatedGrazingCellsPerAlpha alpha), clamped to [32, 64]
//   peak axis (h plain, d mirrored):    R_p = min(kMaxGridResH, kMaxGridProduct / R_g)
#include "material/factor_param.h"
#include "material/lafortune.h"
#include "material/material.h"
#include "shared/lafortune.h"

#include <cstdint>
#include <string>

namespace specula::factorization {

struct FactorizationResolution {
    uint32_t grid_h = 0; ///< h grid is grid_h x grid_h cells (hemispherical octahedral map)
    uint32_t grid_d = 0; ///< d grid is grid_d x grid_d cells
    uint32_t cube_g = 0; ///< face size of the G cube-map
    uint32_t cube_h = 0; ///< face size of the H cube-map
    std::string reason;  ///< how the numbers were chosen, for the report
};

inline constexpr double kCellsPerHalfWidth = 2.0;
inline constexpr double kMirroredPeakCellsPerHalfWidth = 16.0;
/// The warped parametrization (shared/gshd.h part 5): F is exactly rank 1 per channel, so G is
/// flat (R_h = kMinGridRes) and the whole error is H's interpolation along d, where the peak
/// needs kWarpedPeakCellsPerHalfWidth (twice that when a channel has Cz < 0: its peak is at
/// the d map's horizon, where a cell spans about twice the angle it spans at the pole).
inline constexpr double kWarpedPeakCellsPerHalfWidth = 28.0;
inline constexpr uint32_t kMinGridRes = 16;
inline constexpr uint32_t kMaxGridResH = 128;
inline constexpr uint32_t kMaxGridResD = 64;
inline constexpr uint32_t kMaxGridProduct = 3072; // 3 (R_h R_d)^2 floats <= 108 MiB
/// The coated family: the grazing axis's resolution per unit of alpha, and its bounds
/// (resolution.cpp, coated_resolution: why and what was measured).
inline constexpr double kCoatedGrazingCellsPerAlpha = 400.0;
inline constexpr uint32_t kCoatedMinGrazingRes = 32;
inline constexpr uint32_t kCoatedMaxGrazingRes = 64;

/// The default rule above, for the grids of parametrization `param` (the lafortune family's or
/// the coated family's). Non-finite or non-positive exponents count as N = 1.
[[nodiscard]] FactorizationResolution default_resolution(const SpecularModel& model, FactorParam param = FactorParam::Gshd);

/// Cube-map face size that resolves a grid of resolution `grid_res` (texel no larger than a cell).
[[nodiscard]] uint32_t cube_res_for_grid(uint32_t grid_res);

} // namespace specula::factorization
