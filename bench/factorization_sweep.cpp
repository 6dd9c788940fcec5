// Factorization sweep (not a test): approximation error and time against grid and
// cube-map resolution for the thesis's four lobes (table 5.2) and a near-mirror lobe.
//   factorization_sweep [--quick] [--pairs N] [--terms [--grid R] [--grid-d R_d]] [--warped] [--cpu] [--lobe NAME]
// --warped: only the warped parametrization's table (shared/gshd.h part 5: one term, h 16),
// error and time against the d grid and the H cube-map's resolution.
// Errors: "matrix" = relative RMS of G H against F over the valid entries; "direct" =
// relative RMS of G(h) H(d) against the lobe for uniformly random (u, v) pairs, with G and H
// interpolated from the grids ("grid") or from the cube-maps ("cube"). Times: the CPU
// reference (wall), the Vulkan path (wall, including upload/readback) and the sum of its
// dispatches' GPU timestamps. Run with SPECULA_VALIDATION=0 for meaningful Vulkan times.
#include "factorization/factorization.h"
#include "vulkan_env.h"

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

using namespace specula;
using namespace specula::factorization;

namespace {

struct NamedLobe {
    const char* name;
    LafortuneRgb lobe;
};

LafortuneRgb gray(float cx, float cz, float n) { return {glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; }

std::string ms(std::optional<double> ns) {
    if (!ns) return "n/a";
    char b[32];
    std::snprintf(b, sizeof b, "%.2f", *ns * 1e-6);
    return b;
}

} // namespace

int main(int argc, char** argv) try {
    bool quick = false;
    bool terms_only = false;
    bool cpu_only = false;
    bool warped_only = false;
    uint32_t iterations = kResidualIterations;
    uint32_t grid = 0;   // 0: default resolutions
    uint32_t grid_d = 0; // --terms: the d grid, when not --grid's
    std::string only;    // --lobe NAME: that lobe only
    uint32_t pairs = 1u << 20;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--quick") == 0) quick = true;
        else if (std::strcmp(argv[i], "--terms") == 0) terms_only = true;
        else if (std::strcmp(argv[i], "--iterations") == 0 && i + 1 < argc) iterations = static_cast<uint32_t>(std::stoul(argv[++i]));
        else if (std::strcmp(argv[i], "--grid") == 0 && i + 1 < argc) grid = static_cast<uint32_t>(std::stoul(argv[++i]));
        else if (std::strcmp(argv[i], "--grid-d") == 0 && i + 1 < argc) grid_d = static_cast<uint32_t>(std::stoul(argv[++i]));
        else if (std::strcmp(argv[i], "--lobe") == 0 && i + 1 < argc) only = argv[++i];
        else if (std::strcmp(argv[i], "--cpu") == 0) cpu_only = true;
        else if (std::strcmp(argv[i], "--warped") == 0) warped_only = true;
        else if (std::strcmp(argv[i], "--pairs") == 0 && i + 1 < argc) pairs = static_cast<uint32_t>(std::stoul(argv[++i]));
    }
    std::vector<NamedLobe> lobes = {
        {"pepsi", gray(-0.8962f, 0.7587f, 10.11f)},
        {"cologne", gray(-0.8874f, 1.1162f, 18.09f)},
        {"vase", gray(-1.2127f, 0.5653f, 20.36f)},
        {"woodenpot", gray(-1.4299f, -0.7763f, 9.74f)},
        {"mirror", gray(-1.0f, 1.0f, 1000.0f)},
        {"mirror300", gray(-1.0f, 1.0f, 300.0f)},
        {"phong", gray(-1.0f, 1.0f, 10.0f)}, // Cx = -Cz: rank 1 mirrored
        {"retro", gray(1.0f, 1.0f, 10.0f)},  // Cx = +Cz: rank 1 plain
    };
    if (!only.empty())
        std::erase_if(lobes, [&](const NamedLobe& l) { return only != l.name; });
    gpu::Context* ctx = test::vulkan_context();
    std::optional<FactorizeVk> vk;
    if (ctx && !cpu_only) {
        vk.emplace(*ctx);
        std::printf("Vulkan device: %s (validation %s)\n", ctx->info().name.c_str(), ctx->validation_enabled() ? "on" : "off");
    } else {
        std::printf("no Vulkan device: %s\n", test::vulkan_unavailable_reason().c_str());
    }
    std::printf("direct error over %u random (u, v) pairs\n\n", pairs);

    // One factorization on the CPU with its direct error, and the Vulkan path's wall time and
    // GPU time (all dispatches, or the residual terms' only).
    struct Measured {
        Factorization c;
        DirectError ed;
        std::string vk_ms = "n/a", vk_gpu = "n/a";
    };
    const auto measure = [&](const LafortuneRgb& lobe, const FactorizationOptions& o, bool residual_gpu) {
        Measured m{.c = factorize_cpu(lobe, o), .ed = {}};
        m.ed = direct_relative_rms(lobe, m.c, 0, pairs);
        if (vk) {
            const Factorization g = vk->run(lobe, o);
            m.vk_ms = ms(g.timings.total_s * 1e9);
            m.vk_gpu = ms(residual_gpu ? g.timings.residual_gpu_ns : g.timings.gpu_total_ns());
        }
        return m;
    };

    // The warped parametrization: F is rank 1 per channel, so the error is H's interpolation
    // along d (the grid, then the cube-map) and the time is F's size (3 R_h^2 R_d^2 floats).
    std::printf("## Warped parametrization: error and time against the d grid and H cube-map (R_h = 16, K = 1)\n\n");
    std::printf("| lobe | R_d | H cube | matrix rel RMS | direct (grid) | direct (cube) | cpu ms | vulkan ms | vulkan gpu ms |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& l : lobes) {
        if (!warp_for_lobe(l.lobe)) continue;
        const FactorizationResolution def = default_resolution(l.lobe, FactorParam::Warped);
        for (const uint32_t rd : {32u, 64u, def.grid_d, 128u})
            for (const uint32_t cube : {0u, 2 * cube_res_for_grid(rd)}) {
                const FactorizationOptions o{.grid_h = 16, .grid_d = rd, .cube_h = cube, .keep_matrix = true, .terms = 1,
                                             .param = FactorParam::Warped};
                const Measured m = measure(l.lobe, o, false);
                std::printf("| %s | %u%s | %u | %.2g | %.4f | %.4f | %.1f | %s | %s |\n", l.name, rd,
                            rd == def.grid_d ? " (default)" : "", m.c.resolution.cube_h, m.c.terms.matrix_rms.back(),
                            m.ed.grid, m.ed.cube, m.c.timings.total_s * 1e3, m.vk_ms.c_str(), m.vk_gpu.c_str());
                std::fflush(stdout);
            }
    }
    if (warped_only) return 0;
    std::printf("\n");

    // Issue 5: error against the number of separable terms K, default resolutions.
    // Every parametrization (shared/gshd.h parts 4, 5), then the automatic choice's reason.
    std::printf("## Error against the number of terms K (grid %u, 0 = default resolutions; %u iterations)\n\n", grid, iterations);
    std::printf("| lobe | param | R_h | R_d | K | matrix rel RMS | direct (grid) | direct (cube) | cpu ms | vulkan ms | vulkan residual gpu ms |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& l : lobes) {
        for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored, FactorParam::Warped})
        for (uint32_t k = 1; k <= kMaxFactorTerms; ++k) {
            if (param == FactorParam::Warped && (k > 1 || !warp_for_lobe(l.lobe))) continue; // one term: rank 1
            const FactorizationOptions o{.grid_h = grid, .grid_d = grid_d ? grid_d : grid, .keep_matrix = true, .terms = k, .iterations = iterations,
                                         .param = param};
            const Measured m = measure(l.lobe, o, true);
            const Factorization& c = m.c;
            const DirectError& ed = m.ed;
            const std::string& vk_ms = m.vk_ms;
            const std::string& vk_gpu = m.vk_gpu;
            std::printf("| %s | %s | %u | %u | %u | %.4f | %.4f | %.4f | %.1f | %s | %s |\n", l.name, to_string(param), c.resolution.grid_h,
                        c.resolution.grid_d, k, c.terms.matrix_rms.back(), ed.grid, ed.cube, c.timings.total_s * 1e3,
                        vk_ms.c_str(), vk_gpu.c_str());
            std::fflush(stdout);
        }
        const Factorization a = factorize_cpu(l.lobe, {.grid_h = grid, .grid_d = grid_d ? grid_d : grid, .iterations = iterations});
        std::printf("| %s | %s | | | auto: %s; %s | | | | | | |\n", l.name, to_string(a.cubes.param), a.terms.reason.c_str(),
                    a.param_choice.reason.c_str());
    }
    if (terms_only) return 0;

    const std::vector<uint32_t> grids = quick ? std::vector<uint32_t>{8, 16, 32} : std::vector<uint32_t>{8, 16, 24, 32, 48};
    std::printf("## Error and time against grid resolution (R_h = R_d = R, cube faces from the rule), p = 2\n\n");
    std::printf("| lobe | R | cube | matrix rel RMS | direct (grid) | direct (cube) | cpu ms | vulkan ms | vulkan gpu ms |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& l : lobes) {
        for (uint32_t r : grids) {
            const FactorizationOptions o{.grid_h = r, .grid_d = r, .keep_matrix = true};
            const Factorization c = factorize_cpu(l.lobe, o);
            const double em = matrix_relative_rms(*c.matrix, c.grids[0]);
            const DirectError ed = direct_relative_rms(l.lobe, c.grids[0], &c.cubes.terms[0].g, &c.cubes.terms[0].h, pairs);
            std::string vk_ms = "n/a", vk_gpu = "n/a";
            if (vk) {
                const Factorization g = vk->run(l.lobe, {.grid_h = r, .grid_d = r});
                vk_ms = ms(g.timings.total_s * 1e9);
                vk_gpu = ms(g.timings.gpu_total_ns());
            }
            std::printf("| %s | %u | %u | %.4f | %.4f | %.4f | %.1f | %s | %s |\n", l.name, r, c.resolution.cube_g, em,
                        ed.grid, ed.cube, c.timings.total_s * 1e3, vk_ms.c_str(), vk_gpu.c_str());
            std::fflush(stdout);
        }
    }

    const uint32_t fixed = 32;
    const std::vector<uint32_t> cubes = quick ? std::vector<uint32_t>{8, 32, 128} : std::vector<uint32_t>{8, 16, 32, 64, 128};
    std::printf("\n## Direct error against cube-map resolution (grid R = %u), p = 2\n\n", fixed);
    std::printf("| lobe | cube | direct (grid) | direct (cube) | cpu cube ms | vulkan cube gpu ms |\n|---|---|---|---|---|---|\n");
    for (const auto& l : lobes) {
        for (uint32_t cr : cubes) {
            const FactorizationOptions o{.grid_h = fixed, .grid_d = fixed, .cube_g = cr, .cube_h = cr};
            const Factorization c = factorize_cpu(l.lobe, o);
            const DirectError ed = direct_relative_rms(l.lobe, c.grids[0], &c.cubes.terms[0].g, &c.cubes.terms[0].h, pairs);
            std::string gpu = "n/a";
            if (vk) {
                const Factorization g = vk->run(l.lobe, o);
                if (g.timings.cube_g_gpu_ns && g.timings.cube_h_gpu_ns)
                    gpu = ms(*g.timings.cube_g_gpu_ns + *g.timings.cube_h_gpu_ns);
            }
            std::printf("| %s | %u | %.4f | %.4f | %.2f | %s |\n", l.name, cr, ed.grid, ed.cube, c.timings.cubemaps_s * 1e3,
                        gpu.c_str());
            std::fflush(stdout);
        }
    }

    std::printf("\n## p and H weighting of the normalized decomposition (R = %u)\n\n| lobe | p | weighting | matrix rel RMS | direct (grid) |\n|---|---|---|---|---|\n", fixed);
    for (const auto& l : lobes)
        for (auto w : {DecompositionWeighting::Uniform, DecompositionWeighting::Energy})
            for (float p : {1.0f, 2.0f, 4.0f}) {
                const Factorization c =
                    factorize_cpu(l.lobe, {.grid_h = fixed, .grid_d = fixed, .p = p, .weighting = w, .keep_matrix = true});
                const DirectError ed = direct_relative_rms(l.lobe, c.grids[0], nullptr, nullptr, pairs);
                std::printf("| %s | %g | %s | %.4f | %.4f |\n", l.name, p, to_string(w),
                            matrix_relative_rms(*c.matrix, c.grids[0]), ed.grid);
                std::fflush(stdout);
            }

    std::printf("\n## Default resolution rule\n\n| lobe | R_h | R_d | cube G | cube H | matrix | direct (grid) | direct (cube) | cpu ms | vulkan gpu ms |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& l : lobes) {
        const Factorization c = factorize_cpu(l.lobe, {.keep_matrix = true});
        const DirectError ed = direct_relative_rms(l.lobe, c.grids[0], &c.cubes.terms[0].g, &c.cubes.terms[0].h, pairs);
        std::string gpu = "n/a";
        if (vk) gpu = ms(vk->run(l.lobe, {}).timings.gpu_total_ns());
        const auto& r = c.resolution;
        std::printf("| %s | %u | %u | %u | %u | %.4f | %.4f | %.4f | %.1f | %s |\n", l.name, r.grid_h, r.grid_d, r.cube_g,
                    r.cube_h, matrix_relative_rms(*c.matrix, c.grids[0]), ed.grid, ed.cube, c.timings.total_s * 1e3,
                    gpu.c_str());
    }
    for (const auto& l : lobes) std::printf("\n%s: %s", l.name, default_resolution(l.lobe).reason.c_str());
    std::printf("\n");
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
