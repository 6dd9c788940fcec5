#include "geometry/atlas.h"

#include "core/error.h"
#include "geometry/chart_atlas.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <tuple>

namespace specula {

namespace {

constexpr double kA = Atlas::kPatchInset;

/// Is the texel center c (block-local texel coordinates, mirrored into the
/// lower half's frame) in the lower patch's footprint? (See atlas.h.)
bool in_lower_footprint(double cx, double cy, double n) {
    return cx >= kA - 1.0 && cy >= kA - 1.0 && cx <= kA + n + 1.0 && cy <= kA + n + 1.0 && cx + cy <= 2.0 * kA + n + 2.0;
}

/// Leg lengths after scaling and clamping.
std::vector<std::uint32_t> quantize(const std::vector<double>& desired, double scale, const AtlasOptions& o) {
    std::vector<std::uint32_t> legs(desired.size());
    for (std::size_t i = 0; i < desired.size(); ++i) {
        const double l = std::round(desired[i] * scale);
        legs[i] = static_cast<std::uint32_t>(std::clamp(l, double(o.min_patch), double(o.max_patch)));
    }
    return legs;
}

struct Packing {
    std::vector<std::uint32_t> order;      // triangles by leg, descending; pairs (order[2k], order[2k+1]) share block k
    std::vector<std::uint32_t> block_leg;  // per block
    std::vector<glm::uvec2> block_origin;  // per block
    std::uint32_t width = 0;
    std::uint64_t height = 0;
};

/// Sorts, pairs and shelf-packs. Deterministic (ties broken by triangle id).
Packing pack(const std::vector<std::uint32_t>& legs, std::uint32_t max_width, bool full_width) {
    Packing p;
    p.order.resize(legs.size());
    std::iota(p.order.begin(), p.order.end(), 0u);
    std::stable_sort(p.order.begin(), p.order.end(), [&](std::uint32_t a, std::uint32_t b) { return legs[a] > legs[b]; });
    const std::size_t blocks = (legs.size() + 1) / 2;
    p.block_leg.resize(blocks);
    double area = 0.0;
    std::uint32_t widest = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
        p.block_leg[b] = legs[p.order[2 * b]]; // the larger of the pair
        const double side = p.block_leg[b] + Atlas::kBlockPadding;
        area += side * side;
        widest = std::max(widest, p.block_leg[b] + Atlas::kBlockPadding);
    }
    // Aim for a square atlas; shelves waste a little, which the height absorbs.
    std::uint32_t width = static_cast<std::uint32_t>(std::ceil(std::sqrt(area)));
    width = (width + 3u) & ~3u;
    p.width = std::clamp(full_width ? max_width : width, widest, std::max(widest, max_width));
    p.block_origin.resize(blocks);
    std::uint32_t x = 0;
    std::uint64_t shelf_y = 0;
    std::uint32_t shelf_h = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::uint32_t side = p.block_leg[b] + Atlas::kBlockPadding;
        if (x + side > p.width) {
            shelf_y += shelf_h;
            x = 0;
            shelf_h = 0;
        }
        p.block_origin[b] = glm::uvec2(x, static_cast<std::uint32_t>(std::min<std::uint64_t>(shelf_y, 0xFFFFFFFFu)));
        x += side;
        shelf_h = std::max(shelf_h, side);
    }
    p.height = shelf_y + shelf_h;
    return p;
}

double triangle_area(const Mesh& mesh, const glm::uvec3& t) {
    const glm::dvec3 p0(mesh.positions[t.x]), p1(mesh.positions[t.y]), p2(mesh.positions[t.z]);
    return 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
}

/// Corner k of a patch in texel coordinates.
glm::dvec2 patch_corner(const PatchPlacement& p, int k) {
    const double n = p.size;
    const double w = n + Atlas::kBlockPadding;
    const glm::dvec2 origin(p.block_x, p.block_y);
    const glm::dvec2 local[3] = {{kA, kA}, {kA + n, kA}, {kA, kA + n}};
    const glm::dvec2 l = local[k];
    return p.half == 0 ? origin + l : origin + glm::dvec2(w - l.x, w - l.y);
}

} // namespace

glm::dvec2 clamp_to_triangle(const glm::dvec2& st) {
    if (st.x >= 0.0 && st.y >= 0.0 && st.x + st.y <= 1.0) return st;
    auto closest_on_segment = [&](const glm::dvec2& a, const glm::dvec2& b) {
        const glm::dvec2 ab = b - a;
        const double u = std::clamp(glm::dot(st - a, ab) / glm::dot(ab, ab), 0.0, 1.0);
        return a + u * ab;
    };
    const glm::dvec2 c[3] = {closest_on_segment({0, 0}, {1, 0}), closest_on_segment({0, 0}, {0, 1}),
                             closest_on_segment({1, 0}, {0, 1})};
    glm::dvec2 best = c[0];
    double best_d = glm::dot(st - c[0], st - c[0]);
    for (int i = 1; i < 3; ++i) {
        const double d = glm::dot(st - c[i], st - c[i]);
        if (d < best_d) {
            best_d = d;
            best = c[i];
        }
    }
    return best;
}

const char* to_string(AtlasMode mode) { return mode == AtlasMode::Charts ? "charts" : "patchwork"; }

std::optional<AtlasMode> atlas_mode_from_string(std::string_view name) {
    if (name == "charts") return AtlasMode::Charts;
    if (name == "patchwork") return AtlasMode::Patchwork;
    return std::nullopt;
}

glm::dvec2 closest_point_bary(const glm::dvec2& c0, const glm::dvec2& c1, const glm::dvec2& c2, const glm::dvec2& p) {
    // Barycentric coordinates by Cramer's rule; inside: done. Outside: the closest point
    // lies on one of the three edges (the triangle is convex), so take the nearest of the
    // edges' closest points.
    const glm::dvec2 e1 = c1 - c0, e2 = c2 - c0, d = p - c0;
    const double det = e1.x * e2.y - e1.y * e2.x;
    const glm::dvec2 st((d.x * e2.y - d.y * e2.x) / det, (e1.x * d.y - e1.y * d.x) / det);
    if (st.x >= 0.0 && st.y >= 0.0 && st.x + st.y <= 1.0) return st;
    const glm::dvec2 corner_st[3] = {{0, 0}, {1, 0}, {0, 1}};
    const glm::dvec2 corner[3] = {c0, c1, c2};
    glm::dvec2 best_st(0.0);
    double best_d = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 a = corner[k], b = corner[(k + 1) % 3];
        const glm::dvec2 ab = b - a;
        const double len2 = glm::dot(ab, ab);
        const double u = len2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
        const glm::dvec2 q = a + u * ab;
        const double dq = glm::dot(p - q, p - q);
        if (dq < best_d) {
            best_d = dq;
            best_st = (1.0 - u) * corner_st[k] + u * corner_st[(k + 1) % 3];
        }
    }
    return best_st;
}

glm::dvec2 Atlas::patch_bary(std::uint32_t triangle, const glm::dvec2& texel_point) const {
    if (mode == AtlasMode::Patchwork) {
        // The patch's own frame: exact for texel centers (multiples of 1/(4n), see in_patch).
        const PatchPlacement& p = patches[triangle];
        const double n = p.size;
        const double w = n + kBlockPadding;
        glm::dvec2 l = texel_point - glm::dvec2(p.block_x, p.block_y);
        if (p.half == 1) l = glm::dvec2(w - l.x, w - l.y);
        return (l - glm::dvec2(kA, kA)) / n;
    }
    const glm::dvec2 c0 = corner_texel(triangle, 0), e1 = corner_texel(triangle, 1) - c0, e2 = corner_texel(triangle, 2) - c0;
    const glm::dvec2 d = texel_point - c0;
    const double det = e1.x * e2.y - e1.y * e2.x;
    return {(d.x * e2.y - d.y * e2.x) / det, (e1.x * d.y - e1.y * d.x) / det};
}

glm::dvec2 Atlas::closest_bary(std::uint32_t triangle, const glm::dvec2& texel_point) const {
    if (mode == AtlasMode::Patchwork) return clamp_to_triangle(patch_bary(triangle, texel_point)); // isotropic (s, t)
    return closest_point_bary(corner_texel(triangle, 0), corner_texel(triangle, 1), corner_texel(triangle, 2), texel_point);
}

std::size_t atlas_vertex_count(const Mesh& mesh, const Atlas& atlas) {
    // The key make_bundle merges on: the position index and the bits of the coordinate.
    std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> keys;
    keys.reserve(3 * mesh.triangles.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const glm::vec2 uv = atlas.corner_uv[3 * t + std::size_t(k)];
            std::uint32_t bx, by;
            std::memcpy(&bx, &uv.x, 4);
            std::memcpy(&by, &uv.y, 4);
            keys.emplace_back(mesh.triangles[t][k], bx, by);
        }
    std::sort(keys.begin(), keys.end());
    return std::size_t(std::unique(keys.begin(), keys.end()) - keys.begin());
}

std::vector<double> best_pixel_footprint(const Mesh& mesh, std::span<const Camera> cameras) {
    std::vector<double> best(mesh.triangles.size(), 0.0);
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        const glm::uvec3 t = mesh.triangles[i];
        const glm::dvec3 p0(mesh.positions[t.x]), p1(mesh.positions[t.y]), p2(mesh.positions[t.z]);
        const glm::dvec3 face = glm::cross(p1 - p0, p2 - p0);
        const glm::dvec3 centroid = (p0 + p1 + p2) / 3.0;
        for (const Camera& cam : cameras) {
            if (glm::dot(face, cam.center() - centroid) <= 0.0) continue;
            const auto q0 = cam.project(p0), q1 = cam.project(p1), q2 = cam.project(p2), qc = cam.project(centroid);
            if (!q0 || !q1 || !q2 || !qc || !cam.inside(*qc)) continue;
            const glm::dvec2 e1 = *q1 - *q0, e2 = *q2 - *q0;
            best[i] = std::max(best[i], 0.5 * std::abs(e1.x * e2.y - e1.y * e2.x));
        }
    }
    return best;
}

namespace {

Atlas build_patchwork_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options) {
    const std::size_t tri_count = mesh.triangles.size();
    Atlas atlas;
    atlas.mode = AtlasMode::Patchwork;
    AtlasSummary& s = atlas.summary;
    s.mode = to_string(AtlasMode::Patchwork);
    s.triangles = tri_count;

    // 1. Desired leg length per triangle: a leg-n patch holds n^2 / 2 texels.
    std::vector<double> desired(tri_count, 0.0);
    const double budget_area = double(options.max_width) * double(options.max_height);
    bool fill_budget = false;
    if (!cameras.empty()) {
        s.size_source = "cameras";
        const std::vector<double> pixels = best_pixel_footprint(mesh, cameras);
        for (std::size_t i = 0; i < tri_count; ++i) {
            if (pixels[i] > 0.0) {
                desired[i] = std::sqrt(2.0 * options.texels_per_pixel * pixels[i]);
            } else {
                desired[i] = options.min_patch; // no view sees it: its colour will be inpainted anyway
                ++s.triangles_seen_by_no_camera;
            }
        }
    } else {
        // No cameras: patch area proportional to surface area, at the density
        // that fills the budget (found by bisection on the padded block area).
        s.size_source = "surface area";
        fill_budget = true;
        std::vector<double> root_area(tri_count);
        for (std::size_t i = 0; i < tri_count; ++i) root_area[i] = std::sqrt(2.0 * triangle_area(mesh, mesh.triangles[i]));
        auto padded_area = [&](double c) {
            double total = 0.0;
            for (std::size_t i = 0; i < tri_count; i += 2) { // one block per pair, sized by the larger (approximation)
                const double l = std::clamp(std::round(c * std::max(root_area[i], i + 1 < tri_count ? root_area[i + 1] : 0.0)),
                                            double(options.min_patch), double(options.max_patch));
                total += (l + Atlas::kBlockPadding) * (l + Atlas::kBlockPadding);
            }
            return total;
        };
        double lo = 0.0, hi = 1.0;
        while (padded_area(hi) < 0.9 * budget_area && hi < 1e12) hi *= 2.0;
        for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (lo + hi);
            (padded_area(mid) < 0.9 * budget_area ? lo : hi) = mid;
        }
        for (std::size_t i = 0; i < tri_count; ++i) desired[i] = std::max(lo * root_area[i], double(options.min_patch));
    }
    for (double d : desired) s.desired_texels += 0.5 * d * d;

    // 2. Quantize, pair, pack; shrink every leg by one factor until the budget holds.
    double scale = 1.0;
    std::vector<std::uint32_t> legs;
    Packing packing;
    for (int attempt = 0;; ++attempt) {
        legs = quantize(desired, scale, options);
        packing = pack(legs, options.max_width, false);
        if (packing.width <= options.max_width && packing.height <= options.max_height) break;
        packing = pack(legs, options.max_width, true); // a wider, lower atlas may still fit
        if (packing.width <= options.max_width && packing.height <= options.max_height) break;
        const bool at_floor = std::all_of(legs.begin(), legs.end(), [&](std::uint32_t l) { return l <= options.min_patch; });
        if (at_floor || attempt > 200) {
            throw Error("atlas: " + std::to_string(tri_count) + " triangles do not fit a " + std::to_string(options.max_width) + "x" +
                        std::to_string(options.max_height) + " texture even with " + std::to_string(options.min_patch) +
                        "-texel patches (blocks of " + std::to_string(options.min_patch + Atlas::kBlockPadding) +
                        "^2 texels per 2 triangles); raise the budget");
        }
        const double needed = double(packing.width) * double(packing.height);
        scale *= std::clamp(std::sqrt(budget_area / needed), 0.5, 0.98);
    }
    s.budget_scale = scale;
    s.budget_clipped = scale < 1.0 && !fill_budget;
    if (s.budget_clipped) {
        char line[256];
        std::snprintf(line, sizeof line,
                      "texture budget %ux%u reached: every patch scaled by %.3f (%.3g texels per pixel instead of %.3g)",
                      options.max_width, options.max_height, scale, options.texels_per_pixel * scale * scale, options.texels_per_pixel);
        s.notes.emplace_back(line);
    }
    if (s.triangles_seen_by_no_camera > 0)
        s.notes.push_back(std::to_string(s.triangles_seen_by_no_camera) + " triangles face no camera: given " +
                          std::to_string(options.min_patch) + "-texel patches");

    // 3. Placement, texture coordinates, owner map.
    atlas.width = packing.width;
    atlas.height = static_cast<std::uint32_t>(packing.height);
    atlas.patches.resize(tri_count);
    atlas.corner_uv.resize(3 * tri_count);
    atlas.owner.assign(std::size_t(atlas.width) * atlas.height, Atlas::kEmpty);
    const std::size_t blocks = packing.block_leg.size();
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::uint32_t n = packing.block_leg[b];
        const std::uint32_t w = n + Atlas::kBlockPadding;
        const glm::uvec2 origin = packing.block_origin[b];
        const std::uint32_t lower = packing.order[2 * b];
        const std::uint32_t upper = 2 * b + 1 < tri_count ? packing.order[2 * b + 1] : Atlas::kEmpty;
        atlas.patches[lower] = PatchPlacement{origin.x, origin.y, n, 0};
        if (upper != Atlas::kEmpty) atlas.patches[upper] = PatchPlacement{origin.x, origin.y, n, 1};
        for (std::uint32_t j = 0; j < w; ++j) {
            for (std::uint32_t i = 0; i < w; ++i) {
                const double cx = i + 0.5, cy = j + 0.5;
                std::uint32_t o = Atlas::kEmpty;
                if (in_lower_footprint(cx, cy, n)) o = lower;
                else if (upper != Atlas::kEmpty && in_lower_footprint(w - cx, w - cy, n)) o = upper;
                atlas.owner[std::size_t(origin.y + j) * atlas.width + origin.x + i] = o;
            }
        }
    }
    atlas.corners.resize(3 * tri_count);
    for (std::uint32_t t = 0; t < tri_count; ++t)
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 c = patch_corner(atlas.patches[t], k);
            atlas.corners[3 * t + k] = c;
            atlas.corner_uv[3 * t + k] = glm::vec2(float(c.x / atlas.width), float(c.y / atlas.height));
        }

    // 4. Summary.
    std::vector<std::uint32_t> used(tri_count);
    for (std::size_t t = 0; t < tri_count; ++t) used[t] = atlas.patches[t].size;
    std::vector<std::uint32_t> sorted = used;
    std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
    s.patch_median = sorted[sorted.size() / 2];
    s.patch_min = *std::min_element(used.begin(), used.end());
    s.patch_max = *std::max_element(used.begin(), used.end());
    s.patch_mean = std::accumulate(used.begin(), used.end(), 0.0) / double(tri_count);
    s.blocks = blocks;
    s.width = atlas.width;
    s.height = atlas.height;
    for (std::uint32_t y = 0; y < atlas.height; ++y)
        for (std::uint32_t x = 0; x < atlas.width; ++x) {
            const std::uint32_t o = atlas.owner_at(x, y);
            if (o == Atlas::kEmpty) continue;
            const glm::dvec2 st = atlas.patch_bary(o, {x + 0.5, y + 0.5});
            ++(in_patch(st) ? s.interior_texels : s.gutter_texels);
        }
    const double area = double(atlas.width) * atlas.height;
    s.fill_ratio = double(s.interior_texels + s.gutter_texels) / area;
    s.interior_ratio = double(s.interior_texels) / area;
    s.mesh_vertices = mesh.positions.size();
    s.atlas_vertices = atlas_vertex_count(mesh, atlas);
    return atlas;
}

} // namespace

Atlas build_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options) {
    if (mesh.triangles.empty()) throw Error("atlas: the mesh has no triangles");
    if (options.max_width == 0 || options.max_height == 0 || options.max_width > Atlas::kMaxDimension ||
        options.max_height > Atlas::kMaxDimension)
        throw Error("atlas: the texture budget must be between 1 and " + std::to_string(Atlas::kMaxDimension) + " texels per side");
    if (options.min_patch < 1 || options.min_patch > options.max_patch) throw Error("atlas: need 1 <= min_patch <= max_patch");
    if (!(options.texels_per_pixel > 0.0)) throw Error("atlas: texels_per_pixel must be positive");
    return options.mode == AtlasMode::Charts ? build_chart_atlas(mesh, cameras, options) : build_patchwork_atlas(mesh, cameras, options);
}

std::string describe(const AtlasSummary& s) {
    char buf[1024];
    if (s.mode == "charts") {
        std::snprintf(buf, sizeof buf,
                      "atlas %ux%u, charts (%zu triangles in %zu charts, sizes from %s)\n"
                      "  chart triangles: median %u, max %u; %zu seam edges (%zu creases)\n"
                      "  vertices: %zu in the mesh, %zu split along the seams (x%.3f)\n"
                      "  distortion: angle sigma1/sigma2 mean %.3f, max %.3f; area min %.3f, 5%% %.3f, 95%% %.3f, max %.3f\n"
                      "  texels: %zu interior + %zu gutter; fill %.1f%% (interior %.1f%%)\n"
                      "  desired %.0f texels; budget %s (scale %.3f)\n",
                      s.width, s.height, s.triangles, s.charts, s.size_source.c_str(), s.chart_triangles_median, s.chart_triangles_max,
                      s.seam_edges, s.crease_edges, s.mesh_vertices, s.atlas_vertices,
                      s.mesh_vertices ? double(s.atlas_vertices) / double(s.mesh_vertices) : 0.0, s.angle_distortion_mean,
                      s.angle_distortion_max, s.area_distortion_min, s.area_distortion_p05, s.area_distortion_p95, s.area_distortion_max,
                      s.interior_texels, s.gutter_texels, 100.0 * s.fill_ratio, 100.0 * s.interior_ratio, s.desired_texels,
                      s.budget_clipped ? "CLIPPED" : "not reached", s.budget_scale);
    } else {
        std::snprintf(buf, sizeof buf,
                      "atlas %ux%u, patchwork (%zu triangles in %zu blocks, sizes from %s)\n"
                      "  patch leg (texels): min %u, median %u, mean %.2f, max %u\n"
                      "  vertices: %zu in the mesh, %zu split (x%.3f)\n"
                      "  texels: %zu interior + %zu gutter; fill %.1f%% (interior %.1f%%)\n"
                      "  desired %.0f patch texels; budget %s (scale %.3f)\n",
                      s.width, s.height, s.triangles, s.blocks, s.size_source.c_str(), s.patch_min, s.patch_median, s.patch_mean,
                      s.patch_max, s.mesh_vertices, s.atlas_vertices,
                      s.mesh_vertices ? double(s.atlas_vertices) / double(s.mesh_vertices) : 0.0, s.interior_texels, s.gutter_texels,
                      100.0 * s.fill_ratio, 100.0 * s.interior_ratio, s.desired_texels, s.budget_clipped ? "CLIPPED" : "not reached",
                      s.budget_scale);
    }
    std::string out = buf;
    for (const std::string& n : s.notes) out += "  note: " + n + "\n";
    return out;
}

} // namespace specula
