#pragma once
/// \file
/// Where a render of a bundle looks from, as `specula render` and `specula-view` take it
/// on the command line: a capture frame's camera and light exactly (--capture DIR
/// --frame I), or a free pose (--camera EYE,TARGET,UP --light X,Y,Z,I --size N|WxH
/// --fov DEG | --fl PX). Both tools resolve their options here, so the options mean the
/// same in both and their errors read the same.
///
///   evaluate::PoseOptions o{.capture = "cap", .frame = 3};
///   const evaluate::Pose pose = evaluate::resolve_pose(o);              // `specula render`
///   const evaluate::Pose start = evaluate::resolve_pose(o, mesh_bounds(bundle.mesh));
///                                        // `specula-view`: a missing --camera / --light frames the object
///   if (start.frame) Image photo = evaluate::read_frame_photo(*start.frame);
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/image.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>

namespace specula::evaluate {

/// The pose options as given on a command line (empty / nullopt: not given).
struct PoseOptions {
    std::string capture;            ///< --capture: capture folder (or its capture.json)
    std::optional<long long> frame; ///< --frame: index in capture.json's frames list
    std::string camera;             ///< --camera: eye,target,up (9 numbers)
    std::string light;              ///< --light: x,y,z,intensity or x,y,z,r,g,b
    std::string size = "512";       ///< --size: the free camera's image, N or WxH
    std::optional<double> fov;      ///< --fov: free camera vertical field of view, degrees (default 40)
    std::optional<double> fl;       ///< --fl: free camera focal length, pixels (instead of --fov)
};

/// The capture frame a pose came from: what it takes to read its photograph.
struct PoseFrame {
    std::size_t index = 0;
    std::filesystem::path image;           ///< the frame's image file, resolved against the capture
    ColorSpace color_space = ColorSpace::Srgb; ///< the capture's encoding of 8/16-bit images
    int width = 0, height = 0;             ///< the frame's intrinsics: the image must have this size
};

struct Pose {
    Camera camera;
    PointLight light;
    /// The world direction an orbit keeps up: --camera's up vector; for a capture frame
    /// the world axis nearest the camera's up; +Y for the default camera.
    glm::dvec3 up{0.0, 1.0, 0.0};
    /// For messages: "frame 3 (images/r_3.png)" or "a free pose".
    std::string what;
    /// Set when the pose is a capture frame's.
    std::optional<PoseFrame> frame;
};

/// Resolves the pose options. Either --capture and --frame, or the free options; mixing
/// the two, a missing half (--frame without --capture, or the reverse), a frame index out
/// of range, a malformed --size / --camera / --light / --fov / --fl are UsageErrors that name
/// the option. `object`: the bounds of the object a default free pose frames (the camera
/// in front of it, slightly above, its bounding sphere filling the view; the light above
/// right of the camera); without it, a free pose needs both --camera and --light, and no
/// options at all is a UsageError. The capture is read (capture.json only, no images).
[[nodiscard]] Pose resolve_pose(const PoseOptions& options, const std::optional<Bounds>& object = std::nullopt);

/// The photograph of a pose's capture frame (linear float, as read_image decodes it).
/// Throws InputError naming frames[i].file_path when it cannot be read or its size is not
/// the frame's.
[[nodiscard]] Image read_frame_photo(const PoseFrame& frame);

/// An image size option: "N" (N x N) or "WxH", whole numbers from 1 to 16384 and nothing
/// else (no sign, space or trailing characters). Throws UsageError naming `option`.
[[nodiscard]] std::pair<int, int> parse_image_size(const std::string& text, const std::string& option);

} // namespace specula::evaluate
