#pragma once
/// \file
/// Evaluation of a reconstruction against its capture (pipeline.md section 8; thesis
/// chapter 5): every frame (train and test) is re-rendered from the bundle with the
/// frame's camera and light, exactly, and compared with the captured image by every
/// measure of metrics/image_metrics.h, over two pixel sets:
///   - masked (primary): the object's pixels, the capture's mask (FrameImage flag
///     kOutsideMask clear); pixels the capture marks missing (non-finite) are left out.
///     A frame without a mask file uses the render's own coverage instead
///     (FrameEvaluation::mask_source = "render").
///   - full: the whole frame, background included (comparable with the thesis's figures).
/// The rendered image is clipped at the frame's saturation where the capture has one
/// (what the camera would have recorded). Aggregates per split (thesis Definitions
/// 5.1, 5.2: Q1 = 100 - mean RMS%, Q2 = 100 - mean DDE%, metrics_summary.h).
///
/// Every measure is computed on linear values. RMS, RMS%, PSNR and Q1 are computed on display
/// values too (metrics/display_values.h): the captured and the rendered image both in the
/// capture's own encoding (for an 8-bit sRGB capture the render is sRGB-encoded, clipped to
/// [0, 1] and quantized to 8 bits like the stored images, which come back as their stored
/// codes), G = 1: the figures the field reports on stored images. The JSON names both
/// (psnr_display, psnr_linear; the unsuffixed psnr, rms, rms_percent and q1 keep their
/// meaning: linear); the summary table shows display first for sRGB integer captures.
///
/// Sheets (thesis figures 5.1-5.4): captured | rendered | difference, side by side, an
/// sRGB PNG per chosen frame. The difference panel shows, per channel, in display
/// (sRGB-encoded) values, 0.5 + kSheetAmplification * (rendered - captured): mid-gray
/// where they agree, brighter where the render is brighter.
///
/// The renderer draws cast shadows (a shadow map) unless render.shadows is false, the
/// thesis's unshadowed render, where pixels a capture shows in shadow differ from a render.
///
///   Capture cap = load_capture(dir);
///   EvaluationResult r = evaluate(ctx, read_bundle(path), cap, {.sheet_dir = "sheets"});
///   std::cout << format_summary(r);  write json: to_json(r, folder)
#include "capture/capture.h"
#include "core/backend.h"
#include "export/bundle.h"
#include "gpu/context.h"
#include "metrics/display_values.h"
#include "metrics/image_metrics.h"
#include "metrics/metrics_summary.h"
#include "render/renderer.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace specula::evaluate {

/// Amplification of the difference panel of a sheet (around mid-gray, display values).
inline constexpr double kSheetAmplification = 4.0;


/// Where the image measures run by default on `ctx`'s device: the C++ reference on a CPU Vulkan
/// driver (lavapipe runs the metric kernels 4 to 9 times slower: 96 against 21 ms a 384 px frame),
/// the kernels on a GPU.
[[nodiscard]] Backend metrics_backend_for(const gpu::Context& ctx) noexcept;

struct EvaluateOptions {
    /// Mode (both/diffuse/specular), specular model, shadows, passes. Deferred by default: the
    /// same pixels as the forward passes (1e-5 relative, RenderTest.DeferredPassMatchesTheForwardPasses;
    /// every figure of the knot at 384 px the same to the last digit), one shading a pixel instead of lavapipe's
    /// block per triangle: 32 -> 25 ms a shadow-mapped frame there, 38 -> 33 ms on the demo can.
    render::Settings render{.passes = render::Passes::Deferred};
    /// The renderer's options: levels of detail (lod_max_error_px) to measure what they cost the
    /// image, kept as specula-view keeps them: those scoring at least lod_min_psnr_db against the
    /// whole mesh on 4 of the evaluated frames (render::Renderer::accept_levels_of_detail).
    render::Options renderer;
    double lod_min_psnr_db = render::kDefaultLodMinPsnrDb;
    Backend metrics_backend = Backend::Vulkan; ///< metrics_backend_for(device) is the measured choice
    metrics::MetricsOptions metrics;
    /// At most this many frames per split, evenly spaced over the split (0: all).
    std::size_t max_frames_per_split = 0;
    /// At most this many train frames, evenly spaced over those max_frames_per_split leaves (0: no
    /// further bound): `reconstruct` scores every test frame and a sample of the train frames.
    std::size_t max_train_frames = 0;
    /// false: score the test frames only (the sweep needs only those).
    bool include_train = true;
    /// C++ metrics (metrics_backend Cpu): a frame's four scores (masked, full, each on linear and
    /// display values) on up to this many threads (the same scores for any count).
    unsigned threads = 1;
    /// Sheets are written here when set (created if missing).
    std::optional<std::filesystem::path> sheet_dir;
    /// Frames (indices into capture.desc.frames) to make sheets of; empty: the first
    /// evaluated train frame and the first evaluated test frame.
    std::vector<std::size_t> sheet_frames;
    std::string bundle_name = "bundle";            ///< for messages and the JSON
    bool progress = true;                          ///< log::Progress on a terminal
    /// Light the bundle's renderer does not draw, added to each frame's render before it is
    /// scored (light that bounced off the object itself: indirect/indirect.h): called with the
    /// frame (index into capture.desc.frames) and its render. When set, the masked figures of
    /// the render without it are kept too (FrameEvaluation::masked_direct, direct_metrics).
    std::function<void(std::size_t frame, Image& rendered)> add_light;
    /// Images rendered by another tool (an ordinary glTF viewer: tools/threejs-render.mjs), scored
    /// instead of the bundle's own renders: called with a frame (index into capture.desc.frames),
    /// returns its linear image, or nullopt when the tool rendered no image of that frame (the frame
    /// is then left out). The bundle's renderer is not used; a frame's coverage (and its mask when
    /// the capture has none) is its nonzero pixels, and FrameEvaluation::shadowed is false (unknown).
    std::function<std::optional<Image>(std::size_t frame)> external_render;
    /// Render the bundle's glTF core material (Bundle::core; absent: the diffuse-only core,
    /// material/core_material.h) instead of its own model, analytic path, direct light: what an
    /// ordinary viewer (three.js) shows, the figure report.json gives as `viewer`.
    bool core_material = false;
    /// Frames (its keys) to render also with the bundle's core material, as a core_material
    /// evaluation draws them, each right after its own render with the same camera and light:
    /// its G-buffer and shadow map are drawn once (render::FrameInfo::gbuffer_kept, shadow_kept).
    /// Every key evaluated here gets its render; the others are taken out. Not with
    /// core_material or external_render.
    std::map<std::size_t, render::Frame>* core_renders = nullptr;
    /// Renders made already (another evaluation's core_renders, for a core_material one): scored
    /// instead of drawn (taken out of the map); frames not in it are drawn.
    std::map<std::size_t, render::Frame>* rendered = nullptr;
};

struct FrameEvaluation {
    std::size_t frame = 0;          ///< index into capture.desc.frames
    std::string file;               ///< the frame's image, as capture.json names it
    Split split = Split::Train;
    int view_index = 0;
    std::string mask_source;        ///< "capture" or "render" (no mask file)
    metrics::FrameMetrics masked;   ///< over the object's pixels (primary), linear values
    metrics::FrameMetrics full;     ///< over the full frame, linear values
    /// The same pixel sets on display values (RMS, PSNR; no SSIM, no Hausdorff), in the
    /// encoding named by display_encoding (metrics::DisplayEncoding::name(): "srgb8", ...).
    metrics::FrameMetrics masked_display;
    metrics::FrameMetrics full_display;
    std::string display_encoding;
    std::size_t covered_pixels = 0; ///< pixels the render covers
    bool shadowed = false;          ///< the render drew cast shadows (render::FrameInfo::shadow_pass)
    std::string shadow_note;        ///< why not, when render.shadows asked for them (light too close)
    /// With EvaluateOptions::add_light: the masked figures of the render without that light.
    std::optional<metrics::FrameMetrics> masked_direct;
    std::optional<metrics::FrameMetrics> masked_display_direct;
    double render_ms = 0.0;         ///< wall time of the render (incl. readback)
    double metrics_ms = 0.0;        ///< wall time of both metric runs
};

struct EvaluationTimings {
    double setup_s = 0.0;   ///< renderer and metrics kernels (upload, pipelines)
    double render_s = 0.0;  ///< sum over frames
    double metrics_s = 0.0; ///< sum over frames
    double sheets_s = 0.0;
    double total_s = 0.0;
    /// (render_s + metrics_s) / frames
    [[nodiscard]] double per_frame_ms(std::size_t frames) const noexcept {
        return frames == 0 ? 0.0 : 1000.0 * (render_s + metrics_s) / static_cast<double>(frames);
    }
};

struct EvaluationResult {
    std::vector<FrameEvaluation> frames;           ///< in capture order
    metrics::EvaluationMetrics metrics;            ///< aggregates per split and pixel set (linear values)
    metrics::EvaluationMetrics display_metrics;    ///< the same on display values (G = 1)
    /// With EvaluateOptions::add_light: the masked aggregates of the renders without it
    /// (linear and display values; the full-frame aggregates are left empty).
    std::optional<metrics::EvaluationMetrics> direct_metrics;
    std::optional<metrics::EvaluationMetrics> direct_display_metrics;
    std::string display_encoding;                  ///< the frames' encoding name, "mixed" when they differ
    bool display_first = false;                    ///< every frame is an sRGB integer file
    std::size_t train_frames = 0;                  ///< evaluated
    std::size_t test_frames = 0;
    EvaluationTimings timings;
    std::vector<std::filesystem::path> sheets;     ///< written
    std::vector<std::string> warnings;
    std::string bundle_name;
    std::string capture_dir;
    render::Settings render;
    double lod_max_error_px = 0.0; ///< EvaluateOptions::renderer's (0: every triangle drawn)
    /// With levels of detail: the triangles each kept level has and its worst display PSNR
    /// against the whole mesh on the frames accept_levels_of_detail rendered (the whole mesh first).
    std::vector<std::pair<std::size_t, double>> lod_levels;
    Backend metrics_backend = Backend::Vulkan;
};

/// Evaluates a bundle against a capture loaded with its images. Throws Error when the
/// capture has no images loaded, when the factorized model is asked of a bundle without
/// cube-maps, or when a sheet frame is out of range (UsageError).
[[nodiscard]] EvaluationResult evaluate(gpu::Context& ctx, const Bundle& bundle, const Capture& capture,
                                        const EvaluateOptions& options = {});

/// At most max_frames_per_split frames of each split, evenly spaced (indices into capture.desc.frames,
/// in capture order; 0: all).
[[nodiscard]] std::vector<std::size_t> select_frames(const CaptureDesc& desc, std::size_t max_frames_per_split);

/// The frames evaluate() scores with these options, in capture order (the order it renders them,
/// and asks EvaluateOptions::add_light for them): select_frames, then the train frames bounded
/// by max_train_frames (evenly spaced), or none without include_train.
[[nodiscard]] std::vector<std::size_t> evaluated_frames(const CaptureDesc& desc, const EvaluateOptions& options);

/// One sheet: captured | rendered | difference (see the file comment), linear RGB
/// ready for write_image(..., ColorSpace::Srgb). Images must have the same size.
[[nodiscard]] Image make_sheet(const Image& captured, const Image& rendered, double amplification = kSheetAmplification);

/// {bundle, capture, settings, train: {masked, full}, test: {masked, full} (a split with
/// no frame is absent), frames: [...], timings, sheets, warnings, display_encoding}. Numbers
/// are finite. Each aggregate holds metrics_summary.h's keys (linear values) and beside them
/// q1, rms, rms_percent and psnr with the suffixes _display and _linear (the latter equal to
/// the unsuffixed keys) and display_encoding; each frame's masked and full hold rms,
/// rms_percent and psnr with both suffixes. `capture` is the capture's folder relative to
/// `folder`, the folder the JSON is written in (no machine path: core/file_util.h).
[[nodiscard]] nlohmann::json to_json(const EvaluationResult& result, const std::filesystem::path& folder);

/// A plain-text table of the aggregates (one row per split and pixel set: Q1 and PSNR on display
/// and linear values, display first for sRGB captures; the other measures linear) and the timings.
[[nodiscard]] std::string format_summary(const EvaluationResult& result);


} // namespace specula::evaluate
