#pragma once
// The planner (pipeline.md section 9): what this scene needs, decided from the capture
// and from cheap measurements, each decision explicit data that the report shows.
//
//   decision            auto rule                                          forced by
//   occlusion_rays      cast only where the mesh can occlude itself       --occlusion-rays on|off
//                       (visibility/convexity.h)
//   diffuse_mode        photometric only where enough train views have    --mode albedo|photometric
//                       >= 3 non-coplanar light directions and no
//                       specular fit needs the highlights
//   atlas               charts; texels <= image pixels (texels_per_pixel   --atlas charts|patchwork,
//                       1), within the budget (geometry/atlas.h)           --texels-per-pixel, --texture-size
//   albedo_refinement   kPixelFitIterations of the pixel fit               --refine-rounds, --refine-method
//                       (refine/albedo_refine.h)
//   specular_stages     residual samples, then the fit, factorization and  --specular on|off
//                       specular pass only when the residuals hold more
//                       energy than the noise (specular/residuals.h)
//   factorization_grid  no finer than the lobe's width needs              --factorization-grid H,D
//                       (factorization/resolution.h)
//   indirect            light that bounced off the object, removed from    --indirect on|off
//                       the captures before the solves, added to the
//                       renders, where the mesh can see itself and that
//                       light is above the images' quantization
//
// Each decision says whether it was automatic or forced, why, and what it cost or saved:
// when auto skips or coarsens work, `avoided_seconds` is an ESTIMATE of the time that work
// would have taken (from a cheap measurement; `cost_basis` says which); when a flag forces
// the work on, `measured_seconds` is what it took. The decision functions are pure (the
// tests call them directly); reconstruct.cpp is the only caller that runs stages.
#include "capture/capture.h"
#include "material/lafortune.h"
#include "factorization/resolution.h"
#include "geometry/atlas.h"
#include "specular/residuals.h"
#include "visibility/convexity.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace specula {

/// A decision left to the planner, or forced either way from the command line.
enum class Toggle { Auto, On, Off };
[[nodiscard]] const char* to_string(Toggle t) noexcept;

/// The diffuse solve's mode: the planner's choice, or forced.
enum class DiffuseModeChoice { Auto, Albedo, Photometric };
[[nodiscard]] const char* to_string(DiffuseModeChoice m) noexcept;

struct PlanDecision {
    std::string name;    ///< occlusion_rays, diffuse_mode, atlas, specular_stages, factorization_grid
    std::string value;   ///< what was chosen, e.g. "skip", "cast", "photometric", "h 16 x d 16"
    bool forced = false; ///< a flag chose it (else: auto)
    bool skipped = false; ///< the choice leaves a stage or a mode out
    std::string reason;
    std::optional<double> avoided_seconds;  ///< estimated time of the work left out (auto)
    std::optional<double> measured_seconds; ///< measured time of work a flag forced on
    std::string cost_basis;                 ///< how the figure above was obtained
    nlohmann::json detail = nlohmann::json::object();
};

struct Plan {
    std::vector<PlanDecision> decisions;
    [[nodiscard]] PlanDecision* find(const std::string& name);
    [[nodiscard]] const PlanDecision* find(const std::string& name) const;
    PlanDecision& add(PlanDecision d);
    /// [{name, value, mode: "auto"|"forced", skipped, reason, avoided_seconds, measured_seconds, cost_basis, detail}]
    [[nodiscard]] nlohmann::json to_json() const;
};

// ---- occlusion rays ---------------------------------------------------------------------

/// Auto: cast where the mesh is not convex. Off on a non-convex mesh is allowed (to measure
/// what the rays cost) and the reason says the result is then wrong where the mesh shadows
/// or hides itself.
[[nodiscard]] PlanDecision decide_occlusion_rays(const ConvexityReport& convexity, Toggle toggle);

// ---- diffuse mode -----------------------------------------------------------------------

/// How well each train view's lights constrain the photometric solve (thesis eq. 3.1),
/// seen from the mesh's bounding-box centre: per view, the unit light directions u_i give
/// C = sum u_i u_i^T, and rcond = lambda_min / lambda_max of C (0: coplanar or < 3 lights).
struct LightConditioning {
    std::size_t views = 0;          ///< train views
    std::size_t capable_views = 0;  ///< >= 3 lights and rcond >= min_rcond
    double median_rcond = 0.0;
    double min_rcond = 0.0;         ///< the threshold used
    std::size_t min_lights = 0;     ///< fewest train lights of a view
    std::size_t max_lights = 0;     ///< most train lights of a view
    std::size_t rich_views = 0;     ///< >= kNormalMapMinLights lights and rcond >= kNormalMapMinRcond
};
[[nodiscard]] LightConditioning light_conditioning(const Capture& capture, double min_rcond);

/// Fraction of the train views that must allow the photometric solve for auto to pick it.
inline constexpr double kPhotometricViewFraction = 0.5;

/// Auto: albedo mode while the specular stages may run: the photometric solve fits a
/// tilted normal to part of a highlight and hides specular energy from the energy test
/// (measured on the glossy sphere at 128 px: 5.1 -> 2.8 noise variances, below the
/// threshold 4, so the lobe was left out). With the specular stages off, photometric where
/// at least kPhotometricViewFraction of the train views allow it (per particle, the solve
/// still falls back where its best view's lights do not), else albedo.
[[nodiscard]] PlanDecision decide_diffuse_mode(const LightConditioning& lc, DiffuseModeChoice choice, bool specular_may_run);
/// The LambertMode a decision chose.
[[nodiscard]] bool decided_photometric(const PlanDecision& d);

// ---- normal map -------------------------------------------------------------------------

/// A view of a photometric rig (a dome, a light stage): at least this many train lights...
inline constexpr std::size_t kNormalMapMinLights = 12;
/// ...whose directions from the object's centre are this well spread (rcond of sum u u^T).
inline constexpr double kNormalMapMinRcond = 0.05;

/// Auto: on when some train view is rich (kNormalMapMinLights, kNormalMapMinRcond): the
/// photometric solve then refines the normals, with the final material's specular light
/// subtracted and each view's highlights rejected among many samples, and the bundle gets
/// them as a tangent-space normal map (glTF normalTexture). Off otherwise: a few lights per
/// view (the 20 x 6 rig, the thesis's ring) tilt a photometric normal toward each highlight.
[[nodiscard]] PlanDecision decide_normal_map(const LightConditioning& lc, Toggle choice);
[[nodiscard]] bool decided_normal_map(const PlanDecision& d);

// ---- indirect light ---------------------------------------------------------------------
/// Light that bounced off the object (indirect/indirect.h) counts when it changes the captured
/// pixels by at least this many codes of an 8-bit sRGB image at the 99th percentile of the
/// train frames' object pixels: half a code is below what the images can hold.
inline constexpr double kIndirectMinCodes = 0.5;
/// Rounds of the inverse global illumination (solve, indirect light from its albedo, solve on
/// the captures less that light) and the albedo change, relative, that ends them sooner; the
/// round with the material after the specular stages is one more.
/// A round subtracts rho_k S_ind from each pixel (S_ind: the indirect light's part of the
/// shading), so its solve gives rho' = I / S_dir - R rho_k, R = S_ind / S_dir: about the fixed
/// point rho = I / (S_dir + S_ind) it alternates by the factor -R, and diverges where R > 1. So
/// each particle's new albedo is damped, (rho' + R rho_k) / (1 + R), which reaches that fixed
/// point in one round where the light comes from surfaces of about its own albedo, and converges
/// by R / (1 + R) at worst (R per particle from its frames' sums, indirect_images). Knot, 2
/// bounces, 512 px, 64 rays: the hollows' albedo RMSE 2.22% undamped, 2.01% damped
/// (bench/concave_albedo); the vase, forced on, no longer diverges (its rounds moved the albedo
/// by 20%, then 25%; now 8%, then 4.6%) and its hollows go from 57% to 6.1%.
inline constexpr std::uint32_t kIndirectRounds = 2;
inline constexpr double kIndirectTolerance = 0.005;
/// Where R is large, any error of the predicted light is amplified by it in rho': pixels whose
/// added light is over this share of what they show (R over 1) are left out of the solves. Knot,
/// 2 bounces, 512 px, before the damping: the hollows' albedo RMSE 2.54% -> 2.22%.
inline constexpr float kIndirectMaxShare = 0.5f;
/// Does the capture hold the light the model predicts? In the object pixels of the train frames
/// that no light reaches directly (their surface faces away from it, or a shadow ray is blocked), a capture
/// shows only light that bounced off the object (and the room's): the least-squares ratio of the
/// captured values to the predicted indirect light is about 1 for a real object, 0 for a capture
/// rendered with direct light only. Measured over at least kIndirectMinShadowPixels such pixels
/// whose predicted light is at least one 8-bit code, in kIndirectMeasureFrames train frames.
/// Measured: 0.00 for the knot and the can rendered with direct light only; with 2 bounces 1.30
/// (knot, 512 px; 1.30 over all 120 frames), 0.83 (can, 256 px; 0.82) and 0.52 (the vase, 256
/// px; 0.49: its first solve's glossy neck is far too bright, so the prediction is too), where
/// the stage gains: 37.33 -> 37.96 dB test PSNR.
inline constexpr std::size_t kIndirectMinShadowPixels = 500;
inline constexpr double kIndirectMinShadowRatio = 0.25;
/// The measure reads this many train frames, evenly spaced (all when there are fewer): a pass
/// over 24 of 120 frames costs a fifth of one over all of them, which a capture without that
/// light (every capture rendered with direct light only) saves; one with it pays that fifth
/// again, since its rounds need every frame.
inline constexpr std::size_t kIndirectMeasureFrames = 24;
/// ... through a transfer of this many rays a row (a quarter of kTransferRays: a quarter of its
/// time, 0.5 s against 2.0 s on the knot at 384 px). Its prediction is noisier per texel but the
/// ratio sums over thousands of pixels; a capture that holds the light (the measure says on)
/// gets the transfer of --indirect-rays for its rounds.
inline constexpr std::uint32_t kIndirectMeasureRays = 36;
/// ... and of blocks this many times as wide as the rounds' (indirect_block): a quarter of the rows
/// again. The light a surface sends itself varies over the object's features, and the measure sums
/// it over thousands of pixels.
inline constexpr std::uint32_t kIndirectMeasureBlockScale = 2;
struct IndirectMeasure {
    double p99_codes = 0.0;             ///< the predicted light's change of the object pixels, 99th percentile (codes)
    std::size_t shadow_pixels = 0;      ///< unlit object pixels with a prediction of at least one code
    std::optional<double> shadow_ratio; ///< captured / predicted there (least squares), from kIndirectMinShadowPixels on
};
/// Auto: left out when the mesh is convex (it cannot see itself: no ray leaves one point of it
/// toward another); when the indirect light that the first solve's albedo sends stays under
/// kIndirectMinCodes; or when the unlit pixels show less than kIndirectMinShadowRatio of it
/// (the capture does not hold it). On otherwise. `measure` is absent when not measured (convex,
/// or forced off); `estimated_seconds` is the cost of the rays and the rounds (avoided when left out).
[[nodiscard]] PlanDecision decide_indirect(const ConvexityReport& convexity, Toggle toggle,
                                          const std::optional<IndirectMeasure>& measure, double estimated_seconds);
[[nodiscard]] bool decided_indirect(const PlanDecision& d);
/// The transfer's blocks (texels a side): auto, transfer_block_for the particles (about
/// kTransferBlockRows rows); forced, `forced` (--indirect-block). Made where the stage builds a
/// transfer (the measure's included).
[[nodiscard]] PlanDecision decide_indirect_block(std::size_t particles, std::uint32_t forced);
/// The block a decision chose.
[[nodiscard]] std::uint32_t decided_indirect_block(const PlanDecision& d);

// ---- atlas ------------------------------------------------------------------------------

/// Auto: the default AtlasOptions (charts, one texel per pixel of the best view, 4096 budget);
/// forced when the options differ from those defaults (--atlas patchwork included). The
/// decision names the mode and, for charts, how many charts and seam edges. `particle_stage_seconds` (the measured
/// time of the stages whose work grows with the particle count: visibility, diffuse solve,
/// residual samples) gives the estimate of what twice the linear resolution would cost
/// (4x the particles; what it buys is small: the can at 2 texels per pixel, +1.4 dB masked
/// test PSNR, see decide_atlas).
[[nodiscard]] PlanDecision decide_atlas(const AtlasSummary& summary, const AtlasOptions& options, std::size_t particles,
                                        double particle_stage_seconds);

// ---- albedo refinement ------------------------------------------------------------------

/// How the albedo is refined after the last solve (docs/pipeline.md section 3.8).
enum class RefineMethod {
    Pixels,          ///< refine/pixel_fit.h: least squares on the train pixels through the atlas's bilinear read
    BackProjection,  ///< refine/albedo_refine.h: damped back-projection through renders of the train frames
};
[[nodiscard]] const char* to_string(RefineMethod m) noexcept;

/// Iterations of the pixel fit the planner runs (refine/pixel_fit.h). Coated can, 512 px, noise
/// free, spread rig: masked test PSNR on display values 41.25 dB with 8, the last lowering the
/// train pixels' residual by 0.3% (the back-projection's 2 rounds: 38.36 dB); 4 and 16 (before
/// the bounds): 40.81 and 41.16 dB.
inline constexpr std::uint32_t kPixelFitIterations = 8;
/// Rounds of back-projection the planner runs when that method is asked for (refine/albedo_refine.h).
/// Can preset, 512 px, noise free: masked test PSNR 39.8 dB without, 41.4 after 1 round,
/// 41.7 after 2; a third changed it by less than 0.01 dB.
inline constexpr std::uint32_t kAlbedoRefineRounds = 2;

/// Auto: the method's default count (kPixelFitIterations, kAlbedoRefineRounds); forced: the given
/// count (0 leaves the refinement out). `solve_seconds` (the first diffuse solve) gives the
/// estimate of what a forced 0 avoided.
[[nodiscard]] PlanDecision decide_albedo_refinement(RefineMethod method, std::optional<std::uint32_t> forced_rounds,
                                                    double solve_seconds);
/// The iterations or rounds a decision chose.
[[nodiscard]] std::uint32_t decided_refine_rounds(const PlanDecision& d);
/// Records the measured time of the rounds that ran.
void set_refinement_cost(PlanDecision& d, double seconds);

// ---- specular stages --------------------------------------------------------------------

/// How much better than "diffuse only" (in validation PSNR) the best family must be to keep a
/// specular where the residuals' energy alone would leave it out (decision "validate"). Why
/// a margin: on a Lambertian truth a family can fit a near-zero specular and tie (thesis rig,
/// noise-free png8, 256 px, coated against diffuse only: can -0.45 dB, woodenpot +0.21 dB),
/// while a real lobe wins by several dB even where the first solve's albedo absorbed most of
/// it (can, Lafortune truth, 128 px: +5.5 dB; woodenpot, coated truth, 512 px: +3.9 dB).
inline constexpr double kDiffuseOnlyMarginDb = 1.0;

/// Auto: fit when energy.has_specular. With `validation_frames` > 0 and less energy than the
/// threshold, the value is "validate": the families are estimated and "diffuse only" competes
/// with them on the validation frames (kDiffuseOnlyMarginDb). Why not the energy alone: on the
/// thesis's near-camera rig every light of a particle's best view sees its highlight, so the
/// first (Lambertian) solve absorbs most of a real lobe into the albedo and the residuals keep
/// as little of it as a Lambertian truth leaves of nothing (noise-free png8: can, Lafortune
/// truth 2.13 noise variances at 128 px; vase, Lafortune truth, 0.21 at 256 px; woodenpot,
/// coated alpha 0.3, 0.47 at 512 px; Lambertian truths 0.14-0.35) (docs/pipeline.md section
/// 5.8). `probe_seconds` / `probe_samples`: a fit timed on a small subsample when auto skips
/// (nullopt otherwise), scaled to `fit_samples`.
[[nodiscard]] PlanDecision decide_specular(const ResidualEnergy& energy, Toggle toggle, std::size_t validation_frames = 0);
/// Fills the cost figures of a specular decision once known.
void set_specular_cost(PlanDecision& d, std::optional<double> probe_seconds, std::size_t probe_samples,
                       std::size_t fit_samples, std::optional<double> measured_seconds);

// ---- factorization grid -----------------------------------------------------------------

/// Auto: factorization::default_resolution(model) (from the lobe's N, or the coated
/// family's alpha); forced: the given grid (0 = auto for
/// that axis). `measured_seconds` (matrix + decomposition) scales, by the matrix size
/// (3 R_h^2 R_d^2 entries), into the estimated cost of the finest grid the rule allows.
[[nodiscard]] PlanDecision decide_factorization_grid(const SpecularModel& model, std::uint32_t forced_h, std::uint32_t forced_d);
/// `what` names the measurement (wall time of the steps, or their dispatches' GPU time).
void set_factorization_cost(PlanDecision& d, double matrix_and_decomposition_seconds, const std::string& what);
/// The grid a decision chose. Throws UsageError when a forced grid has R_h R_d > kMaxGridProduct.
[[nodiscard]] factorization::FactorizationResolution decided_grid(const SpecularModel& model, std::uint32_t forced_h,
                                                                  std::uint32_t forced_d);

} // namespace specula
