// The directed lobe's first bounce on the CPU: the reference and the pipeline's float path (lobe.h).
#include "indirect/lobe.h"

#include "core/error.h"
#include "core/parallel.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <string>
#include <type_traits>
#include <vector>

namespace specula {

namespace {

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

} // namespace

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
    add_lobe<float>(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

void detail::add_directed_lobe_float_unchecked(const IndirectTransfer& t, const shared::MaterialGpu& m,
                                               std::span<const glm::vec3> row_normal,
                                               std::span<const glm::vec4> light_geometry,
                                               std::span<const glm::vec3> intensity, std::uint32_t frames,
                                               std::span<glm::vec4> out, unsigned threads) {
    add_lobe<float>(t, m, row_normal, light_geometry, intensity, frames, out, threads);
}

} // namespace specula
