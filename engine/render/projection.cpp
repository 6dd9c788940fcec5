#include "render/projection.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace specula::render {

glm::dmat4 vulkan_projection(const Intrinsics& k, double near) {
    const double w = k.w, h = k.h;
    glm::dmat4 p(0.0); // p[column][row]
    p[0][0] = 2.0 * k.fl_x / w;
    p[2][0] = 1.0 - 2.0 * k.cx / w;
    p[1][1] = -2.0 * k.fl_y / h;
    p[2][1] = 1.0 - 2.0 * k.cy / h;
    p[3][2] = near;
    p[2][3] = -1.0;
    return p;
}

double near_plane_for(const Camera& camera, const Bounds& bounds) {
    const double radius = std::max(static_cast<double>(bounds.radius()), 1e-12);
    const double dist = glm::length(camera.center() - glm::dvec3(bounds.center()));
    return std::max(0.5 * (dist - radius), 1e-4 * radius);
}

glm::dmat4 world_to_clip(const Camera& camera, double near) {
    return vulkan_projection(camera.intrinsics, near) * camera.world_to_camera;
}

std::optional<glm::dvec3> project_vulkan(const glm::dmat4& m, const Intrinsics& k, const glm::dvec3& world) {
    const glm::dvec4 clip = m * glm::dvec4(world, 1.0);
    if (!(clip.w > 0.0)) return std::nullopt;
    const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
    return glm::dvec3((ndc.x + 1.0) * 0.5 * k.w, (ndc.y + 1.0) * 0.5 * k.h, ndc.z);
}

PixelBox unite(const PixelBox& a, const PixelBox& b) noexcept {
    if (a.empty()) return b;
    if (b.empty()) return a;
    return {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1)};
}

PixelBox intersect(const PixelBox& a, const PixelBox& b) noexcept {
    const PixelBox c{std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
    return c.empty() ? PixelBox{} : c;
}

PixelBox pixels_of_box(const glm::dmat4& m, const Intrinsics& k, const glm::dvec3& lo, const glm::dvec3& hi) {
    const PixelBox whole{0, 0, k.w, k.h};
    double x_min = std::numeric_limits<double>::infinity(), y_min = x_min, x_max = -x_min, y_max = -x_min;
    for (int corner = 0; corner < 8; ++corner) {
        const glm::dvec3 p((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y, (corner & 4) ? hi.z : lo.z);
        const std::optional<glm::dvec3> f = project_vulkan(m, k, p);
        if (!f || !std::isfinite(f->x) || !std::isfinite(f->y)) return whole;
        x_min = std::min(x_min, f->x);
        x_max = std::max(x_max, f->x);
        y_min = std::min(y_min, f->y);
        y_max = std::max(y_max, f->y);
    }
    // Pixel i's centre i + 0.5 lies in [x_min, x_max] only for floor(x_min) <= i < ceil(x_max); a pixel more each side.
    const auto clamp_to = [](double v, int n) { return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(n))); };
    return intersect(whole, {clamp_to(std::floor(x_min) - 1.0, k.w), clamp_to(std::floor(y_min) - 1.0, k.h),
                             clamp_to(std::ceil(x_max) + 1.0, k.w), clamp_to(std::ceil(y_max) + 1.0, k.h)});
}

} // namespace specula::render
