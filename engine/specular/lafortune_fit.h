#pragma once
// Stage 5 (specular), the Lafortune fit (pipeline.md section 5; thesis eq. 2.1 and section 3.2.2):
// one isotropic lobe per RGB channel, fitted by Levenberg-Marquardt to specular BRDF
// samples (u, v, f_s, weight), u and v the light and view directions in the tangent frame:
//
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N          (eq. 2.1, rho_d = 0)
//
// The model is shared/lafortune.h (one definition for the shaders and this fit).
//
//   LafortuneFitRgb fit = fit_lafortune(samples, {});           // robust (default)
//   fit.channel[0].cx, .cz, .n, .status, .reason, .std_error ...
//   fit_lafortune(samples, {.method = LafortuneFitMethod::ThesisPlain});   // for comparison
//
// Robust method (LafortuneFitMethod::Robust). The lobe's height is |C|^N, so in the
// thesis's (Cx, Cz, N) the columns of the Jacobian are nearly parallel (a change of N is
// undone by a change of |C|) and their scales differ by orders of magnitude when N spans
// 1..1e4. The fit works instead in
//
//     phi  = atan2(Cz, Cx)                       shape (off-specularity; any quadrant,
//                                                so Cz < 0 and Cx > 0 are reachable)
//     L    = ln N                                width, bounded to N in [0.5, 1e5]
//     eta  = ln f_s(u*, v*)                      the lobe's log value at a reference
//                                                sample (the brightest one, near the peak)
//
//     f_s(u, v) = exp(eta + N ln(g(u, v) / g(u*, v*))),   g = cos(phi) a + sin(phi) b,
//     a = ux vx + uy vy,  b = uz vz   (zero where g <= 0: the clamp of eq. 2.1)
//
// so height and width decouple: changing N at fixed eta leaves the lobe's value at the
// reference unchanged and only changes its width; ln(g/g*) is O(1/N) inside the lobe, so
// the columns of J are all of the order of f_s whatever N is. Back to the thesis form:
// |C| = exp(eta / N) / g(u*, v*), Cx = |C| cos(phi), Cz = |C| sin(phi).
// The height is linear in exp(eta): at every start and after each accepted step it is
// re-solved in closed form (weighted linear least squares), and the fit starts from a
// log grid over N (1, 3, 10, ... 1e4) times a few shapes, running LM from the best ones.
//
// Clipped (saturated) samples are censored: a sample at the clip level only says that the
// true value is at least that, so its residual is min(0, model - clip) (Tobit-style).
// The clip level is given, or detected (several samples share the exact maximum).
//
// The result never holds NaN or infinity: non-finite values end the fit with an honest
// status instead.
//
// When the free lobe cannot be trusted, the robust fit falls back to a constrained lobe
// instead of giving up (status `constrained`, and the reason says why the free one was not
// used). The free lobe is not used when
//   - it is underdetermined or did not converge (the statuses above);
//   - the samples see one light-view angle only: the 5-95% spread of acos(u.v) is below
//     `min_light_view_spread_deg` (10 deg). With s = u.v = a + b and t = r.v = b - a
//     (r = u mirrored about the normal), base = (Cx + Cz)/2 s + (Cz - Cx)/2 t: the
//     off-specular part (Cx + Cz) is what changes the lobe with the light-view angle, so
//     samples at one angle (the thesis's rig: six lights on a ring about 15 degrees around
//     each camera) separate Cx from Cz only through the exact shape of the model. On such
//     samples the free fit of a GGX truth settles confidently (standard error 0.01) on a
//     retro-reflective lobe (Cx > 0) that is wrong everywhere else. 10 degrees is about three
//     times the spread the thesis's ring gives (light 15 +- 2 degrees off the view: 3.7). On
//     rings of 13 to 13 + w degrees (1% noise), the free fit of a Lafortune truth extrapolates
//     to the spread rig within 5% from 7 degrees of spread on (21% at 3.6), while that of a
//     rough GGX truth leaves the retro side from about 7 degrees at alpha 0.3 (Cx -0.02; -0.19
//     at 11) and only from about 40 at alpha 0.5, which no Lafortune lobe represents;
//   - its peak lies far outside the samples: the lobe's reachable peak is more than
//     `max_peak_ratio` (K = 256) times the largest value it takes at any sample. K = 2^8 is
//     the range of one 8-bit exposure, and for a Gaussian-like lobe exp(-N x^2 / 2) it puts
//     the nearest sample sqrt(2 ln K) = 3.3 lobe widths from the peak, where only the tail's
//     assumed shape carries the height. The stiff-case suite's noise-free and 5%-noise tail
//     cases extrapolate 10x and 95x and are recovered; its 300-sample 20%-noise case
//     extrapolates 694x and was already underdetermined;
//   - its directional albedo exceeds 1 (the white-furnace bound; lafortune_max_albedo), but
//     not by 2 standard errors of ln(albedo) (propagated from the fit's covariance): the
//     samples do not ask for the excess. A lobe the samples put above the bound by more is
//     kept and the reason says so: the measured values ask for it (a capture's radiometric
//     scale, or a non-physical truth: the thesis's table 5.2 cologne, vase and woodenpot
//     lobes reach 1.5 to 2.3, and the fit must recover them; on the spread rig the vase's
//     peak, towards grazing, is never seen, yet its free fit is right).
// The constrained lobe is a lobe about the mirror direction, Cx = -Cz (a Phong lobe,
// f = Cz^N max(0, r.v)^N): per channel its height, and one N shared by the channels that fall
// back (fit_lafortune), by a 1-D search over ln N with the heights in closed form. Its
// directional albedo is largest at normal incidence, Cz^N 2 pi / (N + 2) (Lafortune and
// Willems 1994, "Using the modified Phong reflectance model for physically based
// rendering"); above 1, not by 2 standard errors, it is refitted with the height bounded by it.
// The channel keeps no lobe (`no specular energy`) only when the residuals hold no more
// energy than the noise.
#include "material/lafortune.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <span>
#include <string>

namespace specula {

/// One specular BRDF sample: unit light (u) and view (v) directions in the tangent frame
/// (z = normal), the value f_s per RGB channel, and a weight (>= 0; e.g. the irradiance E,
/// pipeline.md section 4). Samples with weight 0 are ignored.
struct LafortuneSample {
    glm::vec3 u{0.0f, 0.0f, 1.0f};
    glm::vec3 v{0.0f, 0.0f, 1.0f};
    glm::vec3 f{0.0f};
    float weight = 1.0f;
};

enum class LafortuneFitMethod {
    Robust,      ///< reparametrized (eta, phi, ln N), multi-start, bounded N, censored clipping
    ThesisPlain, ///< thesis section 3.2.2: LM in (Cx, Cz, N) from (-1, 1, 10), nothing else
};

enum class LafortuneFitStatus {
    Converged,        ///< the fit met its tolerances and the parameters are determined
    NotConverged,     ///< iteration limit, or the iteration hit a non-finite value
    Underdetermined,  ///< too few samples, singular J^T J, or the width and height are not separable
    NoSpecularEnergy, ///< the samples hold no more energy than the noise
    Constrained,      ///< the free lobe was not used (reason); a mirror lobe Cx = -Cz was fitted instead
};

/// True for the statuses whose lobe is used (converged and constrained).
[[nodiscard]] constexpr bool has_lobe(LafortuneFitStatus status) noexcept {
    return status == LafortuneFitStatus::Converged || status == LafortuneFitStatus::Constrained;
}

[[nodiscard]] const char* to_string(LafortuneFitStatus status) noexcept;
[[nodiscard]] const char* to_string(LafortuneFitMethod method) noexcept;

struct LafortuneFitOptions {
    LafortuneFitMethod method = LafortuneFitMethod::Robust;
    /// Start point (thesis section 3.2.2). ThesisPlain starts only here; Robust adds it to its grid.
    double start_cx = -1.0;
    double start_cz = 1.0;
    double start_n = 10.0;
    /// Robust: how many of the best grid starts are refined by LM (0 = only the best one).
    std::uint32_t restarts = 4;
    /// Robust: bounds on N.
    double min_n = 0.5;
    double max_n = 1e5;
    std::uint32_t max_iterations = 200;
    double cost_tolerance = 1e-12;     ///< relative decrease of the cost that ends the iteration
    double step_tolerance = 1e-10;     ///< relative step that ends the iteration
    double gradient_tolerance = 1e-14; ///< |J^T r|_inf relative to the cost that ends the iteration
    /// Standard deviation of f_s noise at weight 1 when known (0 = unknown): used for the
    /// "no specular energy" test (the F-test on the fit is used when unknown).
    double noise_sigma = 0.0;
    /// Clip level of f_s: samples at or above it are censored. < 0: detect (at least
    /// `clip_detect_count` samples share the maximum); 0: no clipping. Robust only.
    double saturation = -1.0;
    std::uint32_t clip_detect_count = 3;
    /// Robust: the fit is first run on at most this many samples (a deterministic stride
    /// subsample), then polished on all of them. 0 = always use all.
    std::uint32_t coarse_samples = 20000;
    /// Robust: the grid of starts is ranked on a stride subsample of at most this many of
    /// the coarse samples (0 = on all of them); the best starts' heights are solved again on
    /// the coarse samples before LM. The ranking only picks where LM starts.
    std::uint32_t grid_samples = 10000;
    /// Underdetermined when a relative standard error (Cx, Cz or N) exceeds this...
    double max_relative_error = 0.5;
    /// ...or this, when no sample reaches half of the lobe's reachable peak.
    double max_relative_error_unseen_peak = 0.05;
    double max_condition = 1e14; ///< of the column-scaled internal J^T J
    /// Robust: fall back to the constrained mirror lobe when the free lobe is not used
    /// (lafortune_fit.h, top); false: the free fit's status stands.
    bool constrained_fallback = true;
    /// The free lobe needs the samples' light-view angles acos(u.v) to spread at least this
    /// much (degrees, 5th to 95th weighted percentile).
    double min_light_view_spread_deg = 10.0;
    /// K: the free lobe's reachable peak may be at most K times its largest value at a sample.
    double max_peak_ratio = 256.0;
    /// Refuse (free) or bound (constrained) lobes above the white-furnace bound by less than 2
    /// standard errors of ln(albedo).
    bool white_furnace = true;
    /// Worker threads: above 1, the three channels' free fits run side by side, a thread each (the
    /// fit is the same for any count).
    unsigned threads = 1;
};

/// The fit of one channel, in the thesis's form.
struct LafortuneChannelFit {
    LafortuneFitStatus status = LafortuneFitStatus::Underdetermined;
    std::string reason;         ///< human-readable: why this status
    double cx = 0.0, cz = 0.0, n = 0.0;
    double std_error_cx = 0.0, std_error_cz = 0.0, std_error_n = 0.0; ///< sqrt diag of sigma^2 (J^T J)^-1
    double cost = 0.0;          ///< weighted sum of squared residuals
    double rms = 0.0;           ///< sqrt(cost / sum of weights)
    double condition = 0.0;     ///< of J^T J in (Cx, Cz, N)
    double condition_internal = 0.0; ///< of the column-scaled J^T J in the fit's own parameters
    std::uint32_t iterations = 0;    ///< LM iterations (all starts)
    std::uint32_t samples = 0;       ///< samples with weight > 0
    std::uint32_t censored = 0;      ///< samples treated as clipped
    double peak_seen = 0.0;     ///< max model value over the samples / the lobe's reachable peak
    /// The lobe's largest directional albedo over outgoing directions (the white-furnace
    /// integral, at most 1 for a physical material; robust fits with a lobe only, else 0).
    /// Where the bound max(|Cx|, |Cz|)^N 2 pi / (N + 1) is at most 1, that bound instead.
    double max_albedo = 0.0;
    double light_view_spread_deg = 0.0; ///< 5-95% spread of acos(u.v) over the samples (degrees)
    double seconds = 0.0;
};

struct LafortuneFitRgb {
    LafortuneChannelFit channel[3];
    /// The lobe of the channels whose fit has one (has_lobe: converged or constrained); the
    /// others are zero (Cx = Cz = 0, N = 1: no specular term in that channel). The one
    /// conversion from a fit to a lobe.
    [[nodiscard]] LafortuneRgb converged_lobe() const noexcept;
};

/// Fits one channel (0, 1, 2 = r, g, b of LafortuneSample::f). Throws UsageError for a bad
/// channel or options; everything about the data is reported in the status.
[[nodiscard]] LafortuneChannelFit fit_lafortune_channel(std::span<const LafortuneSample> samples, int channel,
                                                        const LafortuneFitOptions& options = {});

/// Fits the three channels independently; the channels that fall back to the constrained
/// lobe share its N (one highlight shape, a height per channel).
[[nodiscard]] LafortuneFitRgb fit_lafortune(std::span<const LafortuneSample> samples,
                                            const LafortuneFitOptions& options = {});

/// The lobe's largest directional albedo (the white-furnace integral of material.h's
/// directional_albedo, diffuse albedo 0) over outgoing polar angles (every 5 degrees, 88 and
/// 89.5, then a golden-section search around the largest); `theta_deg` receives the angle.
/// The quadrature has ceil(3 sqrt(N)) polar cells (32 to 640): a lobe of width 1/sqrt(N) is
/// resolved, overestimated by about 1%.
[[nodiscard]] double lafortune_max_albedo(double cx, double cz, double n, double* theta_deg = nullptr);

/// The lobe's largest value over mirror (Cx < 0) or retro (Cx > 0) configurations whose
/// polar angles are at most theta_max (radians): the base |Cx| sin^2 + Cz cos^2 is linear
/// in sin^2, so the maximum is at 0 or theta_max.
[[nodiscard]] double lafortune_reachable_peak(double cx, double cz, double n, double theta_max) noexcept;

} // namespace specula
