#pragma once
// Procedural triangle meshes with texture coordinates and smooth vertex
// normals, for synthetic captures and closed-form tests. Every builder emits
// outward-facing, counter-clockwise triangles and no degenerate (zero-area)
// ones; normals are analytic where the surface has a closed form.
// Texture coordinates follow glTF: (0, 0) is the top-left of the image, v grows downward.
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <vector>

namespace specula::synth {

/// Sphere of `segments` x `rings` quads (poles as fans), u = longitude / 2 pi,
/// v = colatitude / pi (v = 0 at the +Y pole). Normals are exact: (p - center) / radius.
[[nodiscard]] Mesh make_uv_sphere(const glm::vec3& center, float radius, int segments, int rings);

/// Parallelogram corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v
/// as two triangles; normal = normalize(cross(edge_u, edge_v)); uv over [0, 1]^2.
[[nodiscard]] Mesh make_quad(const glm::vec3& corner, const glm::vec3& edge_u, const glm::vec3& edge_v);

/// A planar profile curve (x = radius from the +Y axis, y = height), sampled
/// densely, with named marks (arc-length fractions) that textures use to place
/// their bands. Build it from lines and arcs; corners should be rounded with arcs
/// because the surface's normals are smooth along the profile.
class Profile {
public:
    explicit Profile(const glm::vec2& start) : m_points{start} {}
    Profile& line_to(const glm::vec2& p, int steps);
    /// Arc around `center` from the current point's angle to `end_angle` (radians,
    /// measured from +x toward +y), `steps` segments; the radius is the current distance to center.
    Profile& arc_to(const glm::vec2& center, float end_angle, int steps);
    /// Appends points as given (e.g. a spline sampled by the caller).
    Profile& append(const std::vector<glm::vec2>& points);
    /// Remembers the current arc-length fraction under `index` (see mark()).
    Profile& set_mark(int index);

    [[nodiscard]] const std::vector<glm::vec2>& points() const noexcept { return m_points; }
    [[nodiscard]] float length() const;
    /// Arc-length fraction in [0, 1] of a mark set with set_mark (0 when unset).
    [[nodiscard]] float mark(int index) const;

private:
    std::vector<glm::vec2> m_points;
    std::vector<float> m_mark_lengths; // arc length at each mark
};

/// Surface of revolution of `profile` about +Y with `segments` steps around.
/// u = angle / 2 pi (counter-clockwise seen from +Y), v = v0 + (v1 - v0) * arc-length fraction.
/// Profile points on the axis (x == 0) become poles (triangle fans).
/// Normals come from the profile's tangent (central differences), so they are
/// smooth across the seam and along the profile.
[[nodiscard]] Mesh make_revolution(const Profile& profile, int segments, float v0 = 0.0f, float v1 = 1.0f);

/// Box centred at the origin with half extents `half`, every edge and corner
/// rounded with radius `radius` (< min(half)). `flat_steps` quads across each
/// flat part of an edge, `round_steps` quads over each 45 degrees of a rounding.
/// Each of the six faces gets its own tile of the texture: tile (col, row) of a
/// 3 x 2 grid inside the rectangle [u0, u1] x [v0, v1], inset by `inset` (uv units),
/// in the order +X, -X, +Y, -Y, +Z, -Z. Normals are exact.
struct UvRect {
    float u0 = 0.0f, v0 = 0.0f, u1 = 1.0f, v1 = 1.0f;
};
[[nodiscard]] Mesh make_rounded_box(const glm::vec3& half, float radius, int flat_steps, int round_steps,
                                    const UvRect& rect, float inset);
/// The uv rectangle of face `face` (0..5 as above) of make_rounded_box.
[[nodiscard]] UvRect rounded_box_face_rect(const UvRect& rect, float inset, int face);

/// A (p, q) torus knot tube: centre curve
///   c(t) = scale/2 * ((2 + cos q t) cos p t, sin q t, (2 + cos q t) sin p t),  t in [0, 2 pi),
/// swept by a circle of radius `tube`; `samples` steps along, `sides` around.
/// u = t / 2 pi (times `u_repeat`), v = angle around the tube / 2 pi.
[[nodiscard]] Mesh make_torus_knot(int p, int q, float scale, float tube, int samples, int sides, float u_repeat = 1.0f);

/// Appends src to dst (both must agree on having texture coordinates).
void append_mesh(Mesh& dst, const Mesh& src);

/// Applies an affine map to positions (and its inverse transpose to normals).
void transform_mesh(Mesh& mesh, const glm::mat4& m);

} // namespace specula::synth
