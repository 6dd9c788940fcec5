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

/// Pixels [x0, x1) x [y0, y1) of a target, row 0 at the top.
struct PixelBox {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    [[nodiscard]] bool empty() const noexcept { return x1 <= x0 || y1 <= y0; }
    [[nodiscard]] long long area() const noexcept { return empty() ? 0 : static_cast<long long>(x1 - x0) * (y1 - y0); }
    bool operator==(const PixelBox&) const = default;
};
/// The smallest box holding both (an empty one adds nothing).
[[nodiscard]] PixelBox unite(const PixelBox& a, const PixelBox& b) noexcept;
/// The pixels in both (empty when they do not overlap).
[[nodiscard]] PixelBox intersect(const PixelBox& a, const PixelBox& b) noexcept;

/// The pixels of the camera's w x h target whose centres a surface inside the box [lo, hi] can
/// cover when drawn through `world_to_clip` (world_to_clip above): the box's 8 corners projected,
/// their extent widened by a pixel on each side (rounding between this double arithmetic and the
/// rasterizer's float), clipped to the target. Every corner in front of the camera (clip w > 0)
/// puts the whole box there, and the perspective image of a convex set in front is the convex hull
/// of its corners' images; a corner on or behind the camera plane gives the whole target.
[[nodiscard]] PixelBox pixels_of_box(const glm::dmat4& world_to_clip, const Intrinsics& k, const glm::dvec3& lo,
                                     const glm::dvec3& hi);

} // namespace specula::render
