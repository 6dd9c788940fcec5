#pragma once
// The capture's pinhole camera as a Vulkan projection (capture-format.md, "Geometry
// conventions"; engine/capture/camera.h).
//
// Derivation. A camera-space point Xc = (X, Y, Z), in front when Z < 0, lands at
//     x = cx + fx X / (-Z),     y = cy - fy Y / (-Z)                 (capture pixels)
// Vulkan maps normalized device coordinates to framebuffer coordinates with the
// viewport (0, 0, w, h): x_fb = (x_ndc + 1) w / 2, y_fb = (y_ndc + 1) h / 2, with
// y_fb pointing down, and samples pixel (i, j) at its centre (i + 0.5, j + 0.5). The
// capture's pixel (i, j) covers [i, i+1) x [j, j+1) with row 0 at the top, so the two
// agree when x_fb = x and y_fb = y, i.e. with w_clip = -Z:
//     x_clip = (2 fx / w) X + (1 - 2 cx / w) Z
//     y_clip = -(2 fy / h) Y + (1 - 2 cy / h) Z                      (y flipped: Vulkan's y is down)
// (check: x_ndc = x_clip / -Z = 2 (cx + fx X / -Z) / w - 1). An off-centre principal
// point only moves the Z column. Depth is reversed-Z with an infinite far plane:
//     z_clip = near,  z_ndc = near / (-Z) in (0, 1]
// so the near plane maps to 1, infinity to 0; depth clears to 0 and the test is
// GREATER. A float depth buffer then keeps about the same relative precision at
// every distance, and no far plane can clip the object.
#include "capture/camera.h"
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <optional>

namespace specula::render {

/// Camera space -> Vulkan clip space (see the derivation above). near > 0.
[[nodiscard]] glm::dmat4 vulkan_projection(const Intrinsics& k, double near);

/// A near plane for a camera and an object's bounds: half the distance from the
/// camera to the bounding sphere, never below 1e-4 of its radius (a camera inside
/// the bounds still sees everything farther than that).
[[nodiscard]] double near_plane_for(const Camera& camera, const Bounds& bounds);

/// vulkan_projection(camera.intrinsics, near) * camera.world_to_camera.
[[nodiscard]] glm::dmat4 world_to_clip(const Camera& camera, double near);

/// Framebuffer position (pixels, capture convention) and depth of a world point through
/// world_to_clip: what the rasterizer computes, for tests. w <= 0 (behind): nothing.
[[nodiscard]] std::optional<glm::dvec3> project_vulkan(const glm::dmat4& world_to_clip, const Intrinsics& k,
                                                       const glm::dvec3& world);

} // namespace specula::render
