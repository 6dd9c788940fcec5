#pragma once
// The albedo a reconstruction recovered against a synthetic capture's truth, over the whole seen
// surface and over its concave parts (issue 16): points on every triangle (its centroid and three
// points between it and the corners), area-weighted, kept where some train view sees them (facing
// it, an unoccluded ray) and where the truth is flat (kFlatTolerance). A point is concave when at least `concave_fraction` of a stratified
// cosine-weighted hemisphere of rays from it reaches the object again: a definition from the
// geometry alone, not from the code under test. The estimate is the bundle's albedo at the
// point's atlas coordinate; the truth the capture's truth/albedo.exr at its texture coordinate
// (the capture's mesh.glb keeps the preset's). Errors in albedo units (x 100: percent).
#include "capture/capture.h"
#include "core/image.h"
#include "export/bundle.h"
#include "geometry/ray_scene.h"
#include "synth/render.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <stdexcept>

namespace specula::test {

struct AlbedoComparison {
    double rmse_all = 0.0;      ///< RMS over channels and seen points, area-weighted
    double rmse_concave = 0.0;  ///< the same over the concave ones
    double bias_concave = 0.0;  ///< mean signed error there (> 0: too bright)
    double concave_area = 0.0;  ///< their share of the seen area
    std::size_t points = 0;
    std::size_t concave_points = 0;
};

/// A point counts where the truth stays within this of its value 2 truth texels and
/// kFlatAtlasTexels atlas texels away in u and v (0: 2 truth texels only, as before issue 16's
/// sixth session).
inline constexpr float kFlatTolerance = 0.01f;
inline constexpr float kFlatAtlasTexels = 2.0f;

/// One compared point, for a caller that looks closer (bench/concave_albedo --points).
struct PointError {
    glm::vec3 position;
    double area = 0.0;         ///< its share of the triangle's area (the weight)
    double hemisphere = 0.0;   ///< the fraction of its hemisphere that sees the object
    glm::vec3 truth;
    glm::vec3 error;           ///< estimate - truth
};

inline AlbedoComparison compare_albedo(const std::filesystem::path& capture_dir, const std::filesystem::path& bundle_file,
                                       double concave_fraction = 0.25,
                                       const std::function<void(const PointError&)>& each_point = {},
                                       float flat_atlas_texels = kFlatAtlasTexels) {
    const Capture capture = load_capture(capture_dir, {.load_mesh = true, .load_images = false});
    const Image truth = read_image(capture.desc.dir / "truth" / "albedo.exr", ColorSpace::Linear);
    const Bundle bundle = read_bundle(bundle_file);
    const Mesh& mesh = capture.mesh;
    if (!mesh.has_texcoords()) throw std::runtime_error("compare_albedo: the capture's mesh has no texture coordinates");
    if (bundle.mesh.triangles.size() != mesh.triangles.size())
        throw std::runtime_error("compare_albedo: the bundle's triangles are not the capture's");
    const RayScene scene(mesh);
    std::vector<Camera> cameras;
    for (const View& v : capture.views)
        for (std::size_t f : v.frames)
            if (capture.desc.frames[f].split == Split::Train) {
                cameras.push_back(v.camera);
                break;
            }
    const glm::dvec3 corners[4] = {{1.0 / 3, 1.0 / 3, 1.0 / 3}, {2.0 / 3, 1.0 / 6, 1.0 / 6}, {1.0 / 6, 2.0 / 3, 1.0 / 6}, {1.0 / 6, 1.0 / 6, 2.0 / 3}};
    double sum_all = 0.0, w_all = 0.0, sum_concave = 0.0, bias = 0.0, w_concave = 0.0;
    AlbedoComparison out;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::uvec3 tri = mesh.triangles[t], btri = bundle.mesh.triangles[t];
        const glm::vec3 p0 = mesh.positions[tri.x], p1 = mesh.positions[tri.y], p2 = mesh.positions[tri.z];
        if (glm::length(bundle.mesh.positions[btri.x] - p0) > 1e-4f * (1.0f + glm::length(p0)))
            throw std::runtime_error("compare_albedo: the bundle's triangle " + std::to_string(t) + " is not the capture's");
        glm::vec3 ng = glm::cross(p1 - p0, p2 - p0);
        const float area = 0.5f * glm::length(ng);
        if (!(area > 0.0f)) continue;
        ng = glm::normalize(ng);
        // Truth texels per atlas texel, along one side: the square root of the triangle's area
        // ratio in the two textures (texels).
        const auto texel_area = [](const glm::vec2& a, const glm::vec2& b, const glm::vec2& c, const Image& im) {
            const glm::vec2 s(float(im.width), float(im.height));
            const glm::vec2 u = (b - a) * s, v = (c - a) * s;
            return 0.5f * std::abs(u.x * v.y - u.y * v.x);
        };
        const float truth_area = texel_area(mesh.texcoords[tri.x], mesh.texcoords[tri.y], mesh.texcoords[tri.z], truth);
        const float atlas_area =
            texel_area(bundle.mesh.texcoords[btri.x], bundle.mesh.texcoords[btri.y], bundle.mesh.texcoords[btri.z], bundle.albedo);
        const float truth_per_atlas_texel = atlas_area > 0.0f ? std::sqrt(truth_area / atlas_area) : 1.0f;
        for (const glm::dvec3& b : corners) {
            const glm::vec3 p = float(b.x) * p0 + float(b.y) * p1 + float(b.z) * p2;
            const glm::vec3 origin = p + scene.ray_offset() * ng;
            bool seen = false;
            for (const Camera& c : cameras) {
                const glm::vec3 to = glm::vec3(c.center()) - p;
                if (glm::dot(to, ng) <= 0.0f) continue;
                if (!c.project(glm::dvec3(p))) continue;
                if (!scene.occluded(origin, to, 0.0f, 1.0f)) {
                    seen = true;
                    break;
                }
            }
            if (!seen) continue;
            // Concave: stratified cosine-weighted rays (8 x 8) that reach the object again.
            glm::vec3 u = glm::normalize(glm::cross(std::abs(ng.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0), ng));
            const glm::vec3 v = glm::cross(ng, u);
            int hits = 0;
            for (int i = 0; i < 8; ++i)
                for (int j = 0; j < 8; ++j) {
                    const float r = std::sqrt((i + 0.5f) / 8.0f), phi = glm::two_pi<float>() * (j + 0.5f) / 8.0f;
                    const glm::vec3 d = r * std::cos(phi) * u + r * std::sin(phi) * v + std::sqrt(1.0f - r * r) * ng;
                    if (scene.occluded(origin, d, 0.0f, std::numeric_limits<float>::infinity())) ++hits;
                }
            const bool concave = hits >= concave_fraction * 64.0;
            const glm::vec2 uv_truth = float(b.x) * mesh.texcoords[tri.x] + float(b.y) * mesh.texcoords[tri.y] + float(b.z) * mesh.texcoords[tri.z];
            const glm::vec2 uv_atlas = float(b.x) * bundle.mesh.texcoords[btri.x] + float(b.y) * bundle.mesh.texcoords[btri.y] +
                                       float(b.z) * bundle.mesh.texcoords[btri.z];
            // Away from the truth's edges: a texture's edge is blurred by any sampling of it (the
            // solve's bilinear taps, the atlas's texels), which is another error than this one's.
            // So the truth must be flat over 2 of its texels and over 2 of the atlas's texels,
            // whichever reach farther (in concave parts, seen at a slant, the cameras' footprint
            // and so the atlas's texels are larger than the truth's).
            const glm::vec3 centre = synth::sample_albedo(truth, uv_truth);
            const glm::vec2 step = std::max(2.0f, flat_atlas_texels * truth_per_atlas_texel) /
                                   glm::vec2(float(truth.width), float(truth.height));
            bool flat = true;
            for (const glm::vec2 o : {glm::vec2(step.x, 0), glm::vec2(-step.x, 0), glm::vec2(0, step.y), glm::vec2(0, -step.y)}) {
                const glm::vec3 d = glm::abs(synth::sample_albedo(truth, uv_truth + o) - centre);
                flat = flat && std::max({d.x, d.y, d.z}) <= kFlatTolerance;
            }
            if (!flat) continue;
            const glm::vec3 e = synth::sample_albedo(bundle.albedo, uv_atlas) - centre;
            const double sq = glm::dot(e, e) / 3.0, w = area;
            if (each_point) each_point(PointError{p, area / 4.0, hits / 64.0, centre, e});
            sum_all += w * sq;
            w_all += w;
            ++out.points;
            if (concave) {
                sum_concave += w * sq;
                bias += w * (e.x + e.y + e.z) / 3.0;
                w_concave += w;
                ++out.concave_points;
            }
        }
    }
    out.rmse_all = w_all > 0.0 ? std::sqrt(sum_all / w_all) : 0.0;
    out.rmse_concave = w_concave > 0.0 ? std::sqrt(sum_concave / w_concave) : 0.0;
    out.bias_concave = w_concave > 0.0 ? bias / w_concave : 0.0;
    out.concave_area = w_all > 0.0 ? w_concave / w_all : 0.0;
    return out;
}

} // namespace specula::test
