#pragma once
/// \file
/// The core material for ordinary viewers, fitted in image space (docs/SPECULA_lafortune.md,
/// "Viewer approximation"): the roughness, F0 and F90 of glTF's BRDF (shared/gltf_core.h, as
/// three.js draws a point light) that best reproduce the captured train frames' pixels, with the
/// reconstructed albedo as the base colour (times 1 / (1 - F0), material/core_material.h).
///
/// The samples are the residual pass's, as total BRDF samples (coated_fit.h MaterialSample: b and
/// rho / pi, weight Ebar^2, so the cost is the squared pixel error). Two forms, the lower error wins:
///   A. glTF's base specular layer: for a roughness the model is linear in (F0, F90) once the base
///      colour's scale 1 / (1 - F0) is held: solved in closed form with 0 <= F0 <= F90 <= 1, the
///      scale updated from F0 and solved again (4 times: the scale moves by under 1e-4 then);
///   B. a clearcoat layer alone (KHR_materials_clearcoat, F0 0.04), whose Fresnel at the viewer
///      dims the diffuse as a coated dielectric's does: its weight in [0, 1] the same way.
/// The roughness: a grid of 24 values over [0.045, 1] (three.js's floor to 1), then golden-section
/// search between the best one's neighbours.
///
///   CoreFit f = fit_core_material(to_material_samples(rs.samples, 200000));
///   f.material: roughness, f0, f90;  f.rms: the fit's pixel error (image units)
#include "material/core_material.h"
#include "specular/coated_fit.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <span>
#include <string>

namespace specula {

struct CoreFitOptions {
    std::size_t roughness_steps = 24;
    std::size_t golden_iterations = 20;
    /// At most this many samples (every k-th, evenly spaced; 0: all): 5 parameters need few, and
    /// each roughness tried is a pass over them.
    std::size_t max_samples = 50000;
    /// Minimise the error on sRGB-encoded values (the display values the report scores for 8-bit sRGB
    /// captures) instead of linear ones: each sample's weight times the square of the encoding's slope
    /// at its observed pixel value (Ebar b, channel mean).
    bool srgb_display = false;
    /// Workers: the two hypotheses' searches side by side (each the same as alone: the same
    /// result for any count).
    unsigned threads = 1;
};

struct CoreFit {
    CoreMaterial material;
    bool fitted = false;     ///< false: no usable sample (material is then the diffuse-only core)
    /// sqrt(weighted mean square of the pixel error), channel mean: image units, or (srgb_display)
    /// about display units (the encoding's slope times the linear error).
    double rms = 0.0;
    double diffuse_only_rms = 0.0; ///< the same for F0 = F90 = 0 (no specular, base colour = albedo)
    std::size_t samples = 0;
    double seconds = 0.0;
    std::string note;        ///< why not fitted
};

[[nodiscard]] CoreFit fit_core_material(std::span<const MaterialSample> samples, const CoreFitOptions& options = {});

/// {fitted, material (material/core_material.h to_json), rms, diffuse_only_rms, samples, seconds, note}.
[[nodiscard]] nlohmann::json to_json(const CoreFit& f);

} // namespace specula
