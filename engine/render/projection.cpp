#include "render/projection.h"

#include <algorithm>

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

} // namespace specula::render
