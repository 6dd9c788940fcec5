#pragma once
// Ray queries against the mesh: the one place in the engine that talks to
// Embree (style.md habit 5: one move-only RAII owner per handle). A RayScene
// owns an Embree device and a committed triangle scene built from a Mesh
// (robust build: no rays slip through shared edges). After construction the
// scene is read-only, and every query is const and thread-safe: call
// intersect()/occluded() (single rays or batches) from as many threads as you
// like.
//
// Errors: Embree reports through a C callback, which must never throw. The
// callback records the first error; the constructor checks it (and
// rtcGetDeviceError) after the commit and throws specula::Error.
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>

namespace specula {

/// One ray: origin + t * dir for t in [tmin, tmax]. dir need not be unit; t is in units of |dir|.
struct Ray {
    glm::vec3 origin{0.0f};
    float tmin = 0.0f;
    glm::vec3 dir{0.0f, 0.0f, 1.0f};
    float tmax = 0.0f;
};

/// The closest hit of a ray. (u, v) are Embree's barycentrics, the same as the
/// thesis's (s, t) of eq. 3.2: P = (1 - u - v) v0 + u v1 + v v2.
struct RayHit {
    float t = 0.0f;
    std::uint32_t triangle = 0; // index into Mesh::triangles
    float u = 0.0f;
    float v = 0.0f;
};

struct RaySceneOptions {
    /// Embree build threads (its "threads=" device config); 0 lets Embree choose.
    unsigned build_threads = 0;
};

class RayScene {
public:
    /// Relative ray offset: rays leave a surface point p at p + offset * n,
    /// with offset = kRayOffsetRelative * (diagonal of the mesh's bounding box).
    /// 1e-4 of the object's size is ~1000x the float spacing of coordinates of
    /// that size (2^-23 relative), so a ray never re-hits the triangle it
    /// starts on, yet it is far below any feature a capture resolves (a
    /// 512-pixel view of the whole object has pixels ~2e-3 of its size).
    static constexpr float kRayOffsetRelative = 1e-4f;

    explicit RayScene(const Mesh& mesh, const RaySceneOptions& options = {});
    ~RayScene();
    RayScene(RayScene&&) noexcept;
    RayScene& operator=(RayScene&&) noexcept;
    RayScene(const RayScene&) = delete;
    RayScene& operator=(const RayScene&) = delete;

    /// Largest |coordinate| of a ray origin or direction the queries accept: Embree 3 requires
    /// |org|, |dir| <= FLT_LARGE = 1.844e18 per component, and its debug assertions (on in
    /// Debian's build) abort the process otherwise (kernels/common/ray.h, RayK::valid).
    static constexpr float kMaxRayCoordinate = 1e18f;

    /// Every query checks its rays first (check_ray): the engine never trusts that its callers'
    /// inputs were validated. A ray that is not finite, whose coordinates exceed
    /// kMaxRayCoordinate, or whose segment starts below 0 or has a NaN end is refused with an Error naming the ray and its numbers, never handed to Embree.
    /// Closest hit along the ray within [tmin, tmax], or nothing.
    [[nodiscard]] std::optional<RayHit> intersect(const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) const;
    /// True when anything is hit within [tmin, tmax] (any hit, cheaper than intersect).
    [[nodiscard]] bool occluded(const glm::vec3& origin, const glm::vec3& dir, float tmin, float tmax) const;

    /// Batched queries: the same results as the single-ray calls (see ray_scene.cpp
    /// for why they do not use Embree's stream API). out.size() must equal rays.size().
    /// Thread-safe.
    void intersect(std::span<const Ray> rays, std::span<std::optional<RayHit>> out) const;
    /// out[i] = 1 when rays[i] is occluded, else 0.
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> out) const;

    /// The offset (world units) rays should start away from the surface: see kRayOffsetRelative.
    [[nodiscard]] float ray_offset() const noexcept { return m_ray_offset; }
    /// A ray from surface point p (normal n) toward `target`: starts at
    /// p + ray_offset() * n and stops ray_offset() short of the target.
    [[nodiscard]] Ray ray_toward(const glm::vec3& p, const glm::vec3& n, const glm::vec3& target) const;

    /// Throws Error when `ray` is outside what Embree accepts (see above); `what` names the query.
    static void check_ray(const Ray& ray, const char* what, std::size_t index = 0);

    [[nodiscard]] const Bounds& bounds() const noexcept { return m_bounds; }
    [[nodiscard]] std::size_t triangle_count() const noexcept { return m_triangle_count; }

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    Bounds m_bounds;
    float m_ray_offset = 0.0f;
    std::size_t m_triangle_count = 0;
};

} // namespace specula
