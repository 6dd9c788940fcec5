#pragma once
// Stage 5 (specular): the fit of one material family to residual samples, whichever it is
// (docs/pipeline.md section 5.6). The Lafortune fit (lafortune_fit.h) reads the specular
// residual f_s (its diffuse is Lambertian, k_d = 1); the coated fit (coated_fit.h) reads the
// total BRDF c / E, since its diffuse factor depends on the index it fits.
#include "material/material.h"
#include "specular/coated_fit.h"
#include "specular/lafortune_fit.h"
#include "specular/residuals.h"

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula {

struct MaterialFitOptions {
    LafortuneFitOptions lafortune;
    CoatedFitOptions coated;
    std::size_t max_samples = 200000; ///< a deterministic stride subsample of at most this many (0: all)
};

/// One family's fit: the family's own record (parameters, standard errors, status) and the
/// model it gives.
struct MaterialFit {
    MaterialFamily family = MaterialFamily::Lafortune;
    std::optional<LafortuneFitRgb> lafortune; ///< family Lafortune
    std::optional<CoatedFit> coated;          ///< family Coated
    std::size_t samples = 0;                  ///< samples the fit used (after the subsample)
    double seconds = 0.0;
    /// The model to render and subtract: the Lafortune lobe of the converged channels (absent
    /// when none converged), or the coated parameters when usable.
    [[nodiscard]] std::optional<SpecularModel> model() const;
    /// Per channel for Lafortune, one entry for coated: the fit's status words.
    [[nodiscard]] std::vector<std::string> status() const;
    /// One line: the parameters and the status.
    [[nodiscard]] std::string describe() const;
};

/// Fits `family` to the used samples.
[[nodiscard]] MaterialFit fit_material(MaterialFamily family, std::span<const ResidualSample> samples,
                                       const MaterialFitOptions& options);

/// At most max_samples of `all`, by a deterministic stride (0: all).
template <class T> [[nodiscard]] std::vector<T> stride_subsample(std::vector<T> all, std::size_t max_samples) {
    if (max_samples != 0 && all.size() > max_samples) {
        const std::size_t stride = (all.size() + max_samples - 1) / max_samples;
        std::size_t k = 0;
        for (std::size_t i = 0; i < all.size(); i += stride) all[k++] = all[i];
        all.resize(k);
    }
    return all;
}

/// The largest relative change |next - previous| / max(1e-6, |previous|) of the parameters
/// (Lafortune: Cx, Cz, N per channel; coated: eta, alpha, tint). Different families: 1.
[[nodiscard]] double max_relative_change(const SpecularModel& next, const SpecularModel& previous) noexcept;

} // namespace specula
