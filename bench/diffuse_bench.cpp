// Measurements for the diffuse stage notes (run by hand, not a test):
//   diffuse_bench [size=512] [views=20] [lights=6] [presets=can,cologne,vase,woodenpot,knot] [format=exr|png8|png16] [exposure=1] [lambertian=0|1]
//   SPECULA_BENCH_LIGHT_ANGLES=a,b,... sets the rig's train light angles (synth/rig.h; "14": a thesis-like ring)
// Prints per preset and mode: particles, solve time on cpu and vulkan (GPU time from the
// timestamps), and the albedo RMSE against the truth over seen particles, over particles
// whose truth is flat around them, and over the flat ones shadowed in some frames (issue 3's
// "no baked shadows" figure; test::shadowed_texel_error).
#include "diffuse_scene.h"

#include "diffuse/albedo_texture.h"
#include "gpu/context.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>

using namespace specula;

int main(int argc, char** argv) try {
    const int size = argc > 1 ? std::atoi(argv[1]) : 512;
    const int views = argc > 2 ? std::atoi(argv[2]) : 20;
    const int lights = argc > 3 ? std::atoi(argv[3]) : 6;
    const std::string presets = argc > 4 ? argv[4] : "can,cologne,vase,woodenpot,knot";
    const std::string format = argc > 5 ? argv[5] : "exr";
    const double exposure = argc > 6 ? std::atof(argv[6]) : 1.0;
    const bool lambertian = argc > 7 ? std::atoi(argv[7]) != 0 : true;
    std::unique_ptr<gpu::Context> ctx;
    try {
        ctx = std::make_unique<gpu::Context>();
        std::printf("vulkan device: %s\n", ctx->info().name.c_str());
    } catch (const std::exception& e) {
        std::printf("no vulkan: %s\n", e.what());
    }
    std::stringstream ss(presets);
    std::string name;
    while (std::getline(ss, name, ',')) {
        test::SceneOptions so;
        so.preset = name;
        so.size = size;
        so.views = views;
        so.lights = lights;
        so.format = synth::parse_image_format(format);
        so.exposure = exposure;
        so.lambertian = lambertian;
        if (const char* a = std::getenv("SPECULA_BENCH_LIGHT_ANGLES")) { // e.g. "14": the thesis-like ring
            std::stringstream ss(a);
            std::string item;
            while (std::getline(ss, item, ',')) so.light_angles_deg.push_back(std::atof(item.c_str()));
        }
        const test::DiffuseScene scene = test::make_scene(so);
        const LambertInputs in = scene.inputs();
        std::printf("\n== %s %dx%d, %d views x %d lights, %s, exposure %.2f, %s: %zu particles, %zu clipped pixels (scene %.1f s)\n",
                    name.c_str(), size, size, views, lights, format.c_str(), exposure, lambertian ? "lambertian" : "with lobe",
                    scene.particles.particles.size(), scene.clipped_pixels, scene.seconds);
        std::printf("%s", describe(scene.visibility.stats).c_str());
        const auto flat = test::flat_truth(scene, 1.5, 0.004f);
        if (std::getenv("DIFFUSE_DEBUG")) {
            LambertOutputs out = lambert_solve_cpu(in, {});
            std::vector<std::pair<double, std::size_t>> errs;
            std::size_t big_gutter = 0, big = 0;
            for (std::size_t p = 0; p < scene.truth.size(); ++p) {
                if (!(out.particles[p].status & shared::kLambertOk)) continue;
                const glm::vec3 d = out.albedo(p) - scene.truth[p];
                const double e = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
                errs.push_back({e, p});
                if (e > 0.1) { ++big; big_gutter += scene.particles.particles[p].is_gutter(); }
            }
            std::sort(errs.rbegin(), errs.rend());
            std::printf("err > 0.1: %zu (gutter %zu) of %zu; interior %zu gutter %zu\n", big, big_gutter, errs.size(), scene.particles.interior, scene.particles.gutter);
            for (int i = 0; i < 12; ++i) {
                const std::size_t p = errs[std::size_t(i) * errs.size() / 200].second;
                const auto& r = out.particles[p];
                const auto& pa = scene.particles.particles[p];
                const glm::uvec3 t = scene.capture.mesh.triangles[pa.triangle];
                std::printf("e %.3f p %zu gutter %d tri %u bary %.3f %.3f uv0 %.3f %.3f uv1 %.3f %.3f uv2 %.3f %.3f est %.3f %.3f %.3f truth %.3f %.3f %.3f views %u best %u used %u\n",
                    errs[std::size_t(i) * errs.size() / 200].first, p, int(pa.is_gutter()), pa.triangle, pa.bary.x, pa.bary.y,
                    scene.capture.mesh.texcoords[t.x].x, scene.capture.mesh.texcoords[t.x].y, scene.capture.mesh.texcoords[t.y].x, scene.capture.mesh.texcoords[t.y].y,
                    scene.capture.mesh.texcoords[t.z].x, scene.capture.mesh.texcoords[t.z].y,
                    out.albedo(p).x, out.albedo(p).y, out.albedo(p).z, scene.truth[p].x, scene.truth[p].y, scene.truth[p].z, r.views, r.best_view, r.used);
            }
            continue;
        }
        for (LambertMode mode : {LambertMode::Albedo, LambertMode::Photometric}) {
            for (Backend backend : {Backend::Cpu, Backend::Vulkan}) {
                if (backend == Backend::Vulkan && !ctx) continue;
                LambertOptions o;
                o.mode = mode;
                LambertOutputs out = lambert_solve(in, o, backend, ctx.get());
                std::printf("%s / %s: %.3f s wall", to_string(mode), to_string(backend), out.summary.seconds);
                if (out.summary.gpu_ms) std::printf(", GPU %.2f ms (pairs %.2f, combine %.2f)", *out.summary.gpu_ms,
                                                    out.summary.gpu_dispatch_ms[0].second, out.summary.gpu_dispatch_ms[1].second);
                std::printf("\n");
                if (backend == Backend::Cpu) std::printf("%s", describe(out.summary, mode).c_str());
                for (ViewChoice choice : {ViewChoice::BestView, ViewChoice::Robust}) {
                    out.choice = choice;
                    std::vector<std::uint8_t> seen(scene.truth.size()), flat_seen(scene.truth.size());
                    for (std::size_t p = 0; p < seen.size(); ++p) {
                        seen[p] = (out.particles[p].status & shared::kLambertOk) ? 1 : 0;
                        flat_seen[p] = seen[p] && flat[p];
                    }
                    const auto e_all = test::albedo_error(scene, out, seen);
                    const auto e_flat = test::albedo_error(scene, out, flat_seen);
                    const auto e_shadow = test::shadowed_texel_error(scene, out, flat);
                    std::printf("  %-6s RMSE seen %.4f%% (max %.3f, n %zu); flat truth %.4f%% (max %.3f, n %zu); "
                                "flat, shadowed in some frames %.4f%% (signed mean %+.4f%%, n %zu)\n",
                                choice == ViewChoice::BestView ? "best" : "robust", 100 * e_all.rmse, e_all.max_abs, e_all.count,
                                100 * e_flat.rmse, e_flat.max_abs, e_flat.count, 100 * e_shadow.rmse, 100 * e_shadow.signed_mean,
                                e_shadow.count);
                }
            }
        }
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
