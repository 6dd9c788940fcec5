#include "evaluate/pose.h"

#include "core/error.h"
#include "evaluate/bundle_render.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>

namespace specula::evaluate {

namespace {

constexpr int kMaxImageSize = 16384; // as free_camera checks it
constexpr double kDefaultFovDegrees = 40.0;

// The world axis closest to the camera's up: the orbit turns about it.
glm::dvec3 snapped_up(const Camera& camera) {
    const glm::dvec3 u = glm::normalize(glm::dvec3(camera.camera_to_world[1]));
    int best = 0;
    for (int a = 1; a < 3; ++a)
        if (std::abs(u[a]) > std::abs(u[best])) best = a;
    glm::dvec3 axis(0.0);
    axis[best] = u[best] < 0.0 ? -1.0 : 1.0;
    return axis;
}

Pose capture_pose(const PoseOptions& o) {
    if (o.capture.empty()) throw UsageError("--frame needs --capture DIR");
    if (!o.frame) throw UsageError("--capture needs --frame INDEX");
    const Capture capture = load_capture(o.capture, {.load_mesh = false, .load_images = false});
    const std::size_t n = capture.desc.frames.size();
    if (*o.frame < 0 || static_cast<std::size_t>(*o.frame) >= n)
        throw UsageError("--frame: " + std::to_string(*o.frame) + " is out of range: " + capture_json_path(o.capture).string() +
                         (n == 0 ? std::string(" has no frames")
                                 : " has " + std::to_string(n) + " frames (0 to " + std::to_string(n - 1) + ")"));
    const std::size_t i = static_cast<std::size_t>(*o.frame);
    const FrameDesc& f = capture.desc.frames[i];
    Pose p;
    p.camera = f.camera();
    p.light = f.light;
    p.up = snapped_up(p.camera);
    p.what = "frame " + std::to_string(i) + " (" + f.file_path.generic_string() + ")";
    p.frame = PoseFrame{.index = i,
                        .image = capture.desc.resolve(f.file_path),
                        .color_space = capture.desc.color_space,
                        .width = f.intrinsics.w,
                        .height = f.intrinsics.h};
    return p;
}

Pose free_pose(const PoseOptions& o, const std::optional<Bounds>& object) {
    if (!object && (o.camera.empty() || o.light.empty())) throw UsageError("a free pose needs both --camera and --light");
    const auto [w, h] = parse_image_size(o.size, "--size");
    std::optional<double> fov = o.fov;
    if (!fov && !o.fl) fov = kDefaultFovDegrees;
    Pose p;
    p.what = "a free pose";
    // The default camera: in front of the object and a little above, far enough that its
    // bounding sphere (radius r) fits the vertical field of view with a margin:
    // sin(fov / 2) = 1.15 r / distance. The default light is placed at that distance too.
    const glm::dvec3 dir = glm::normalize(glm::dvec3(0.0, 0.35, 1.0));
    glm::dvec3 center(0.0);
    double distance = 0.0;
    if (object) {
        center = glm::dvec3(object->center());
        const double r = std::max(static_cast<double>(object->radius()), 1e-6);
        // free_camera checks the size and --fov / --fl first (and words their errors).
        const Camera unit = free_camera(center + dir, center, p.up, w, h, fov, o.fl);
        const double half_fov = fov ? 0.5 * glm::radians(*fov) : std::atan(0.5 * h / unit.intrinsics.fl_y);
        distance = 1.15 * r / std::sin(half_fov);
    }
    if (!o.camera.empty()) {
        p.camera = parse_free_camera(o.camera, w, h, fov, o.fl);
        const auto v = parse_numbers(o.camera, "--camera", {9}, "eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z");
        p.up = glm::normalize(glm::dvec3(v[6], v[7], v[8]));
    } else {
        p.camera = free_camera(center + distance * dir, center, p.up, w, h, fov, o.fl);
    }
    if (!o.light.empty()) {
        p.light = parse_light(o.light);
    } else {
        // Above, right of and behind the camera. A point light gives a surface at distance d
        // facing it the irradiance E = I / d^2 (inverse square law), and a Lambertian surface
        // of albedo rho shows the radiance rho / pi * E: I = 0.8 pi d^2 makes that 0.8 rho
        // at the object's centre, bright but not clipped.
        const glm::dvec3 eye = p.camera.center();
        const glm::dvec3 right(p.camera.camera_to_world[0]), up(p.camera.camera_to_world[1]);
        p.light.position = eye + 0.5 * distance * (right + up);
        const double d = glm::length(p.light.position - center);
        p.light.intensity = glm::dvec3(0.8 * glm::pi<double>() * d * d);
    }
    return p;
}

} // namespace

Pose resolve_pose(const PoseOptions& o, const std::optional<Bounds>& object) {
    const bool from_capture = !o.capture.empty() || o.frame.has_value();
    const bool free_options = !o.camera.empty() || !o.light.empty();
    if (from_capture && free_options) throw UsageError("give either --capture and --frame, or --camera and --light, not both");
    if (from_capture) return capture_pose(o);
    if (!free_options && !object) throw UsageError("give --capture DIR --frame INDEX, or --camera EYE,TARGET,UP --light X,Y,Z,I");
    return free_pose(o, object);
}

Image read_frame_photo(const PoseFrame& f) {
    const std::string field = "frames[" + std::to_string(f.index) + "].file_path";
    Image photo = read_image(f.image, f.color_space, field);
    if (photo.width != f.width || photo.height != f.height)
        throw InputError(f.image, field,
                         "the image is " + std::to_string(photo.width) + "x" + std::to_string(photo.height) +
                             " but the frame's intrinsics say " + std::to_string(f.width) + "x" + std::to_string(f.height));
    return photo;
}

std::pair<int, int> parse_image_size(const std::string& text, const std::string& option) {
    const auto bad = [&] {
        return UsageError(option + ": '" + text + "' is not N or WxH (whole numbers from 1 to " + std::to_string(kMaxImageSize) +
                          ")");
    };
    // One side: 1 to 5 decimal digits, nothing else (std::stoi would take "12abc", " 12" and "+12").
    const auto side = [&](const std::string& s) {
        if (s.empty() || s.size() > 5 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
            throw bad();
        const int v = std::stoi(s);
        if (v < 1 || v > kMaxImageSize) throw bad();
        return v;
    };
    const auto x = text.find('x');
    const int w = side(text.substr(0, x));
    const int h = x == std::string::npos ? w : side(text.substr(x + 1));
    return {w, h};
}

} // namespace specula::evaluate
