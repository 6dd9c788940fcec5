// Frame time of each render mode on the knot_hd preset (204,800 triangles) at 512x512
// and 1024x1024. Run by hand (not a ctest):
//   build/bench/render_bench [frames=10]
// Validation is off here (it costs far more than the rendering). The albedo atlas is a
// real one (build_atlas by surface area, default 4096 budget) filled with the truth, so
// texture access patterns are those of a reconstruction; the factorized mode uses
// constant cube-maps of the sizes the warped parametrization's default rule gives this lobe
// (contents do not change the cost of a lookup), in the warped parametrization (the
// automatic choice: a lookup per channel and the radial factor) and in the thesis's GSHD.
#include "material/factor_param.h"
#include "core/timer.h"
#include "factorization/resolution.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "gpu/context.h"
#include "render/renderer.h"
#include "synth/presets.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace specula;

namespace {

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

CubeMap constant_cube(uint32_t res, float value) {
    return {res, std::vector<glm::vec3>(std::size_t{6} * res * res, glm::vec3(value))};
}

} // namespace

int main(int argc, char** argv) try {
    const int frames = argc > 1 ? std::max(1, std::atoi(argv[1])) : 10;
    Stopwatch setup;
    const synth::Preset preset = synth::make_preset("knot_hd");
    const Atlas atlas = build_atlas(preset.mesh, {});
    const ParticleSet particles = build_particles(preset.mesh, atlas);
    Image albedo(static_cast<int>(atlas.width), static_cast<int>(atlas.height), 3, 0.0f);
    for (const Particle& p : particles.particles) {
        const glm::uvec3 t = preset.mesh.triangles[p.triangle];
        const glm::vec2 uv = (1.0f - p.bary.x - p.bary.y) * preset.mesh.texcoords[t.x] + p.bary.x * preset.mesh.texcoords[t.y] +
                             p.bary.y * preset.mesh.texcoords[t.z];
        const glm::vec3 rho = synth::sample_albedo(preset.material.albedo_texture, uv);
        for (int c = 0; c < 3; ++c) albedo.at(static_cast<int>(p.texel_x()), static_cast<int>(p.texel_y()), c) = rho[c];
    }
    std::printf("knot_hd: %zu triangles, atlas %ux%u (setup %.1f s)\n", preset.mesh.triangles.size(), atlas.width,
                atlas.height, setup.seconds());

    gpu::Context ctx(gpu::ContextOptions{.validation = false});
    std::printf("device: %s\n", ctx.info().name.c_str());
    render::Renderer renderer(ctx, {.mesh = &preset.mesh,
                                    .corner_uv = atlas.corner_uv,
                                    .albedo = &albedo,
                                    .material = {.specular = preset.material.lobe}},
                            {.culling = std::getenv("BENCH_NO_CULLING") != nullptr ? render::Culling::Never
                                                                                    : render::Culling::Auto});
    std::printf("back-face culling: %s (BENCH_NO_CULLING=1 turns it off)\n", renderer.culls_back_faces() ? "on" : "off");
    const LafortuneRgb lobe{preset.material.lobe.cx, preset.material.lobe.cz, preset.material.lobe.n};
    const factorization::FactorizationResolution res = factorization::default_resolution(lobe, FactorParam::Warped);
    const glm::vec4 warp = warp_for_lobe(lobe).value();
    std::printf("factorized: one term, cube faces %u (G) and %u (H)\n", res.cube_g, res.cube_h);

    struct Case {
        const char* name;
        render::Settings settings;
        FactorParam param = FactorParam::Warped;
    };
    const Case cases[] = {
        {"diffuse", {.mode = render::Mode::Diffuse}},
        {"specular (analytic)", {.mode = render::Mode::Specular, .specular = render::SpecularPath::Analytic}},
        {"specular (fact. warped)", {.mode = render::Mode::Specular, .specular = render::SpecularPath::Factorized}},
        {"specular (fact. gshd)", {.mode = render::Mode::Specular, .specular = render::SpecularPath::Factorized},
         FactorParam::Gshd},
        {"both (analytic)", {.mode = render::Mode::Both, .specular = render::SpecularPath::Analytic}},
        {"both (fact. warped)", {.mode = render::Mode::Both, .specular = render::SpecularPath::Factorized}},
        {"both (fact. gshd)", {.mode = render::Mode::Both, .specular = render::SpecularPath::Factorized}, FactorParam::Gshd},
    };
    std::printf("%-10s %-24s %10s %10s %10s %10s %10s %8s\n", "size", "mode", "wall ms", "pass1 ms", "pass2 ms",
                "readback", "fps(wall)", "covered");
    for (const int size : {512, 1024}) {
        const double f = 1.2 * size; // about 45 degrees across
        const Camera cam(Intrinsics{size, size, f, f, 0.5 * size, 0.5 * size},
                         look_at_camera_to_world({1.5, 2.0, 4.5}, {0.0, 0.0, 0.0}, {0.0, 1.0, 0.0}));
        const PointLight light{{3.0, 3.0, 4.0}, {30.0, 30.0, 30.0}};
        for (const Case& c : cases) {
            renderer.set_factorization({.param = c.param,
                                        .warp = c.param == FactorParam::Warped ? warp : glm::vec4(1.0f),
                                        .terms = {{constant_cube(res.cube_g, 0.5f), constant_cube(res.cube_h, 0.5f)}}});
            for (int i = 0; i < 2; ++i) (void)renderer.render(cam, light, c.settings); // warm-up
            std::vector<double> wall, p1, p2, rb;
            std::size_t covered = 0;
            for (int i = 0; i < frames; ++i) {
                const render::Frame fr = renderer.render(cam, light, c.settings);
                wall.push_back(fr.info.wall_ms);
                p1.push_back(fr.info.diffuse_gpu_ms.value_or(0.0));
                p2.push_back(fr.info.specular_gpu_ms.value_or(0.0));
                rb.push_back(fr.info.readback_gpu_ms.value_or(0.0));
                covered = fr.info.covered_pixels;
            }
            const std::string sz = std::to_string(size) + "x" + std::to_string(size);
            std::printf("%-10s %-24s %10.2f %10.2f %10.2f %10.2f %10.1f %8zu\n", sz.c_str(), c.name, median(wall),
                        median(p1), median(p2), median(rb), 1000.0 / median(wall), covered);
        }
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
