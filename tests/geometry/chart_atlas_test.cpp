// The chart atlas (engine/geometry/chart_atlas.h, the default AtlasMode): charts are
// edge-connected, UV triangles do not overlap and keep their orientation, the conformal
// maps' distortion is bounded, the bundle keeps at most 1.3x the mesh's vertices on every
// preset, bilinear lookups at mip levels 0 and 1 read only their chart (and no mip level
// reads an unfilled texel of the written albedo), particles follow the chart's texels, and
// texel density and the budget behave as for the patchwork.
#include "core/error.h"
#include "core/image.h"
#include "diffuse/albedo_texture.h"
#include "export/bundle.h"
#include "geometry/atlas.h"
#include "geometry/chart_atlas.h"
#include "geometry/particles.h"
#include "synth/presets.h"

#include "test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <numeric>
#include <set>

namespace specula {
namespace {

Camera make_camera(glm::dvec3 eye, glm::dvec3 target, int size = 256, double fl = 300.0) {
    return Camera(Intrinsics{size, size, fl, fl, size / 2.0, size / 2.0}, look_at_camera_to_world(eye, target, {0, 1, 0}));
}

std::vector<Camera> ring_of_cameras(int count, double distance, int size = 256) {
    std::vector<Camera> cams;
    for (int i = 0; i < count; ++i) {
        const double a = 2.0 * 3.14159265358979 * i / count;
        cams.push_back(make_camera({distance * std::cos(a), 0.7 * distance * std::sin(3.0 * a), distance * std::sin(a)}, {0, 0, 0}, size));
    }
    return cams;
}

/// Small meshes with poles, creases, a hole, a reflex edge and an open border.
std::vector<std::pair<std::string, Mesh>> test_meshes() {
    return {{"sphere", test::sphere(1.0f, 12, 16)},
            {"torus", test::torus(1.0f, 0.35f, 48, 16)},
            {"box", test::box({-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f})},
            {"plane_with_box", test::plane_with_box()},
            {"l_shape", test::l_shape()}};
}

/// Texel-space corners exactly as the renderer interpolates them (float uv times the size).
glm::dvec2 render_corner(const Atlas& atlas, std::uint32_t t, int k) {
    const glm::vec2 uv = atlas.corner_uv[3 * std::size_t(t) + std::size_t(k)];
    return {double(uv.x) * atlas.width, double(uv.y) * atlas.height};
}

double cross2(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }

// ---- the charts ----------------------------------------------------------------------

/// Each chart's triangles form one component over shared mesh edges (two position indices).
void expect_charts_connected(const Mesh& mesh, const Atlas& atlas) {
    ASSERT_EQ(atlas.chart_of.size(), mesh.triangles.size());
    std::vector<std::uint32_t> parent(mesh.triangles.size());
    std::iota(parent.begin(), parent.end(), 0u);
    const auto find = [&](std::uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    std::map<std::pair<unsigned, unsigned>, std::vector<std::uint32_t>> edges;
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const unsigned a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
            edges[{std::min(a, b), std::max(a, b)}].push_back(t);
        }
    for (const auto& [key, tris] : edges)
        for (std::size_t i = 1; i < tris.size(); ++i)
            for (std::size_t j = 0; j < i; ++j)
                if (atlas.chart_of[tris[i]] == atlas.chart_of[tris[j]]) parent[find(tris[i])] = find(tris[j]);
    std::vector<std::set<std::uint32_t>> roots(atlas.charts.size());
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        ASSERT_LT(atlas.chart_of[t], atlas.charts.size());
        roots[atlas.chart_of[t]].insert(find(t));
    }
    for (std::size_t c = 0; c < roots.size(); ++c) {
        EXPECT_EQ(roots[c].size(), 1u) << "chart " << c << " (" << atlas.charts[c].triangles << " triangles) has " << roots[c].size()
                                       << " edge-connected components";
        std::uint32_t count = 0;
        for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) count += atlas.chart_of[t] == c;
        EXPECT_EQ(count, atlas.charts[c].triangles);
    }
}

/// No texel center lies strictly inside two triangles (of different charts or of the same
/// chart); every texel center inside a triangle is an interior texel owned by that triangle
/// (or, on a shared edge, by its neighbour of the same chart).
void expect_no_overlap(const Atlas& atlas) {
    std::vector<std::uint32_t> inside(std::size_t(atlas.width) * atlas.height, Atlas::kEmpty);
    std::size_t overlaps = 0, checked = 0;
    for (std::uint32_t t = 0; t < atlas.chart_of.size(); ++t) {
        const glm::dvec2 c0 = render_corner(atlas, t, 0), c1 = render_corner(atlas, t, 1), c2 = render_corner(atlas, t, 2);
        const double area2 = cross2(c1 - c0, c2 - c0);
        const glm::dvec2 lo = glm::min(c0, glm::min(c1, c2)), hi = glm::max(c0, glm::max(c1, c2));
        for (long y = std::max(0L, long(std::floor(lo.y))); y <= std::min(long(atlas.height) - 1, long(hi.y)); ++y)
            for (long x = std::max(0L, long(std::floor(lo.x))); x <= std::min(long(atlas.width) - 1, long(hi.x)); ++x) {
                const glm::dvec2 p(x + 0.5, y + 0.5);
                // Strictly inside: at least 1e-4 texel from every edge.
                const double e0 = cross2(c1 - c0, p - c0), e1 = cross2(c2 - c1, p - c1), e2 = cross2(c0 - c2, p - c2);
                const double margin = 1e-4;
                if (e0 <= margin * glm::length(c1 - c0) || e1 <= margin * glm::length(c2 - c1) || e2 <= margin * glm::length(c0 - c2))
                    continue;
                ASSERT_GT(area2, 0.0);
                ++checked;
                const std::size_t i = std::size_t(y) * atlas.width + std::size_t(x);
                if (inside[i] != Atlas::kEmpty && ++overlaps < 10)
                    ADD_FAILURE() << "texel (" << x << ", " << y << ") lies inside triangles " << inside[i] << " (chart "
                                  << atlas.chart_of[inside[i]] << ") and " << t << " (chart " << atlas.chart_of[t] << ")";
                inside[i] = t;
                const std::uint32_t o = atlas.owner[i];
                EXPECT_EQ(o, t) << "texel (" << x << ", " << y << ") inside triangle " << t;
            }
    }
    EXPECT_EQ(overlaps, 0u);
    EXPECT_GT(checked, 0u);
}

void expect_positive_uv_areas(const Atlas& atlas) {
    for (std::uint32_t t = 0; t < atlas.chart_of.size(); ++t) {
        const glm::dvec2 c0 = render_corner(atlas, t, 0), c1 = render_corner(atlas, t, 1), c2 = render_corner(atlas, t, 2);
        EXPECT_GT(cross2(c1 - c0, c2 - c0), 0.0) << "triangle " << t;
        for (const glm::dvec2& c : {c0, c1, c2}) {
            EXPECT_GE(c.x, 0.0);
            EXPECT_GE(c.y, 0.0);
            EXPECT_LE(c.x, double(atlas.width));
            EXPECT_LE(c.y, double(atlas.height));
        }
    }
}

struct Distortion {
    double angle_max = 0.0, angle_mean = 0.0;   ///< sigma1 / sigma2
    double area_min = 1e300, area_max = 0.0;    ///< texel area per surface area, over the chart's
    double area_p05 = 0.0, area_p95 = 0.0;      ///< area-weighted quantiles of the same
};

/// Distortion from the renderer's corners, by the texture-stretch formulas of Sander et al.
/// 2001 ("Texture mapping progressive meshes", section 3): with S_s, S_t the partial
/// derivatives of the surface point by the texture coordinates, the singular values of that
/// map are sqrt((a + c +- sqrt((a - c)^2 + 4 b^2)) / 2), a = S_s.S_s, b = S_s.S_t, c = S_t.S_t.
Distortion distortion(const Mesh& mesh, const Atlas& atlas) {
    const std::size_t n = mesh.triangles.size();
    std::vector<double> surface(n), texel(n);
    std::vector<double> chart_surface(atlas.charts.size(), 0.0), chart_texel(atlas.charts.size(), 0.0);
    Distortion d;
    double weight = 0.0;
    for (std::uint32_t t = 0; t < n; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        const glm::dvec3 p0(mesh.positions[tri.x]), p1(mesh.positions[tri.y]), p2(mesh.positions[tri.z]);
        const glm::dvec2 q0 = render_corner(atlas, t, 0), q1 = render_corner(atlas, t, 1), q2 = render_corner(atlas, t, 2);
        const double a2 = cross2(q1 - q0, q2 - q0);
        const glm::dvec3 ss = (p0 * (q1.y - q2.y) + p1 * (q2.y - q0.y) + p2 * (q0.y - q1.y)) / a2;
        const glm::dvec3 st = (p0 * (q2.x - q1.x) + p1 * (q0.x - q2.x) + p2 * (q1.x - q0.x)) / a2;
        const double a = glm::dot(ss, ss), b = glm::dot(ss, st), c = glm::dot(st, st);
        const double root = std::sqrt((a - c) * (a - c) + 4.0 * b * b);
        const double g1 = std::sqrt(0.5 * (a + c + root)), g2 = std::sqrt(std::max(0.0, 0.5 * (a + c - root)));
        surface[t] = 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
        texel[t] = 0.5 * a2;
        chart_surface[atlas.chart_of[t]] += surface[t];
        chart_texel[atlas.chart_of[t]] += texel[t];
        const double angle = g1 / g2;
        d.angle_max = std::max(d.angle_max, angle);
        d.angle_mean += surface[t] * angle;
        weight += surface[t];
    }
    d.angle_mean /= weight;
    std::vector<std::pair<double, double>> ratio;
    for (std::uint32_t t = 0; t < n; ++t) {
        const std::uint32_t c = atlas.chart_of[t];
        const double r = (texel[t] / surface[t]) / (chart_texel[c] / chart_surface[c]);
        d.area_min = std::min(d.area_min, r);
        d.area_max = std::max(d.area_max, r);
        ratio.emplace_back(r, surface[t]);
    }
    std::sort(ratio.begin(), ratio.end());
    double acc = 0.0;
    d.area_p05 = ratio.front().first;
    for (const auto& [r, w] : ratio) {
        if (acc < 0.05 * weight) d.area_p05 = r;
        acc += w;
        if (acc <= 0.95 * weight) d.area_p95 = r;
    }
    return d;
}

void expect_bounded_distortion(const Mesh& mesh, const Atlas& atlas) {
    const Distortion d = distortion(mesh, atlas);
    // Per triangle, the bounds every chart's flattening was checked against (plus the float
    // rounding of sub-texel triangles' corners).
    EXPECT_LE(d.angle_max, kChartMaxAngleDistortion * 1.02);
    EXPECT_GE(d.area_min, 1.0 / (kChartMaxAreaDistortion * 1.02));
    EXPECT_LE(d.area_max, kChartMaxAreaDistortion * 1.02);
    // Over the surface: nearly conformal, and nearly the chart's density everywhere
    // (measured: mean 1.001-1.012 on the presets, 1.04 on the coarsest test mesh; quantiles
    // 0.90-0.94 and 1.01-1.10).
    EXPECT_LE(d.angle_mean, 1.06);
    EXPECT_GE(d.area_p05, 0.8);
    EXPECT_LE(d.area_p95, 1.25);
    // The summary reports the same figures.
    EXPECT_NEAR(atlas.summary.angle_distortion_max, d.angle_max, 0.01 * d.angle_max);
    EXPECT_NEAR(atlas.summary.area_distortion_p95, d.area_p95, 0.01);
}

TEST(ChartAtlas, ChartsAreConnectedDisjointAndConformal) {
    for (const auto& [name, mesh] : test_meshes()) {
        const Atlas atlas = build_atlas(mesh, ring_of_cameras(4, 4.0, 512));
        SCOPED_TRACE(name + ": " + describe(atlas.summary));
        EXPECT_EQ(atlas.mode, AtlasMode::Charts);
        EXPECT_EQ(atlas.summary.mode, "charts");
        EXPECT_GE(atlas.charts.size(), 1u);
        expect_charts_connected(mesh, atlas);
        expect_positive_uv_areas(atlas);
        expect_no_overlap(atlas);
        expect_bounded_distortion(mesh, atlas);
    }
}

TEST(ChartAtlas, PresetsAreConnectedDisjointAndConformal) {
    for (const char* name : {"can", "vase", "knot"}) {
        const synth::Preset preset = synth::make_preset(name);
        const Atlas atlas = build_atlas(preset.mesh, {}, {.max_width = 512, .max_height = 512});
        SCOPED_TRACE(std::string(name) + ": " + describe(atlas.summary));
        expect_charts_connected(preset.mesh, atlas);
        expect_positive_uv_areas(atlas);
        expect_no_overlap(atlas);
        expect_bounded_distortion(preset.mesh, atlas);
    }
}

TEST(ChartAtlas, ChartsFollowTheSurfaceNotTheTriangles) {
    // A flat plane is one chart with no seam; a box's faces meet at 90-degree creases, so
    // each face (two triangles) is its own chart; a sphere needs a few charts.
    const Mesh plane = test::plane(1.0f, 8);
    // add_quad gives every quad its own vertices: weld them, so the plane is one sheet.
    Mesh welded;
    std::map<std::tuple<float, float, float>, unsigned> index;
    for (const glm::uvec3& t : plane.triangles) {
        glm::uvec3 w;
        for (int k = 0; k < 3; ++k) {
            const glm::vec3 p = plane.positions[t[k]];
            auto [it, added] = index.try_emplace({p.x, p.y, p.z}, unsigned(welded.positions.size()));
            if (added) {
                welded.positions.push_back(p);
                welded.normals.push_back(plane.normals[t[k]]);
            }
            w[k] = it->second;
        }
        welded.triangles.push_back(w);
    }
    const AtlasOptions small{.max_width = 256, .max_height = 256};
    const Atlas flat = build_atlas(welded, {}, small);
    EXPECT_EQ(flat.summary.charts, 1u);
    EXPECT_EQ(flat.summary.seam_edges, 0u);
    EXPECT_EQ(flat.summary.atlas_vertices, welded.positions.size());
    EXPECT_NEAR(flat.summary.angle_distortion_max, 1.0, 1e-3);

    const Atlas box = build_atlas(test::box({0, 0, 0}, {1, 1, 1}), {}, small);
    EXPECT_EQ(box.summary.charts, 6u);

    const Mesh sphere = test::sphere(1.0f, 16, 24);
    const Atlas round = build_atlas(sphere, {}, small);
    EXPECT_GE(round.summary.charts, 4u);
    EXPECT_LE(round.summary.charts, 16u);
    EXPECT_GT(round.summary.seam_edges, 0u);
    EXPECT_EQ(round.summary.atlas_vertices, atlas_vertex_count(sphere, round));
}

// ---- the bundle's vertices -------------------------------------------------------------

TEST(ChartAtlas, BundleKeepsAtMostOnePointThreeTimesTheMeshVerticesOnEveryPreset) {
    for (const synth::PresetInfo& info : synth::list_presets()) {
        const synth::Preset preset = synth::make_preset(info.name);
        const Atlas atlas = build_atlas(preset.mesh, {}, {.max_width = 1024, .max_height = 1024});
        const Bundle bundle = make_bundle(preset.mesh, atlas.corner_uv, Image(int(atlas.width), int(atlas.height), 3, 0.5f), Material{});
        const double ratio = double(bundle.mesh.positions.size()) / double(preset.mesh.positions.size());
        std::printf("%-10s %7zu triangles, %7zu mesh vertices -> %7zu bundle vertices (x%.3f), %zu charts\n", info.name.c_str(),
                    preset.mesh.triangles.size(), preset.mesh.positions.size(), bundle.mesh.positions.size(), ratio, atlas.summary.charts);
        EXPECT_LE(ratio, 1.3) << info.name;
        EXPECT_EQ(bundle.mesh.positions.size(), atlas.summary.atlas_vertices) << info.name;
    }
    // The patchwork gives every triangle its own three vertices.
    const synth::Preset can = synth::make_preset("can");
    const Atlas patchwork = build_atlas(can.mesh, {}, {.mode = AtlasMode::Patchwork});
    EXPECT_EQ(patchwork.summary.atlas_vertices, 3 * can.mesh.triangles.size());
}

// ---- texels, gutters and mip levels ----------------------------------------------------

/// Bilinear filtering inside a chart's triangles (and 0.2 texel around each sample, for GPU
/// sub-texel rounding) reads only texels owned by triangles of the same chart.
TEST(ChartAtlas, BilinearInsideAChartReadsOnlyItsOwnTexels) {
    const Mesh mesh = test::torus(1.0f, 0.35f, 48, 16);
    for (const int size : {64, 256, 1024}) {
        const Atlas atlas = build_atlas(mesh, ring_of_cameras(3, 4.0, size));
        SCOPED_TRACE("image size " + std::to_string(size) + ": " + describe(atlas.summary));
        std::size_t failures = 0, checked = 0;
        for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
            const glm::dvec2 c0 = render_corner(atlas, t, 0), c1 = render_corner(atlas, t, 1), c2 = render_corner(atlas, t, 2);
            const int steps = 4 + int(2.0 * std::max({glm::length(c1 - c0), glm::length(c2 - c0), glm::length(c2 - c1)}));
            for (int i = 0; i <= steps; ++i)
                for (int j = 0; i + j <= steps; ++j) {
                    const glm::dvec2 p = c0 + double(i) / steps * (c1 - c0) + double(j) / steps * (c2 - c0);
                    for (const glm::dvec2 d : {glm::dvec2(0, 0), glm::dvec2(0.2, 0.2), glm::dvec2(-0.2, 0.2), glm::dvec2(0.2, -0.2),
                                               glm::dvec2(-0.2, -0.2)}) {
                        const double fx = std::floor(p.x + d.x - 0.5), fy = std::floor(p.y + d.y - 0.5);
                        for (int dy = 0; dy < 2; ++dy)
                            for (int dx = 0; dx < 2; ++dx) {
                                ++checked;
                                const double x = fx + dx, y = fy + dy;
                                const bool ok = x >= 0 && y >= 0 && x < atlas.width && y < atlas.height &&
                                                atlas.owner_at(std::uint32_t(x), std::uint32_t(y)) != Atlas::kEmpty &&
                                                atlas.chart_of[atlas.owner_at(std::uint32_t(x), std::uint32_t(y))] == atlas.chart_of[t];
                                if (!ok && ++failures < 10)
                                    ADD_FAILURE() << "triangle " << t << " (chart " << atlas.chart_of[t] << ") reads texel (" << x << ", " << y
                                                  << ")";
                            }
                    }
                }
        }
        EXPECT_EQ(failures, 0u) << "of " << checked << " taps";
    }
}

TEST(ChartAtlas, ParticlesAreTheChartTexels) {
    Mesh mesh = test::sphere(1.0f, 10, 14);
    const Atlas atlas = build_atlas(mesh, ring_of_cameras(3, 3.0, 384));
    const ParticleSet set = build_particles(mesh, atlas);
    EXPECT_EQ(set.particles.size(), atlas.summary.interior_texels + atlas.summary.gutter_texels);
    EXPECT_EQ(set.interior, atlas.summary.interior_texels);
    EXPECT_EQ(set.gutter, atlas.summary.gutter_texels);
    std::size_t owned = 0;
    for (std::uint32_t o : atlas.owner) owned += o != Atlas::kEmpty;
    EXPECT_EQ(set.particles.size(), owned);
    std::set<std::pair<std::uint32_t, std::uint32_t>> texels;
    std::uint32_t last_chart = 0;
    for (const Particle& p : set.particles) {
        EXPECT_TRUE(texels.insert({p.texel_x(), p.texel_y()}).second) << "texel used twice";
        ASSERT_EQ(atlas.owner_at(p.texel_x(), p.texel_y()), p.triangle);
        // Chart by chart.
        EXPECT_GE(atlas.chart_of[p.triangle], last_chart);
        last_chart = atlas.chart_of[p.triangle];
        const glm::dvec2 center(p.texel_x() + 0.5, p.texel_y() + 0.5);
        const glm::dvec2 st = atlas.patch_bary(p.triangle, center);
        EXPECT_EQ(p.is_gutter(), !in_patch(st));
        const glm::dvec2 c0 = atlas.corner_texel(p.triangle, 0), c1 = atlas.corner_texel(p.triangle, 1);
        const glm::dvec2 c2 = atlas.corner_texel(p.triangle, 2);
        if (!p.is_gutter()) {
            // Interior: the texel center's own barycentric coordinates.
            EXPECT_NEAR(p.bary.x, st.x, 1e-6);
            EXPECT_NEAR(p.bary.y, st.y, 1e-6);
            continue;
        }
        // Gutter: on the triangle's boundary, the closest point of the chart to the center
        // (no other triangle of the chart is closer), within the bilinear reach.
        const float s = p.bary.x, t = p.bary.y;
        EXPECT_LT(std::min({s, t, std::abs(1.0f - s - t)}), 1e-6f);
        const glm::dvec2 q = c0 + double(s) * (c1 - c0) + double(t) * (c2 - c0);
        const double d = glm::length(center - q);
        EXPECT_LE(std::max(std::abs(center.x - q.x), std::abs(center.y - q.y)), kChartGutterReach * std::sqrt(2.0) + 1e-6);
        for (std::uint32_t u = 0; u < mesh.triangles.size(); ++u) {
            if (atlas.chart_of[u] != atlas.chart_of[p.triangle] || u == p.triangle) continue;
            const glm::dvec2 b = closest_point_bary(atlas.corner_texel(u, 0), atlas.corner_texel(u, 1), atlas.corner_texel(u, 2), center);
            const glm::dvec2 r = atlas.corner_texel(u, 0) + b.x * (atlas.corner_texel(u, 1) - atlas.corner_texel(u, 0)) +
                                 b.y * (atlas.corner_texel(u, 2) - atlas.corner_texel(u, 0));
            EXPECT_GE(glm::length(center - r), d - 1e-5) << "triangle " << u << " is closer to gutter texel " << p.texel_x() << ","
                                                         << p.texel_y();
        }
        // Eq. 3.2 at the clamped point.
        const glm::uvec3 tri = mesh.triangles[p.triangle];
        const glm::vec3 expected = (1.0f - s - t) * mesh.positions[tri.x] + s * mesh.positions[tri.y] + t * mesh.positions[tri.z];
        EXPECT_LT(glm::length(p.p() - expected), 1e-5f);
    }
}

/// Box-filtered mip chain of an image and of its coverage (1 where the texel holds a value).
struct Mip {
    int w, h;
    std::vector<glm::vec3> color;
    std::vector<float> coverage;
};

std::vector<Mip> mip_chain(const Image& image) {
    std::vector<Mip> chain;
    Mip m0{image.width, image.height, {}, {}};
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const glm::vec3 c(image.at(x, y, 0), image.at(x, y, 1), image.at(x, y, 2));
            m0.color.push_back(c);
            m0.coverage.push_back(c.r > 0.0f || c.g > 0.0f || c.b > 0.0f ? 1.0f : 0.0f); // every value written is >= 0.05
        }
    chain.push_back(std::move(m0));
    while (chain.back().w > 1 || chain.back().h > 1) {
        const Mip& f = chain.back();
        Mip c{(f.w + 1) / 2, (f.h + 1) / 2, {}, {}}; // an odd side's last texel averages with itself
        for (int y = 0; y < c.h; ++y)
            for (int x = 0; x < c.w; ++x) {
                glm::vec3 sum(0.0f);
                float cov = 0.0f;
                int n = 0;
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx) {
                        const int fx = std::min(2 * x + dx, f.w - 1), fy = std::min(2 * y + dy, f.h - 1);
                        sum += f.color[std::size_t(fy) * std::size_t(f.w) + std::size_t(fx)];
                        cov += f.coverage[std::size_t(fy) * std::size_t(f.w) + std::size_t(fx)];
                        ++n;
                    }
                c.color.push_back(sum / float(n));
                c.coverage.push_back(cov / float(n));
            }
        chain.push_back(std::move(c));
    }
    return chain;
}

/// Checks bilinear lookups of every mip level at points of every triangle: every tap fully
/// covered; for `exact_levels` levels, the value equals the triangle's expected colour.
void expect_mips_read_filled_texels(const Mesh& mesh, const Atlas& atlas, const Image& written, int exact_levels,
                                    const std::function<glm::vec3(std::uint32_t)>& expected) {
    const std::vector<Mip> chain = mip_chain(written);
    std::size_t uncovered = 0, wrong = 0, taps = 0;
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::dvec2 c0 = render_corner(atlas, t, 0), c1 = render_corner(atlas, t, 1), c2 = render_corner(atlas, t, 2);
        for (const glm::dvec2 st : {glm::dvec2(1.0 / 3, 1.0 / 3), glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(0, 1), glm::dvec2(0.5, 0),
                                    glm::dvec2(0, 0.5), glm::dvec2(0.5, 0.5)}) {
            const glm::dvec2 p0 = c0 + st.x * (c1 - c0) + st.y * (c2 - c0);
            for (std::size_t level = 0; level < chain.size(); ++level) {
                const Mip& m = chain[level];
                // The level's texel coordinates of the point (the level covers the same uv square).
                const glm::dvec2 p(p0.x / atlas.width * m.w, p0.y / atlas.height * m.h);
                const int x0 = int(std::floor(p.x - 0.5)), y0 = int(std::floor(p.y - 0.5));
                const double ax = p.x - 0.5 - x0, ay = p.y - 0.5 - y0;
                glm::dvec3 value(0.0);
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx) {
                        const int x = std::clamp(x0 + dx, 0, m.w - 1), y = std::clamp(y0 + dy, 0, m.h - 1); // clamp to edge
                        const std::size_t i = std::size_t(y) * std::size_t(m.w) + std::size_t(x);
                        ++taps;
                        if (m.coverage[i] < 1.0f && ++uncovered < 10)
                            ADD_FAILURE() << "mip level " << level << " reads texel (" << x << ", " << y << ") with coverage " << m.coverage[i]
                                          << " for triangle " << t;
                        value += (dx ? ax : 1.0 - ax) * (dy ? ay : 1.0 - ay) * glm::dvec3(m.color[i]);
                    }
                if (int(level) < exact_levels && glm::length(value - glm::dvec3(expected(t))) > 1e-5 && ++wrong < 10)
                    ADD_FAILURE() << "mip level " << level << " at triangle " << t << " reads (" << value.x << ", " << value.y << ", "
                                  << value.z << "), its chart is (" << expected(t).x << ", " << expected(t).y << ", " << expected(t).z << ")";
            }
        }
    }
    EXPECT_EQ(uncovered, 0u) << "of " << taps << " taps";
    EXPECT_EQ(wrong, 0u);
}

/// The written albedo (albedo.exr read back) of an atlas whose particles hold `colour`; every
/// 7th particle has no value (inpainted).
Image written_albedo(const Mesh& mesh, const Atlas& atlas, const std::function<glm::vec3(const Particle&)>& colour,
                     const std::string& tag) {
    const ParticleSet set = build_particles(mesh, atlas);
    std::vector<glm::vec3> albedo(set.particles.size());
    std::vector<std::uint8_t> valid(set.particles.size());
    for (std::size_t p = 0; p < set.particles.size(); ++p) {
        albedo[p] = colour(set.particles[p]);
        valid[p] = p % 7 != 3;
    }
    const AlbedoTexture texture = make_albedo_texture(atlas, set.particles, albedo, valid);
    EXPECT_GT(texture.stats.filled_same_patch + texture.stats.filled_across, 0u);
    EXPECT_EQ(texture.stats.texels + texture.stats.filled_dilation + texture.stats.filled_pull_push,
              std::size_t(atlas.width) * atlas.height);
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("specula_chart_mips_" + tag);
    std::filesystem::create_directories(dir);
    write_albedo_texture(texture, dir / "albedo");
    Image back = read_image(dir / "albedo.exr", ColorSpace::Linear, "albedo");
    std::filesystem::remove_all(dir);
    return back;
}

glm::vec3 chart_colour(std::uint32_t id) {
    const std::uint32_t h = (id + 1) * 2654435761u;
    return glm::vec3(0.05f + 0.9f * float(h & 255u) / 255.0f, 0.05f + 0.9f * float((h >> 8) & 255u) / 255.0f,
                     0.05f + 0.9f * float((h >> 16) & 255u) / 255.0f);
}

TEST(ChartAtlas, NoMipLevelReadsAnUnfilledTexel) {
    const Mesh mesh = test::merge(test::torus(1.0f, 0.35f, 48, 16), test::sphere(0.4f, 10, 14, {0.0f, 1.2f, 0.0f}));
    const std::vector<Camera> cams = ring_of_cameras(4, 4.0, 256);
    {
        // Charts: levels 0 and 1 read exactly their chart (its texels and its gutter rings);
        // every level reads only filled texels. (Sides are multiples of 4, so level 1 halves exactly.)
        const Atlas atlas = build_atlas(mesh, cams);
        SCOPED_TRACE(describe(atlas.summary));
        EXPECT_EQ(atlas.width % 4, 0u);
        EXPECT_EQ(atlas.height % 4, 0u);
        const Image img = written_albedo(mesh, atlas, [&](const Particle& p) { return chart_colour(atlas.chart_of[p.triangle]); }, "charts");
        expect_mips_read_filled_texels(mesh, atlas, img, 2, [&](std::uint32_t t) { return chart_colour(atlas.chart_of[t]); });
    }
    {
        // The patchwork: every texel filled too (its unowned texels were black before).
        const Atlas atlas = build_atlas(mesh, cams, {.mode = AtlasMode::Patchwork});
        const Image img = written_albedo(mesh, atlas, [&](const Particle& p) { return chart_colour(p.triangle); }, "patchwork");
        expect_mips_read_filled_texels(mesh, atlas, img, 0, [&](std::uint32_t t) { return chart_colour(t); });
    }
}

// ---- density and budget ----------------------------------------------------------------

/// Four triangles facing +Z at z = 0: two with legs `big`, two with legs `small`.
Mesh four_triangles(float big, float small) {
    Mesh m;
    test::add_triangle(m, {-3, 0, 0}, {-3 + big, 0, 0}, {-3, big, 0}, {0, 0, 1});
    test::add_triangle(m, {-1, 0, 0}, {-1 + big, 0, 0}, {-1, big, 0}, {0, 0, 1});
    test::add_triangle(m, {1, 0, 0}, {1 + small, 0, 0}, {1, small, 0}, {0, 0, 1});
    test::add_triangle(m, {2, 0, 0}, {2 + small, 0, 0}, {2, small, 0}, {0, 0, 1});
    return m;
}

TEST(ChartAtlas, TexelDensityFollowsThePixelFootprint) {
    // Each chart's texels are kChartTexelsPerPatchTexel times the pixels its triangles cover
    // in their best views (at one texel per pixel; a triangle no camera sees asks for
    // min_patch^2 / 2 = 0.5), a quarter of that at 0.25 texels per pixel.
    const Mesh mesh = test::sphere(1.0f, 16, 24);
    const std::vector<Camera> cams = ring_of_cameras(4, 3.0, 512);
    std::vector<double> pixels = best_pixel_footprint(mesh, cams);
    std::size_t unseen_count = 0;
    for (double& p : pixels) {
        if (p == 0.0) {
            p = 0.5;
            ++unseen_count;
        } else {
            p *= kChartTexelsPerPatchTexel;
        }
    }
    double want = 0.0;
    for (double p : pixels) want += p;
    const Atlas atlas = build_atlas(mesh, cams);
    EXPECT_EQ(atlas.summary.size_source, "cameras");
    EXPECT_FALSE(atlas.summary.budget_clipped);
    EXPECT_EQ(atlas.summary.triangles_seen_by_no_camera, unseen_count);
    EXPECT_NEAR(atlas.summary.desired_texels, want, 1e-6 * want);
    EXPECT_NEAR(double(atlas.summary.interior_texels), want, 0.03 * want);
    // Per chart: its texel area is the sum of its triangles' footprints.
    std::vector<double> chart_want(atlas.charts.size(), 0.0), chart_has(atlas.charts.size(), 0.0);
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::dvec2 c0 = atlas.corner_texel(t, 0);
        chart_has[atlas.chart_of[t]] += 0.5 * cross2(atlas.corner_texel(t, 1) - c0, atlas.corner_texel(t, 2) - c0);
        chart_want[atlas.chart_of[t]] += pixels[t];
    }
    for (std::size_t c = 0; c < chart_want.size(); ++c) EXPECT_NEAR(chart_has[c], chart_want[c], 1e-4 * chart_want[c]);

    AtlasOptions coarse;
    coarse.texels_per_pixel = 0.25;
    const Atlas quarter = build_atlas(mesh, cams, coarse);
    EXPECT_NEAR(double(quarter.summary.interior_texels), 0.25 * want, 0.05 * want);
    EXPECT_LT(double(quarter.width) * quarter.height, 0.5 * double(atlas.width) * atlas.height);

    // A triangle no camera sees asks for min_patch^2 / 2 texels, and the summary says so.
    const std::vector<Camera> behind = {make_camera({0, 0, -5}, {0, 0, 0}, 512, 400.0)};
    const Atlas unseen = build_atlas(four_triangles(0.4f, 0.2f), behind);
    EXPECT_EQ(unseen.summary.triangles_seen_by_no_camera, 4u);
    EXPECT_NEAR(unseen.summary.desired_texels, 4 * 0.5, 1e-12);
    ASSERT_FALSE(unseen.summary.notes.empty());
}

TEST(ChartAtlas, BudgetScalesEveryChartAndSaysSo) {
    const Mesh mesh = test::sphere(1.0f, 16, 24);
    const std::vector<Camera> cams = ring_of_cameras(4, 3.0, 512);
    const Atlas free = build_atlas(mesh, cams);
    ASSERT_FALSE(free.summary.budget_clipped);
    EXPECT_EQ(free.summary.budget_scale, 1.0);

    AtlasOptions tight;
    tight.max_width = tight.max_height = 128;
    const Atlas clipped = build_atlas(mesh, cams, tight);
    EXPECT_TRUE(clipped.summary.budget_clipped);
    EXPECT_LT(clipped.summary.budget_scale, 1.0);
    EXPECT_LE(clipped.width, 128u);
    EXPECT_LE(clipped.height, 128u);
    ASSERT_FALSE(clipped.summary.notes.empty());
    EXPECT_NE(clipped.summary.notes[0].find("budget"), std::string::npos);
    EXPECT_NE(describe(clipped.summary).find("CLIPPED"), std::string::npos);
    expect_no_overlap(clipped);
    // Every chart by one factor: the texel area relative to the free atlas is scale^2.
    const double scale2 = clipped.summary.budget_scale * clipped.summary.budget_scale;
    EXPECT_NEAR(double(clipped.summary.interior_texels) / double(free.summary.interior_texels), scale2, 0.15 * scale2);

    AtlasOptions impossible;
    impossible.max_width = impossible.max_height = 8;
    EXPECT_THROW((void)build_atlas(test::sphere(1.0f, 20, 20), cams, impossible), Error);
}

TEST(ChartAtlas, WithoutCamerasTheChartsFillTheBudget) {
    const Mesh mesh = test::torus(1.0f, 0.35f, 48, 16);
    const Atlas atlas = build_atlas(mesh, {}, {.max_width = 256, .max_height = 256});
    EXPECT_EQ(atlas.summary.size_source, "surface area");
    EXPECT_FALSE(atlas.summary.budget_clipped);
    EXPECT_LE(atlas.width, 256u);
    EXPECT_LE(atlas.height, 256u);
    EXPECT_GT(double(atlas.width) * atlas.height, 0.8 * 256 * 256);
    EXPECT_GT(atlas.summary.fill_ratio, 0.5);
}

// A bundle's texture coordinates give back the atlas it was made from (what `specula evaluate
// --indirect` builds its particles on): the same charts and, but for texels whose centres lie
// on a triangle's edge within the float rounding of the coordinates, the same owners.
TEST(ChartAtlas, TextureCoordinatesGiveBackTheAtlas) {
    for (const char* name : {"knot", "can", "vase"}) {
        const synth::Preset preset = synth::make_preset(name);
        const Atlas atlas = build_atlas(preset.mesh, {}, {.max_width = 512, .max_height = 512});
        const Bundle bundle = make_bundle(preset.mesh, atlas.corner_uv, Image(int(atlas.width), int(atlas.height), 3, 0.5f), Material{});
        ASSERT_EQ(bundle.mesh.triangles.size(), preset.mesh.triangles.size());
        const Atlas back = atlas_from_texture_coordinates(bundle.mesh, atlas.width, atlas.height);
        EXPECT_EQ(back.charts.size(), atlas.charts.size()) << name;
        EXPECT_EQ(back.summary.size_source, "texture coordinates");
        // One chart of the bundle per chart of the atlas, and the other way round.
        std::map<std::uint32_t, std::uint32_t> forward, backward;
        for (std::size_t t = 0; t < atlas.chart_of.size(); ++t) {
            const auto [f, f_new] = forward.emplace(atlas.chart_of[t], back.chart_of[t]);
            const auto [b, b_new] = backward.emplace(back.chart_of[t], atlas.chart_of[t]);
            ASSERT_EQ(f->second, back.chart_of[t]) << name << ": triangle " << t;
            ASSERT_EQ(b->second, atlas.chart_of[t]) << name << ": triangle " << t;
        }
        std::size_t differ = 0, owned = 0;
        for (std::size_t i = 0; i < atlas.owner.size(); ++i) {
            if (atlas.owner[i] != Atlas::kEmpty) ++owned;
            if (atlas.owner[i] != back.owner[i]) ++differ;
        }
        std::printf("%-5s %zu charts, %zu owned texels, %zu owned differently\n", name, back.charts.size(), owned, differ);
        EXPECT_LT(double(differ), 1e-3 * double(owned)) << name;
        EXPECT_EQ(back.summary.interior_texels + back.summary.gutter_texels, atlas.summary.interior_texels + atlas.summary.gutter_texels);
        // The particles land on the same texels.
        EXPECT_NEAR(double(build_particles(bundle.mesh, back).particles.size()), double(owned), 1e-3 * double(owned)) << name;
    }
}

TEST(ChartAtlas, TextureCoordinatesThatCannotMakeAnAtlasAreRefused) {
    Mesh mesh = test::plane(1.0f, 2);
    EXPECT_THROW((void)atlas_from_texture_coordinates(mesh, 64, 64), Error); // no texture coordinates
    mesh.texcoords.assign(mesh.positions.size(), glm::vec2(0.5f));
    EXPECT_THROW((void)atlas_from_texture_coordinates(mesh, 0, 64), Error);
    EXPECT_THROW((void)atlas_from_texture_coordinates(mesh, 64, Atlas::kMaxDimension + 1), Error);
    // Every triangle on one point of the texture: none has area there, none owns a texel.
    const Atlas flat = atlas_from_texture_coordinates(mesh, 64, 64);
    EXPECT_TRUE(std::all_of(flat.owner.begin(), flat.owner.end(), [](std::uint32_t o) { return o == Atlas::kEmpty; }));
    mesh.texcoords[1].x = std::nanf("");
    EXPECT_THROW((void)atlas_from_texture_coordinates(mesh, 64, 64), Error);
}

TEST(ChartAtlas, ModeNamesRoundTrip) {
    EXPECT_EQ(atlas_mode_from_string("charts"), AtlasMode::Charts);
    EXPECT_EQ(atlas_mode_from_string("patchwork"), AtlasMode::Patchwork);
    EXPECT_FALSE(atlas_mode_from_string("lscm").has_value());
    EXPECT_STREQ(to_string(AtlasMode::Charts), "charts");
    EXPECT_EQ(AtlasOptions{}.mode, AtlasMode::Charts);
}

TEST(ChartAtlas, StretchOfAKnownMap) {
    // A right triangle mapped by diag(2, 1) (times a rotation): sigma 2 and 1.
    const glm::dvec2 s = triangle_stretch({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0}, {0, 2}, {-1, 0});
    EXPECT_NEAR(s.x, 2.0, 1e-12);
    EXPECT_NEAR(s.y, 1.0, 1e-12);
    // Mirrored: negative sigma2.
    EXPECT_LT(triangle_stretch({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0}, {1, 0}, {0, -1}).y, 0.0);
}

} // namespace
} // namespace specula
