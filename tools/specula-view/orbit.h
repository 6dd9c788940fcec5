#pragma once
// The viewer's camera and light control: an orbit around a target point, with the
// light kept at a fixed offset from the object's centre that can itself be orbited.
// Pure math (no window, no GPU), so tests can check it.
//
//   OrbitView view(start_camera, start_light, bounds, up);
//   view.orbit(dx, dy);  view.pan(dx, dy);  view.zoom(steps);  view.move_light(dx, dy);
//   Camera cam = view.camera(window_w, window_h);   // the start camera exactly at its own size
//
// The start camera is kept exactly (rotation, intrinsics): the first frame of
// `--capture DIR --frame I` is that frame's view. Window sizes other than the start
// image's scale the intrinsics uniformly and centre the image (letterbox), so the
// captured photograph maps onto the render by one scale and offset (image_rect).
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"

#include <glm/glm.hpp>

namespace specula::view {

/// Where the start image lies in a window: x, y (top-left, pixels), width, height.
struct ImageRect {
    double x = 0.0, y = 0.0, width = 0.0, height = 0.0;
};

class OrbitView {
public:
    /// `up`: the axis the orbit turns about (world +Y for Specula's synthetic rigs).
    /// The orbit target is the point of the start camera's optical axis nearest the
    /// centre of `bounds` (at least a tenth of the bounds' radius in front of the camera).
    OrbitView(const Camera& start, const PointLight& light, const Bounds& bounds, const glm::dvec3& up);

    /// Turns the camera about the target: dx radians about `up`, dy radians about the
    /// camera's right axis (refused within ~3 degrees of the poles).
    void orbit(double dx, double dy);
    /// Moves camera and target in the image plane by (dx, dy) pixels of the start image
    /// at the target's depth (+x right, +y down, as a drag moves the object).
    void pan(double dx_px, double dy_px);
    /// Distance to the target times 0.9^steps (positive steps move closer).
    void zoom(double steps);
    /// Turns the light about the object's centre: dx radians about `up`, dy about the
    /// camera's right axis.
    void move_light(double dx, double dy);
    /// Back to the start camera and light.
    void reset();

    /// The camera for a window of width x height pixels (see the header comment).
    [[nodiscard]] Camera camera(int width, int height) const;
    [[nodiscard]] PointLight light() const { return m_light; }
    /// Where the start image (a captured photograph) lands in such a window.
    [[nodiscard]] ImageRect image_rect(int width, int height) const;
    /// Window pixels per pixel of the start image.
    [[nodiscard]] double window_scale(int width, int height) const { return image_rect(width, height).width / m_start.intrinsics.w; }
    [[nodiscard]] double distance() const noexcept { return m_distance; }
    [[nodiscard]] glm::dvec3 target() const noexcept { return m_target; }

private:
    Camera m_start;
    PointLight m_start_light;
    glm::dvec3 m_up;
    glm::dvec3 m_center;
    double m_radius;
    glm::dmat3 m_start_rotation;
    glm::dvec3 m_start_target;
    double m_start_distance;

    glm::dmat3 m_rotation; // camera-to-world axes: right, up, back (the camera looks along -back)
    glm::dvec3 m_target;
    double m_distance;
    PointLight m_light;
};

} // namespace specula::view
