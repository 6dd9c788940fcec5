#pragma once
// Pinhole camera of the capture format (capture-format.md, "Geometry conventions"):
// camera-to-world 4x4, OpenGL camera axes (looks along -Z, +Y up, +X right),
// pixel (i, j) covers [i, i+1) x [j, j+1), row 0 at the top.
//   Xc = inverse(transform) * X;  in front when Xc.z < 0
//   x = cx + fl_x * Xc.x / (-Xc.z);  y = cy - fl_y * Xc.y / (-Xc.z)
#include <glm/glm.hpp>

#include <optional>

namespace specula {

struct Intrinsics {
    int w = 0;
    int h = 0;
    double fl_x = 0.0;
    double fl_y = 0.0;
    double cx = 0.0;
    double cy = 0.0;
};

struct Camera {
    Intrinsics intrinsics;
    glm::dmat4 camera_to_world{1.0};
    glm::dmat4 world_to_camera{1.0}; // kept equal to inverse(camera_to_world)

    Camera() = default;
    Camera(const Intrinsics& k, const glm::dmat4& c2w) : intrinsics(k), camera_to_world(c2w), world_to_camera(glm::inverse(c2w)) {}

    [[nodiscard]] glm::dvec3 center() const { return glm::dvec3(camera_to_world[3]); }

    /// Camera-space position of a world point.
    [[nodiscard]] glm::dvec3 to_camera(const glm::dvec3& world) const { return glm::dvec3(world_to_camera * glm::dvec4(world, 1.0)); }

    /// Continuous image position (pixel units, see header) of a world point, or
    /// nothing when the point is not in front of the camera.
    [[nodiscard]] std::optional<glm::dvec2> project(const glm::dvec3& world) const {
        const glm::dvec3 c = to_camera(world);
        if (!(c.z < 0.0)) return std::nullopt;
        return glm::dvec2(intrinsics.cx + intrinsics.fl_x * c.x / (-c.z), intrinsics.cy - intrinsics.fl_y * c.y / (-c.z));
    }

    /// Unit world-space direction of the ray through image position (x, y).
    [[nodiscard]] glm::dvec3 ray_direction(double x, double y) const {
        const glm::dvec3 d_cam((x - intrinsics.cx) / intrinsics.fl_x, -(y - intrinsics.cy) / intrinsics.fl_y, -1.0);
        return glm::normalize(glm::dmat3(camera_to_world) * d_cam);
    }

    /// True when image position (x, y) is inside [0, w) x [0, h).
    [[nodiscard]] bool inside(const glm::dvec2& p) const {
        return p.x >= 0.0 && p.y >= 0.0 && p.x < intrinsics.w && p.y < intrinsics.h;
    }
};

/// Camera-to-world matrix of a camera at `eye` looking at `target` with `up` roughly up.
[[nodiscard]] inline glm::dmat4 look_at_camera_to_world(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
    const glm::dvec3 back = glm::normalize(eye - target); // camera +Z points away from the view direction
    glm::dvec3 right = glm::cross(up, back);
    if (glm::length(right) < 1e-9) right = glm::cross(glm::dvec3(1, 0, 0), back);
    right = glm::normalize(right);
    const glm::dvec3 cam_up = glm::cross(back, right);
    glm::dmat4 m(1.0);
    m[0] = glm::dvec4(right, 0.0);
    m[1] = glm::dvec4(cam_up, 0.0);
    m[2] = glm::dvec4(back, 0.0);
    m[3] = glm::dvec4(eye, 1.0);
    return m;
}

} // namespace specula
