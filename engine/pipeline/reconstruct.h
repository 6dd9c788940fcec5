#pragma once
// The pipeline: the only code that knows the stage order (pipeline.md; style.md
// layout). `specula reconstruct` maps its arguments to a ReconstructConfig and
// calls reconstruct(); everything is timed, counted, and written to report.json
// with what was left out for this scene and why.
//
//   load capture -> atlas -> particles -> visibility (Embree) -> diffuse solve
//     -> residual samples -> Lafortune fit (when the residuals hold specular energy) -> albedo texture
//     -> factorization (when there is a lobe) -> bundle (object.glb) -> self-evaluation
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "specular/lafortune_fit.h"
#include "specular/residuals.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace specula {

/// Auto: fit the lobe only when the residuals hold more energy than the noise (pipeline.md section 9).
enum class SpecularMode { Auto, On, Off };

struct ReconstructConfig {
    std::filesystem::path capture;  ///< folder or capture.json
    std::filesystem::path out_dir;  ///< albedo.exr, albedo.png, report.json go here
    LambertBackend backend = LambertBackend::Vulkan;
    std::string device;             ///< Vulkan device selector (empty: SPECULA_DEVICE, then the default)
    LambertOptions lambert;         ///< solve mode, view choice, rejection thresholds
    AtlasOptions atlas;             ///< texture budget and texels per pixel
    bool force_occlusion_rays = false; ///< cast occlusion rays even where the mesh is convex
    SpecularMode specular = SpecularMode::Auto;
    /// Auto: specular energy is present when the mean squared residual exceeds this many noise
    /// variances (lambert.noise_sigma, floored at one 16-bit step).
    double specular_energy_threshold = 4.0;
    /// The fit runs on a deterministic stride subsample of at most this many samples (0 = all).
    std::uint32_t max_fit_samples = 200000;
    LafortuneFitOptions lafortune;  ///< noise_sigma is set from lambert.noise_sigma (weights make f_s noise image noise)
    /// Joint estimate: after a fit, at most this many rounds of (diffuse solve with the lobe's
    /// light subtracted, residuals, fit); 0 = the thesis's one pass.
    std::uint32_t joint_rounds = 3;
    double joint_tolerance = 0.005; ///< stop when no lobe parameter changes by more than this (relative)
    unsigned threads = 2;           ///< CPU threads (image decoding, visibility)
    /// Self-evaluation: re-render every frame from the bundle and compare (needs a Vulkan
    /// device; left out, with the reason, when none can be had).
    bool evaluate = true;
    std::size_t evaluate_max_frames = 0; ///< per split, evenly spaced (0: all frames)
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
    std::vector<StageRecord> stages;
    std::vector<LeftOut> left_out;
    std::vector<std::string> warnings;
    nlohmann::json report; ///< the content of report.json
    double total_seconds = 0.0;
};

/// Runs every stage built so far and writes the outputs into config.out_dir
/// (each file atomically; report.json last, so its presence means a complete run).
/// Throws InputError for a bad capture, Error for a failed stage.
ReconstructResult reconstruct(const ReconstructConfig& config);

} // namespace specula
