#include "visibility/visibility.h"

#include "core/error.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "shared/lambert.h"

#include <glm/gtc/packing.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace specula {

namespace {

constexpr std::size_t kChunk = 1024; // particles per work item

struct ThreadCounts {
    std::uint64_t rays_cast = 0;
    std::uint64_t rays_occluded = 0;
    std::uint64_t rays_avoided = 0;
    std::uint64_t footprint_rejected = 0;
    std::uint64_t shadow_edge_rejected = 0;
    std::uint64_t rays_answered = 0;
};

constexpr float kNoHit = std::numeric_limits<float>::infinity();

// What the ray through each pixel center hits first: distance, triangle and Embree's
// barycentrics (t == kNoHit on a miss).
struct PixelHit {
    float t = kNoHit;
    std::uint32_t triangle = 0;
    float u = 0.0f;
    float v = 0.0f;
};

std::vector<PixelHit> depth_map(const RayScene& scene, const Camera& cam, unsigned threads) {
    const int w = cam.intrinsics.w, h = cam.intrinsics.h;
    std::vector<PixelHit> depth(std::size_t(w) * std::size_t(h));
    const glm::vec3 eye(cam.center());
    parallel_for(std::size_t(std::max(h, 0)), threads, [&](std::size_t row) {
        const int y = static_cast<int>(row);
        for (int x = 0; x < w; ++x) {
            const glm::vec3 dir(cam.ray_direction(x + 0.5, y + 0.5));
            if (const auto hit = scene.intersect(eye, dir, 0.0f, kNoHit))
                depth[std::size_t(y) * w + x] = {hit->t, hit->triangle, hit->u, hit->v};
        }
    });
    return depth;
}

PixelHits to_pixel_hits(const Camera& cam, const std::vector<PixelHit>& depth) {
    PixelHits out;
    out.width = cam.intrinsics.w;
    out.height = cam.intrinsics.h;
    out.triangle.resize(depth.size());
    out.uv.resize(depth.size());
    for (std::size_t i = 0; i < depth.size(); ++i) {
        out.triangle[i] = depth[i].t == kNoHit ? PixelHits::kMiss : depth[i].triangle;
        out.uv[i] = glm::vec2(depth[i].u, depth[i].v);
    }
    return out;
}

// Barycentrics (s, t) of point q in the plane of triangle (a, b, c): q = (1 - s - t) a + s b + t c.
glm::vec2 barycentrics(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& q) {
    const glm::vec3 e1 = b - a, e2 = c - a, d = q - a;
    const float d11 = glm::dot(e1, e1), d12 = glm::dot(e1, e2), d22 = glm::dot(e2, e2);
    const float d1 = glm::dot(d, e1), d2 = glm::dot(d, e2);
    const float det = d11 * d22 - d12 * d12;
    if (!(det > 0.0f)) return glm::vec2(1.0f / 3.0f);
    return glm::vec2(d22 * d1 - d12 * d2, d11 * d2 - d12 * d1) / det;
}

// 1 where the surface a pixel shows (depth map) gets no light, so the pixel is black:
//   - it faces away from the light (attached shadow): its interpolated normal or its
//     triangle's face (the side the camera sees) has n.u <= 0, or
//   - a shadow ray from the hit point (moved `offset` back toward the camera) to the light
//     is occluded (cast shadow).
// 0 elsewhere, background included. Returns the number of shadow rays cast.
std::uint64_t shadow_map(const RayScene& scene, const Mesh& mesh, std::span<const glm::vec3> face_normal, const Camera& cam,
                         const std::vector<PixelHit>& depth, const glm::vec3& light, unsigned threads,
                         std::vector<std::uint8_t>& out) {
    const int w = cam.intrinsics.w, h = cam.intrinsics.h;
    out.assign(std::size_t(w) * std::size_t(h), 0u);
    const glm::vec3 eye(cam.center());
    const float offset = scene.ray_offset();
    const bool vertex_normals = mesh.normals.size() == mesh.positions.size();
    std::atomic<std::uint64_t> rays{0};
    parallel_for(std::size_t(std::max(h, 0)), threads, [&](std::size_t row) {
        const int y = static_cast<int>(row);
        std::uint64_t cast = 0;
        for (int x = 0; x < w; ++x) {
            const PixelHit& hit = depth[std::size_t(y) * w + x];
            if (hit.t == kNoHit) continue;
            const glm::vec3 dir(cam.ray_direction(x + 0.5, y + 0.5));
            const glm::vec3 p = eye + (hit.t - offset) * dir;
            const glm::vec3 to_light = light - p;
            const float d = glm::length(to_light);
            const glm::vec3 u = to_light / d;
            glm::vec3 face = face_normal[hit.triangle];
            if (glm::dot(face, dir) > 0.0f) face = -face;
            glm::vec3 n = face;
            if (vertex_normals) {
                const glm::uvec3 tri = mesh.triangles[hit.triangle];
                const glm::vec2 b = barycentrics(mesh.positions[tri.x], mesh.positions[tri.y], mesh.positions[tri.z],
                                                 eye + hit.t * dir);
                n = (1.0f - b.x - b.y) * mesh.normals[tri.x] + b.x * mesh.normals[tri.y] + b.y * mesh.normals[tri.z];
            }
            if (!(glm::dot(n, u) > 0.0f) || !(glm::dot(face, u) > 0.0f)) {
                out[std::size_t(y) * w + x] = 1u;
                continue;
            }
            ++cast;
            if (scene.occluded(p, u, offset, d - offset)) out[std::size_t(y) * w + x] = 1u;
        }
        rays += cast;
    });
    return rays;
}

// True when any of the 4 pixels a bilinear sample at q reads is set in `map`.
bool any_tap_set(const Camera& cam, const std::vector<std::uint8_t>& map, const glm::dvec2& q) {
    const int w = cam.intrinsics.w, h = cam.intrinsics.h;
    const int x0 = static_cast<int>(std::floor(q.x - 0.5)), y0 = static_cast<int>(std::floor(q.y - 0.5));
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
            if (map[std::size_t(y) * w + x]) return true;
        }
    return false;
}

// True when the 4 pixels a bilinear sample at image position q reads all show the
// surface through `pos` with normal `n`: each pixel's depth matches where its ray meets
// the particle's tangent plane, within `tolerance` pixel footprints (curvature over a
// pixel is far below that; an occluder or a surface behind an edge is far above it).
bool footprint_on_surface(const Camera& cam, const std::vector<PixelHit>& depth, const glm::dvec2& q, const glm::vec3& pos,
                          const glm::vec3& n, float tolerance) {
    const glm::dvec3 eye = cam.center();
    const glm::dvec3 to_p = glm::dvec3(pos) - eye;
    const double dist = glm::length(to_p);
    const double cos_view = std::max(static_cast<double>(kFootprintMinCos), -glm::dot(glm::dvec3(n), to_p / dist));
    const double footprint = dist / std::min(cam.intrinsics.fl_x, cam.intrinsics.fl_y); // world size of a pixel at pos
    const double allowed = tolerance * footprint / cos_view;
    const int w = cam.intrinsics.w, h = cam.intrinsics.h;
    const int x0 = static_cast<int>(std::floor(q.x - 0.5)), y0 = static_cast<int>(std::floor(q.y - 0.5));
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
            const float t_hit = depth[std::size_t(y) * w + x].t;
            if (t_hit == kNoHit) return false;
            const glm::dvec3 dir = cam.ray_direction(x + 0.5, y + 0.5);
            const double denom = glm::dot(dir, glm::dvec3(n));
            if (!(denom < 0.0)) return false; // the tap's ray does not meet the front of the plane
            const double t_plane = glm::dot(glm::dvec3(pos) - eye, glm::dvec3(n)) / denom;
            if (std::abs(static_cast<double>(t_hit) - t_plane) > allowed) return false;
        }
    return true;
}

SurfaceMap surface_map(const Mesh& mesh, const Camera& cam, const std::vector<PixelHit>& depth) {
    SurfaceMap m;
    m.width = cam.intrinsics.w;
    m.height = cam.intrinsics.h;
    m.words.assign(depth.size() * 4, 0u);
    for (std::size_t i = 0; i < depth.size(); ++i) {
        std::uint32_t* out = &m.words[4 * i];
        if (depth[i].t == kNoHit) {
            out[3] = shared::kLambertNoHit;
            continue;
        }
        const SurfacePoint sp = surface_point(mesh, depth[i].triangle, glm::dvec2(depth[i].u, depth[i].v));
        pack_surface_pixel(sp.position, sp.normal, out);
        ++m.hits;
    }
    return m;
}

struct Target {
    bool is_view;
    std::uint32_t index;
};

std::vector<glm::vec3> face_normals(const Mesh& mesh) {
    std::vector<glm::vec3> face_normal(mesh.triangles.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        const glm::vec3 n = glm::cross(mesh.positions[tri.y] - mesh.positions[tri.x], mesh.positions[tri.z] - mesh.positions[tri.x]);
        const float len = glm::length(n);
        face_normal[t] = len > 0.0f ? n / len : glm::vec3(0.0f);
    }
    return face_normal;
}

// Whether a particle (position, shading normal, face normal) faces the point `to` (a camera
// centre or a light): both normals must, or no ray is cast and no bit set.
bool faces(const glm::vec3& n, const glm::vec3& face, const glm::vec3& pos, const glm::vec3& to) {
    const glm::vec3 d = to - pos;
    return glm::dot(n, d) > 0.0f && glm::dot(face, d) > 0.0f;
}

} // namespace

void pack_surface_pixel(const glm::vec3& position, const glm::vec3& normal, std::uint32_t* words) {
    std::memcpy(words, &position, 12);
    // Octahedral: project onto |x| + |y| + |z| = 1, fold the lower half over the diagonals.
    const float l1 = std::abs(normal.x) + std::abs(normal.y) + std::abs(normal.z);
    glm::vec2 e = l1 > 0.0f ? glm::vec2(normal.x, normal.y) / l1 : glm::vec2(0.0f);
    if (normal.z < 0.0f) {
        const glm::vec2 folded = 1.0f - glm::abs(glm::vec2(e.y, e.x));
        e = glm::vec2(e.x >= 0.0f ? folded.x : -folded.x, e.y >= 0.0f ? folded.y : -folded.y);
    }
    words[3] = glm::packSnorm2x16(e);
}

glm::vec3 unpack_surface_normal(std::uint32_t word) {
    return glm::vec3(shared::lambert_oct_decode(glm::unpackSnorm2x16(word)));
}

bool SurfaceMap::at(int x, int y, glm::vec3& position, glm::vec3& normal) const {
    const std::uint32_t* p = &words[4 * (std::size_t(y) * std::size_t(width) + std::size_t(x))];
    if (p[3] == shared::kLambertNoHit) return false;
    std::memcpy(&position, p, 12);
    normal = unpack_surface_normal(p[3]);
    return true;
}

Visibility compute_visibility(std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                              std::span<const VisibilityView> views, std::span<const PointLight> lights,
                              const VisibilityOptions& options) {
    const Stopwatch clock;
    if (scene.triangle_count() != mesh.triangles.size()) throw Error("visibility: the ray scene was built from another mesh");
    for (std::size_t v = 0; v < views.size(); ++v) {
        const Intrinsics& k = views[v].camera.intrinsics;
        if (!views[v].flags.empty() && views[v].flags.size() != std::size_t(k.w) * std::size_t(k.h))
            throw Error("visibility: view " + std::to_string(v) + " has " + std::to_string(views[v].flags.size()) +
                        " pixel flags for a " + std::to_string(k.w) + "x" + std::to_string(k.h) + " image");
    }

    Visibility vis;
    vis.particle_count = static_cast<std::uint32_t>(particles.size());
    vis.view_count = static_cast<std::uint32_t>(views.size());
    vis.frame_count = static_cast<std::uint32_t>(lights.size());
    vis.view_words = std::max<std::uint32_t>(1, (vis.view_count + 31) / 32);
    vis.frame_words = std::max<std::uint32_t>(1, (vis.frame_count + 31) / 32);
    vis.seen.assign(std::size_t(vis.particle_count) * vis.view_words, 0u);
    vis.lit.assign(std::size_t(vis.particle_count) * vis.frame_words, 0u);
    vis.best_view.assign(vis.particle_count, -1);

    VisibilityStats& st = vis.stats;
    st.particles = particles.size();
    st.views = views.size();
    st.frames = lights.size();
    st.convexity = analyze_convexity(mesh);
    const bool skip_rays = options.skip_rays || (st.convexity.convex && !options.force_rays);
    if (skip_rays)
        st.skipped = st.convexity.convex ? "mesh is convex (closed, connected, no reflex edge): the facing test is exact"
                                         : "occlusion rays turned off (the mesh can occlude itself: " + st.convexity.reason + ")";

    const std::vector<glm::vec3> face_normal = face_normals(mesh);
    std::vector<glm::vec3> view_center(views.size());
    for (std::size_t v = 0; v < views.size(); ++v) view_center[v] = glm::vec3(views[v].camera.center());

    // A convex mesh has no occluders and no surface behind an edge: the test would be exact and is skipped.
    // (On a convex mesh a tap off the particle's surface can only be background, which the
    // capture's mask already flags.)
    const bool footprint_test = options.footprint_test && !st.convexity.convex && !options.skip_rays;
    std::vector<std::vector<PixelHit>> depth(footprint_test || options.surface_maps ? views.size() : 0);
    for (std::size_t v = 0; v < depth.size(); ++v) {
        depth[v] = depth_map(scene, views[v].camera, std::max(1u, options.threads));
        st.depth_rays += depth[v].size();
        if (options.surface_maps) vis.surfaces.push_back(surface_map(mesh, views[v].camera, depth[v]));
        if (options.keep_pixel_hits) vis.pixel_hits.push_back(to_pixel_hits(views[v].camera, depth[v]));
    }
    st.surface_maps = vis.surfaces.size();
    const bool tap_shadows = footprint_test && !options.frame_view.empty();
    if (tap_shadows && options.frame_view.size() != lights.size())
        throw Error("visibility: frame_view has " + std::to_string(options.frame_view.size()) + " entries for " +
                    std::to_string(lights.size()) + " frames");
    std::vector<std::vector<std::uint8_t>> shadows(tap_shadows ? lights.size() : 0);
    for (std::size_t f = 0; f < shadows.size(); ++f) {
        const std::uint32_t v = options.frame_view[f];
        if (v >= views.size()) throw Error("visibility: frame " + std::to_string(f) + " names view " + std::to_string(v));
        st.shadow_map_rays += shadow_map(scene, mesh, face_normal, views[v].camera, depth[v], glm::vec3(lights[f].position),
                                         std::max(1u, options.threads), shadows[f]);
    }

    // Light rays only toward the particles a frame's view sees (skipped rays leave nothing to defer).
    if (options.lit_seen_only && !options.frame_view.empty() && options.frame_view.size() != lights.size())
        throw Error("visibility: frame_view has " + std::to_string(options.frame_view.size()) + " entries for " +
                    std::to_string(lights.size()) + " frames");
    const bool seen_only = options.lit_seen_only && !options.frame_view.empty() && !skip_rays;
    for (const std::uint32_t v : seen_only ? options.frame_view : std::span<const std::uint32_t>{})
        if (v >= views.size()) throw Error("visibility: a frame names view " + std::to_string(v));
    vis.lit_complete.assign(lights.size(), seen_only ? 0 : 1);

    // Work is split by chunks of particles; every particle's bits depend on that particle alone.
    const unsigned threads = std::max(1u, options.threads);
    const unsigned thread_count = parallel_workers(particles.size(), threads, kChunk);
    std::vector<ThreadCounts> counts(thread_count);
    struct Scratch {
        std::vector<Ray> rays;
        std::vector<Target> targets;
        std::vector<std::uint8_t> occluded;
    };
    std::vector<Scratch> scratch(thread_count);
    parallel_for_chunks(particles.size(), threads, kChunk, [&](unsigned worker, std::size_t begin, std::size_t end) {
        ThreadCounts& c = counts[worker];
        std::vector<Ray>& rays = scratch[worker].rays;
        std::vector<Target>& targets = scratch[worker].targets;
        std::vector<std::uint8_t>& occluded = scratch[worker].occluded;
        for (std::size_t p = begin; p < end; ++p) {
            const Particle& particle = particles[p];
            const glm::vec3 pos = particle.p();
            const glm::vec3 n = particle.n();
            const glm::vec3 face = face_normal[particle.triangle];
            std::uint32_t* seen = &vis.seen[p * vis.view_words];
            std::uint32_t* lit = &vis.lit[p * vis.frame_words];
            rays.clear();
            targets.clear();

            for (std::uint32_t v = 0; v < views.size(); ++v) {
                if (!faces(n, face, pos, view_center[v])) continue;
                const Camera& cam = views[v].camera;
                const auto q = cam.project(glm::dvec3(pos));
                if (!q || !cam.inside(*q)) continue;
                if (!views[v].flags.empty()) {
                    const std::size_t px = static_cast<std::size_t>(q->x), py = static_cast<std::size_t>(q->y);
                    if (views[v].flags[py * std::size_t(cam.intrinsics.w) + px] & options.reject_flags) continue;
                }
                if (footprint_test && !footprint_on_surface(cam, depth[v], *q, pos, n, options.footprint_tolerance)) {
                    ++c.footprint_rejected;
                    continue;
                }
                if (skip_rays) {
                    seen[v / 32] |= 1u << (v % 32);
                    ++c.rays_avoided;
                } else {
                    rays.push_back(scene.ray_toward(pos, n, view_center[v]));
                    targets.push_back({true, v});
                }
            }
            const auto cast = [&] {
                if (rays.empty()) return;
                occluded.resize(rays.size());
                scene.occluded(rays, occluded);
                c.rays_cast += rays.size();
                for (std::size_t i = 0; i < rays.size(); ++i) {
                    if (occluded[i]) {
                        ++c.rays_occluded;
                        continue;
                    }
                    const Target t = targets[i];
                    (t.is_view ? seen : lit)[t.index / 32] |= 1u << (t.index % 32);
                }
                rays.clear();
                targets.clear();
            };
            // The views' rays first where the lights' depend on what the particle sees.
            const bool maps_answer = tap_shadows && options.shadow_maps_answer_lights;
            if (seen_only || tap_shadows) cast();
            for (std::uint32_t f = 0; f < lights.size(); ++f) {
                const glm::vec3 light = glm::vec3(lights[f].position);
                if (!faces(n, face, pos, light)) continue;
                const bool view_sees = !options.frame_view.empty() && ((seen[options.frame_view[f] / 32] >> (options.frame_view[f] % 32)) & 1u);
                if (seen_only && !view_sees) continue;
                if (skip_rays) {
                    lit[f / 32] |= 1u << (f % 32);
                    ++c.rays_avoided;
                    continue;
                }
                if (tap_shadows && view_sees) {
                    // A frame whose sample would read a dark pixel (its shadow map) does not light
                    // the particle, whatever its own light ray would say: that ray is not cast.
                    const Camera& cam = views[options.frame_view[f]].camera;
                    const auto q = cam.project(glm::dvec3(pos));
                    if (q && any_tap_set(cam, shadows[f], *q)) {
                        ++c.shadow_edge_rejected;
                        continue;
                    }
                }
                if (maps_answer && view_sees) {
                    lit[f / 32] |= 1u << (f % 32); // its taps are lit
                    ++c.rays_answered;
                } else {
                    rays.push_back(scene.ray_toward(pos, n, light));
                    targets.push_back({false, f});
                }
            }
            cast();

            // Best view (thesis 3.1.2): smallest angle between the normal and the direction to the camera.
            float best = -2.0f;
            for (std::uint32_t v = 0; v < views.size(); ++v) {
                if (!((seen[v / 32] >> (v % 32)) & 1u)) continue;
                const float cosine = glm::dot(n, glm::normalize(view_center[v] - pos));
                if (cosine > best) {
                    best = cosine;
                    vis.best_view[p] = static_cast<std::int32_t>(v);
                }
            }
        }
    });

    st.threads = thread_count;
    for (const ThreadCounts& c : counts) {
        st.rays_cast += c.rays_cast;
        st.rays_occluded += c.rays_occluded;
        st.rays_avoided += c.rays_avoided;
        st.footprint_rejected += c.footprint_rejected;
        st.shadow_edge_rejected += c.shadow_edge_rejected;
        st.rays_answered += c.rays_answered;
    }
    for (std::size_t p = 0; p < particles.size(); ++p) {
        if (vis.best_view[p] < 0) ++st.seen_by_no_view;
        const std::uint32_t* lit = &vis.lit[p * vis.frame_words];
        if (std::all_of(lit, lit + vis.frame_words, [](std::uint32_t w) { return w == 0; })) ++st.lit_by_no_frame;
    }
    st.seconds = clock.seconds();
    return vis;
}

void complete_lit(Visibility& vis, std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                  std::span<const VisibilityView> views, std::span<const PointLight> lights,
                  std::span<const std::uint32_t> frame_view, std::span<const std::size_t> frames, unsigned threads,
                  std::span<const std::uint32_t> stand_in) {
    if (particles.size() != vis.particle_count || lights.size() != vis.frame_count || frame_view.size() != lights.size() ||
        views.size() != vis.view_count || vis.lit_complete.size() != lights.size())
        throw Error("complete_lit: the particles, lights, views and frame_view are not the ones the visibility was computed for");
    if (!stand_in.empty() && stand_in.size() != particles.size())
        throw Error("complete_lit: " + std::to_string(stand_in.size()) + " stand-ins for " + std::to_string(particles.size()) +
                    " particles");
    for (std::size_t p = 0; p < stand_in.size(); ++p)
        if (stand_in[p] >= particles.size() || stand_in[stand_in[p]] != stand_in[p])
            throw Error("complete_lit: particle " + std::to_string(p) + "'s stand-in " + std::to_string(stand_in[p]) +
                        " is not a particle that stands for itself");
    const auto own = [&](std::size_t p) { return stand_in.empty() || stand_in[p] == p; };
    for (const std::uint32_t v : frame_view)
        if (v >= views.size()) throw Error("complete_lit: a frame names view " + std::to_string(v) + " of " + std::to_string(views.size()));
    std::vector<std::uint32_t> todo;
    for (const std::size_t f : frames) {
        if (f >= lights.size()) throw Error("complete_lit: frame " + std::to_string(f) + " of " + std::to_string(lights.size()));
        if (!vis.lit_complete[f] && std::find(todo.begin(), todo.end(), f) == todo.end()) todo.push_back(static_cast<std::uint32_t>(f));
    }
    if (todo.empty()) return;
    const std::vector<glm::vec3> face_normal = face_normals(mesh);
    const unsigned workers = parallel_workers(particles.size(), std::max(1u, threads), kChunk);
    std::vector<ThreadCounts> counts(workers);
    std::vector<std::vector<Ray>> rays(workers);
    std::vector<std::vector<std::uint32_t>> targets(workers);
    std::vector<std::vector<std::uint8_t>> occluded(workers);
    parallel_for_chunks(particles.size(), std::max(1u, threads), kChunk, [&](unsigned worker, std::size_t begin, std::size_t end) {
        for (std::size_t p = begin; p < end; ++p) {
            if (!own(p)) continue;
            const Particle& particle = particles[p];
            const glm::vec3 pos = particle.p(), n = particle.n(), face = face_normal[particle.triangle];
            std::uint32_t* lit = &vis.lit[p * vis.frame_words];
            rays[worker].clear();
            targets[worker].clear();
            for (const std::uint32_t f : todo) {
                if (vis.sees(p, frame_view[f])) continue; // cast with the visibility
                const glm::vec3 light = glm::vec3(lights[f].position);
                if (!faces(n, face, pos, light)) continue;
                rays[worker].push_back(scene.ray_toward(pos, n, light));
                targets[worker].push_back(f);
            }
            if (rays[worker].empty()) continue;
            occluded[worker].resize(rays[worker].size());
            scene.occluded(rays[worker], occluded[worker]);
            counts[worker].rays_cast += rays[worker].size();
            for (std::size_t i = 0; i < rays[worker].size(); ++i)
                if (!occluded[worker][i]) lit[targets[worker][i] / 32] |= 1u << (targets[worker][i] % 32);
        }
    });
    // The particles a stand-in answers for, once every stand-in's bits are in.
    if (!stand_in.empty())
        parallel_for_chunks(particles.size(), std::max(1u, threads), kChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t p = begin; p < end; ++p) {
                if (own(p)) continue;
                const Particle& particle = particles[p];
                const glm::vec3 pos = particle.p(), n = particle.n(), face = face_normal[particle.triangle];
                std::uint32_t* lit = &vis.lit[p * vis.frame_words];
                const std::size_t other = stand_in[p];
                for (const std::uint32_t f : todo)
                    if (!vis.sees(p, frame_view[f]) && faces(n, face, pos, glm::vec3(lights[f].position)) && vis.lights(other, f))
                        lit[f / 32] |= 1u << (f % 32);
            }
        });
    for (const std::uint32_t f : todo) vis.lit_complete[f] = 1;
    for (const ThreadCounts& c : counts) vis.stats.rays_completed += c.rays_cast;
}

PixelHits cast_pixel_hits(const RayScene& scene, const Camera& camera, unsigned threads) {
    return to_pixel_hits(camera, depth_map(scene, camera, std::max(1u, threads)));
}

void uncomplete_lit(Visibility& vis, std::span<const std::uint32_t> frame_view, std::span<const std::size_t> frames) {
    if (frame_view.size() != vis.frame_count || vis.lit_complete.size() != vis.frame_count)
        throw Error("uncomplete_lit: frame_view is not the one the visibility was computed for");
    for (const std::size_t f : frames) {
        if (f >= vis.frame_count) throw Error("uncomplete_lit: frame " + std::to_string(f) + " of " + std::to_string(vis.frame_count));
        if (!vis.lit_complete[f]) continue;
        if (frame_view[f] >= vis.view_count)
            throw Error("uncomplete_lit: a frame names view " + std::to_string(frame_view[f]) + " of " + std::to_string(vis.view_count));
        for (std::size_t p = 0; p < vis.particle_count; ++p)
            if (!vis.sees(p, frame_view[f])) vis.lit[p * vis.frame_words + f / 32] &= ~(1u << (f % 32));
        vis.lit_complete[f] = 0;
    }
}

VisibilityInputs visibility_inputs(const Capture& capture) {
    VisibilityInputs in;
    in.views.reserve(capture.views.size());
    in.frame_view.assign(capture.desc.frames.size(), 0u);
    for (std::size_t v = 0; v < capture.views.size(); ++v) {
        const View& view = capture.views[v];
        VisibilityView vv;
        vv.camera = view.camera;
        for (std::size_t f : view.frames) {
            if (f < in.frame_view.size()) in.frame_view[f] = static_cast<std::uint32_t>(v);
            if (f >= capture.images.size() || capture.images[f].flags.empty()) continue;
            const std::vector<std::uint8_t>& flags = capture.images[f].flags;
            if (vv.flags.empty()) vv.flags.assign(flags.size(), 0u);
            if (flags.size() != vv.flags.size())
                throw Error("visibility: frames of view " + std::to_string(view.view_index) + " have images of different sizes");
            for (std::size_t i = 0; i < flags.size(); ++i) vv.flags[i] |= flags[i];
        }
        in.views.push_back(std::move(vv));
    }
    in.lights.reserve(capture.desc.frames.size());
    for (const FrameDesc& f : capture.desc.frames) in.lights.push_back(f.light);
    return in;
}

std::string describe(const VisibilityStats& s) {
    char buf[1024];
    std::snprintf(buf, sizeof buf,
                  "visibility: %zu particles x %zu views, %zu frames, %u threads, %.3f s\n"
                  "  seen by no view: %zu (%.2f%%); lit by no frame: %zu (%.2f%%)\n"
                  "  occlusion rays: %llu cast (%llu occluded), %llu avoided\n",
                  s.particles, s.views, s.frames, s.threads, s.seconds, s.seen_by_no_view,
                  s.particles ? 100.0 * double(s.seen_by_no_view) / double(s.particles) : 0.0, s.lit_by_no_frame,
                  s.particles ? 100.0 * double(s.lit_by_no_frame) / double(s.particles) : 0.0,
                  static_cast<unsigned long long>(s.rays_cast), static_cast<unsigned long long>(s.rays_occluded),
                  static_cast<unsigned long long>(s.rays_avoided));
    std::string out = buf;
    if (s.depth_rays > 0)
        out += "  depth rays (surface maps of " + std::to_string(s.surface_maps) + " views, footprint test): " +
               std::to_string(s.depth_rays) + "\n";
    if (s.footprint_rejected > 0)
        out += "  footprint test: " + std::to_string(s.footprint_rejected) +
               " (particle, view) pairs dropped (a bilinear tap shows another surface)\n";
    if (s.shadow_map_rays > 0)
        out += "  shadow-edge test: " + std::to_string(s.shadow_edge_rejected) +
               " (particle, frame) pairs unlit (a bilinear tap is dark: in a cast shadow or facing away from the light); " + std::to_string(s.shadow_map_rays) +
               " shadow-map rays\n";
    if (s.rays_answered > 0)
        out += "  " + std::to_string(s.rays_answered) +
               " (particle, frame) pairs answered by the frames' shadow maps, without a light ray of their own\n";
    out += s.skipped.empty() ? "  occlusion rays cast: " + (s.convexity.convex ? std::string("forced on a convex mesh") : "mesh not convex: " + s.convexity.reason) + "\n"
                             : "  occlusion rays skipped: " + s.skipped + "\n";
    return out;
}

std::vector<std::string> visibility_warnings(const VisibilityStats& s) {
    std::vector<std::string> out;
    if (s.particles == 0) return out;
    auto percent = [&](std::size_t n) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.1f%%", 100.0 * double(n) / double(s.particles));
        return std::string(buf);
    };
    const double limit = kUnseenWarningFraction * double(s.particles);
    if (double(s.seen_by_no_view) > limit)
        out.push_back(std::to_string(s.seen_by_no_view) + " of " + std::to_string(s.particles) + " surface particles (" +
                      percent(s.seen_by_no_view) + ") are seen by no view: their albedo is not measured, only filled in "
                      "from seen neighbours (is the object inside the views and the masks, and the mesh wound outward?)");
    if (double(s.lit_by_no_frame) > limit)
        out.push_back(std::to_string(s.lit_by_no_frame) + " of " + std::to_string(s.particles) + " surface particles (" +
                      percent(s.lit_by_no_frame) + ") are lit by no frame (every light is behind them or shadowed): "
                      "they give no sample");
    return out;
}

void require_usable_visibility(const Visibility& vis, std::span<const std::uint32_t> frame_view, const std::filesystem::path& capture,
                               std::span<const std::size_t> frames) {
    std::vector<std::size_t> all;
    if (frames.empty()) {
        all.resize(std::min<std::size_t>(vis.frame_count, frame_view.size()));
        for (std::size_t f = 0; f < all.size(); ++f) all[f] = f;
        frames = all;
    }
    std::size_t seen = 0;
    for (std::size_t p = 0; p < vis.particle_count; ++p) {
        bool seen_here = false;
        for (std::size_t v = 0; v < vis.view_count && !seen_here; ++v) seen_here = vis.sees(p, v);
        if (!seen_here) continue;
        ++seen;
        for (const std::size_t f : frames)
            if (f < frame_view.size() && f < vis.frame_count && vis.lights(p, f) && vis.sees(p, frame_view[f])) return;
    }
    if (seen == 0)
        throw InputError(capture, "",
                         "nothing to reconstruct: no view sees any of the " + std::to_string(vis.particle_count) +
                             " surface particles (the mesh is outside every image, behind every camera, facing away, "
                             "or outside every mask; do the poses and the mesh share one coordinate frame and unit?)");
    throw InputError(capture, "",
                     "nothing to reconstruct: " + std::to_string(seen) + " surface particles are seen, but none is lit by a "
                     "frame of a view that sees it (every light is behind the surface or shadowed: check light.position)");
}

} // namespace specula
