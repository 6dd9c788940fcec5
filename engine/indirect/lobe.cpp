// The directed lobe's first bounce on the CPU: the reference and the pipeline's float path (lobe.h).
#include "indirect/lobe.h"

#include "core/error.h"
#include "core/parallel.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#if defined(__x86_64__) && defined(__GLIBC__)
#include <immintrin.h>
#define SPECULA_LOBE_SIMD 1
// glibc's vector math library (libmvec): logf and expf on 8 floats, in the x86-64 vector
// function ABI's AVX2 variant.
extern "C" __m256 _ZGVdN8v_logf(__m256);
extern "C" __m256 _ZGVdN8v_expf(__m256);
#endif

namespace specula {

namespace {

bool simd_supported() {
#ifdef SPECULA_LOBE_SIMD
    __builtin_cpu_init(); // before main: the processor's features may not be read yet
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return false;
#endif
}
std::atomic<bool> g_simd{simd_supported()};

// Rows per chunk of the parallel loop: a row costs entries x frames evaluations of the lobe
// (a power per channel, or the coating's microfacet terms), so chunks stay short.
constexpr std::size_t kRowsPerChunk = 256;

// Both paths: Real (float or double) is the type every term is computed and summed in.
template <typename Real>
void add_lobe(const IndirectTransfer& t, const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
              std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity, std::uint32_t frames,
              std::span<glm::vec4> out, unsigned threads) {
    using Vec = glm::vec<3, Real>;
    const std::size_t n = t.rows;
    parallel_for_chunks(n, std::max(threads, 1u), kRowsPerChunk, [&](unsigned, std::size_t begin, std::size_t end) {
        std::vector<Vec> sum(frames);
        for (std::size_t i = begin; i < end; ++i) {
            std::fill(sum.begin(), sum.end(), Vec(0));
            for (std::uint32_t k = t.row_begin[i]; k < t.row_begin[i + 1]; ++k) {
                if (k + detail::kPrefetchAhead < t.entries.size())
                    detail::prefetch(&light_geometry[std::size_t{t.entries[k + detail::kPrefetchAhead].source} * frames],
                                     frames * sizeof(glm::vec4));
                const glm::vec4 v = t.entry_direction[k];
                if (!(v.w > 0.0f)) continue; // leaves the source from under its surface
                const std::size_t j = t.entries[k].source;
                const Real w = glm::pi<Real>() * static_cast<Real>(t.entries[k].weight);
                const Vec normal(row_normal[j]);
                for (std::size_t f = 0; f < frames; ++f) {
                    const glm::vec4 l = light_geometry[j * frames + f];
                    if (!(l.w > 0.0f)) continue; // no particle of the source is lit
                    const Vec u = Vec(glm::vec3(l));
                    const Real ci = glm::dot(normal, u);
                    if (!(ci > Real(0))) continue; // the light is behind the source
                    const Real cuv = glm::dot(u, Vec(glm::vec3(v)));
                    Vec fs;
                    if constexpr (std::is_same_v<Real, double>) fs = shared::f64::material_specular(m, ci, Real(v.w), cuv);
                    else fs = shared::material_specular(m, ci, v.w, cuv);
                    sum[f] += (w * static_cast<Real>(l.w)) * glm::max(fs, Vec(0)) * Vec(intensity[f]);
                }
            }
            for (std::size_t f = 0; f < frames; ++f) {
                glm::vec4& o = out[f * n + i];
                // The float path adds its float sum (the kernel's arithmetic); the reference rounds once.
                if constexpr (std::is_same_v<Real, double>) o = glm::vec4(glm::vec3(glm::dvec3(glm::vec3(o)) + sum[f]), o.w);
                else o += glm::vec4(sum[f], 0.0f);
            }
        }
    });
}

#ifdef SPECULA_LOBE_SIMD
// The lafortune family's term in float, 8 frames at a time: the scalar path's arithmetic
// (ci = N.u, material_specular's a = u.v - ci co, b = ci co, base = Cx a + Cz b; (w g) f_s I,
// summed in entry order per frame), with base^N as exp(N log base).
struct LafortuneSimd {
    // 8 frames of one source row: u and the geometry g, 0 where the term is zero (unlit, or not
    // finite; the light behind the source is found from ci) and in the padding. 128 bytes, as
    // many as the 8 frames' light_geometry: an entry reads two cache lines per 8 frames.
    struct alignas(64) Group {
        float ux[8], uy[8], uz[8], g[8];
    };
    std::uint32_t groups = 0;        // frames / 8, rounded up
    std::vector<Group> light;        // row r's groups at r * groups
    std::vector<float> intensity[3]; // per channel, lanes() frames
    [[nodiscard]] std::size_t lanes() const { return std::size_t{groups} * 8; }

    LafortuneSimd(std::size_t rows, std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensities,
                  std::uint32_t frames)
        : groups((frames + 7u) / 8u), light(rows * groups, Group{}) {
        for (std::size_t r = 0; r < rows; ++r)
            for (std::size_t f = 0; f < frames; ++f) {
                const glm::vec4 l = light_geometry[r * frames + f];
                Group& q = light[r * groups + f / 8];
                const std::size_t lane = f % 8;
                const bool finite = std::isfinite(l.x + l.y + l.z + l.w);
                q.ux[lane] = finite ? l.x : 0.0f, q.uy[lane] = finite ? l.y : 0.0f, q.uz[lane] = finite ? l.z : 0.0f;
                q.g[lane] = finite && l.w > 0.0f ? l.w : 0.0f; // the scalar path's skip of unlit sources
            }
        for (int c = 0; c < 3; ++c) {
            intensity[c].assign(lanes(), 0.0f);
            for (std::size_t f = 0; f < frames; ++f) intensity[c][f] = intensities[f][c];
        }
    }
};

// One row's sums, `sum` holding 3 x lanes() floats (r, g, b), zeroed by the caller.
__attribute__((target("avx2,fma"))) void lafortune_row_simd(const LafortuneSimd& d, const IndirectTransfer& t,
                                                             const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
                                                             std::size_t row, float* sum) {
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
    const __m256 lowest = _mm256_set1_ps(std::log(std::numeric_limits<float>::min())); // -87.3
    const __m256 cx[3] = {_mm256_set1_ps(m.a.x), _mm256_set1_ps(m.a.y), _mm256_set1_ps(m.a.z)};
    const __m256 cz[3] = {_mm256_set1_ps(m.b.x), _mm256_set1_ps(m.b.y), _mm256_set1_ps(m.b.z)};
    const __m256 n[3] = {_mm256_set1_ps(m.c.x), _mm256_set1_ps(m.c.y), _mm256_set1_ps(m.c.z)};
    const std::size_t lanes = d.lanes();
    for (std::uint32_t k = t.row_begin[row]; k < t.row_begin[row + 1]; ++k) {
        if (k + detail::kPrefetchAhead < t.entries.size())
            detail::prefetch(&d.light[std::size_t{t.entries[k + detail::kPrefetchAhead].source} * d.groups],
                             d.groups * sizeof(LafortuneSimd::Group));
        const glm::vec4 v = t.entry_direction[k];
        if (!(v.w > 0.0f)) continue; // leaves the source from under its surface
        const std::uint32_t j = t.entries[k].source;
        const __m256 w = _mm256_set1_ps(glm::pi<float>() * t.entries[k].weight);
        const __m256 vx = _mm256_set1_ps(v.x), vy = _mm256_set1_ps(v.y), vz = _mm256_set1_ps(v.z), co = _mm256_set1_ps(v.w);
        const __m256 nx = _mm256_set1_ps(row_normal[j].x), ny = _mm256_set1_ps(row_normal[j].y),
                     nz = _mm256_set1_ps(row_normal[j].z);
        const LafortuneSimd::Group* q = &d.light[std::size_t{j} * d.groups];
        for (std::uint32_t group = 0; group < d.groups; ++group, ++q) {
            const __m256 g = _mm256_load_ps(q->g);
            const __m256 ux = _mm256_load_ps(q->ux), uy = _mm256_load_ps(q->uy), uz = _mm256_load_ps(q->uz);
            const __m256 ci = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(nx, ux), _mm256_mul_ps(ny, uy)), _mm256_mul_ps(nz, uz));
            const __m256 wg = _mm256_mul_ps(w, g);
            const __m256 live = _mm256_and_ps(_mm256_cmp_ps(wg, zero, _CMP_GT_OQ), _mm256_cmp_ps(ci, zero, _CMP_GT_OQ));
            if (_mm256_movemask_ps(live) == 0) continue;
            const __m256 cuv = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ux, vx), _mm256_mul_ps(uy, vy)), _mm256_mul_ps(uz, vz));
            const __m256 b = _mm256_mul_ps(ci, co);
            const __m256 a = _mm256_sub_ps(cuv, b);
            for (int c = 0; c < 3; ++c) {
                const __m256 base = _mm256_add_ps(_mm256_mul_ps(cx[c], a), _mm256_mul_ps(cz[c], b));
                const __m256 on = _mm256_and_ps(live, _mm256_cmp_ps(base, zero, _CMP_GT_OQ));
                if (_mm256_movemask_ps(on) == 0) continue;
                // Lanes off, and powers under float's smallest normal (the scalar path's denormals),
                // take exp(0) and are masked: libmvec's expf leaves its vector path for a vector
                // with a lane out of its range (measured: with those lanes in, the 8-wide path was
                // slower than one frame at a time).
                const __m256 x = _mm256_mul_ps(n[c], _ZGVdN8v_logf(_mm256_blendv_ps(one, base, on)));
                const __m256 normal = _mm256_and_ps(on, _mm256_cmp_ps(x, lowest, _CMP_GE_OQ));
                const __m256 fs = _ZGVdN8v_expf(_mm256_and_ps(x, normal));
                const std::size_t at = std::size_t{group} * 8;
                const __m256 term = _mm256_mul_ps(_mm256_mul_ps(wg, fs), _mm256_loadu_ps(&d.intensity[c][at]));
                float* s = sum + static_cast<std::size_t>(c) * lanes + at;
                _mm256_storeu_ps(s, _mm256_add_ps(_mm256_loadu_ps(s), _mm256_and_ps(normal, term)));
            }
        }
    }
}

void add_lafortune_simd(const IndirectTransfer& t, const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
                        std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity, std::uint32_t frames,
                        std::span<glm::vec4> out, unsigned threads) {
    const std::size_t n = t.rows;
    const LafortuneSimd d(n, light_geometry, intensity, frames);
    const std::size_t lanes = d.lanes();
    parallel_for_chunks(n, std::max(threads, 1u), kRowsPerChunk, [&](unsigned, std::size_t begin, std::size_t end) {
        std::vector<float> sum(3 * lanes);
        for (std::size_t i = begin; i < end; ++i) {
            std::fill(sum.begin(), sum.end(), 0.0f);
            lafortune_row_simd(d, t, m, row_normal, i, sum.data());
            for (std::size_t f = 0; f < frames; ++f) out[f * n + i] += glm::vec4(sum[f], sum[lanes + f], sum[2 * lanes + f], 0.0f);
        }
    });
}
#endif

// The float path: the lafortune family 8 frames at a time where lobe_simd() says so.
void add_lobe_float(const IndirectTransfer& t, const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
                    std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity, std::uint32_t frames,
                    std::span<glm::vec4> out, unsigned threads) {
#ifdef SPECULA_LOBE_SIMD
    if (m.family.x == shared::kMaterialLafortune && detail::lobe_simd()) {
        add_lafortune_simd(t, m, row_normal, light_geometry, intensity, frames, out, threads);
        return;
    }
#endif
    add_lobe<float>(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

} // namespace

bool detail::lobe_simd() { return g_simd.load(std::memory_order_relaxed); }

void detail::set_lobe_simd(bool on) { g_simd.store(on && simd_supported(), std::memory_order_relaxed); }

void validate_directed_lobe(const IndirectTransfer& t, std::size_t row_normals, std::size_t light_geometry,
                            std::size_t intensities, std::uint32_t frames, std::size_t out_values, const char* who) {
    validate_transfer(t);
    const auto refuse = [&](const std::string& what) { throw Error(std::string(who) + ": " + what); };
    if (t.entry_direction.size() != t.entries.size())
        refuse("the transfer keeps no entry directions (" + std::to_string(t.entry_direction.size()) + " for " +
               std::to_string(t.entries.size()) + " entries): build it with them for the directed lobe");
    const std::size_t values = std::size_t{frames} * t.rows;
    if (row_normals != t.rows)
        refuse("row_normal holds " + std::to_string(row_normals) + " values, the transfer has " + std::to_string(t.rows) +
               " rows");
    if (light_geometry != values)
        refuse("light_geometry holds " + std::to_string(light_geometry) + " values, " + std::to_string(t.rows) + " rows x " +
               std::to_string(frames) + " frames need " + std::to_string(values));
    if (intensities != frames)
        refuse("intensity holds " + std::to_string(intensities) + " values for " + std::to_string(frames) + " frames");
    if (out_values != values)
        refuse("out holds " + std::to_string(out_values) + " values, " + std::to_string(frames) + " frames x " +
               std::to_string(t.rows) + " rows need " + std::to_string(values));
}

void add_directed_lobe_cpu(const IndirectTransfer& t, const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
                           std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity,
                           std::uint32_t frames, std::span<glm::vec4> out, unsigned threads) {
    validate_directed_lobe(t, row_normal.size(), light_geometry.size(), intensity.size(), frames, out.size(),
                           "add_directed_lobe_cpu");
    add_lobe<double>(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

void add_directed_lobe_float(const IndirectTransfer& t, const shared::MaterialGpu& m, std::span<const glm::vec3> row_normal,
                             std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity,
                             std::uint32_t frames, std::span<glm::vec4> out, unsigned threads) {
    validate_directed_lobe(t, row_normal.size(), light_geometry.size(), intensity.size(), frames, out.size(),
                           "add_directed_lobe_float");
    add_lobe_float(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

void detail::add_directed_lobe_float_unchecked(const IndirectTransfer& t, const shared::MaterialGpu& m,
                                               std::span<const glm::vec3> row_normal,
                                               std::span<const glm::vec4> light_geometry,
                                               std::span<const glm::vec3> intensity, std::uint32_t frames,
                                               std::span<glm::vec4> out, unsigned threads) {
    add_lobe_float(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

} // namespace specula
