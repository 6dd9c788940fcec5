#pragma once
// Capture format version 1 (docs/capture-format.md): reading,
// validating and writing `capture.json`, plus the decoded images and masks.
// Every refusal names the file and the field (InputError).
#include "capture/camera.h"
#include "capture/mesh.h"
#include "core/image.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace specula {

struct PointLight {
    glm::dvec3 position{0.0};
    glm::dvec3 intensity{0.0}; // RGB radiant intensity
};

enum class Split { Train, Test };

struct FrameDesc {
    std::filesystem::path file_path;               // relative to the capture folder, as written in capture.json
    int view_index = 0;
    glm::dmat4 transform{1.0};                     // camera-to-world
    Intrinsics intrinsics;                         // resolved: the capture's values, overridden by the frame's own
    PointLight light;
    std::optional<std::filesystem::path> mask_path; // relative, like file_path
    Split split = Split::Train;
    nlohmann::json extra = nlohmann::json::object(); // unknown fields, kept and written back
    nlohmann::json light_extra = nlohmann::json::object(); // unknown fields of "light", kept and written back

    [[nodiscard]] Camera camera() const { return Camera(intrinsics, transform); }
};

struct CaptureDesc {
    std::filesystem::path dir;              // folder holding capture.json; paths below are relative to it
    std::filesystem::path mesh_path;
    ColorSpace color_space = ColorSpace::Srgb;
    std::optional<double> saturation;       // as given; see effective_saturation()
    std::vector<FrameDesc> frames;
    nlohmann::json ground_truth;            // null when absent; never read by reconstruction
    nlohmann::json extra = nlohmann::json::object(); // unknown top-level fields, kept

    [[nodiscard]] std::filesystem::path resolve(const std::filesystem::path& rel) const { return dir / rel; }
};

/// Per-pixel flags of a decoded frame.
enum PixelFlag : std::uint8_t {
    kClippedR = 1u << 0, // channel at or above saturation: carries no information
    kClippedG = 1u << 1,
    kClippedB = 1u << 2,
    kMissing = 1u << 3,     // a non-finite value in the file (the value is set to 0)
    kOutsideMask = 1u << 4, // mask is zero here: not to be used
};
inline constexpr std::uint8_t kClippedAny = kClippedR | kClippedG | kClippedB;

struct FrameImage {
    Image color;                      // linear RGB, 3 channels, w x h of the frame
    std::vector<std::uint8_t> flags;  // one PixelFlag set per pixel
    float saturation = std::numeric_limits<float>::infinity(); // effective, linear
    std::size_t missing_pixels = 0;   // non-finite pixels found
    std::optional<ImageFileInfo> file_info; // the header of the file decoded (absent: made in memory):
                                            // how the capture stores it (evaluation's display values)
};

/// Frames sharing a view_index: one camera pose lit by several lights.
struct View {
    int view_index = 0;
    Camera camera;
    std::vector<std::size_t> frames; // indices into CaptureDesc::frames, in file order
};

struct Capture {
    CaptureDesc desc;
    Mesh mesh;
    std::vector<View> views;          // sorted by view_index
    std::vector<FrameImage> images;   // parallel to desc.frames; empty when images were not loaded
    std::vector<std::string> warnings;
    double load_seconds = 0.0;        // wall-clock time load_capture took

    [[nodiscard]] std::size_t frame_count(Split split) const;
};

struct CaptureLoadOptions {
    bool load_mesh = true;
    bool load_images = true; // false: only headers are read (sizes checked), pixels are not decoded
    int threads = 2;         // image decoding threads (at least 1)
};

/// Tolerances of the checks on transform_matrix (max abs entry of R^T R - I, and of the
/// last row against 0 0 0 1) and on poses of frames of one view (max abs difference of
/// rotation entries; translation distance relative to max(1, |t|)).
inline constexpr double kRigidTolerance = 1e-4;
inline constexpr double kPoseAgreementTolerance = 1e-4;

/// The capture's folder from a path to the folder or to its capture.json.
[[nodiscard]] std::filesystem::path capture_json_path(const std::filesystem::path& dir_or_file);

/// Parses and validates capture.json's content (no file access beyond it).
/// `json_path` is used in error messages and to set desc.dir.
[[nodiscard]] CaptureDesc parse_capture_desc(const nlohmann::json& j, const std::filesystem::path& json_path);

/// Loads a capture: description, mesh, images, masks. Throws InputError naming
/// the file and the field for every refusal case of the format spec.
[[nodiscard]] Capture load_capture(const std::filesystem::path& dir_or_file, const CaptureLoadOptions& options = {});

/// The saturation that applies to an image file: the capture's value, else 1.0
/// for integer formats and none (infinity) for float formats.
[[nodiscard]] float effective_saturation(const CaptureDesc& desc, const ImageFileInfo& file);

/// Serializes a description to capture.json's form (per-frame intrinsics only where they differ from the first frame).
[[nodiscard]] nlohmann::json capture_desc_to_json(const CaptureDesc& desc);

/// Writes desc.dir / "capture.json" atomically.
void write_capture_json(const CaptureDesc& desc);

/// Human-readable summary (views, frames per view, image size, lights, triangles, split, warnings).
[[nodiscard]] std::string summarize(const Capture& capture);

} // namespace specula
