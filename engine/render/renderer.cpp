#include "render/renderer.h"

#include "core/error.h"
#include "core/timer.h"
#include "render/projection.h"

#include "render/both_analytic.frag.h"
#include "render/both_factorized.frag.h"
#include "render/deferred_analytic.frag.h"
#include "render/deferred_factorized.frag.h"
#include "render/diffuse.frag.h"
#include "render/fullscreen.vert.h"
#include "render/gbuffer.frag.h"
#include "render/raster.vert.h"
#include "render/shadow.vert.h"
#include "render/specular_analytic.frag.h"
#include "render/specular_factorized.frag.h"

#include <meshoptimizer.h>

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <numbers>
#include <tuple>
#include <unordered_map>

namespace specula::render {

namespace {

// Set 0 of every raster pipeline: the per-frame parameters, then the textures the pass
// samples (shaders/render/*.{vert,frag}): the albedo atlas, the shadow map
// (render/terms.glsl SPECULA_SHADOW_SAMPLER), and for the factorized passes term k's G
// at kBindingCubeG + k, its H at kBindingCubeH + k (render/terms.glsl SPECULA_FACTOR_SAMPLERS);
// unused bindings hold term 1's cube-maps. The shadow map's depth pass uses the first one.
// The vertices are vertex input binding 0 (set_vertex_input), not a descriptor.
constexpr uint32_t kBindingParams = 0, kBindingAlbedo = 1, kBindingShadow = 2, kBindingCubeG = 3,
                   kBindingCubeH = kBindingCubeG + kMaxFactorTerms;
constexpr uint32_t kLitBindings = kBindingShadow + 1;
constexpr uint32_t kFactorizedBindings = kBindingCubeH + kMaxFactorTerms;
constexpr uint32_t kShadowPassBindings = 1;
// The deferred shading subpass adds the G-buffer's two input attachments after the
// bindings of its forward counterpart (shaders/render/deferred_*.frag).
constexpr uint32_t kDeferredAnalyticGbuffer = kLitBindings, kDeferredFactorizedGbuffer = kFactorizedBindings;

// The shadow map's frustum: a light at least this many bounding radii from the centre
// (half-angle asin(1 / 1.1) = 65 degrees); a closer light gets no shadow pass.
constexpr double kMinLightDistanceRadii = 1.1;
// Beyond this many bounding radii the shadow map is a parallel projection (light_frustum).
constexpr double kOrthographicLightDistanceRadii = 1000.0;
// Field-of-view margin over the bounding sphere's silhouette, and near/far margins.
constexpr double kFovMargin = 1.02, kDepthMargin = 0.02;
// Bias (shared/render.h shadow_lookup_point; the depth pass's rasterizer bias): a normal
// offset of (kNormalOffsetConstant + kNormalOffsetGrazing sin(theta)) texels, and a
// slope-scaled depth bias of kDepthBiasSlope times the depth's slope per texel. The offset
// moves the shadow's edge by as much, so it is small: a quarter texel leaves a convex surface
// unshadowed with a margin (RenderTest.ShadowMapPutsNoAcneOnAConvexSphere: acne at 0.15 texel
// with a frustum around the bounding sphere, at 0.05 with the one fitted to the vertices); a
// texel and more, as until 2026-12, cost the coated can 1.3 dB and the woodenpot 4.1 dB of
// display PSNR (pooled over the test frames).
constexpr float kNormalOffsetConstant = 0.25f, kNormalOffsetGrazing = 0.25f, kDepthBiasSlope = 2.0f;

struct LightFrustum {
    glm::dmat4 to_clip{1.0};
    double texel_per_distance = 0.0; // world size of one map texel per unit of distance from the light
};

/// The perspective frustum from the light aimed at the bounding sphere's centre c that just
/// covers the mesh's vertices `positions` (at most the sphere of radius r; a parallel one
/// covering the sphere for a light beyond kOrthographicLightDistanceRadii); nullopt, with
/// `note` saying why, when the light is too close.
std::optional<LightFrustum> light_frustum(const glm::dvec3& light, const glm::dvec3& c, double r, uint32_t size,
                                          std::span<const glm::vec3> positions, std::string& note) {
    const double d = glm::length(light - c);
    if (!(r > 0.0) || !std::isfinite(d)) {
        note = "degenerate mesh bounds: no shadow map";
        return std::nullopt;
    }
    if (d < kMinLightDistanceRadii * r) {
        note = "light " + std::to_string(d) + " from the bounds' centre, inside or within " +
               std::to_string(static_cast<int>(std::lround((kMinLightDistanceRadii - 1.0) * 100))) +
               "% of the bounding sphere (radius " + std::to_string(r) + "): no shadow map, drawn unshadowed";
        return std::nullopt;
    }
    const glm::dvec3 forward = (c - light) / d;
    const glm::dvec3 up = std::abs(forward.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
    LightFrustum f;
    if (d > kOrthographicLightDistanceRadii * r) {
        // A distant light (a directional light's stand-in, capture.h): parallel projection from
        // 2 r before the sphere, so that the depths span 2 r, not the light's distance (whose
        // float rounding would exceed the bias). Its rays differ from the light's by < r / d.
        const double extent = r * kFovMargin;
        const glm::dvec3 eye = c - 2.0 * r * forward;
        f.to_clip = glm::orthoRH_ZO(-extent, extent, -extent, extent, r * (1.0 - kDepthMargin), 3.0 * r * (1.0 + kDepthMargin)) *
                    glm::lookAtRH(eye, c, up);
        f.texel_per_distance = 2.0 * extent / size / d; // the shader scales it by the distance to the light
        return f;
    }
    // The cone about the axis toward the centre that holds every vertex (and so every triangle,
    // their convex combinations), and their depths along the axis: tighter than the bounding
    // sphere's wherever the mesh does not fill it (a squat bowl seen from the side: texels two
    // thirds as large, RenderTest.ShadowMapFrustumHoldsTheMeshNotItsBoundingSphere). The light
    // is outside the sphere, so every vertex lies ahead of it.
    double half = std::asin(r / d);
    double near = d - r, far = d + r;
    double min_cos = 1.0, lo = far, hi = near;
    for (const glm::vec3& q : positions) {
        const glm::dvec3 v = glm::dvec3(q) - light;
        const double along = glm::dot(v, forward);
        min_cos = std::min(min_cos, along / glm::length(v));
        lo = std::min(lo, along);
        hi = std::max(hi, along);
    }
    half = std::clamp(std::acos(std::clamp(min_cos, -1.0, 1.0)), 1e-3 * half, half); // > 0: vertices all on the axis
    near = std::max(near, lo);
    far = std::min(far, hi);
    half *= kFovMargin;
    near *= 1.0 - kDepthMargin;
    far *= 1.0 + kDepthMargin;
    f.to_clip = glm::perspectiveRH_ZO(2.0 * half, 1.0, near, far) * glm::lookAtRH(light, c, up);
    f.texel_per_distance = 2.0 * std::tan(half) / size;
    return f;
}

/// Params, then textures up to `count` bindings, then `inputs` input attachments.
std::vector<gpu::DescriptorBinding> bindings_for(uint32_t count, uint32_t inputs = 0) {
    const gpu::DescriptorBinding params{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                        VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT};
    const gpu::DescriptorBinding texture{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, VK_SHADER_STAGE_FRAGMENT_BIT};
    const gpu::DescriptorBinding input{VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT, VK_SHADER_STAGE_FRAGMENT_BIT};
    std::vector<gpu::DescriptorBinding> all{params};
    all.resize(count, texture);
    all.resize(count + inputs, input);
    return all;
}

double to_ms(const std::optional<double>& ns) { return *ns * 1e-6; }

gpu::Image upload_cube(gpu::Context& ctx, const CubeMap& cube, const char* name) {
    const std::size_t texels = std::size_t{6} * cube.resolution * cube.resolution;
    if (cube.resolution == 0 || cube.texels.size() != texels)
        throw Error(std::string("cube-map ") + name + ": expected 6 x " + std::to_string(cube.resolution) + "^2 texels, got " +
                    std::to_string(cube.texels.size()));
    const VkFormat format = gpu::choose_float_texture_format(ctx);
    gpu::Image image(ctx, {.name = name, .kind = gpu::ImageKind::CubeMap, .width = cube.resolution,
                           .height = cube.resolution, .format = format});
    const std::span<const float> rgb(&cube.texels.front().x, texels * 3); // glm::vec3 is 3 packed floats
    image.upload(gpu::pack_rgba(rgb, 3, texels, format));
    return image;
}

// Whether a factorization in `param` can be drawn for `specular`: the warped parametrization
// multiplies the terms by the Lafortune lobe's radial factor (shared/gshd.h part 5), which no
// other family has.
void require_drawable(FactorParam param, const std::optional<SpecularModel>& specular) {
    if (param != FactorParam::Warped || !specular || family_of(*specular) == MaterialFamily::Lafortune) return;
    throw Error(std::string("renderer: a warped factorization needs the lafortune family's radial factor; the specular "
                            "model is ") +
                to_string(family_of(*specular)) + " (its factorizations are plain or mirrored GSHD)");
}

} // namespace

const char* mode_name(Mode mode) noexcept {
    switch (mode) {
    case Mode::Diffuse: return "diffuse";
    case Mode::Specular: return "specular";
    case Mode::Both: return "both";
    }
    return "?";
}

const char* passes_name(Passes passes) noexcept {
    switch (passes) {
    case Passes::Separate: return "separate";
    case Passes::Fused: return "fused";
    case Passes::Deferred: return "deferred";
    }
    return "?";
}

const char* specular_path_name(SpecularPath model) noexcept {
    return model == SpecularPath::Analytic ? "analytic" : "factorized";
}

IndexedVertices index_vertices(const Mesh& mesh, std::span<const glm::vec2> corner_uv) {
    if (corner_uv.size() != 3 * mesh.triangles.size())
        throw Error("renderer: " + std::to_string(corner_uv.size()) + " corner texture coordinates for " +
                    std::to_string(mesh.triangles.size()) + " triangles (3 per triangle expected)");
    if (mesh.normals.size() != mesh.positions.size())
        throw Error("renderer: the mesh needs one normal per position");
    IndexedVertices out;
    out.indices.resize(3 * mesh.triangles.size());
    // (position index, atlas coordinate bits) -> vertex
    std::unordered_map<uint64_t, std::vector<std::pair<uint64_t, uint32_t>>> seen;
    seen.reserve(mesh.positions.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = tri[k];
            if (v >= mesh.positions.size()) throw Error("renderer: triangle " + std::to_string(t) + " has an index out of range");
            const glm::vec2 uv = corner_uv[3 * t + static_cast<std::size_t>(k)];
            const uint64_t uv_bits = (uint64_t{std::bit_cast<uint32_t>(uv.x)} << 32) | std::bit_cast<uint32_t>(uv.y);
            std::vector<std::pair<uint64_t, uint32_t>>& at = seen[v];
            auto it = std::find_if(at.begin(), at.end(), [&](const auto& e) { return e.first == uv_bits; });
            if (it == at.end()) {
                at.emplace_back(uv_bits, static_cast<uint32_t>(out.vertices.size()));
                out.vertices.push_back({glm::vec4(mesh.positions[v], uv.x), glm::vec4(glm::normalize(mesh.normals[v]), uv.y)});
                it = std::prev(at.end());
            }
            out.indices[3 * t + static_cast<std::size_t>(k)] = it->second;
        }
    }
    return out;
}

namespace {

// Each position's place: positions equal bit for bit share one (texture seams duplicate vertices
// at the same place), numbered 0, 1, ... in first-use order.
std::vector<uint32_t> weld_by_position(std::span<const glm::vec3> positions) {
    std::map<std::tuple<float, float, float>, uint32_t> ids;
    std::vector<uint32_t> welded(positions.size());
    for (std::size_t i = 0; i < positions.size(); ++i) {
        const glm::vec3& p = positions[i];
        welded[i] = ids.try_emplace({p.x, p.y, p.z}, static_cast<uint32_t>(ids.size())).first->second;
    }
    return welded;
}

glm::vec3 triangle_centroid(const IndexedVertices& mesh, const uint32_t* tri) {
    return (glm::vec3(mesh.vertices[tri[0]].position_u) + glm::vec3(mesh.vertices[tri[1]].position_u) +
            glm::vec3(mesh.vertices[tri[2]].position_u)) / 3.0f;
}

glm::vec3 triangle_normal(const IndexedVertices& mesh, const uint32_t* tri) {
    const glm::vec3 a(mesh.vertices[tri[0]].position_u), b(mesh.vertices[tri[1]].position_u), c(mesh.vertices[tri[2]].position_u);
    return glm::cross(b - a, c - a); // length: twice the area
}

// Orders `tris` (triangle numbers) so that runs of at most `most` are compact: splits at the median
// of the centroids along the longest side of their box, recursively. Appends each run's size to `runs`.
void split_into_patches(std::span<uint32_t> tris, std::span<const glm::vec3> centroids, std::size_t most,
                        std::vector<std::size_t>& runs) {
    if (tris.size() <= most) {
        runs.push_back(tris.size());
        return;
    }
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (const uint32_t t : tris) {
        lo = glm::min(lo, centroids[t]);
        hi = glm::max(hi, centroids[t]);
    }
    const glm::vec3 extent = hi - lo;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : extent.y >= extent.z ? 1 : 2;
    const std::size_t half = tris.size() / 2;
    std::nth_element(tris.begin(), tris.begin() + static_cast<std::ptrdiff_t>(half), tris.end(),
                     [&](uint32_t a, uint32_t b) { return centroids[a][axis] < centroids[b][axis]; });
    split_into_patches(tris.first(half), centroids, most, runs);
    split_into_patches(tris.subspan(half), centroids, most, runs);
}

// The shape of a patch's surface, by its directed edges (welded position ids): its border (the
// edges no triangle among them walks the other way, sorted), and its folds (edges walked twice the
// same way, and triangles with two corners at one place), which a simplification must not add.
struct PatchEdges {
    std::vector<uint64_t> edges; // every directed edge, (from << 32) | to, sorted
    std::vector<uint64_t> border;
    std::size_t folds = 0;
};
PatchEdges patch_edges(std::span<const uint32_t> indices, std::span<const uint32_t> welded) {
    PatchEdges out;
    out.edges.reserve(indices.size());
    for (std::size_t t = 0; t < indices.size(); t += 3)
        for (std::size_t k = 0; k < 3; ++k) {
            const uint32_t from = welded[indices[t + k]], to = welded[indices[t + (k + 1) % 3]];
            if (from == to) ++out.folds;
            out.edges.push_back(uint64_t{from} << 32 | to);
        }
    std::sort(out.edges.begin(), out.edges.end());
    for (std::size_t i = 0; i < out.edges.size(); ++i) {
        const uint64_t e = out.edges[i];
        if (i > 0 && out.edges[i - 1] == e) ++out.folds;
        if (!std::binary_search(out.edges.begin(), out.edges.end(), (e << 32) | (e >> 32))) out.border.push_back(e);
    }
    return out;
}

} // namespace

LevelsOfDetail build_levels_of_detail(IndexedVertices& mesh, std::size_t max_levels, std::size_t patch_triangles) {
    if (mesh.indices.size() % 3 != 0 || mesh.indices.empty())
        throw Error("renderer: levels of detail need whole triangles (" + std::to_string(mesh.indices.size()) + " indices)");
    if (patch_triangles == 0) throw Error("renderer: levels of detail need patches of at least one triangle");
    const std::size_t full = mesh.indices.size();
    LevelsOfDetail out;
    out.levels.push_back({.first_index = 0, .index_count = static_cast<uint32_t>(full), .error = 0.0});
    constexpr std::size_t kMinTriangles = 1000;
    if (max_levels < 2 || full / 3 / 2 < kMinTriangles) return out;

    // Level 0 in patches.
    const std::size_t triangles = full / 3;
    std::vector<glm::vec3> centroids(triangles);
    for (std::size_t t = 0; t < triangles; ++t) centroids[t] = triangle_centroid(mesh, &mesh.indices[3 * t]);
    std::vector<uint32_t> order(triangles);
    std::iota(order.begin(), order.end(), 0u);
    std::vector<std::size_t> runs;
    split_into_patches(order, centroids, patch_triangles, runs);
    {
        std::vector<uint32_t> reordered(full);
        for (std::size_t i = 0; i < triangles; ++i)
            for (std::size_t k = 0; k < 3; ++k) reordered[3 * i + k] = mesh.indices[3 * order[i] + k];
        mesh.indices = std::move(reordered);
    }
    // Welded by exact position (atlas seams split vertices): what "the same border" compares.
    std::vector<glm::vec3> positions(mesh.vertices.size());
    for (std::size_t v = 0; v < positions.size(); ++v) positions[v] = glm::vec3(mesh.vertices[v].position_u);
    const std::vector<uint32_t> welded = weld_by_position(positions);
    const std::size_t places = std::size_t{*std::max_element(welded.begin(), welded.end())} + 1;

    // Each patch's level 0, and its vertices numbered locally (the simplifier's work scales with them).
    constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
    std::vector<uint32_t> local_of(mesh.vertices.size(), kNone);
    struct Local {
        std::vector<uint32_t> global;  // local vertex -> mesh vertex
        std::vector<float> positions;  // xyz per local vertex
        std::vector<uint32_t> indices; // level 0, local
        float scale = 0.0f;            // meshopt_simplifyScale
        PatchEdges edges;              // level 0's
    };
    std::vector<Local> locals(runs.size());
    std::vector<uint32_t> patch_at(places, kNone); // a patch with a corner at each place
    std::vector<bool> shared(places, false);        // places where patches meet
    std::size_t first = 0;
    for (std::size_t p = 0; p < runs.size(); ++p) {
        Local& l = locals[p];
        const std::span<const uint32_t> range(mesh.indices.data() + first, 3 * runs[p]);
        for (const uint32_t v : range) {
            if (local_of[v] == kNone) {
                local_of[v] = static_cast<uint32_t>(l.global.size());
                l.global.push_back(v);
                const glm::vec4& q = mesh.vertices[v].position_u;
                l.positions.insert(l.positions.end(), {q.x, q.y, q.z});
            }
            l.indices.push_back(local_of[v]);
        }
        for (const uint32_t v : l.global) local_of[v] = kNone;
        l.scale = meshopt_simplifyScale(l.positions.data(), l.global.size(), 3 * sizeof(float));
        l.edges = patch_edges(range, welded);
        for (const uint32_t v : l.global) {
            uint32_t& at = patch_at[welded[v]];
            if (at != kNone && at != p) shared[welded[v]] = true;
            at = static_cast<uint32_t>(p);
        }
        MeshPatch& patch = out.patches.emplace_back();
        patch.levels.push_back({.first_index = static_cast<uint32_t>(first), .index_count = static_cast<uint32_t>(range.size())});
        first += range.size();
    }
    // Which patch walks each directed edge between two places where patches meet, at any level: a
    // simplified patch may not walk another's (their triangles would overlap in some mix of levels).
    // Only such edges can be two patches': any other has a corner in one patch only.
    std::unordered_map<uint64_t, uint32_t> owner;
    const auto between_patches = [&](uint64_t e) { return shared[e >> 32] && shared[e & 0xffffffffu]; };
    for (std::size_t p = 0; p < locals.size(); ++p)
        for (const uint64_t e : locals[p].edges.edges)
            if (between_patches(e)) owner.try_emplace(e, static_cast<uint32_t>(p));

    std::vector<uint32_t> simplified, global_indices;
    while (out.levels.size() < max_levels) {
        const std::size_t k = out.levels.size();
        const std::size_t previous = out.levels.back().index_count;
        if ((full >> k) / 3 < kMinTriangles) break;
        LevelOfDetail level{.first_index = static_cast<uint32_t>(mesh.indices.size())};
        std::vector<uint32_t> appended;
        appended.reserve(full >> k);
        std::vector<LevelOfDetail> ranges(out.patches.size());
        for (std::size_t p = 0; p < out.patches.size(); ++p) {
            const Local& l = locals[p];
            simplified.resize(l.indices.size());
            float relative_error = 0.0f;
            // target_error 1: no bound on the error (the patch's extent); the level is chosen per frame by its error.
            const std::size_t count =
                meshopt_simplify(simplified.data(), l.indices.data(), l.indices.size(), l.positions.data(), l.global.size(),
                                 3 * sizeof(float), (l.indices.size() >> k) / 3 * 3, 1.0f, meshopt_SimplifyLockBorder,
                                 &relative_error);
            global_indices.resize(count);
            for (std::size_t i = 0; i < count; ++i) global_indices[i] = l.global[simplified[i]];
            const PatchEdges edges = patch_edges(global_indices, welded);
            const bool same_shape =
                count > 0 && edges.border == l.edges.border && edges.folds <= l.edges.folds &&
                std::none_of(edges.edges.begin(), edges.edges.end(), [&](uint64_t e) {
                    if (!between_patches(e)) return false;
                    const auto it = owner.find(e);
                    return it != owner.end() && it->second != p;
                });
            if (same_shape)
                for (const uint64_t e : edges.edges)
                    if (between_patches(e)) owner.try_emplace(e, static_cast<uint32_t>(p));
            // Else the patch keeps its level before (its border is level 0's).
            const LevelOfDetail& before = out.patches[p].levels.back();
            const std::span<const uint32_t> chosen =
                same_shape ? std::span<const uint32_t>(global_indices)
                           : std::span<const uint32_t>(mesh.indices.data() + before.first_index, before.index_count);
            ranges[p] = {.first_index = static_cast<uint32_t>(level.first_index + appended.size()),
                         .index_count = static_cast<uint32_t>(chosen.size()),
                         .error = same_shape ? static_cast<double>(relative_error) * l.scale : before.error};
            appended.insert(appended.end(), chosen.begin(), chosen.end());
            level.error = std::max(level.error, ranges[p].error);
        }
        level.index_count = static_cast<uint32_t>(appended.size());
        if (4 * appended.size() > 3 * previous || appended.size() < 3 * kMinTriangles) break;
        mesh.indices.insert(mesh.indices.end(), appended.begin(), appended.end());
        for (std::size_t p = 0; p < out.patches.size(); ++p) out.patches[p].levels.push_back(ranges[p]);
        out.levels.push_back(level);
    }
    if (out.levels.size() == 1) {
        out.patches.clear();
        return out;
    }

    // Each patch's sphere (what its error is seen from).
    for (MeshPatch& patch : out.patches) {
        glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
        const LevelOfDetail& whole = patch.levels[0];
        const std::span<const uint32_t> corners(mesh.indices.data() + whole.first_index, whole.index_count);
        for (const uint32_t v : corners) {
            lo = glm::min(lo, glm::vec3(mesh.vertices[v].position_u));
            hi = glm::max(hi, glm::vec3(mesh.vertices[v].position_u));
        }
        patch.center = 0.5f * (lo + hi);
        for (const uint32_t v : corners)
            patch.radius = std::max(patch.radius, glm::length(glm::vec3(mesh.vertices[v].position_u) - patch.center));
    }
    return out;
}

bool may_graze(const TriangleCluster& c, const glm::vec3& eye, float grazing) noexcept {
    const glm::vec3 d = eye - c.center;
    const float distance = glm::length(d);
    if (!(distance > c.radius)) return true; // the eye inside the sphere: any angle
    const float seen = std::asin(c.radius / distance); // the directions to the eye from the sphere's points
    const float from_axis = std::acos(std::clamp(glm::dot(d / distance, c.axis), -1.0f, 1.0f));
    const float lo = from_axis - c.spread - seen, hi = from_axis + c.spread + seen;
    return hi > grazing && lo < std::numbers::pi_v<float> - grazing;
}

std::vector<std::vector<TriangleCluster>> cluster_levels(IndexedVertices& mesh, std::span<const LevelOfDetail> levels,
                                                         std::span<const MeshPatch> patches) {
    constexpr std::size_t kMaxVertices = 64, kMaxTriangles = 124;
    const auto* positions = reinterpret_cast<const float*>(mesh.vertices.data()); // position_u: xyz first
    std::vector<std::vector<TriangleCluster>> out;
    for (std::size_t k = 0; k < levels.size(); ++k) {
        const LevelOfDetail& level = levels[k];
        std::vector<TriangleCluster>& clusters = out.emplace_back();
        std::vector<uint32_t> ordered;
        ordered.reserve(level.index_count);
        // The level's runs: its patches' ranges, or the whole level.
        std::vector<std::pair<LevelOfDetail, uint32_t>> runs;
        if (patches.empty())
            runs.emplace_back(level, 0u);
        else
            for (std::size_t p = 0; p < patches.size(); ++p) runs.emplace_back(patches[p].levels.at(k), static_cast<uint32_t>(p));
        for (const auto& [run, patch] : runs) {
            const uint32_t* indices = mesh.indices.data() + run.first_index;
            const std::size_t bound = meshopt_buildMeshletsBound(run.index_count, kMaxVertices, kMaxTriangles);
            std::vector<meshopt_Meshlet> meshlets(bound);
            std::vector<uint32_t> meshlet_vertices(bound * kMaxVertices);
            std::vector<unsigned char> meshlet_triangles(bound * kMaxTriangles * 3);
            meshlets.resize(meshopt_buildMeshlets(meshlets.data(), meshlet_vertices.data(), meshlet_triangles.data(), indices,
                                                  run.index_count, positions, mesh.vertices.size(),
                                                  sizeof(shared::RenderVertex), kMaxVertices, kMaxTriangles, 0.5f));
            for (const meshopt_Meshlet& m : meshlets) {
                const meshopt_Bounds b = meshopt_computeMeshletBounds(&meshlet_vertices[m.vertex_offset],
                                                                      &meshlet_triangles[m.triangle_offset], m.triangle_count,
                                                                      positions, mesh.vertices.size(), sizeof(shared::RenderVertex));
                clusters.push_back({.first_index = static_cast<uint32_t>(level.first_index + ordered.size()),
                                    .index_count = 3 * m.triangle_count,
                                    .apex = {b.cone_apex[0], b.cone_apex[1], b.cone_apex[2]},
                                    .axis = {b.cone_axis[0], b.cone_axis[1], b.cone_axis[2]},
                                    .cutoff = b.cone_cutoff,
                                    .center = {b.center[0], b.center[1], b.center[2]},
                                    .radius = b.radius,
                                    .patch = patch});
                const std::size_t start = ordered.size();
                for (std::size_t i = 0; i < 3 * std::size_t{m.triangle_count}; ++i)
                    ordered.push_back(meshlet_vertices[m.vertex_offset + meshlet_triangles[m.triangle_offset + i]]);
                float least = 1.0f;
                for (std::size_t i = start; i < ordered.size(); i += 3) {
                    const glm::vec3 n = triangle_normal(mesh, &ordered[i]);
                    const float l = glm::length(n);
                    if (l > 0.0f) least = std::min(least, glm::dot(n / l, clusters.back().axis));
                }
                clusters.back().spread = std::acos(std::clamp(least, -1.0f, 1.0f));
            }
        }
        if (ordered.size() != level.index_count)
            throw Error("renderer: the clusters hold " + std::to_string(ordered.size()) + " indices of a level's " +
                        std::to_string(level.index_count));
        std::copy(ordered.begin(), ordered.end(), mesh.indices.begin() + level.first_index);
    }
    return out;
}

bool faces_away(const TriangleCluster& c, const glm::vec3& eye) noexcept {
    const glm::vec3 d = c.apex - eye;
    const float len = glm::length(d);
    return len > 0.0f && glm::dot(d / len, c.axis) >= c.cutoff;
}

std::size_t choose_level_of_detail(std::span<const LevelOfDetail> levels, const Camera& camera, const glm::dvec3& center,
                                   double radius, double max_error_px) {
    if (!(max_error_px > 0.0) || levels.empty()) return 0;
    const double distance = std::max(glm::length(camera.center() - center) - radius, radius / 100.0);
    const double focal = std::max(camera.intrinsics.fl_x, camera.intrinsics.fl_y);
    std::size_t chosen = 0;
    for (std::size_t k = 1; k < levels.size(); ++k)
        if (levels[k].error * focal / distance <= max_error_px) chosen = k;
    return chosen;
}

bool is_closed_outward(const Mesh& mesh) {
    if (mesh.triangles.empty()) return false;
    const std::vector<uint32_t> welded = weld_by_position(mesh.positions);
    std::map<std::pair<uint32_t, uint32_t>, int> directed; // count of each directed edge
    double volume6 = 0.0;
    for (const glm::uvec3& t : mesh.triangles) {
        const uint32_t v[3] = {welded[t.x], welded[t.y], welded[t.z]};
        for (int k = 0; k < 3; ++k)
            if (++directed[{v[k], v[(k + 1) % 3]}] > 1) return false;
        volume6 += glm::dot(glm::dvec3(mesh.positions[t.x]),
                            glm::cross(glm::dvec3(mesh.positions[t.y]), glm::dvec3(mesh.positions[t.z])));
    }
    for (const auto& [edge, count] : directed)
        if (directed.find({edge.second, edge.first}) == directed.end()) return false;
    return volume6 > 0.0;
}

struct Renderer::Impl {
    gpu::Context* ctx;
    Options options;
    bool cull = false;
    std::optional<SpecularModel> specular;
    shared::MaterialGpu material; // material_gpu(specular): what every pass shader evaluates
    /// Set by set_material: the material drawn instead of the model's, and whether it has a specular term.
    std::optional<bool> material_override;
    [[nodiscard]] bool draws_specular() const noexcept {
        return material_override ? *material_override : specular && !is_zero(*specular);
    }
    Bounds bounds;
    std::vector<glm::vec3> positions; // the mesh's vertices: the shadow map's frustum holds them
    std::size_t triangles = 0;

    gpu::Buffer params;
    struct MeshBuffers {
        gpu::Buffer vertices;
        gpu::Buffer indices;
        std::vector<LevelOfDetail> levels; // [0]: every triangle; more with Options::lod_max_error_px
        std::vector<MeshPatch> patches;    // with more than one level
        std::vector<std::vector<TriangleCluster>> clusters; // per level, with Options::cluster_culling and culling
        // With clusters and patches: per level, where each patch's clusters start (and, last, the end).
        std::vector<std::vector<uint32_t>> patch_clusters;
        std::vector<uint32_t> cpu_indices;                  // with clusters: what `indices` holds
        // With clusters and patches: each triangle of cpu_indices' unit normal and centroid.
        std::vector<glm::vec3> facet_normals, facet_points;
        std::optional<gpu::Buffer> visible;                 // with clusters: the frame's clusters facing the camera
        std::optional<gpu::Buffer> patched;                 // with patches by the view: every patch at its level (the shadow map)
    } mesh_buffers;
    uint32_t visible_count = 0; // indices in mesh_buffers.visible this frame (prepare)
    PixelBox drawn_box;         // FrameInfo::drawn this frame (prepare): the deferred shading pass's scissor
    std::size_t drawn_level = 0; // the frame's level of detail (prepare), drawn by every pass
    std::optional<std::size_t> forced_level; // accept_levels_of_detail's renders: this level
    std::size_t accepted_levels = 1;         // levels a frame may draw (accept_levels_of_detail)
    gpu::Image albedo;
    std::vector<gpu::Image> cubes_g, cubes_h; // one per term (empty before set_factorization)
    FactorParam factor_param = FactorParam::Gshd; // their parametrization
    glm::vec4 factor_warp{1.0f};                  // and its warp: params.factor_warp
    // The lit passes' specialization constants (render/terms.glsl): what lavapipe would otherwise
    // evaluate on every side of a branch. prepare() rebuilds the lit pipelines when a frame needs
    // other values (a new factorization or material family, shadows turned on or off).
    struct ShaderConstants {
        uint32_t factor_terms = 1; // kFactorTerms: the cube-maps' term count (1 before any)
        uint32_t factor_param = 0; // kFactorParam: their parametrization
        uint32_t family = 0;       // kMaterialFamily: the material's family (params.material.family.x)
        uint32_t shadows = 1;      // kShadows: the shadow map may be sampled (Settings::shadows)
        uint32_t shared_warp = 0;  // kSharedWarp: the warped cube-maps have one warp for the channels
        bool operator==(const ShaderConstants&) const = default;
    } built;
    gpu::UniqueSampler sampler;

    std::unique_ptr<gpu::RenderTarget> target; // resized to each camera
    // What a deferred frame's G-buffer depends on: the target, the camera's projection and
    // position (which also choose the clusters drawn), the level of detail, and with patches by
    // the view each patch's level (which the light chooses too, with shadows). prepare() sets
    // frame_key; render() keeps, in target_gbuffer, the key of the G-buffer its target holds.
    struct GbufferKey {
        VkImageView view = VK_NULL_HANDLE;
        glm::mat4 world_to_clip{0.0f};
        glm::vec3 eye{0.0f};
        std::size_t level = 0;
        std::vector<uint8_t> patch_levels;
        bool operator==(const GbufferKey&) const = default;
    };
    GbufferKey frame_key;
    std::optional<GbufferKey> target_gbuffer;
    // What the shadow map's depth depends on: the light's projection and the level of detail
    // (drawn whole), or with patches by the view each patch's level. prepare() sets frame_shadow
    // (none: no shadow pass); render() keeps, in shadow_drawn, the key of the depth the map holds;
    // record() draws its own and clears it.
    struct ShadowKey {
        glm::mat4 light_to_clip{0.0f};
        std::size_t level = 0;
        std::vector<uint8_t> patch_levels;
        bool operator==(const ShadowKey&) const = default;
    };
    std::optional<ShadowKey> frame_shadow;
    std::optional<ShadowKey> shadow_drawn;
    gpu::ShadowMap shadow_map;
    gpu::GraphicsPipeline shadow_pass;
    gpu::DescriptorSet shadow_set;
    gpu::GraphicsPipeline diffuse;
    gpu::GraphicsPipeline specular_analytic;
    gpu::GraphicsPipeline specular_factorized;
    gpu::GraphicsPipeline both_analytic;   // Passes::Fused
    gpu::GraphicsPipeline both_factorized;
    gpu::GraphicsPipeline gbuffer;              // Passes::Deferred, subpass 0
    gpu::GraphicsPipeline deferred_analytic;    // Passes::Deferred, subpass 1
    gpu::GraphicsPipeline deferred_factorized;
    gpu::DescriptorSet diffuse_set;
    gpu::DescriptorSet analytic_set;
    gpu::DescriptorSet factorized_set; // textures written by set_factorization
    gpu::DescriptorSet both_analytic_set;
    gpu::DescriptorSet both_factorized_set; // cube-maps written by set_factorization
    gpu::DescriptorSet gbuffer_set;
    gpu::DescriptorSet deferred_analytic_set;   // G-buffer inputs: the last target drawn (use_gbuffer_of)
    gpu::DescriptorSet deferred_factorized_set; // and cube-maps written by set_factorization
    VkImageView gbuffer_bound = VK_NULL_HANDLE; // the target whose G-buffer the deferred sets read
    gpu::Sequence sequence;

    Impl(gpu::Context& c, const Scene& scene, const Options& opts)
        : ctx(&c), options(opts),
          cull(opts.culling == Culling::Always ||
               (opts.culling == Culling::Auto && is_closed_outward(*checked_mesh(scene)))),
          specular(scene.material.specular), material(material_gpu(scene.material.specular)), bounds(mesh_bounds(*checked_mesh(scene))),
          positions(scene.mesh->positions),
          triangles(scene.mesh->triangles.size()),
          params(gpu::Buffer::of<shared::RenderParams>(c, 1, "render parameters")),
          mesh_buffers(upload_mesh(c, scene, opts.lod_max_error_px > 0.0, opts.cluster_culling && cull)),
          accepted_levels(mesh_buffers.levels.size()),
          albedo(upload_albedo(c, scene)),
          factor_param(scene.material.factorized ? scene.material.factorized->param : FactorParam::Gshd),
          built{.factor_terms = scene.material.factorized ? static_cast<uint32_t>(std::max<std::size_t>(scene.material.factorized->terms.size(), 1)) : 1u,
                .factor_param = static_cast<uint32_t>(factor_param),
                .family = material.family.x,
                .shadows = 1u,
                .shared_warp = factor_param == FactorParam::Warped && is_shared_warp(scene.material.factorized->warp) ? 1u : 0u},
          sampler(gpu::make_linear_clamp_sampler(c, "render textures")),
          // Pipelines are built against a 1x1 target's render pass; every target has the
          // same formats, so its passes are compatible with them.
          target(std::make_unique<gpu::RenderTarget>(c, 1, 1, "render target")),
          shadow_map(c, opts.shadow_map_size, "shadow map"),
          shadow_pass(c, shadow_pass_desc()),
          shadow_set(c, shadow_pass),
          diffuse(c, lit_desc(LitPass::Diffuse)),
          specular_analytic(c, lit_desc(LitPass::SpecularAnalytic)),
          specular_factorized(c, lit_desc(LitPass::SpecularFactorized)),
          both_analytic(c, lit_desc(LitPass::FusedAnalytic)),
          both_factorized(c, lit_desc(LitPass::FusedFactorized)),
          gbuffer(c, gbuffer_desc()),
          deferred_analytic(c, lit_desc(LitPass::DeferredAnalytic)),
          deferred_factorized(c, lit_desc(LitPass::DeferredFactorized)),
          diffuse_set(c, diffuse), analytic_set(c, specular_analytic), factorized_set(c, specular_factorized),
          both_analytic_set(c, both_analytic), both_factorized_set(c, both_factorized), gbuffer_set(c, gbuffer),
          deferred_analytic_set(c, deferred_analytic), deferred_factorized_set(c, deferred_factorized),
          sequence(c, 8) {
        gbuffer_set.write_buffer(kBindingParams, params);
        for (gpu::DescriptorSet* set : lit_sets()) write_lit_bindings(*set);
        shadow_set.write_buffer(kBindingParams, params);
    }

    // Every lit pass's set, and the factorized passes' ones.
    std::array<gpu::DescriptorSet*, 7> lit_sets() {
        return {&diffuse_set, &analytic_set, &factorized_set, &both_analytic_set, &both_factorized_set, &deferred_analytic_set,
                &deferred_factorized_set};
    }
    std::array<gpu::DescriptorSet*, 3> factorized_sets() { return {&factorized_set, &both_factorized_set, &deferred_factorized_set}; }

    // What every lit pass's set holds: the frame's parameters, the albedo atlas, the shadow map.
    void write_lit_bindings(gpu::DescriptorSet& set) const {
        set.write_buffer(kBindingParams, params);
        set.write_image(kBindingAlbedo, albedo, sampler.get());
        set.write_image(kBindingShadow, shadow_map.depth(), shadow_map.compare_sampler());
    }

    // The factorized passes' sets: term k's G and H at kBindingCubeG + k and kBindingCubeH + k; the
    // unused bindings repeat term 1 (valid descriptors; the shaders do not read them).
    void write_cubes(gpu::DescriptorSet& set) const {
        for (uint32_t k = 0; k < kMaxFactorTerms; ++k) {
            const std::size_t t = k < cubes_g.size() ? k : 0;
            set.write_image(kBindingCubeG + k, cubes_g[t], sampler.get());
            set.write_image(kBindingCubeH + k, cubes_h[t], sampler.get());
        }
    }

    enum class LitPass { Diffuse, SpecularAnalytic, SpecularFactorized, FusedAnalytic, FusedFactorized, DeferredAnalytic,
                         DeferredFactorized };
    // A lit pass's pipeline, with the specialization constants `built`.
    gpu::GraphicsPipelineDesc lit_desc(LitPass pass) const {
        gpu::GraphicsPipelineDesc d;
        switch (pass) {
        case LitPass::Diffuse: d = pipeline_desc("diffuse pass", render_diffuse_frag, kLitBindings, false); break;
        case LitPass::SpecularAnalytic:
            d = pipeline_desc("specular pass (analytic)", render_specular_analytic_frag, kLitBindings, true);
            break;
        case LitPass::SpecularFactorized:
            d = pipeline_desc("specular pass (factorized)", render_specular_factorized_frag, kFactorizedBindings, true);
            break;
        case LitPass::FusedAnalytic: d = pipeline_desc("fused pass (analytic)", render_both_analytic_frag, kLitBindings, false); break;
        case LitPass::FusedFactorized:
            d = pipeline_desc("fused pass (factorized)", render_both_factorized_frag, kFactorizedBindings, false);
            break;
        case LitPass::DeferredAnalytic:
            d = shading_desc("deferred shading (analytic)", render_deferred_analytic_frag, bindings_for(kLitBindings, 2));
            break;
        case LitPass::DeferredFactorized:
            d = shading_desc("deferred shading (factorized)", render_deferred_factorized_frag, bindings_for(kFactorizedBindings, 2));
            break;
        }
        d.fragment_constants = {built.factor_terms, built.factor_param, built.family, built.shadows, built.shared_warp};
        return d;
    }

    // Every lit pass's pipeline, in the order of lit_sets().
    std::array<gpu::GraphicsPipeline*, 7> lit_pipelines() {
        return {&diffuse, &specular_analytic, &specular_factorized, &both_analytic, &both_factorized, &deferred_analytic,
                &deferred_factorized};
    }
    static constexpr std::array<LitPass, 7> kLitPasses{LitPass::Diffuse,         LitPass::SpecularAnalytic,
                                                      LitPass::SpecularFactorized, LitPass::FusedAnalytic,
                                                      LitPass::FusedFactorized,  LitPass::DeferredAnalytic,
                                                      LitPass::DeferredFactorized};
    // Lit pipelines and sets built for other constants, kept for when a frame needs them again
    // (a viewer toggling shadows, an evaluation between the bundle's material and the core one).
    struct Parked {
        ShaderConstants constants;
        std::vector<gpu::GraphicsPipeline> pipelines; // lit_pipelines() order
        std::vector<gpu::DescriptorSet> sets;         // lit_sets() order
    };
    static constexpr std::size_t kMaxParked = 8;
    std::vector<Parked> parked; // oldest first

    // Makes the lit pipelines and sets those built for `wanted`: a parked variant, else built now
    // (nothing is in flight: render() waits, record()'s caller waits for the previous frame). The
    // variant in use is parked.
    void use_constants(const ShaderConstants& wanted) {
        if (wanted == built) return;
        Parked out{built, {}, {}};
        for (gpu::GraphicsPipeline* p : lit_pipelines()) out.pipelines.push_back(std::move(*p));
        for (gpu::DescriptorSet* set : lit_sets()) out.sets.push_back(std::move(*set));
        built = wanted; // what lit_desc builds for
        const auto it = std::find_if(parked.begin(), parked.end(), [&](const Parked& v) { return v.constants == wanted; });
        if (it != parked.end()) {
            for (std::size_t i = 0; i < kLitPasses.size(); ++i) {
                *lit_pipelines()[i] = std::move(it->pipelines[i]);
                *lit_sets()[i] = std::move(it->sets[i]);
            }
            parked.erase(it);
        } else {
            for (std::size_t i = 0; i < kLitPasses.size(); ++i) {
                *lit_pipelines()[i] = gpu::GraphicsPipeline(*ctx, lit_desc(kLitPasses[i]));
                *lit_sets()[i] = gpu::DescriptorSet(*ctx, *lit_pipelines()[i]);
                write_lit_bindings(*lit_sets()[i]);
            }
        }
        parked.push_back(std::move(out));
        if (parked.size() > kMaxParked) parked.erase(parked.begin());
        // The cube-maps may have changed since the sets were parked; the G-buffer inputs are
        // written when the deferred pass next draws.
        if (!cubes_g.empty())
            for (gpu::DescriptorSet* set : factorized_sets()) write_cubes(*set);
        gbuffer_bound = VK_NULL_HANDLE;
    }

    gpu::GraphicsPipelineDesc shadow_pass_desc() const {
        gpu::GraphicsPipelineDesc d;
        d.name = "shadow map depth pass";
        d.vertex_spirv = render_shadow_vert; // no fragment shader: depth only
        d.bindings = bindings_for(kShadowPassBindings);
        d.render_pass = shadow_map.render_pass();
        d.depth_compare = VK_COMPARE_OP_LESS; // standard depth (gpu/shadow_map.h)
        d.cull_mode = VK_CULL_MODE_NONE;      // both sides cast shadows (open meshes)
        d.depth_bias_slope = kDepthBiasSlope;
        set_vertex_input(d, true);
        return d;
    }

    // Subpass 0 of the deferred pass: the mesh, depth-tested, into the two G-buffer images.
    gpu::GraphicsPipelineDesc gbuffer_desc() const {
        gpu::GraphicsPipelineDesc d = pipeline_desc("deferred G-buffer pass", render_gbuffer_frag, kBindingParams + 1, false);
        d.render_pass = target->deferred_render_pass();
        d.subpass = 0;
        d.color_attachments = 2;
        return d;
    }

    // Subpass 1 of the deferred pass: one full-target triangle, no depth test.
    gpu::GraphicsPipelineDesc shading_desc(const char* name, std::span<const uint32_t> frag,
                                           std::vector<gpu::DescriptorBinding> bindings) const {
        gpu::GraphicsPipelineDesc d;
        d.name = name;
        d.vertex_spirv = render_fullscreen_vert;
        d.fragment_spirv = frag;
        d.bindings = std::move(bindings);
        d.render_pass = target->deferred_render_pass();
        d.subpass = 1;
        d.depth_test = false;
        d.depth_write = false;
        return d;
    }

    // shared::RenderVertex as vertex input binding 0: location 0 position_u and, unless
    // `position_only` (the depth pass, whose shader reads nothing else), 1 normal_v.
    static void set_vertex_input(gpu::GraphicsPipelineDesc& d, bool position_only = false) {
        d.vertex_stride = sizeof(shared::RenderVertex);
        d.vertex_attributes = {{.location = 0, .binding = 0, .format = VK_FORMAT_R32G32B32A32_SFLOAT,
                                .offset = offsetof(shared::RenderVertex, position_u)}};
        if (!position_only)
            d.vertex_attributes.push_back({.location = 1, .binding = 0, .format = VK_FORMAT_R32G32B32A32_SFLOAT,
                                           .offset = offsetof(shared::RenderVertex, normal_v)});
    }

    static const Mesh* checked_mesh(const Scene& scene) {
        if (scene.mesh == nullptr || scene.mesh->triangles.empty()) throw Error("renderer: the scene has no mesh");
        return scene.mesh;
    }

    /// The vertex and index buffers (index_vertices), with the levels of detail when `lod`.
    static MeshBuffers upload_mesh(gpu::Context& c, const Scene& scene, bool lod, bool clusters) {
        IndexedVertices data = index_vertices(*scene.mesh, scene.corner_uv);
        LevelsOfDetail levels = lod ? build_levels_of_detail(data)
                                    : LevelsOfDetail{{{.index_count = static_cast<uint32_t>(data.indices.size())}}, {}};
        MeshBuffers b{gpu::Buffer::of<shared::RenderVertex>(c, data.vertices.size(), "render vertices"),
                      gpu::Buffer::of<uint32_t>(c, data.indices.size(), "render indices"), std::move(levels.levels),
                      std::move(levels.patches)};
        if (clusters) {
            b.clusters = cluster_levels(data, b.levels, b.patches);
            if (!b.patches.empty())
                for (const std::vector<TriangleCluster>& level : b.clusters) {
                    std::vector<uint32_t>& starts = b.patch_clusters.emplace_back(b.patches.size() + 1, 0u);
                    for (const TriangleCluster& cl : level) ++starts[cl.patch + 1];
                    std::partial_sum(starts.begin(), starts.end(), starts.begin());
                }
            b.visible.emplace(gpu::Buffer::of<uint32_t>(c, b.levels[0].index_count, "render indices facing the camera"));
            if (!b.patches.empty())
                b.patched.emplace(gpu::Buffer::of<uint32_t>(c, b.levels[0].index_count, "render indices, each patch at its level"));
        }
        b.vertices.upload(data.vertices);
        b.indices.upload(data.indices);
        if (clusters) b.cpu_indices = std::move(data.indices);
        if (clusters && !b.patches.empty()) {
            const std::size_t facets = b.cpu_indices.size() / 3;
            b.facet_normals.resize(facets);
            b.facet_points.resize(facets);
            for (std::size_t t = 0; t < facets; ++t) {
                const uint32_t* tri = &b.cpu_indices[3 * t];
                const glm::vec3 n = triangle_normal(data, tri);
                const float l = glm::length(n);
                b.facet_normals[t] = l > 0.0f ? n / l : glm::vec3(0.0f); // degenerate (draws nothing): skipped
                b.facet_points[t] = triangle_centroid(data, tri);
            }
        }
        return b;
    }

    // The frame's clusters that do not face wholly away from the camera at `eye`, into `visible`;
    // returns the pixels their spheres can cover seen through `to_clip`. With `light` (shadows), a
    // patch the light grazes keeps its triangles too: a coarser surface would move the shadow's edge.
    PixelBox collect_visible_clusters(const glm::vec3& eye, std::optional<glm::vec3> light, const glm::dmat4& to_clip,
                                      const Intrinsics& k) {
        std::vector<uint32_t>& staging = visible_scratch;
        staging.clear();
        PixelBox covered;
        const auto collect = [&](std::span<const TriangleCluster> clusters) {
            for (const TriangleCluster& c : clusters)
                if (!faces_away(c, eye)) {
                    staging.insert(staging.end(), mesh_buffers.cpu_indices.begin() + c.first_index,
                                   mesh_buffers.cpu_indices.begin() + c.first_index + c.index_count);
                    const glm::dvec3 r(c.radius);
                    covered = unite(covered, pixels_of_box(to_clip, k, glm::dvec3(c.center) - r, glm::dvec3(c.center) + r));
                }
        };
        if (drawn_level == 0 || !patches_by_view()) {
            patch_levels.assign(mesh_buffers.patches.size(), static_cast<uint8_t>(drawn_level));
            collect(mesh_buffers.clusters[drawn_level]);
        } else {
            // Each patch draws the coarsest level, up to the frame's, none of whose triangles, nor
            // level 0's, the view (or the light) may graze: there a coarser surface moves the point
            // the ray meets by its error over the cosine of the angle (may_graze on each cluster's
            // cone, then its triangles); level 0 where every level may. The patches' borders are the
            // same at every level.
            const double focal = std::max(k.fl_x, k.fl_y);
            patch_levels.assign(mesh_buffers.patches.size(), 0);
            for (std::size_t p = 0; p < mesh_buffers.patches.size(); ++p) {
                const MeshPatch& patch = mesh_buffers.patches[p];
                const double distance = std::max(double(glm::length(eye - patch.center)) - patch.radius, patch.radius / 100.0);
                // Whether a triangle of the patch's `level` is seen from `from` within the grazing
                // band, or the patch holds triangles facing both ways (a silhouette runs through it,
                // between two triangles each seen outside the band).
                const auto grazes_from = [&](const glm::vec3& from, std::size_t level, float grazing) {
                    const float cos2 = std::cos(grazing) * std::cos(grazing);
                    const std::vector<uint32_t>& starts = mesh_buffers.patch_clusters[level];
                    unsigned sides = 0; // 1: a triangle facing `from`, 2: one facing away
                    for (uint32_t ci = starts[p]; ci < starts[p + 1]; ++ci) {
                        const TriangleCluster& c = mesh_buffers.clusters[level][ci];
                        if (!may_graze(c, from, grazing)) { // every triangle on the side its axis is
                            sides |= glm::dot(from - c.center, c.axis) > 0.0f ? 1u : 2u;
                        } else {
                            for (uint32_t t = c.first_index / 3; t < (c.first_index + c.index_count) / 3; ++t) {
                                const glm::vec3& n = mesh_buffers.facet_normals[t];
                                if (n == glm::vec3(0.0f)) continue;
                                const glm::vec3 d = from - mesh_buffers.facet_points[t];
                                const float along = glm::dot(n, d);
                                if (along * along < cos2 * glm::dot(d, d)) return true;
                                sides |= along > 0.0f ? 1u : 2u;
                            }
                        }
                        if (sides == 3u) return true;
                    }
                    return false;
                };
                const auto grazes = [&](std::size_t level, float grazing) {
                    return grazes_from(eye, level, grazing) || (light && grazes_from(*light, level, grazing));
                };
                std::size_t level = drawn_level;
                for (; level > 0; --level) {
                    const double error_px = patch.levels[level].error * focal / distance;
                    if (error_px > options.lod_max_error_px) continue;
                    const float grazing = static_cast<float>(std::atan2(options.lod_max_error_px, error_px));
                    if (!grazes(0, grazing) && !grazes(level, grazing)) break;
                }
                patch_levels[p] = static_cast<uint8_t>(level);
                const std::vector<uint32_t>& starts = mesh_buffers.patch_clusters[level];
                collect(std::span(mesh_buffers.clusters[level]).subspan(starts[p], starts[p + 1] - starts[p]));
            }
        }
        visible_count = static_cast<uint32_t>(staging.size());
        if (visible_count > 0) mesh_buffers.visible->upload(staging);
        return covered;
    }
    std::vector<uint32_t> visible_scratch;
    std::vector<uint8_t> patch_levels; // the frame's level of each patch (with patches; collect_visible_clusters)

    // With patches by the view: every patch's triangles at the frame's level for it, into `patched`
    // (the shadow map draws what the lit passes draw, so the surfaces it compares are the same).
    void collect_patched() {
        std::vector<uint32_t>& staging = visible_scratch;
        staging.clear();
        for (std::size_t p = 0; p < mesh_buffers.patches.size(); ++p) {
            const LevelOfDetail& r = mesh_buffers.patches[p].levels[patch_levels[p]];
            staging.insert(staging.end(), mesh_buffers.cpu_indices.begin() + r.first_index,
                           mesh_buffers.cpu_indices.begin() + r.first_index + r.index_count);
        }
        patched_count = static_cast<uint32_t>(staging.size());
        mesh_buffers.patched->upload(staging);
    }
    uint32_t patched_count = 0;

    /// Whether each patch chooses its level by the view (levels, patches and clusters).
    [[nodiscard]] bool patches_by_view() const noexcept { return mesh_buffers.visible && !mesh_buffers.patches.empty(); }

    /// Binds the mesh and draws the frame's level of detail (the pipeline and its set bound): its
    /// clusters facing the camera where there are clusters, unless `whole` (the shadow map: every
    /// patch at the frame's level for it, where patches are chosen by the view).
    void draw_mesh(VkCommandBuffer cmd, bool whole = false) const {
        const LevelOfDetail& lod = mesh_buffers.levels[drawn_level];
        gpu::bind_vertex_buffer(cmd, mesh_buffers.vertices);
        if (whole && patches_by_view()) {
            vkCmdBindIndexBuffer(cmd, mesh_buffers.patched->handle(), 0, VK_INDEX_TYPE_UINT32);
            vkCmdDrawIndexed(cmd, patched_count, 1, 0, 0, 0);
            return;
        }
        if (!whole && mesh_buffers.visible) {
            if (visible_count == 0) return;
            vkCmdBindIndexBuffer(cmd, mesh_buffers.visible->handle(), 0, VK_INDEX_TYPE_UINT32);
            vkCmdDrawIndexed(cmd, visible_count, 1, 0, 0, 0);
            return;
        }
        vkCmdBindIndexBuffer(cmd, mesh_buffers.indices.handle(), 0, VK_INDEX_TYPE_UINT32);
        vkCmdDrawIndexed(cmd, lod.index_count, 1, lod.first_index, 0, 0);
    }

    static gpu::Image upload_albedo(gpu::Context& c, const Scene& scene) {
        const Image* img = scene.albedo;
        if (img == nullptr || img->empty() || img->channels < 1 || img->channels > 4)
            throw Error("renderer: the scene needs an albedo atlas image (linear RGB)");
        const VkFormat format = gpu::choose_float_texture_format(c);
        gpu::Image image(c, {.name = "albedo atlas", .kind = gpu::ImageKind::Texture2D,
                             .width = static_cast<uint32_t>(img->width), .height = static_cast<uint32_t>(img->height),
                             .format = format});
        image.upload(gpu::pack_rgba(img->pixels, img->channels, static_cast<std::size_t>(img->width) * img->height, format));
        return image;
    }

    gpu::GraphicsPipelineDesc pipeline_desc(const char* name, std::span<const uint32_t> frag, uint32_t bindings,
                                            bool additive) const {
        gpu::GraphicsPipelineDesc d;
        d.name = name;
        d.vertex_spirv = render_raster_vert;
        d.fragment_spirv = frag;
        d.bindings = bindings_for(bindings);
        d.render_pass = target->render_pass();
        d.cull_mode = cull ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_NONE;
        // The projection keeps the image's orientation (camera +Y up = row 0 at the top), so
        // a triangle counter-clockwise seen from outside is counter-clockwise on screen, which
        // is what Vulkan's VK_FRONT_FACE_COUNTER_CLOCKWISE means with y pointing down.
        d.front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;
        set_vertex_input(d);
        if (additive) {
            // Pass 2 shades exactly the fragments pass 1 kept: same vertex shader module,
            // `precise` position, so the depths are bit-identical and EQUAL selects them.
            d.depth_compare = VK_COMPARE_OP_EQUAL;
            d.depth_write = false;
            d.blend = gpu::BlendMode::Additive;
        } else {
            d.depth_compare = VK_COMPARE_OP_GREATER; // reversed-Z
        }
        return d;
    }

    /// Checks the camera and settings, says which passes run, and writes the frame's
    /// parameters (the previous frame must be done with them).
    FrameInfo prepare(const Camera& camera, const PointLight& light, const Settings& settings) {
        const Intrinsics& k = camera.intrinsics;
        if (k.w <= 0 || k.h <= 0 || !(k.fl_x > 0.0) || !(k.fl_y > 0.0))
            throw Error("renderer: the camera needs a positive image size and focal lengths");
        FrameInfo info;
        // With patches drawn by the view, each patch chooses its level up to this one (collect_visible_clusters).
        drawn_level = forced_level.value_or(
            patches_by_view() ? accepted_levels - 1
                              : choose_level_of_detail(std::span(mesh_buffers.levels).first(accepted_levels), camera,
                                                       glm::dvec3(bounds.center()), bounds.radius(), options.lod_max_error_px));
        info.lod_level = drawn_level;
        info.triangles = mesh_buffers.levels[drawn_level].index_count / 3;
        const double near = settings.near.value_or(near_plane_for(camera, bounds));
        const glm::dmat4 to_clip = world_to_clip(camera, near);
        // Every level's triangles join the mesh's vertices, so the bounds hold what any level covers.
        drawn_box = pixels_of_box(to_clip, k, glm::dvec3(bounds.min), glm::dvec3(bounds.max));
        if (mesh_buffers.visible) {
            drawn_box = intersect(drawn_box, collect_visible_clusters(glm::vec3(camera.center()),
                                                                      settings.shadows ? std::optional(glm::vec3(light.position))
                                                                                       : std::nullopt,
                                                                      to_clip, k));
            info.triangles = visible_count / 3;
            if (patches_by_view()) {
                info.patches = patch_levels.size();
                info.patches_whole = static_cast<std::size_t>(std::count(patch_levels.begin(), patch_levels.end(), 0));
            }
        }
        const bool want_diffuse = settings.mode != Mode::Specular;
        const bool want_specular = settings.mode != Mode::Diffuse;
        info.diffuse_pass = want_diffuse;
        if (!want_specular) {
            info.specular_note = "mode diffuse";
        } else if (!draws_specular()) {
            info.specular_note = material_override ? "the material drawn instead of the model has no specular term: the specular "
                                                      "pass is left out"
                                                    : "no lobe (no specular model, or a zero one: Cx = Cz = 0 on every channel, or "
                                                      "a coated tint of 0): the specular pass is left out";
        } else if (material_override && settings.specular == SpecularPath::Factorized) {
            throw Error("renderer: a material drawn instead of the model (Renderer::set_material) has no factorization: "
                        "render it with the analytic path");
        } else if (settings.specular == SpecularPath::Factorized && cubes_g.empty()) {
            throw Error("renderer: the factorized specular model needs the G and H cube-maps (Renderer::set_factorization)");
        } else {
            if (settings.specular == SpecularPath::Factorized) require_drawable(factor_param, specular);
            info.specular_pass = true;
            info.fused = settings.mode == Mode::Both && settings.passes == Passes::Fused;
        }
        info.deferred = settings.passes == Passes::Deferred;
        info.drawn = drawn_box;

        std::optional<LightFrustum> frustum;
        if (!settings.shadows)
            info.shadow_note = "shadows off";
        else
            frustum = light_frustum(light.position, glm::dvec3(bounds.center()), bounds.radius(), shadow_map.size(), positions,
                                    info.shadow_note);
        info.shadow_pass = frustum.has_value();

        use_constants({.factor_terms = static_cast<uint32_t>(std::max<std::size_t>(cubes_g.size(), 1)),
                       .factor_param = static_cast<uint32_t>(factor_param),
                       .family = material.family.x,
                       .shadows = settings.shadows ? 1u : 0u,
                       .shared_warp = factor_param == FactorParam::Warped && is_shared_warp(factor_warp) ? 1u : 0u});
        shared::RenderParams p{};
        p.world_to_clip = glm::mat4(to_clip);
        p.eye = glm::vec4(glm::vec3(camera.center()), 1.0f);
        frame_key = {.world_to_clip = p.world_to_clip,
                     .eye = glm::vec3(p.eye),
                     .level = drawn_level,
                     .patch_levels = patches_by_view() ? patch_levels : std::vector<uint8_t>{}};
        p.light_position = glm::vec4(glm::vec3(light.position), 1.0f);
        p.light_intensity = glm::vec4(glm::vec3(light.intensity), 0.0f);
        p.material = material;
        p.flags = glm::uvec4(want_diffuse ? 1u : 0u, 0u, info.specular_pass ? 1u : 0u, 0u);
        p.factor_warp = factor_warp;
        frame_shadow = std::nullopt;
        if (frustum) {
            frame_shadow = ShadowKey{glm::mat4(frustum->to_clip), drawn_level, patches_by_view() ? patch_levels : std::vector<uint8_t>{}};
            if (patches_by_view() && frame_shadow != shadow_drawn) collect_patched();
            p.light_to_clip = glm::mat4(frustum->to_clip);
            p.shadow = glm::vec4(1.0f, static_cast<float>(frustum->texel_per_distance), kNormalOffsetGrazing,
                                 kNormalOffsetConstant);
        } else {
            p.light_to_clip = glm::mat4(1.0f);
            p.shadow = glm::vec4(0.0f);
        }
        params.upload(std::span<const shared::RenderParams>(&p, 1)); // made visible by the submit
        return info;
    }

    // Before the lit passes when FrameInfo::shadow_pass: the mesh's depth seen from the light.
    void draw_shadow_map(VkCommandBuffer cmd) const {
        shadow_map.begin(cmd);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shadow_pass.pipeline());
        const VkDescriptorSet s = shadow_set.get();
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shadow_pass.layout(), 0, 1, &s, 0, nullptr);
        draw_mesh(cmd, /*whole=*/true); // seen from the light: no camera culling
        shadow_map.end(cmd);
    }

    // Pass 1 always runs: it resolves visibility (depth) and coverage (alpha) for pass 2.
    void draw_diffuse(VkCommandBuffer cmd, const gpu::RenderTarget& t) const {
        draw(cmd, t, diffuse, diffuse_set, gpu::RenderTarget::Load::Clear);
    }
    // Passes::Fused: both terms in one pass, in place of the two.
    void draw_fused(VkCommandBuffer cmd, const gpu::RenderTarget& t, SpecularPath model) const {
        const bool analytic = model == SpecularPath::Analytic;
        draw(cmd, t, analytic ? both_analytic : both_factorized, analytic ? both_analytic_set : both_factorized_set,
             gpu::RenderTarget::Load::Clear);
    }
    // Passes::Deferred: the G-buffer, then each pixel shaded once (params.flags say which terms).
    // keep_gbuffer: t's G-buffer already holds this frame's view (render(), FrameInfo::gbuffer_kept).
    void draw_deferred(VkCommandBuffer cmd, const gpu::RenderTarget& t, SpecularPath model, gpu::PassClock* clock = nullptr,
                       bool keep_gbuffer = false) {
        use_gbuffer_of(t);
        t.begin_deferred(cmd, keep_gbuffer ? gpu::RenderTarget::GbufferLoad::Keep : gpu::RenderTarget::GbufferLoad::Clear);
        if (!keep_gbuffer) {
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbuffer.pipeline());
            const VkDescriptorSet g = gbuffer_set.get();
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, gbuffer.layout(), 0, 1, &g, 0, nullptr);
            draw_mesh(cmd);
        }
        if (clock != nullptr) clock->mark(cmd, "g-buffer");
        t.next_subpass(cmd);
        // Without a factorization the analytic shader serves (flags.z is 0 unless the specular term is drawn).
        const bool factorized = model == SpecularPath::Factorized && !cubes_g.empty();
        const gpu::GraphicsPipeline& shade = factorized ? deferred_factorized : deferred_analytic;
        const VkDescriptorSet s = (factorized ? deferred_factorized_set : deferred_analytic_set).get();
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shade.pipeline());
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, shade.layout(), 0, 1, &s, 0, nullptr);
        // Only where the mesh can be: lavapipe runs the whole shader on an uncovered pixel (both
        // sides of its branch), which on knot_hd at 1024 px was 4 pixels in 5.
        if (!drawn_box.empty()) {
            const VkRect2D box{{drawn_box.x0, drawn_box.y0},
                               {static_cast<uint32_t>(drawn_box.x1 - drawn_box.x0),
                                static_cast<uint32_t>(drawn_box.y1 - drawn_box.y0)}};
            vkCmdSetScissor(cmd, 0, 1, &box);
            vkCmdDraw(cmd, 3, 1, 0, 0);
        }
        t.end(cmd);
    }

    // Points the deferred shading sets at t's G-buffer. Nothing is in flight between frames
    // (render() waits; record()'s caller waits for the previous frame), so they can be rewritten.
    void use_gbuffer_of(const gpu::RenderTarget& t) {
        if (gbuffer_bound == t.gbuffer(0).view()) return;
        deferred_analytic_set.write_input_attachment(kDeferredAnalyticGbuffer, t.gbuffer(0));
        deferred_analytic_set.write_input_attachment(kDeferredAnalyticGbuffer + 1, t.gbuffer(1));
        deferred_factorized_set.write_input_attachment(kDeferredFactorizedGbuffer, t.gbuffer(0));
        deferred_factorized_set.write_input_attachment(kDeferredFactorizedGbuffer + 1, t.gbuffer(1));
        gbuffer_bound = t.gbuffer(0).view();
    }

    void draw_specular(VkCommandBuffer cmd, const gpu::RenderTarget& t, SpecularPath model) const {
        const bool analytic = model == SpecularPath::Analytic;
        draw(cmd, t, analytic ? specular_analytic : specular_factorized, analytic ? analytic_set : factorized_set,
             gpu::RenderTarget::Load::Keep);
    }

    void draw(VkCommandBuffer cmd, const gpu::RenderTarget& t, const gpu::GraphicsPipeline& pipeline,
              const gpu::DescriptorSet& set, gpu::RenderTarget::Load load) const {
        t.begin(cmd, load);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline.pipeline());
        const VkDescriptorSet s = set.get();
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline.layout(), 0, 1, &s, 0, nullptr);
        draw_mesh(cmd);
        t.end(cmd);
    }
};

Renderer::Renderer(gpu::Context& ctx, const Scene& scene, const Options& options)
    : m_impl(std::make_unique<Impl>(ctx, scene, options)) {
    if (scene.material.factorized) set_factorization(*scene.material.factorized);
}
Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

void Renderer::set_specular(const std::optional<SpecularModel>& specular) {
    m_impl->specular = specular;
    m_impl->material = material_gpu(specular);
    m_impl->material_override.reset();
}
void Renderer::set_material(const shared::MaterialGpu& material, bool has_specular) {
    m_impl->material = material;
    m_impl->material_override = has_specular;
}
const std::optional<SpecularModel>& Renderer::specular() const noexcept { return m_impl->specular; }
bool Renderer::has_specular() const noexcept { return m_impl->draws_specular(); }
shared::MaterialGpu Renderer::material() const noexcept { return m_impl->material; }
std::size_t Renderer::triangle_count() const noexcept { return m_impl->triangles; }
std::span<const LevelOfDetail> Renderer::levels_of_detail() const noexcept { return m_impl->mesh_buffers.levels; }
std::size_t Renderer::accepted_levels_of_detail() const noexcept { return m_impl->accepted_levels; }

namespace {
/// Masked display PSNR of `b` against `a`: sRGB-encoded 8-bit codes over the pixels either covers.
double display_psnr(const Frame& a, const Frame& b) {
    const auto code = [](float v) { return std::round(255.0 * linear_to_srgb(std::clamp(v, 0.0f, 1.0f))); };
    double sum = 0.0;
    std::size_t n = 0;
    const std::size_t pixels = a.mask.size();
    for (std::size_t i = 0; i < pixels; ++i) {
        if (a.mask[i] == 0 && b.mask[i] == 0) continue;
        for (std::size_t c = 0; c < 3; ++c) {
            const double d = (code(a.color.pixels[3 * i + c]) - code(b.color.pixels[3 * i + c])) / 255.0;
            sum += d * d;
        }
        n += 3;
    }
    if (n == 0 || sum == 0.0) return std::numeric_limits<double>::infinity();
    return 10.0 * std::log10(static_cast<double>(n) / sum);
}
} // namespace

std::vector<double> Renderer::accept_levels_of_detail(std::span<const Camera> cameras, std::span<const PointLight> lights,
                                                      const Settings& settings, double min_psnr_db) {
    if (lights.size() != cameras.size())
        throw Error("renderer: " + std::to_string(lights.size()) + " lights for " + std::to_string(cameras.size()) +
                    " cameras (one each expected)");
    Impl& m = *m_impl;
    const std::size_t levels = m.mesh_buffers.levels.size();
    std::vector<double> worst(levels, std::numeric_limits<double>::infinity());
    struct Unforce {
        Impl& m;
        ~Unforce() { m.forced_level.reset(); }
    } unforce{m};
    for (std::size_t v = 0; v < cameras.size(); ++v) {
        m.forced_level = 0;
        const Frame full = render(cameras[v], lights[v], settings);
        for (std::size_t k = 1; k < levels; ++k) {
            m.forced_level = k;
            worst[k] = std::min(worst[k], display_psnr(full, render(cameras[v], lights[v], settings)));
        }
    }
    m.accepted_levels = 1;
    while (m.accepted_levels < levels && worst[m.accepted_levels] >= min_psnr_db) ++m.accepted_levels;
    return worst;
}
bool Renderer::culls_back_faces() const noexcept { return m_impl->cull; }
VkFormat Renderer::albedo_format() const noexcept { return m_impl->albedo.format(); }
bool Renderer::has_factorization() const noexcept { return !m_impl->cubes_g.empty(); }
uint32_t Renderer::factorization_terms() const noexcept { return static_cast<uint32_t>(m_impl->cubes_g.size()); }
FactorParam Renderer::factorization_param() const noexcept { return m_impl->factor_param; }
glm::vec4 Renderer::factorization_warp() const noexcept { return m_impl->factor_warp; }

void Renderer::set_factorization(const FactorizedSpecular& cubes) {
    const std::vector<FactorTerm>& terms = cubes.terms;
    const FactorParam param = cubes.param;
    const glm::vec4 warp = cubes.warp;
    if (terms.empty() || terms.size() > kMaxFactorTerms)
        throw Error("renderer: the factorized model takes 1 to " + std::to_string(kMaxFactorTerms) + " terms (got " +
                    std::to_string(terms.size()) + ")");
    if (param == FactorParam::Warped && !valid_warp(warp))
        throw Error("renderer: the warped parametrization needs a warp (+-1, k_r, k_g, k_b), every k in [1/64, 64]");
    Impl& m = *m_impl;
    require_drawable(param, m.specular);
    std::vector<gpu::Image> g, h; // all uploaded before anything is replaced
    for (std::size_t k = 0; k < terms.size(); ++k) {
        const std::string suffix = " cube-map (term " + std::to_string(k + 1) + ")";
        g.push_back(upload_cube(*m.ctx, terms[k].g, ("G" + suffix).c_str()));
        h.push_back(upload_cube(*m.ctx, terms[k].h, ("H" + suffix).c_str()));
    }
    // Nothing is in flight between frames (render() waits), so the sets can be rewritten. The
    // pipelines follow the new term count and parametrization at the next frame (prepare).
    m.cubes_g = std::move(g);
    m.cubes_h = std::move(h);
    m.factor_param = param;
    m.factor_warp = param == FactorParam::Warped ? warp : glm::vec4(1.0f);
    for (gpu::DescriptorSet* set : m.factorized_sets()) m.write_cubes(*set);
}

FrameInfo Renderer::record(VkCommandBuffer cmd, const gpu::RenderTarget& target, const Camera& camera,
                            const PointLight& light, const Settings& settings, gpu::PassClock* clock) {
    Impl& m = *m_impl;
    const Intrinsics& k = camera.intrinsics;
    if (target.width() != static_cast<uint32_t>(k.w) || target.height() != static_cast<uint32_t>(k.h))
        throw Error("renderer: the target is " + std::to_string(target.width()) + "x" + std::to_string(target.height()) +
                    " but the camera's image is " + std::to_string(k.w) + "x" + std::to_string(k.h));
    FrameInfo info = m.prepare(camera, light, settings);
    const auto mark = [&](const char* label) {
        if (clock != nullptr) clock->mark(cmd, label);
    };
    if (info.shadow_pass) {
        m.shadow_drawn.reset(); // render() draws its own again
        m.draw_shadow_map(cmd);
        mark("shadow map");
    }
    if (info.deferred) {
        if (&target == m.target.get()) m.target_gbuffer.reset(); // render()'s own target drawn here
        m.draw_deferred(cmd, target, settings.specular, clock);
        mark("shading");
        return info;
    }
    if (info.fused) {
        m.draw_fused(cmd, target, settings.specular);
        mark("fused pass");
        return info;
    }
    m.draw_diffuse(cmd, target);
    mark("diffuse pass");
    if (info.specular_pass) {
        m.draw_specular(cmd, target, settings.specular);
        mark("specular pass");
    }
    return info;
}

Frame Renderer::render(const Camera& camera, const PointLight& light, const Settings& settings) {
    const Stopwatch wall;
    Impl& m = *m_impl;
    Frame frame;
    frame.info = m.prepare(camera, light, settings);
    FrameInfo& info = frame.info;
    const Intrinsics& k = camera.intrinsics;
    if (m.target->width() != static_cast<uint32_t>(k.w) || m.target->height() != static_cast<uint32_t>(k.h)) {
        m.target = std::make_unique<gpu::RenderTarget>(*m.ctx, static_cast<uint32_t>(k.w), static_cast<uint32_t>(k.h),
                                                       "render target");
        m.target_gbuffer.reset();
    }
    m.frame_key.view = m.target->gbuffer(0).view();
    info.gbuffer_kept = info.deferred && m.target_gbuffer == m.frame_key;
    info.shadow_kept = info.shadow_pass && m.shadow_drawn == m.frame_shadow;
    const bool draw_shadow = info.shadow_pass && !info.shadow_kept;

    gpu::Sequence& seq = m.sequence;
    seq.reset();
    if (draw_shadow)
        seq.time_begin("shadow pass").record([&](VkCommandBuffer cmd) { m.draw_shadow_map(cmd); }).time_end();
    if (info.deferred)
        seq.time_begin("diffuse pass")
            .record([&](VkCommandBuffer cmd) {
                m.draw_deferred(cmd, *m.target, settings.specular, nullptr, info.gbuffer_kept);
            })
            .time_end();
    else if (info.fused)
        seq.time_begin("diffuse pass")
            .record([&](VkCommandBuffer cmd) { m.draw_fused(cmd, *m.target, settings.specular); })
            .time_end();
    else
        seq.time_begin("diffuse pass").record([&](VkCommandBuffer cmd) { m.draw_diffuse(cmd, *m.target); }).time_end();
    if (info.specular_pass && !info.fused && !info.deferred)
        seq.time_begin("specular pass")
            .record([&](VkCommandBuffer cmd) { m.draw_specular(cmd, *m.target, settings.specular); })
            .time_end();
    seq.time_begin("readback").record([&](VkCommandBuffer cmd) { m.target->record_readback(cmd); }).time_end();
    if (info.deferred) m.target_gbuffer.reset(); // until the submit has completed
    if (draw_shadow) m.shadow_drawn.reset();
    seq.submit_and_wait();
    if (info.deferred) m.target_gbuffer = m.frame_key;
    if (draw_shadow) m.shadow_drawn = m.frame_shadow;
    for (const gpu::GpuTiming& t : seq.timings()) {
        if (!t.ns) continue;
        if (t.label == "shadow pass") info.shadow_gpu_ms = to_ms(t.ns);
        if (t.label == "diffuse pass") info.diffuse_gpu_ms = to_ms(t.ns);
        if (t.label == "specular pass") info.specular_gpu_ms = to_ms(t.ns);
        if (t.label == "readback") info.readback_gpu_ms = to_ms(t.ns);
    }

    const std::vector<glm::vec4> rgba = m.target->read_color();
    frame.color = Image(k.w, k.h, 3);
    frame.mask.assign(rgba.size(), 0);
    for (std::size_t i = 0; i < rgba.size(); ++i) {
        const glm::vec4& c = rgba[i];
        if (c.a > 0.5f) {
            frame.mask[i] = 255;
            ++info.covered_pixels;
        }
        frame.color.pixels[3 * i + 0] = c.r;
        frame.color.pixels[3 * i + 1] = c.g;
        frame.color.pixels[3 * i + 2] = c.b;
    }
    info.wall_ms = wall.seconds() * 1e3;
    return frame;
}

} // namespace specula::render
