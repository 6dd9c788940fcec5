#include "orbit.h"

#include "core/error.h"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>

namespace specula::view {

namespace {

glm::dmat3 rotation_about(const glm::dvec3& axis, double angle) {
    return glm::dmat3(glm::rotate(glm::dmat4(1.0), angle, glm::normalize(axis)));
}

} // namespace

OrbitView::OrbitView(const Camera& start, const PointLight& light, const Bounds& bounds, const glm::dvec3& up)
    : m_start(start), m_start_light(light), m_up(glm::normalize(up)), m_center(glm::dvec3(bounds.center())),
      m_radius(std::max(static_cast<double>(bounds.radius()), 1e-6)) {
    if (!(glm::length(up) > 0.0)) throw Error("OrbitView: the up axis must not be zero");
    m_start_rotation = glm::dmat3(start.camera_to_world);
    const glm::dvec3 eye = start.center();
    const glm::dvec3 forward = -glm::normalize(m_start_rotation[2]);
    m_start_distance = std::max(glm::dot(m_center - eye, forward), 0.1 * m_radius);
    m_start_target = eye + m_start_distance * forward;
    reset();
}

void OrbitView::reset() {
    m_rotation = m_start_rotation;
    m_target = m_start_target;
    m_distance = m_start_distance;
    m_light = m_start_light;
}

void OrbitView::orbit(double dx, double dy) {
    const glm::dmat3 yaw = rotation_about(m_up, dx);
    glm::dmat3 r = yaw * m_rotation;
    const glm::dmat3 pitched = rotation_about(r[0], dy) * r;
    // Refuse a pitch that would pass over a pole (the view would flip about `up`).
    if (std::abs(glm::dot(glm::normalize(pitched[2]), m_up)) < std::cos(glm::radians(3.0))) r = pitched;
    m_rotation = r;
}

void OrbitView::pan(double dx_px, double dy_px) {
    const double world_per_px = m_distance / m_start.intrinsics.fl_y;
    m_target += world_per_px * (-dx_px * m_rotation[0] + dy_px * m_rotation[1]);
}

void OrbitView::zoom(double steps) {
    m_distance = std::clamp(m_distance * std::pow(0.9, steps), 0.02 * m_radius, 100.0 * m_radius);
}

void OrbitView::move_light(double dx, double dy) {
    const glm::dvec3 offset = m_light.position - m_center;
    const glm::dmat3 turn = rotation_about(m_rotation[0], dy) * rotation_about(m_up, dx);
    m_light.position = m_center + turn * offset;
}

ImageRect OrbitView::image_rect(int width, int height) const {
    const Intrinsics& k = m_start.intrinsics;
    const double s = std::min(static_cast<double>(width) / k.w, static_cast<double>(height) / k.h);
    return {0.5 * (width - s * k.w), 0.5 * (height - s * k.h), s * k.w, s * k.h};
}

Camera OrbitView::camera(int width, int height) const {
    if (width <= 0 || height <= 0) throw Error("OrbitView::camera: the window has no pixels");
    const Intrinsics& k0 = m_start.intrinsics;
    const ImageRect rect = image_rect(width, height);
    const double s = rect.width / k0.w;
    const Intrinsics k{width, height, s * k0.fl_x, s * k0.fl_y, rect.x + s * k0.cx, rect.y + s * k0.cy};
    glm::dmat4 c2w(m_rotation);
    c2w[3] = glm::dvec4(m_target + m_distance * glm::normalize(m_rotation[2]), 1.0);
    if (m_rotation == m_start_rotation && m_target == m_start_target && m_distance == m_start_distance)
        c2w = m_start.camera_to_world; // bit-exact start pose (no round trip through the target)
    return Camera(k, c2w);
}

} // namespace specula::view
