#pragma once
// Capture format versions 1 and 1.1 (docs/capture-format.md): reading,
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
#include <string_view>
#include <vector>

namespace specula {

/// A distant light (capture format 1.1): the same direction and irradiance at every point.
struct DirectionalLight {
    glm::dvec3 direction{0.0, 0.0, 1.0}; ///< unit, world space, from the object toward the light
    glm::dvec3 irradiance{0.0};          ///< RGB irradiance on a surface facing the light
};

/// The light of a frame as every stage computes with it: a point light. A directional light
/// keeps its description in `directional`, and `position` and `intensity` hold its stand-in:
/// a point light kDirectionalStandIn times the mesh's size D from the centre of the mesh's
/// bounding box in `direction`, of intensity irradiance x distance^2 (directional_stand_in).
/// Across the mesh the stand-in's direction differs from `direction` by at most 1 / (2 x
/// kDirectionalStandIn) radian (1e-6) and its irradiance from `irradiance` by a relative
/// 1 / kDirectionalStandIn (2e-6): below what any image resolves (16 bits: 1.5e-5), and
/// measured in tests/capture (docs/capture-format.md "Directional lights").
struct PointLight {
    glm::dvec3 position{0.0};
    glm::dvec3 intensity{0.0}; // RGB radiant intensity
    std::optional<DirectionalLight> directional;
};

/// Distance of a directional light's stand-in point light, in units of the mesh's size D
/// (half the largest distance kMaxDistanceToObject that a light may have).
inline constexpr double kDirectionalStandIn = 5e5;

/// The stand-in point light of `light` for a mesh whose bounding box is `bounds` (see PointLight).
[[nodiscard]] PointLight directional_stand_in(const DirectionalLight& light, const Bounds& bounds);

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
    std::filesystem::path json_file;        // the description's file (error messages name it)
    std::filesystem::path mesh_path;
    ColorSpace color_space = ColorSpace::Srgb;
    std::optional<double> saturation;       // as given; see effective_saturation()
    std::vector<FrameDesc> frames;
    nlohmann::json ground_truth;            // null when absent; never read by reconstruction
    nlohmann::json extra = nlohmann::json::object(); // unknown top-level fields, kept

    [[nodiscard]] std::filesystem::path resolve(const std::filesystem::path& rel) const { return dir / rel; }
};

/// Sets the stand-in (position, intensity) of every directional light of `desc` for `mesh`
/// (load_capture calls it once the mesh is read; parse_capture_desc leaves them at 0).
void place_directional_lights(CaptureDesc& desc, const Mesh& mesh);

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
    std::size_t missing_pixels = 0;   // non-finite (or beyond kMaxPixelMagnitude) pixels found
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
    std::size_t image_files_decoded = 0; // distinct image files decoded (each once, whatever frames name it)

    [[nodiscard]] std::size_t frame_count(Split split) const;
};

struct CaptureLoadOptions {
    bool load_mesh = true;
    bool load_images = true; // false: only headers are read (sizes checked), pixels are not decoded
    int threads = 2;         // image decoding threads (at least 1)
    /// Memory the decoded images may take; unset: what core/memory.h available_memory() finds.
    /// A capture whose decoded_image_bytes() exceed it is refused before any pixel is decoded.
    std::optional<std::uint64_t> memory_available;
};

/// Tolerances of the checks on transform_matrix (max abs entry of R^T R - I, and of the
/// last row against 0 0 0 1) and on poses of frames of one view (max abs difference of
/// rotation entries; translation distance relative to max(1, |t|)).
inline constexpr double kRigidTolerance = 1e-4;
inline constexpr double kPoseAgreementTolerance = 1e-4;

// Ranges of the numbers of a capture (docs/capture-format.md, "Ranges"). The file holds
// doubles; the engine computes in float (Embree, the Vulkan kernels, the renderer) and
// squares distances and irradiances, so each number is checked against the range it is used
// in, with room (a factor of 1e6 or more) for the products formed from it. What the reader
// accepts, reconstruction runs without overflow.
// D below is the diagonal of the mesh's bounding box (the object's size).
/// Largest image width or height: the largest image the renderer's devices hold (core/image.h).
inline constexpr int kMaxImageDimension = kMaxDecodedImageDimension;
/// Largest |coordinate| of a mesh vertex, camera centre or light: a difference of two points
/// is at most 2 sqrt(3) 1e15, its square 1.2e31, below FLT_MAX / 1e6 = 3.4e32; and far below
/// 1.8e18, the largest ray coordinate Embree accepts.
inline constexpr double kMaxWorldCoordinate = 1e15;
/// Smallest mesh diagonal D: the shortest distance the engine squares is the ray offset,
/// 1e-4 D (RayScene::kRayOffsetRelative), and (1e-14)^2 = 1e-28 stays a normal float with a
/// factor 1e9 to spare (FLT_MIN = 1.2e-38).
inline constexpr double kMinMeshDiagonal = 1e-10;
/// Largest distance of a camera centre or a light from the centre of the mesh's bounding box,
/// in units of D. Beyond it a camera (focal length at most kMaxFocalLength) sees the whole
/// object inside one pixel, and a light's direction changes by less than 1e-6 radian across
/// it: place such a light at 1e5 D in the same direction, its intensity scaled by the squared
/// ratio of the distances, and nothing measurable changes.
inline constexpr double kMaxDistanceToObject = 1e6;
/// Smallest focal length, relative to max(w, h): a field of view of 179.9 degrees (a pinhole
/// sees less than 180).
inline constexpr double kMinFocalRelative = 1e-3;
/// Largest focal length, in pixels: positions are floats (relative spacing 2^-24 = 6e-8), and
/// a camera projects that spacing to fl x 6e-8 pixels, 0.06 pixel at 1e6.
inline constexpr double kMaxFocalLength = 1e6;
/// Largest |cx|, |cy|, relative to max(w, h).
inline constexpr double kMaxPrincipalPointRelative = 1e4;
/// Largest light intensity per channel: finite as a float (3.4e38) with 1e8 to spare.
inline constexpr double kMaxLightIntensity = 1e30;
/// Irradiance range: a light of intensity I > 0 (per channel) gives every surface point an
/// irradiance I / d^2 (full scale 1: a white Lambertian surface reads E / pi) within
/// [kMinIrradiance, kMaxIrradiance], with d the distance from the light to the nearest and to
/// the farthest point of the mesh. The diffuse solve sums E^2 over a view's frames in float:
/// even 1e6 frames give 1e6 x (1e15)^2 = 1e36 below FLT_MAX / 100, (1e-15)^2 = 1e-30 above FLT_MIN x 1e6.
/// Pixels between them read 3e-16 to 3e14 of full scale: no real capture is near either end.
inline constexpr double kMaxIrradiance = 1e15;
inline constexpr double kMinIrradiance = 1e-15;
/// Smallest distance from a light to the mesh's surface, in units of D (the ray offset):
/// nearer, I / d^2 has no useful bound.
inline constexpr double kMinLightDistanceRelative = 1e-4;
/// Saturation range: a normal, finite float with room.
inline constexpr double kMinSaturation = 1e-30;
inline constexpr double kMaxSaturation = 1e30;
/// Pixel values of float files beyond +-1e15 are missing, like non-finite ones: the solve
/// multiplies them by irradiances up to 1e15.
inline constexpr float kMaxPixelMagnitude = 1e15f;
/// Largest capture.json: 256 MiB (a capture of 100,000 frames is about 50 MB).
inline constexpr std::uint64_t kMaxCaptureJsonBytes = std::uint64_t{1} << 28;
/// Deepest JSON nesting accepted in capture.json (checked on the text before parsing).
inline constexpr int kMaxCaptureJsonDepth = 256;

/// Why `m` is not a camera-to-world transform the format accepts (docs/capture-format.md,
/// "Geometry conventions" and "Ranges"): the last row, an orthonormal rotation of determinant
/// +1, the translation's range. `entry` names the offending entry within the matrix ("" for
/// the whole, "[r][3]" for a translation). nullopt when it is one.
struct TransformProblem {
    std::string entry;
    std::string message;
};
[[nodiscard]] std::optional<TransformProblem> transform_problem(const glm::dmat4& m);

/// The capture's folder from a path to the folder or to its capture.json.
[[nodiscard]] std::filesystem::path capture_json_path(const std::filesystem::path& dir_or_file);

/// Parses and validates capture.json's content (no file access beyond it).
/// `json_path` is used in error messages and to set desc.dir.
[[nodiscard]] CaptureDesc parse_capture_desc(const nlohmann::json& j, const std::filesystem::path& json_path);

/// The same from the text of capture.json: nesting depth and duplicate keys are checked on
/// the text before it is parsed (core/json_guard.h), then parse_capture_desc.
[[nodiscard]] CaptureDesc parse_capture_text(std::string_view text, const std::filesystem::path& json_path);

/// Reads and parses capture.json (the size limit, then parse_capture_text); opens no other file.
[[nodiscard]] CaptureDesc read_capture_desc(const std::filesystem::path& dir_or_file);

/// Every path a capture is read from: its folder (which holds capture.json), the mesh, each distinct image
/// and mask (what an output folder may not be or contain: core/output_dir.h).
[[nodiscard]] std::vector<std::filesystem::path> capture_input_paths(const CaptureDesc& desc);

/// The checks that need the mesh (docs/capture-format.md, "Ranges"): the mesh's size and
/// coordinates, camera centres and lights within kMaxDistanceToObject of it, lights off its
/// surface, irradiances within [kMinIrradiance, kMaxIrradiance]. Throws InputError naming the
/// field; returns warnings (views that cannot see the mesh, lights that light nothing, a mesh
/// far from the origin for its size). load_capture calls it when it loads the mesh; a caller
/// that loads the capture without its mesh (specula evaluate) can call it with the bundle's.
[[nodiscard]] std::vector<std::string> check_capture_scene(const CaptureDesc& desc, const std::vector<View>& views,
                                                           const Mesh& mesh, const std::filesystem::path& mesh_file);

/// Memory the decoded images of a capture take (load_capture with load_images): per frame
/// w x h x 13 bytes (linear float RGB and one flag byte), per distinct mask file w x h bytes,
/// and per decoding thread one file's decode buffers (w x h x 3 x 6 bytes at most).
[[nodiscard]] std::uint64_t decoded_image_bytes(const CaptureDesc& desc, int threads);

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
