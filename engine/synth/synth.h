#pragma once
// Synthetic captures: a known object (mesh, albedo texture, and a Lafortune lobe or a
// coated material) rendered under a rig (rig.h: spread or thesis) by the ground-truth renderer
// (render.h), with seeded sensor noise and clipping (noise.h), written in the
// capture format (capture-format.md) with the truth recorded in ground_truth.
#include "capture/capture.h"
#include "core/timer.h"
#include "synth/noise.h"
#include "synth/presets.h"
#include "synth/render.h"
#include "synth/rig.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace specula::synth {

enum class ImageFormat { Png8, Png16, Exr };
[[nodiscard]] ImageFormat parse_image_format(std::string_view text); // "png8", "png16", "exr"; UsageError otherwise
[[nodiscard]] std::string_view to_string(ImageFormat format);

struct SynthOptions {
    int size = 512;
    int views = 20;
    int lights = 6;
    int test_views = 4;
    int test_lights = 2;
    int held_out_lights = 0;  // per train view, test frames of that view (rig.h)
    bool directional = false; // directional lights (capture format 1.1, rig.h)
    RigKind rig = RigKind::Spread; // spread (light_angles_deg) or thesis (a 15-degree ring), rig.h
    std::vector<double> light_angles_deg = RigOptions{}.light_angles_deg; // spread: train lights off the camera (rig.h)
    double noise_sigma = 0.0; // Gaussian read noise, relative to full scale 1.0
    double shot_noise = 0.0;  // variance = shot_noise * value
    double exposure = 1.0;
    /// Interreflections (render.h, Interreflection): 0 (direct light only, the images as they
    /// always were) to Interreflection::kMaxBounces bounces, with bounce_samples paths per pixel
    /// (at least 1). Their random numbers come from `seed` and the frame's index.
    int bounces = 0;
    int bounce_samples = Interreflection{}.samples;
    ImageFormat format = ImageFormat::Png8;
    std::uint64_t seed = 1; // sensor noise and interreflection samples
    int threads = 2;
    bool lambertian = false; // zero the lobe (lafortune family only: refused for a coated material)
    bool force = false;      // replace an existing non-empty output folder (only once the new one is complete)
    /// Files the object was read from (--mesh, --albedo): the output folder may not hold them.
    std::vector<std::filesystem::path> inputs;
    /// Called after each frame is rendered and queued for writing (done, total); may throw
    /// to abort (nothing is then left at the output path).
    std::function<void(std::size_t done, std::size_t total)> on_frame;

    [[nodiscard]] RigOptions rig_options() const;
};

/// What is rendered: the object and its known material.
struct SynthObject {
    std::string name; // recorded as ground_truth.preset
    Mesh mesh;
    Material material;
};
[[nodiscard]] SynthObject to_object(Preset preset);

struct SynthResult {
    std::filesystem::path dir;
    std::size_t views = 0;
    std::size_t train_frames = 0;
    std::size_t test_frames = 0;
    std::size_t triangles = 0;
    std::size_t object_pixels = 0;    // mask pixels, summed over frames
    std::size_t clipped_pixels = 0;   // object pixels with a channel at saturation (integer formats)
    std::size_t shadowed_pixels = 0;  // object pixels facing the light but shadowed, over all frames
    std::vector<StageTime> times;     // per step
    double seconds = 0.0;
};

/// Renders and writes a whole capture into `out` (see capture-format.md):
/// images/, masks/, mesh.glb, truth/albedo.exr, capture.json. Everything goes to a
/// staging folder beside it first and is renamed into place at the end
/// (core/output_dir.h): a failure or a kill leaves no output, or the previous one. An
/// existing non-empty `out` is refused (UsageError) unless options.force, in which case it is
/// replaced only after the new capture is complete; a second run on the same `out` is refused.
SynthResult write_synthetic_capture(const SynthObject& object, const std::filesystem::path& out, const SynthOptions& options);

/// Writes a preset's mesh.glb, albedo.exr (linear truth), albedo.png (sRGB preview)
/// and preset.json (lobe, coated parameters, description, counts) into `out`, atomically as above.
void export_preset(const Preset& preset, const std::filesystem::path& out, bool force);

/// ground_truth.lobe's JSON form: {"cx": [r, g, b], "cz": [...], "n": [...]}.
[[nodiscard]] nlohmann::json lobe_to_json(const LafortuneRgb& lobe);
[[nodiscard]] LafortuneRgb lobe_from_json(const nlohmann::json& j);

/// ground_truth.material's JSON form: the family and its exact parameters,
///   {"family": "lafortune", "cx": [r, g, b], "cz": [...], "n": [...]}
///   {"family": "coated", "eta": e, "alpha": a, "tint": [r, g, b]}
/// Floats are written as the doubles they convert to, so reading back gives the same floats.
[[nodiscard]] nlohmann::json material_to_json(const SpecularModel& model);
/// The inverse of material_to_json; throws Error naming what is missing or unknown.
[[nodiscard]] SpecularModel material_from_json(const nlohmann::json& j);

} // namespace specula::synth
