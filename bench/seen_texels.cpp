// Albedo error over every seen texel of a Lambertian synthetic capture (issue 3: "RMSE under
// 0.5% of full scale over seen texels"), and where it lives (run by hand, not a test):
//   seen_texels CAPTURE PRESET[@V] [OUT ...]      (@V: uniform albedo V, synth --albedo-value V,V,V)
// CAPTURE: `specula synth --preset PRESET --lambertian --out CAPTURE`; each OUT: `specula
// reconstruct CAPTURE -o OUT` (its albedo.exr, read at the particles' texels). The tool
// rebuilds what reconstruct builds (the atlas from the train views with default options, the
// particles, visibility) and the diffuse solve (albedo mode, CPU): its seen texels are the
// particles it gives a value (kLambertOk), the texels reconstruct writes from a solve rather
// than inpaints. For the solve's best-view and robust values and for each OUT it prints the
// RMSE against two truths:
//   point  the preset's albedo at the particle's surface point (diffuse_scene.h; issue 3's words)
//   box    that albedo averaged over the particle's texel (test::texel_box_truth)
// and the surface error (test::surface_error: the texture's bilinear value against the truth
// at points between texel centres too). Rows "atlas of ... truth" write the truths themselves
// into the atlas: what it can hold. Each row then splits the point truth's squared error four
// ways: interior / gutter texels; the cosine of the best view (grazing views near
// silhouettes); the sub-texel detail |point - box| (max channel); resolved by the images
// (test::flat_truth, 1.5 px, 0.004) or not. The figures for the presets are in README.md
// ("How the albedo is sharpened").
#include "diffuse_scene.h"

#include "capture/capture.h"
#include "core/image.h"
#include "diffuse/albedo_texture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

using namespace specula;

namespace {

struct Partition {
    const char* name;
    std::vector<const char*> buckets;
    std::function<int(std::size_t)> bucket; // particle -> bucket index
};

void report(const char* label, const std::vector<glm::vec3>& estimate, const Image& texture, const test::DiffuseScene& scene,
            const std::vector<glm::vec3>& box, const std::vector<std::uint8_t>& seen, const std::vector<Partition>& splits) {
    const test::AlbedoError point_err = test::albedo_error(estimate, scene.truth, seen);
    const test::AlbedoError box_err = test::albedo_error(estimate, box, seen);
    const test::AlbedoError surface_err = test::surface_error(scene, texture, seen);
    std::printf("%-22s RMSE over seen texels: point truth %.3f%% (max %.3f), box truth %.3f%% (max %.3f); "
                "surface %.3f%% (max %.3f); n %zu\n", label, 100 * point_err.rmse, point_err.max_abs, 100 * box_err.rmse,
                box_err.max_abs, 100 * surface_err.rmse, surface_err.max_abs, point_err.count);
    if (splits.empty()) return;
    double total = 0.0;
    std::vector<double> sq(seen.size(), 0.0), sq_box(seen.size(), 0.0);
    for (std::size_t p = 0; p < seen.size(); ++p) {
        if (!seen[p]) continue;
        const glm::dvec3 d = glm::dvec3(estimate[p] - scene.truth[p]), db = glm::dvec3(estimate[p] - box[p]);
        sq[p] = glm::dot(d, d);
        sq_box[p] = glm::dot(db, db);
        total += sq[p];
    }
    for (const Partition& split : splits) {
        std::printf("  %-18s", split.name);
        std::vector<double> s(split.buckets.size()), sb(split.buckets.size()), n(split.buckets.size());
        for (std::size_t p = 0; p < seen.size(); ++p) {
            if (!seen[p]) continue;
            const int b = split.bucket(p);
            s[std::size_t(b)] += sq[p];
            sb[std::size_t(b)] += sq_box[p];
            n[std::size_t(b)] += 1;
        }
        for (std::size_t b = 0; b < split.buckets.size(); ++b)
            std::printf(" | %s: %4.1f%% of texels, %4.1f%% of SSE, RMSE %.3f%% (box %.3f%%)", split.buckets[b],
                        100 * n[b] / double(point_err.count), total > 0 ? 100 * s[b] / total : 0.0,
                        n[b] > 0 ? 100 * std::sqrt(s[b] / (3 * n[b])) : 0.0, n[b] > 0 ? 100 * std::sqrt(sb[b] / (3 * n[b])) : 0.0);
        std::printf("\n");
    }
}

} // namespace

int main(int argc, char** argv) try {
    if (argc < 3) {
        std::fprintf(stderr, "usage: seen_texels CAPTURE PRESET [OUT ...] (see the source's first comment)\n");
        return 2;
    }
    test::DiffuseScene scene;
    // PRESET@V: the preset's mesh with a uniform albedo V (`specula synth --preset PRESET
    // --lambertian --albedo-value V,V,V`).
    std::string preset_name = argv[2];
    std::optional<float> uniform;
    if (const auto at = preset_name.find('@'); at != std::string::npos) {
        uniform = std::stof(preset_name.substr(at + 1));
        preset_name.resize(at);
    }
    scene.preset = synth::make_preset(preset_name, true);
    if (uniform) std::fill(scene.preset.material.albedo_texture.pixels.begin(), scene.preset.material.albedo_texture.pixels.end(), *uniform);
    scene.capture = load_capture(argv[1]);
    if (scene.capture.mesh.triangles != scene.preset.mesh.triangles || scene.capture.mesh.texcoords.size() != scene.preset.mesh.texcoords.size())
        throw std::runtime_error(std::string("the capture's mesh is not preset ") + argv[2] + "'s");
    scene.capture.mesh.texcoords = scene.preset.mesh.texcoords; // the truth's uv (the glb round trip is float anyway)
    test::build_scene_stages(scene);
    const LambertOutputs solve = lambert_solve_cpu(scene.inputs(), {});
    const std::vector<glm::vec3> box = test::texel_box_truth(scene);
    const std::vector<std::uint8_t> flat = test::flat_truth(scene, 1.5, 0.004f);
    std::vector<std::uint8_t> seen(scene.truth.size());
    for (std::size_t p = 0; p < seen.size(); ++p) seen[p] = (solve.particles[p].status & shared::kLambertOk) ? 1 : 0;
    std::printf("%s: atlas %ux%u, %zu particles, %zu seen\n", argv[2], scene.atlas.width, scene.atlas.height, seen.size(),
                static_cast<std::size_t>(std::count(seen.begin(), seen.end(), 1)));
    const auto texture = [&](const std::vector<glm::vec3>& albedo) {
        return make_albedo_texture(scene.atlas, scene.particles.particles, albedo, seen).image;
    };
    // What the atlas can hold: the truths themselves written into it (unseen texels inpainted).
    report("atlas of point truth", scene.truth, texture(scene.truth), scene, box, seen, {});
    report("atlas of box truth", box, texture(box), scene, box, seen, {});

    const auto best_cos = [&](std::size_t p) {
        const Particle& part = scene.particles.particles[p];
        const Camera& cam = scene.capture.views[solve.particles[p].best_view].camera;
        return glm::dot(glm::dvec3(part.n()), glm::normalize(cam.center() - glm::dvec3(part.p())));
    };
    const std::vector<Partition> splits = {
        {"texel", {"interior", "gutter"}, [&](std::size_t p) { return scene.particles.particles[p].is_gutter() ? 1 : 0; }},
        {"best view cos", {"<0.3", "0.3-0.6", ">=0.6"}, [&](std::size_t p) {
             const double c = best_cos(p);
             return c < 0.3 ? 0 : c < 0.6 ? 1 : 2;
         }},
        {"|point - box|", {"<0.5%", "0.5-2%", "2-5%", ">=5%"}, [&](std::size_t p) {
             const glm::vec3 d = glm::abs(box[p] - scene.truth[p]);
             const float m = std::max({d.x, d.y, d.z});
             return m < 0.005f ? 0 : m < 0.02f ? 1 : m < 0.05f ? 2 : 3;
         }},
        {"resolved", {"yes", "no"}, [&](std::size_t p) { return flat[p] ? 0 : 1; }},
    };

    std::vector<glm::vec3> estimate(seen.size());
    for (const ViewChoice choice : {ViewChoice::BestView, ViewChoice::Robust}) {
        for (std::size_t p = 0; p < seen.size(); ++p) {
            const LambertParticleResult& r = solve.particles[p];
            estimate[p] = glm::vec3(choice == ViewChoice::BestView ? r.albedo_best : r.albedo_robust);
        }
        report(choice == ViewChoice::BestView ? "solve, best view" : "solve, robust", estimate, texture(estimate), scene, box,
               seen, splits);
    }
    // The worst texels of the best-view solve, to tell a texture edge from a geometric failure.
    std::vector<std::pair<float, std::size_t>> worst;
    for (std::size_t p = 0; p < seen.size(); ++p) {
        if (!seen[p]) continue;
        const glm::vec3 d = glm::abs(glm::vec3(solve.particles[p].albedo_best) - scene.truth[p]);
        worst.push_back({std::max({d.x, d.y, d.z}), p});
    }
    const std::size_t shown = std::min<std::size_t>(8, worst.size());
    std::partial_sort(worst.begin(), worst.begin() + static_cast<std::ptrdiff_t>(shown), worst.end(), std::greater<>());
    for (std::size_t i = 0; i < shown; ++i) {
        const std::size_t p = worst[i].second;
        const LambertParticleResult& r = solve.particles[p];
        const glm::vec3 t = scene.truth[p], b = box[p], e = glm::vec3(r.albedo_best);
        std::printf("worst %zu: particle %zu%s, best view %u (cos %.3f), %u views, %u samples; truth (%.3f %.3f %.3f) box "
                    "(%.3f %.3f %.3f) best (%.3f %.3f %.3f) robust (%.3f %.3f %.3f)\n",
                    i, p, scene.particles.particles[p].is_gutter() ? " (gutter)" : "", r.best_view, best_cos(p), r.views, r.used,
                    t.x, t.y, t.z, b.x, b.y, b.z, e.x, e.y, e.z, r.albedo_robust.x, r.albedo_robust.y, r.albedo_robust.z);
    }
    for (int i = 3; i < argc; ++i) {
        const std::filesystem::path file = std::filesystem::path(argv[i]) / "albedo.exr";
        const Image atlas = read_image(file, ColorSpace::Linear);
        if (atlas.width != int(scene.atlas.width) || atlas.height != int(scene.atlas.height))
            throw std::runtime_error(file.string() + " is not the atlas rebuilt here");
        for (std::size_t p = 0; p < seen.size(); ++p) {
            const Particle& part = scene.particles.particles[p];
            for (int c = 0; c < 3; ++c) estimate[p][c] = atlas.at(int(part.texel_x()), int(part.texel_y()), c);
        }
        report(argv[i], estimate, atlas, scene, box, seen, splits);
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
