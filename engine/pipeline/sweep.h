#pragma once
/// \file
/// Error against run time (`specula bench sweep`): the pipeline run over a grid of the
/// knobs that trade accuracy for time, each point scored on the capture's TEST frames
/// (masked RMS %, i.e. 100 - Q1), with the Pareto front of (run time, error).
///
///   knob                 ReconstructConfig field                  default
///   texels_per_pixel     atlas.texels_per_pixel (atlas size)      1
///   fit_samples          max_fit_samples (sample reduction)       200000
///   factorization_grid   factorization_grid_h = _d (0: auto)      auto
///   backend              backend (vulkan | cpu)                   vulkan
///
/// The capture is loaded once (its load time is reported apart); a point's run time is the
/// sum of its stages without the self-evaluation (scoring is not reconstruction). The lobe
/// is rendered through the factorization's cube-maps (what the real-time renderer draws),
/// so the grid's error shows. The point
/// with every knob at its default is always run and marked. Outputs in out_dir:
/// sweep.csv, sweep.json, sweep.svg (each written atomically), and points/NN/ with each
/// point's outputs when keep_points is set, and sweep.html (the plot and the table on one
/// self-contained page).
#include "pipeline/reconstruct.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace specula {

struct SweepKnobs {
    std::vector<double> texels_per_pixel{0.5, 1.0};
    std::vector<std::uint32_t> fit_samples{20000, 200000};
    std::vector<std::uint32_t> factorization_grid{0};
    std::vector<Backend> backends{Backend::Vulkan, Backend::Cpu};
};

struct SweepOptions {
    std::filesystem::path capture;
    std::filesystem::path out_dir;
    SweepKnobs knobs;
    ReconstructConfig base;   ///< everything the knobs do not set (device, threads, ...)
    bool keep_points = false; ///< keep each point's outputs in out_dir/points/NN
};

struct SweepPoint {
    double texels_per_pixel = 1.0;
    std::uint32_t fit_samples = 0;
    std::uint32_t factorization_grid = 0; ///< 0: auto; N: h grid N, d grid min(N, kMaxGridProduct / N)
    Backend backend = Backend::Vulkan;
    std::string label;        ///< e.g. "tpp 0.5, fit 20k, grid auto, vulkan"
    bool is_default = false;
    bool on_front = false;
    double seconds = 0.0;     ///< run time without load and evaluation
    double error = 0.0;       ///< test frames, masked RMS % (100 - Q1)
    double test_q1 = 0.0;
    double test_psnr = 0.0;
    double test_full_rms_percent = 0.0;
    std::size_t particles = 0;
    std::string grid_used;    ///< the factorization grid the run used ("none" without a lobe)
    bool has_lobe = false;
    nlohmann::json stages;    ///< [{name, seconds}]
    std::string failure;      ///< why the run failed (then seconds and error are NaN); the sweep goes on
};

struct SweepResult {
    std::vector<SweepPoint> points;
    std::vector<std::size_t> front; ///< indices into points, by increasing run time
    double load_seconds = 0.0;
    std::size_t test_frames = 0;
};

/// Indices of the points not dominated in (x, y), both minimized (a point is dominated
/// when another is no worse in both and better in one), by increasing x. Non-finite
/// points are never on the front.
[[nodiscard]] std::vector<std::size_t> pareto_front(std::span<const std::pair<double, double>> xy);

/// Runs the sweep and writes its files. Throws UsageError for an empty knob list or a
/// capture with no test frames (the error is measured on them). A point whose run fails
/// is recorded with the reason and left off the front; the others still run.
SweepResult run_sweep(const SweepOptions& options);

[[nodiscard]] nlohmann::json to_json(const SweepResult& r);
[[nodiscard]] std::string to_csv(const SweepResult& r);
[[nodiscard]] std::string to_svg(const SweepResult& r, const std::string& title);
[[nodiscard]] std::string to_html(const SweepResult& r, const std::string& title);

} // namespace specula
