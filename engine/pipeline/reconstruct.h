#pragma once
// The pipeline: the only code that knows the stage order (pipeline.md; style.md
// layout). `specula reconstruct` maps its arguments to a ReconstructConfig and
// calls reconstruct(); the planner (planner.h) decides what this scene needs, and
// everything is timed, counted, and written to report.json and report.html with the
// planner's decisions and what was left out for this scene and why.
//
//   load capture -> plan (convexity, light directions) -> atlas -> particles
//     -> visibility (Embree; occlusion rays only where the mesh can occlude itself)
//     -> diffuse solve (photometric where the lights allow it) -> residual samples
//     -> Lafortune fit (when the residuals hold specular energy)
//     -> albedo refinement (back-projection through renders of the train frames) -> albedo texture
//     -> factorization (grid from the lobe's width) -> bundle (object.glb)
//     -> self-evaluation -> report.html -> report.json
#include "material/factor_param.h"
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "indirect/indirect.h"
#include "pipeline/planner.h"
#include "specular/lafortune_fit.h"
#include "specular/coated_fit.h"
#include "specular/residuals.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace specula {

/// Train frames the self-evaluation scores by default (ReconstructConfig::evaluate_train_frames),
/// evenly spaced; every test frame is scored. 24 of 120 frames on the default rig: the
/// evaluation of the knot at 384 px takes about a quarter of its time for all 128 frames.
inline constexpr std::size_t kEvaluateTrainFrames = 24;

/// Auto: fit the lobe only when the residuals hold more energy than the noise (pipeline.md section 9).
enum class SpecularMode { Auto, On, Off };

struct ReconstructConfig {
    std::filesystem::path capture;  ///< folder or capture.json
    std::filesystem::path out_dir;  ///< albedo.exr, albedo.png, report.json go here
    /// Replace an existing non-empty out_dir that holds no earlier result of reconstruct (no
    /// report.json of specula): replacing deletes what it holds, so that needs asking for.
    bool force = false;
    Backend backend = Backend::Vulkan;
    /// The backend was not asked for (`--backend auto`): with Vulkan, the per-particle passes
    /// (diffuse solves, residual samples) run the C++ reference when the device is a CPU Vulkan
    /// driver (lavapipe), where the kernels run slower (PipelineRun::compute_context).
    bool backend_auto = false;
    std::string device;             ///< Vulkan device selector (empty: SPECULA_DEVICE, then the default)
    LambertOptions lambert;         ///< solve mode, view choice, rejection thresholds
    AtlasOptions atlas;             ///< texture budget and texels per pixel
    /// Occlusion rays: auto casts them only where the mesh can occlude itself; on/off force it.
    Toggle occlusion_rays = Toggle::Auto;
    /// The frames' pixel shadow maps answer for the particles' light rays (VisibilityOptions::
    /// shadow_maps_answer_lights): visibility 2.30 -> 1.41 s on the knot at 384 px, the same
    /// figures on the demo can; off by default (docs/pipeline.md section 2: the Lafortune vase's
    /// and woodenpot's lobes at 512 px move by 0.27% and 0.49%).
    bool light_rays_from_shadow_maps = false;
    /// Diffuse solve mode: auto picks photometric where the lights allow it (planner.h); the
    /// forced modes set lambert.mode. (lambert.mode itself is overwritten by this choice.)
    DiffuseModeChoice diffuse_mode = DiffuseModeChoice::Auto;
    SpecularMode specular = SpecularMode::Auto;
    /// Factorization grid (0: the planner's choice from the lobe's width, per axis).
    std::uint32_t factorization_grid_h = 0;
    std::uint32_t factorization_grid_d = 0;
    /// Parametrization of the factorization (shared/gshd.h part 4): nullopt = automatic (both,
    /// factorization::ParamChoice), else forced (Gshd: the thesis's).
    std::optional<FactorParam> factor_param;
    /// The warped parametrization's warp: nullopt = automatic (factorization::FactorizationOptions::
    /// shared_warp), true = one warp shared by the channels, false = a warp per channel.
    std::optional<bool> shared_warp;
    /// Auto: specular energy is present when the mean squared residual exceeds this many noise
    /// variances (lambert.noise_sigma, floored at one 16-bit step).
    double specular_energy_threshold = 4.0;
    /// The fit runs on a deterministic stride subsample of at most this many samples (0 = all).
    std::uint32_t max_fit_samples = 200000;
    /// The material family: nullopt (auto) estimates every family and keeps the one of least
    /// error on the validation frames; a family forces it (pipeline.md section 5.6).
    std::optional<MaterialFamily> material;
    CoatedFitOptions coated;        ///< the coated family's fit
    LafortuneFitOptions lafortune;  ///< noise_sigma is set from lambert.noise_sigma (weights make f_s noise image noise)
    /// Joint estimate: after a fit, at most this many rounds of (diffuse solve with the lobe's
    /// light subtracted, residuals, fit); 0 = the thesis's one pass. 8: on the thesis's
    /// near-camera rig the rounds converge slowly (each removes about half of what the first
    /// solve's albedo absorbed; can, coated, 128 px: 6 rounds to settle, 3 leave alpha 7.6% low).
    std::uint32_t joint_rounds = 8;
    double joint_tolerance = 0.005; ///< stop when no lobe parameter changes by more than this (relative)
    /// Albedo refinement after the last solve (planner.h RefineMethod): the pixel fit
    /// (refine/pixel_fit.h, the default) or back-projection through renders (refine/albedo_refine.h).
    RefineMethod refine_method = RefineMethod::Pixels;
    /// Its iterations (pixel fit) or rounds (back-projection). nullopt: the planner's choice
    /// (kPixelFitIterations, kAlbedoRefineRounds); 0: the solve's albedo (bilinear reading of the best view).
    std::optional<std::uint32_t> refine_rounds;
    /// Refined normals as a normal map in the bundle (planner.h decide_normal_map): auto on
    /// for photometric rigs (a view with many well-spread lights).
    Toggle normal_map = Toggle::Auto;
    /// Light that bounced off the object (planner.h decide_indirect; indirect/indirect.h): auto
    /// where the mesh can see itself and that light is above the images' quantization.
    Toggle indirect = Toggle::Auto;
    std::uint32_t indirect_bounces = 2;   ///< bounces of the indirect light (1: one bounce)
    std::uint32_t indirect_rays = kTransferRays; ///< rays per row of the transfer (rounded up to a square)
    /// The transfer's rows: blocks of this many texels a side (1: every particle); 0: the planner's
    /// (transfer_block_for the particles, plan decision indirect_block).
    std::uint32_t indirect_block = 0;
    bool indirect_lobe_directions = true; ///< the lobe's first bounce directed (IndirectOptions::lobe_directions), else spread
    std::uint32_t indirect_rounds = kIndirectRounds; ///< at most this many rounds of solve and indirect light
    unsigned threads = 2;           ///< CPU threads (image decoding, visibility)
    /// Self-evaluation: re-render every frame from the bundle and compare (needs a Vulkan
    /// device; left out, with the reason, when none can be had).
    bool evaluate = true;
    std::size_t evaluate_max_frames = 0; ///< per split, evenly spaced (0: all frames)
    bool evaluate_train = true;          ///< false: score the test frames only
    /// At most this many train frames are scored, evenly spaced (0: all; every test frame always).
    std::size_t evaluate_train_frames = kEvaluateTrainFrames;
    /// Render the lobe through the bundle's factorization cube-maps (what Specula's real-time
    /// renderer draws) instead of the analytic lobe (the reference) when there are cube-maps.
    bool evaluate_factorized = false;
    bool write_sheets = true;            ///< evaluation sheets in out_dir/sheets
    /// The linear float albedo inside object.glb (12 bytes a texel) instead of beside it as
    /// albedo.exr, which the bundle then names (export/bundle.h BundleWriteOptions).
    bool embed_float_albedo = false;
    bool write_html = true;              ///< out_dir/report.html
    /// Time small probes so the report can estimate what skipped work would have cost
    /// (occlusion rays on a subset of pairs, the fit on a subsample).
    bool cost_probes = true;
};

struct StageRecord {
    std::string name;
    double seconds = 0.0;
};

/// Something the pipeline did not do for this scene, and why.
struct LeftOut {
    std::string what;
    std::string why;
};

struct ReconstructResult {
    Plan plan;
    std::vector<StageRecord> stages;
    std::vector<LeftOut> left_out;
    std::vector<std::string> warnings;
    nlohmann::json report; ///< the content of report.json
    double total_seconds = 0.0;
};

/// Runs every stage built so far and writes the outputs into config.out_dir, as a whole
/// (core/output_dir.h): into a staging folder beside it, renamed into place once complete,
/// so out_dir holds the previous complete result or the new one, never a part. Refused before
/// any stage runs (UsageError / InputError naming out_dir): an out_dir that is a file, that is
/// or contains the capture's folder, mesh, images or masks, that cannot be created, that is a
/// non-empty folder without an earlier result (unless config.force), or that another run is
/// writing (its lock, .NAME.lock beside it).
/// Throws InputError for a bad capture, Error for a failed stage.
/// `preloaded`: a capture already loaded with its mesh and images (the sweep loads once);
/// its load time is then not part of this run's stages.
ReconstructResult reconstruct(const ReconstructConfig& config, const Capture* preloaded = nullptr);

/// The SpecularMode as written on the command line.
[[nodiscard]] const char* to_string(SpecularMode mode) noexcept;

} // namespace specula
