#include "synth/shapes.h"

#include "core/error.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace specula::synth {

namespace {

constexpr float kTwoPi = glm::two_pi<float>();

// Makes every triangle's winding agree with its vertex normals (counter-clockwise
// seen from outside), so builders need not track orientation by hand.
void orient_triangles(Mesh& mesh) {
    for (glm::uvec3& t : mesh.triangles) {
        const glm::vec3 p0 = mesh.positions[t.x], p1 = mesh.positions[t.y], p2 = mesh.positions[t.z];
        const glm::vec3 n = mesh.normals[t.x] + mesh.normals[t.y] + mesh.normals[t.z];
        if (glm::dot(glm::cross(p1 - p0, p2 - p0), n) < 0.0f) std::swap(t.y, t.z);
    }
}

std::uint32_t add_vertex(Mesh& mesh, const glm::vec3& p, const glm::vec3& n, const glm::vec2& uv) {
    mesh.positions.push_back(p);
    mesh.normals.push_back(n);
    mesh.texcoords.push_back(uv);
    return static_cast<std::uint32_t>(mesh.positions.size() - 1);
}

// Quad grid over a (rows+1) x (cols+1) vertex lattice, vertex (i, j) at first + i * (cols + 1) + j.
// `pole(i)` says that every vertex of row i is at one point: the quads touching it become single triangles.
template <class IsPole>
void add_grid_triangles(Mesh& mesh, std::uint32_t first, int rows, int cols, IsPole pole) {
    const auto at = [&](int i, int j) { return first + static_cast<std::uint32_t>(i * (cols + 1) + j); };
    for (int i = 0; i < rows; ++i) {
        for (int j = 0; j < cols; ++j) {
            const std::uint32_t a = at(i, j), b = at(i, j + 1), c = at(i + 1, j), d = at(i + 1, j + 1);
            if (pole(i) && pole(i + 1)) continue;
            if (pole(i)) {
                mesh.triangles.emplace_back(a, c, d);
            } else if (pole(i + 1)) {
                mesh.triangles.emplace_back(a, b, c);
            } else {
                mesh.triangles.emplace_back(a, b, d);
                mesh.triangles.emplace_back(a, d, c);
            }
        }
    }
}

} // namespace

Mesh make_uv_sphere(const glm::vec3& center, float radius, int segments, int rings) {
    if (segments < 3 || rings < 2 || !(radius > 0.0f)) throw Error("make_uv_sphere: need segments >= 3, rings >= 2, radius > 0");
    Mesh mesh;
    for (int i = 0; i <= rings; ++i) {
        const float theta = glm::pi<float>() * static_cast<float>(i) / static_cast<float>(rings);
        const bool pole = i == 0 || i == rings;
        for (int j = 0; j <= segments; ++j) {
            // The seam column repeats column 0's position exactly (index modulo), so the mesh is watertight.
            const float phi = kTwoPi * static_cast<float>(j % segments) / static_cast<float>(segments);
            const glm::vec3 n = pole ? glm::vec3(0.0f, i == 0 ? 1.0f : -1.0f, 0.0f)
                                     : glm::vec3(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
            const float u = (static_cast<float>(j) + (pole ? 0.5f : 0.0f)) / static_cast<float>(segments);
            add_vertex(mesh, center + radius * n, n, {u, static_cast<float>(i) / static_cast<float>(rings)});
        }
    }
    add_grid_triangles(mesh, 0, rings, segments, [&](int i) { return i == 0 || i == rings; });
    orient_triangles(mesh);
    return mesh;
}

Mesh make_quad(const glm::vec3& corner, const glm::vec3& edge_u, const glm::vec3& edge_v) {
    Mesh mesh;
    const glm::vec3 n = glm::normalize(glm::cross(edge_u, edge_v));
    add_vertex(mesh, corner, n, {0.0f, 1.0f});
    add_vertex(mesh, corner + edge_u, n, {1.0f, 1.0f});
    add_vertex(mesh, corner + edge_u + edge_v, n, {1.0f, 0.0f});
    add_vertex(mesh, corner + edge_v, n, {0.0f, 0.0f});
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

// ---- Profile -------------------------------------------------------------------------

Profile& Profile::line_to(const glm::vec2& p, int steps) {
    const glm::vec2 a = m_points.back();
    steps = std::max(steps, 1);
    for (int k = 1; k <= steps; ++k) m_points.push_back(glm::mix(a, p, static_cast<float>(k) / static_cast<float>(steps)));
    return *this;
}

Profile& Profile::arc_to(const glm::vec2& center, float end_angle, int steps) {
    const glm::vec2 d = m_points.back() - center;
    const float r = glm::length(d);
    const float a0 = std::atan2(d.y, d.x);
    steps = std::max(steps, 1);
    for (int k = 1; k <= steps; ++k) {
        const float a = a0 + (end_angle - a0) * static_cast<float>(k) / static_cast<float>(steps);
        glm::vec2 p = center + r * glm::vec2(std::cos(a), std::sin(a));
        if (std::abs(p.x) < 1e-6f * r) p.x = 0.0f; // land exactly on the axis (a pole) when meant to
        m_points.push_back(p);
    }
    return *this;
}

Profile& Profile::append(const std::vector<glm::vec2>& points) {
    m_points.insert(m_points.end(), points.begin(), points.end());
    return *this;
}

float Profile::length() const {
    float len = 0.0f;
    for (std::size_t i = 1; i < m_points.size(); ++i) len += glm::length(m_points[i] - m_points[i - 1]);
    return len;
}

Profile& Profile::set_mark(int index) {
    if (index < 0) throw Error("Profile::set_mark: negative index");
    if (m_mark_lengths.size() <= static_cast<std::size_t>(index)) m_mark_lengths.resize(static_cast<std::size_t>(index) + 1, 0.0f);
    m_mark_lengths[static_cast<std::size_t>(index)] = length();
    return *this;
}

float Profile::mark(int index) const {
    if (index < 0 || static_cast<std::size_t>(index) >= m_mark_lengths.size()) return 0.0f;
    const float total = length();
    return total > 0.0f ? m_mark_lengths[static_cast<std::size_t>(index)] / total : 0.0f;
}

Mesh make_revolution(const Profile& profile, int segments, float v0, float v1) {
    const std::vector<glm::vec2>& pts = profile.points();
    const int m = static_cast<int>(pts.size());
    if (m < 2 || segments < 3) throw Error("make_revolution: need at least 2 profile points and 3 segments");
    std::vector<float> arc(static_cast<std::size_t>(m), 0.0f);
    for (int i = 1; i < m; ++i) arc[i] = arc[i - 1] + glm::length(pts[i] - pts[i - 1]);
    const float total = arc.back();

    Mesh mesh;
    for (int i = 0; i < m; ++i) {
        // Profile normal from the tangent (central differences, one-sided at the ends):
        // the solid lies to the left of the direction of travel, so (t.y, -t.x) points out.
        const glm::vec2 t = pts[std::min(i + 1, m - 1)] - pts[std::max(i - 1, 0)];
        const glm::vec2 n2 = glm::normalize(glm::vec2(t.y, -t.x));
        const bool pole = pts[i].x == 0.0f;
        const float v = v0 + (v1 - v0) * (total > 0.0f ? arc[i] / total : 0.0f);
        for (int j = 0; j <= segments; ++j) {
            const float phi = kTwoPi * static_cast<float>(j % segments) / static_cast<float>(segments);
            const float c = std::cos(phi), s = std::sin(phi);
            const glm::vec3 p(pts[i].x * c, pts[i].y, -pts[i].x * s);
            const glm::vec3 n = pole ? glm::vec3(0.0f, n2.y >= 0.0f ? 1.0f : -1.0f, 0.0f) : glm::vec3(n2.x * c, n2.y, -n2.x * s);
            const float u = (static_cast<float>(j) + (pole ? 0.5f : 0.0f)) / static_cast<float>(segments);
            add_vertex(mesh, p, n, {u, v});
        }
    }
    add_grid_triangles(mesh, 0, m - 1, segments, [&](int i) { return pts[i].x == 0.0f; });
    orient_triangles(mesh);
    return mesh;
}

// ---- Rounded box ---------------------------------------------------------------------

namespace {

// Face coordinates along one axis: a rounding strip, the flat part, a rounding strip.
// In a strip, q = inner + r tan(alpha) with alpha uniform over [0, 45 deg], so the
// rounded surface (the point clamp(q) + r normalize(q - clamp(q))) gets uniform angular steps.
std::vector<float> box_axis_coords(float half, float radius, int flat_steps, int round_steps) {
    const float inner = half - radius;
    std::vector<float> q;
    for (int k = round_steps; k >= 1; --k)
        q.push_back(-inner - radius * std::tan(glm::quarter_pi<float>() * static_cast<float>(k) / static_cast<float>(round_steps)));
    for (int k = 0; k <= flat_steps; ++k) q.push_back(-inner + 2.0f * inner * static_cast<float>(k) / static_cast<float>(flat_steps));
    for (int k = 1; k <= round_steps; ++k)
        q.push_back(inner + radius * std::tan(glm::quarter_pi<float>() * static_cast<float>(k) / static_cast<float>(round_steps)));
    q.front() = -half; // tan(45 deg) is not exactly 1 in float: snap the face planes
    q.back() = half;
    return q;
}

struct BoxFace {
    int axis;    // the fixed axis
    float sign;  // which side
    int u_axis;  // texture u runs along this axis ...
    float u_sign; // ... in this direction
    int v_axis;
    float v_sign;
};

// Tiles read upright from outside: v runs down (-Y) on the side faces.
constexpr BoxFace kBoxFaces[6] = {
    {0, +1.0f, 2, -1.0f, 1, -1.0f}, // +X
    {0, -1.0f, 2, +1.0f, 1, -1.0f}, // -X
    {1, +1.0f, 0, +1.0f, 2, +1.0f}, // +Y
    {1, -1.0f, 0, +1.0f, 2, -1.0f}, // -Y
    {2, +1.0f, 0, +1.0f, 1, -1.0f}, // +Z
    {2, -1.0f, 0, -1.0f, 1, -1.0f}, // -Z
};

} // namespace

UvRect rounded_box_face_rect(const UvRect& rect, float inset, int face) {
    const int col = face % 3, row = face / 3;
    const float tw = (rect.u1 - rect.u0) / 3.0f, th = (rect.v1 - rect.v0) / 2.0f;
    return {rect.u0 + tw * static_cast<float>(col) + inset, rect.v0 + th * static_cast<float>(row) + inset,
            rect.u0 + tw * static_cast<float>(col + 1) - inset, rect.v0 + th * static_cast<float>(row + 1) - inset};
}

Mesh make_rounded_box(const glm::vec3& half, float radius, int flat_steps, int round_steps, const UvRect& rect, float inset) {
    if (!(radius > 0.0f) || radius >= std::min({half.x, half.y, half.z}) || flat_steps < 1 || round_steps < 1)
        throw Error("make_rounded_box: need 0 < radius < min(half extents) and at least one step");
    const std::vector<float> coords[3] = {box_axis_coords(half.x, radius, flat_steps, round_steps),
                                          box_axis_coords(half.y, radius, flat_steps, round_steps),
                                          box_axis_coords(half.z, radius, flat_steps, round_steps)};
    const glm::vec3 inner = half - glm::vec3(radius);
    Mesh mesh;
    for (int f = 0; f < 6; ++f) {
        const BoxFace& face = kBoxFaces[f];
        const UvRect tile = rounded_box_face_rect(rect, inset, f);
        const std::vector<float>& cu = coords[face.u_axis];
        const std::vector<float>& cv = coords[face.v_axis];
        const int nu = static_cast<int>(cu.size()), nv = static_cast<int>(cv.size());
        const auto first = static_cast<std::uint32_t>(mesh.positions.size());
        for (int i = 0; i < nv; ++i) {
            for (int j = 0; j < nu; ++j) {
                // Walk u and v in their texture directions; coordinates come from the shared
                // per-axis lists, so vertices on an edge are bitwise equal on both faces.
                const int ju = face.u_sign > 0.0f ? j : nu - 1 - j;
                const int iv = face.v_sign > 0.0f ? i : nv - 1 - i;
                glm::vec3 q(0.0f);
                q[face.axis] = face.sign * half[face.axis];
                q[face.u_axis] = cu[static_cast<std::size_t>(ju)];
                q[face.v_axis] = cv[static_cast<std::size_t>(iv)];
                const glm::vec3 c = glm::clamp(q, -inner, inner);
                const glm::vec3 n = glm::normalize(q - c);
                const float fu = static_cast<float>(j) / static_cast<float>(nu - 1);
                const float fv = static_cast<float>(i) / static_cast<float>(nv - 1);
                add_vertex(mesh, c + radius * n, n, {glm::mix(tile.u0, tile.u1, fu), glm::mix(tile.v0, tile.v1, fv)});
            }
        }
        add_grid_triangles(mesh, first, nv - 1, nu - 1, [](int) { return false; });
    }
    orient_triangles(mesh);
    return mesh;
}

// ---- Torus knot ----------------------------------------------------------------------

Mesh make_torus_knot(int p, int q, float scale, float tube, int samples, int sides, float u_repeat) {
    if (samples < 8 || sides < 3 || !(tube > 0.0f)) throw Error("make_torus_knot: need samples >= 8, sides >= 3, tube > 0");
    const float fp = static_cast<float>(p), fq = static_cast<float>(q), h = 0.5f * scale;
    Mesh mesh;
    for (int i = 0; i <= samples; ++i) {
        const float t = kTwoPi * static_cast<float>(i % samples) / static_cast<float>(samples);
        const float cq = std::cos(fq * t), sq = std::sin(fq * t), cp = std::cos(fp * t), sp = std::sin(fp * t);
        const glm::vec3 c = h * glm::vec3((2.0f + cq) * cp, sq, (2.0f + cq) * sp);
        const glm::vec3 dc = h * glm::vec3(-fq * sq * cp - fp * (2.0f + cq) * sp, fq * cq, -fq * sq * sp + fp * (2.0f + cq) * cp);
        // Frame: tangent, and the direction from the knot's centre made orthogonal to it.
        const glm::vec3 tangent = glm::normalize(dc);
        const glm::vec3 binormal = glm::normalize(glm::cross(tangent, c));
        const glm::vec3 normal = glm::cross(binormal, tangent);
        for (int k = 0; k <= sides; ++k) {
            const float a = kTwoPi * static_cast<float>(k % sides) / static_cast<float>(sides);
            const glm::vec3 n = std::cos(a) * normal + std::sin(a) * binormal;
            add_vertex(mesh, c + tube * n, n,
                       {u_repeat * static_cast<float>(i) / static_cast<float>(samples), static_cast<float>(k) / static_cast<float>(sides)});
        }
    }
    add_grid_triangles(mesh, 0, samples, sides, [](int) { return false; });
    orient_triangles(mesh);
    return mesh;
}

void append_mesh(Mesh& dst, const Mesh& src) {
    if (!dst.positions.empty() && dst.has_texcoords() != src.has_texcoords())
        throw Error("append_mesh: both meshes must have texture coordinates, or neither");
    const auto offset = static_cast<std::uint32_t>(dst.positions.size());
    dst.positions.insert(dst.positions.end(), src.positions.begin(), src.positions.end());
    dst.normals.insert(dst.normals.end(), src.normals.begin(), src.normals.end());
    dst.texcoords.insert(dst.texcoords.end(), src.texcoords.begin(), src.texcoords.end());
    for (const glm::uvec3& t : src.triangles) dst.triangles.push_back(t + glm::uvec3(offset));
}

void transform_mesh(Mesh& mesh, const glm::mat4& m) {
    const glm::mat3 nm = glm::transpose(glm::inverse(glm::mat3(m)));
    for (glm::vec3& p : mesh.positions) p = glm::vec3(m * glm::vec4(p, 1.0f));
    for (glm::vec3& n : mesh.normals) n = glm::normalize(nm * n);
}

} // namespace specula::synth
