// Stage driver and error measurement of the factorization (factorization.h).
#include "factorization/factorization.h"

#include "core/error.h"
#include "core/timer.h"

#include <cmath>
#include <limits>
#include <random>

namespace specula::factorization {

const char* to_string(FactorizationBackend backend) noexcept {
    return backend == FactorizationBackend::Cpu ? "cpu" : "vulkan";
}

std::optional<double> FactorizationTimings::gpu_total_ns() const {
    if (!matrix_gpu_ns || !decomposition_g_gpu_ns || !decomposition_h_gpu_ns || !cube_g_gpu_ns || !cube_h_gpu_ns)
        return std::nullopt;
    return *matrix_gpu_ns + *decomposition_g_gpu_ns + *decomposition_h_gpu_ns + *cube_g_gpu_ns + *cube_h_gpu_ns;
}

FactorizationResolution resolve_resolution(const LafortuneRgb& lobe, const FactorizationOptions& o) {
    FactorizationResolution r = default_resolution(lobe);
    std::string forced;
    const auto force = [&](uint32_t value, uint32_t& field, const char* name) {
        if (value == 0) return;
        field = value;
        forced += std::string(forced.empty() ? "" : ", ") + name + " = " + std::to_string(value);
    };
    force(o.grid_h, r.grid_h, "h grid");
    force(o.grid_d, r.grid_d, "d grid");
    if (o.cube_g == 0 && o.grid_h != 0) r.cube_g = cube_res_for_grid(r.grid_h);
    if (o.cube_h == 0 && o.grid_d != 0) r.cube_h = cube_res_for_grid(r.grid_d);
    force(o.cube_g, r.cube_g, "G cube");
    force(o.cube_h, r.cube_h, "H cube");
    if (!forced.empty()) r.reason = "forced: " + forced + "; default rule: " + r.reason;
    return r;
}

Factorization factorize_cpu(const LafortuneRgb& lobe, const FactorizationOptions& options) {
    Factorization f;
    f.resolution = resolve_resolution(lobe, options);
    f.p = options.p;
    f.weighting = options.weighting;
    Stopwatch total;
    Stopwatch step;
    BrdfMatrix m = brdf_matrix_cpu({.lobe = lobe, .res_h = f.resolution.grid_h, .res_d = f.resolution.grid_d});
    f.timings.matrix_s = step.seconds();
    step.restart();
    f.decomposition = normalized_decomposition_cpu({.matrix = &m, .p = options.p, .weighting = options.weighting});
    f.timings.decomposition_s = step.seconds();
    step.restart();
    f.cube_g = cubemaps_cpu({.grid = f.decomposition.g, .grid_res = f.resolution.grid_h, .cube_res = f.resolution.cube_g});
    f.cube_h = cubemaps_cpu({.grid = f.decomposition.h, .grid_res = f.resolution.grid_d, .cube_res = f.resolution.cube_h});
    f.timings.cubemaps_s = step.seconds();
    f.timings.total_s = total.seconds();
    if (options.keep_matrix) f.matrix = std::move(m);
    return f;
}

FactorizeVk::FactorizeVk(gpu::Context& ctx) : m_ctx(&ctx), m_matrix(ctx), m_decomposition(ctx), m_cubemaps(ctx) {}

Factorization FactorizeVk::run(const LafortuneRgb& lobe, const FactorizationOptions& options) {
    Factorization f;
    f.resolution = resolve_resolution(lobe, options);
    f.p = options.p;
    f.weighting = options.weighting;
    const FactorizationResolution& r = f.resolution;
    const BrdfMatrixInputs min{.lobe = lobe, .res_h = r.grid_h, .res_d = r.grid_d};
    brdf_matrix_validate(min);
    if (!(options.p >= 1.0f && options.p <= 64.0f)) throw Error("factorize: p must be in [1, 64]");
    Stopwatch total;
    const std::size_t rows = std::size_t{r.grid_h} * r.grid_h;
    const std::size_t cols = std::size_t{r.grid_d} * r.grid_d;
    const std::size_t texels_g = std::size_t{6} * r.cube_g * r.cube_g;
    const std::size_t texels_h = std::size_t{6} * r.cube_h * r.cube_h;
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, 3 * rows * cols, "factorization F");
    gpu::Buffer g = gpu::Buffer::of<glm::vec3>(*m_ctx, rows, "factorization G grid");
    gpu::Buffer h = gpu::Buffer::of<glm::vec3>(*m_ctx, cols, "factorization H grid");
    gpu::Buffer cube_g = gpu::Buffer::of<glm::vec3>(*m_ctx, texels_g, "factorization G cube-map");
    gpu::Buffer cube_h = gpu::Buffer::of<glm::vec3>(*m_ctx, texels_h, "factorization H cube-map");

    gpu::Sequence seq(*m_ctx, 8);
    m_matrix.record(seq, matrix, min);
    seq.barrier(gpu::Barrier::ComputeToCompute);
    m_decomposition.record(seq, matrix, g, h, r.grid_h, r.grid_d, options.p, options.weighting);
    seq.barrier(gpu::Barrier::ComputeToCompute);
    m_cubemaps.record(seq, g, cube_g, r.grid_h, r.cube_g, "cube_g");
    m_cubemaps.record(seq, h, cube_h, r.grid_d, r.cube_h, "cube_h");
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();

    f.decomposition = Decomposition{.res_h = r.grid_h, .res_d = r.grid_d, .g = g.download<glm::vec3>(rows),
                                    .h = h.download<glm::vec3>(cols)};
    f.cube_g = Cubemap{.res = r.cube_g, .texels = cube_g.download<glm::vec3>(texels_g)};
    f.cube_h = Cubemap{.res = r.cube_h, .texels = cube_h.download<glm::vec3>(texels_h)};
    if (options.keep_matrix)
        f.matrix = BrdfMatrix{.res_h = r.grid_h, .res_d = r.grid_d, .values = matrix.download<float>(3 * rows * cols)};
    f.timings.total_s = total.seconds();
    for (const auto& t : seq.timings()) {
        if (t.label == "brdf_matrix") f.timings.matrix_gpu_ns = t.ns;
        else if (t.label == "decomposition_g") f.timings.decomposition_g_gpu_ns = t.ns;
        else if (t.label == "decomposition_h") f.timings.decomposition_h_gpu_ns = t.ns;
        else if (t.label == "cube_g") f.timings.cube_g_gpu_ns = t.ns;
        else if (t.label == "cube_h") f.timings.cube_h_gpu_ns = t.ns;
    }
    return f;
}

Factorization factorize(const LafortuneRgb& lobe, const FactorizationOptions& options, FactorizationBackend backend,
                        gpu::Context* ctx) {
    if (backend == FactorizationBackend::Cpu) return factorize_cpu(lobe, options);
    if (ctx == nullptr) throw Error("factorize: the Vulkan backend needs a gpu::Context");
    return FactorizeVk(*ctx).run(lobe, options);
}

double matrix_relative_rms(const BrdfMatrix& m, const Decomposition& dec) {
    if (dec.res_h != m.res_h || dec.res_d != m.res_d) throw Error("matrix_relative_rms: resolutions differ");
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    double err = 0.0;
    double ref = 0.0;
    for (uint32_t c = 0; c < 3; ++c)
        for (std::size_t row = 0; row < rows; ++row) {
            const double g = dec.g[row][static_cast<int>(c)];
            const float* f = &m.values[(c * rows + row) * cols];
            for (std::size_t col = 0; col < cols; ++col) {
                if (f[col] < 0.0f) continue;
                const double e = g * dec.h[col][static_cast<int>(c)] - f[col];
                err += e * e;
                ref += static_cast<double>(f[col]) * f[col];
            }
        }
    return ref > 0.0 ? std::sqrt(err / ref) : 0.0;
}

DirectError direct_relative_rms(const LafortuneRgb& lobe, const Decomposition& dec, const Cubemap* cube_g,
                                const Cubemap* cube_h, uint32_t pairs, uint32_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const double two_pi = 6.283185307179586;
    const auto hemisphere = [&] { // uniform in solid angle: z ~ U(0, 1)
        const double z = uni(rng);
        const double phi = two_pi * uni(rng);
        const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
        return glm::dvec3(s * std::cos(phi), s * std::sin(phi), z);
    };
    const bool cubes = cube_g != nullptr && cube_h != nullptr;
    double err_grid = 0.0, err_cube = 0.0, ref = 0.0;
    for (uint32_t i = 0; i < pairs; ++i) {
        const glm::dvec3 u = hemisphere();
        const glm::dvec3 v = hemisphere();
        const shared::f64::GshdCoords c = shared::f64::gshd_from_uv(u, v);
        const glm::dvec3 gg = grid_sample(dec.g, dec.res_h, c.h) * grid_sample(dec.h, dec.res_d, c.d);
        glm::dvec3 gc(0.0);
        if (cubes) gc = cubemap_sample(*cube_g, c.h) * cubemap_sample(*cube_h, c.d);
        for (int k = 0; k < 3; ++k) {
            const double f = std::min<double>(lafortune_eval_f64(lobe.cx[k], lobe.cz[k], lobe.n[k], u, v), shared::kGshdMaxValue);
            ref += f * f;
            err_grid += (gg[k] - f) * (gg[k] - f);
            err_cube += (gc[k] - f) * (gc[k] - f);
        }
    }
    DirectError out;
    out.pairs = pairs;
    out.grid = ref > 0.0 ? std::sqrt(err_grid / ref) : 0.0;
    out.cube = !cubes ? std::numeric_limits<double>::quiet_NaN() : ref > 0.0 ? std::sqrt(err_cube / ref) : 0.0;
    return out;
}

} // namespace specula::factorization
