#pragma once
// Stage 5 (specular), the coated family's fit (docs/pipeline.md section 5.6; the model is
// shaders/shared/coated.h). Every residual sample carries the total BRDF the capture shows,
//
//     b = c / E = (rho / pi) k_d(u, v; eta) + tint F D G1 G1 / (4 (n.u) (n.v))(u, v; alpha, eta),
//
// with rho the particle's albedo from the diffuse solve. The global parameters (alpha, eta) are
// fitted by Levenberg-Marquardt on the weighted residuals sqrt(w) (model - b) (w = Ebar^2, so a
// residual is in image units, shared/residuals.h), in (ln alpha, eta): the log makes alpha's
// column scale-free from a near-mirror 0.01 to a rough 1. The tint enters linearly: it is 1
// (a clear dielectric, the default), or solved per channel in closed form at every step
// (variable projection, Golub and Pereyra 1973), so LM only sees the two nonlinear parameters.
// So does a scale s of the diffuse term, b = s (rho / pi) k_d + ...: rho comes from a diffuse
// solve made with another material (the first one's is Lambertian, k_d = 1), which spreads the
// coating's fall-off over the albedo and leaves it low by the mean of k_d over the views it
// read (5 to 15%); without s that deficit shows everywhere as a broad reflection, and on the
// vase at 512 px the fit ran to alpha = 1 (docs/pipeline.md 5.7). The albedo is solved again
// with the fitted material, so s only keeps that offset out of (alpha, eta). The steps take the
// curvature in (ln alpha, eta) with s and the tint projected out (Kaufman 1975: the Schur
// complement of J^T J); eta and s both scale the diffuse term, and with them held fixed the
// iteration crept along that valley (40 to 96 iterations a run on the demo can, 5 to 17 now).
//
// Starts: a grid over (ln alpha, eta) on a stride subsample; LM from the best cells, on all the
// samples. Robust: iteratively reweighted (Huber weights, k = 1.345 robust sigmas, sigma from
// the median absolute residual): clipped highlights are already dropped by the residual pass,
// and what remains of shadow edges and of light that bounced off the object itself counts
// linearly, not quadratically.
//
// Uncertainty as the Lafortune fit reports it: standard errors sqrt(diag(s^2 (J^T J)^-1)),
// s^2 = cost / (m - p), the condition number of J^T J (column-scaled), iterations and cost;
// J^T J with the free linear parameters projected out (the scale and eta trade against each
// other: with the scale held, eta's error would understate what the samples leave open). A
// parameter whose relative standard error exceeds `max_relative_error` is named as one the
// samples do not determine (for instance eta from a rig whose lights sit near the camera: the
// diffuse factor's fall-off and the Fresnel term both need grazing or wide-angle samples).
#include "material/material.h"
#include "specular/residuals.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula {

/// One sample of the total BRDF: unit light and view directions in the tangent frame, the
/// observed c / E per channel, the particle's rho / pi, and the weight (Ebar^2; 0: ignored).
struct MaterialSample {
    glm::vec3 u{0.0f, 0.0f, 1.0f};
    glm::vec3 v{0.0f, 0.0f, 1.0f};
    glm::vec3 b{0.0f};
    glm::vec3 rho_over_pi{0.0f};
    float weight = 1.0f;
};

/// The residual pass's samples as total BRDF samples: b = f_s + (rho / pi) k_d, undoing the
/// diffuse term of the material the residuals were computed with (dropped samples are skipped).
/// With max_samples, only every used_sample_stride-th used one (residuals.h).
[[nodiscard]] std::vector<MaterialSample> to_material_samples(std::span<const ResidualSample> samples, std::size_t max_samples = 0);

enum class CoatedFitStatus {
    Converged,      ///< tolerances met, alpha and eta determined
    Underdetermined,///< converged, but a parameter's relative standard error exceeds the bound (named in `reason`)
    NotConverged,   ///< iteration limit or a non-finite value
    TooFewSamples,  ///< fewer samples than parameters
};
[[nodiscard]] const char* to_string(CoatedFitStatus s) noexcept;

struct CoatedFitOptions {
    bool fit_tint = false;          ///< solve the tint per channel (else 1, 1, 1)
    bool fit_diffuse_scale = true;  ///< solve the diffuse term's scale s (else 1)
    /// Set: eta is held at this value (the coating's index when known: 1.45 to 1.6 for most
    /// plastics, varnishes and glazes) and alpha alone is fitted; its standard error is then 0.
    std::optional<double> fixed_eta;
    /// Set (and eta not held): where eta ends within 5% of the top of its range, the fit is made again with
    /// eta held at this value, status underdetermined with the reason. 1.5: most plastics,
    /// varnishes and glazes.
    std::optional<double> eta_at_bound = 1.5;
    std::uint32_t coarse_samples = 20000; ///< grid search on a stride subsample of at most this many
    std::uint32_t restarts = 3;     ///< LM from this many of the best grid cells
    std::uint32_t max_iterations = 100;
    std::uint32_t robust_passes = 4;///< IRLS reweightings (0: plain least squares)
    double cost_tolerance = 1e-10;  ///< relative cost decrease that ends the iteration
    double max_relative_error = 0.05; ///< a parameter is determined when its relative std error is below this
    unsigned threads = 0;           ///< threads of the grid search, the LM starts and the sums over all samples (0: the hardware's)
};

struct CoatedFit {
    CoatedFitStatus status = CoatedFitStatus::TooFewSamples;
    std::string reason;
    CoatedParams params;
    double std_error_alpha = 0.0, std_error_eta = 0.0;
    glm::dvec3 std_error_tint{0.0};
    double diffuse_scale = 1.0; ///< s: what the samples' rho / pi was off by, in the fit's eyes
    bool alpha_determined = false, eta_determined = false;
    double cost = 0.0;      ///< robust-weighted sum of squared residuals (image units^2)
    double rms = 0.0;       ///< sqrt(unweighted-by-robustness mean square residual per channel)
    double condition = 0.0; ///< of the column-scaled J^T J in (ln alpha, eta), the linear parameters projected out
    std::uint32_t iterations = 0;
    std::uint32_t samples = 0;
    double seconds = 0.0;
    /// The params when usable (Converged or Underdetermined: the best fit, with what it does
    /// not determine said), else nullopt.
    [[nodiscard]] bool usable() const noexcept {
        return status == CoatedFitStatus::Converged || status == CoatedFitStatus::Underdetermined;
    }
};

/// Fits (alpha, eta) and optionally the tint to the samples (eta held where the options say
/// so, or where it ends at the top of its range: CoatedFitOptions::eta_at_bound). Never returns NaN: a
/// non-finite value ends the fit with an honest status.
[[nodiscard]] CoatedFit fit_coated(std::span<const MaterialSample> samples, const CoatedFitOptions& options = {});

/// The weighted mean square (image units^2, channel mean) of model - b over the samples, for any
/// material family: the validation error of the model choice.
[[nodiscard]] double material_mean_square_error(const SpecularModel& model, std::span<const MaterialSample> samples);
/// The same over the used residual samples, converted one at a time (to_material_samples,
/// without holding the converted list): the same value to the last bit.
[[nodiscard]] double material_mean_square_error(const SpecularModel& model, std::span<const ResidualSample> samples);
/// One used residual sample's part of that error: adds w |model - b|^2 / 3 to sq and w to wsum
/// (nothing where the weight is not positive); in the samples' order, the same sums.
void add_material_square_error(const shared::MaterialGpu& m, const ResidualSample& s, double& sq, double& wsum) noexcept;

} // namespace specula
