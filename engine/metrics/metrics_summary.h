#pragma once
// Aggregates of image_metrics over a sequence of frames (thesis Definitions 5.1, 5.2),
// and their JSON for the report (`specula evaluate` writes an EvaluationMetrics at
// train.masked / train.full / test.masked / test.full).
//
//   Q1 = 100 - mean over frames of RMS%      (eq. 5.7, 5.8; G = MetricsOptions::peak)
//   Q2 = 100 - mean over frames of DDE%      (eq. 5.9, 5.10)
//   every other measure: the plain mean over frames of the per-frame value (PSNR too:
//   the mean of per-frame dB, each capped at psnr_cap_db), except hausdorff_max, the max.
// Frames whose pixel set is empty are counted in frames_empty and left out of the means.
// With no frame left, every measure is null in the JSON (the struct holds 0).
// JSON numbers are always finite: a non-finite double is written as null.
#include "metrics/image_metrics.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <span>

namespace specula::metrics {

struct MetricsSummary {
    uint64_t frames = 0;       // frames in the means (non-empty pixel set)
    uint64_t frames_empty = 0; // frames with an empty pixel set, left out
    uint64_t pixels = 0;       // total N over the frames
    double q1 = 0.0;
    double q2 = 0.0;
    double rms = 0.0;
    double rms_percent = 0.0;
    double dde = 0.0;
    double dde_percent = 0.0;
    double ncc = 0.0;
    double l1 = 0.0;
    double l2 = 0.0;
    double psnr = 0.0;
    double ssim = 0.0;
    double hausdorff = 0.0;     // mean over frames
    double hausdorff_max = 0.0; // max over frames
    bool hausdorff_exact = true;
    bool has_ssim = false;      // every frame had it
    bool has_hausdorff = false; // every frame had it
    double g = 1.0;             // the G / peak used
    double psnr_cap_db = 100.0;
};

[[nodiscard]] MetricsSummary summarize(std::span<const FrameMetrics> frames, const MetricsOptions& options = {});

/// The four summaries of an evaluation.
struct EvaluationMetrics {
    MetricsSummary train_masked;
    MetricsSummary train_full;
    MetricsSummary test_masked;
    MetricsSummary test_full;
};

/// {pixels, channels, mse, rms, rms_percent, dde, dde_percent, ncc, l1, l2, psnr, ssim,
///  hausdorff, hausdorff_exact}; measures null when the pixel set is empty or the measure was skipped.
[[nodiscard]] nlohmann::json to_json(const FrameMetrics& m);
/// {frames, frames_empty, pixels, q1, q2, rms, rms_percent, dde, dde_percent, ncc, l1, l2,
///  psnr, ssim, hausdorff, hausdorff_max, hausdorff_exact, g, psnr_cap_db}.
[[nodiscard]] nlohmann::json to_json(const MetricsSummary& s);
/// {"train": {"masked": ..., "full": ...}, "test": {"masked": ..., "full": ...}}.
[[nodiscard]] nlohmann::json to_json(const EvaluationMetrics& e);

} // namespace specula::metrics
