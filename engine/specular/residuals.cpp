// Residual samples: backend dispatch, conversion for the fit, and the energy test.
#include "specular/residuals.h"

#include "specular/coated_fit.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>

namespace specula {

ResidualSamples residual_samples(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& options,
                                 Backend backend, gpu::Context* ctx) {
    if (backend == Backend::Cpu) return residual_samples_cpu(in, diffuse, options);
    if (ctx == nullptr) throw UsageError("residual_samples: the Vulkan backend needs a gpu::Context");
    ResidualsVk kernel(*ctx);
    ResidualSamples rs = kernel.run(in, diffuse, options);
    rs.energy = {};
    for (const ResidualSample& s : rs.samples)
        if (s.status == shared::kResidualUsed) rs.energy.add(s.f, s.v.w);
    thin_for_fit(rs.samples, options.fit_samples); // the C++ pass makes only these
    return rs;
}

ResidualScore residual_mean_square_error(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& options,
                                        const SpecularModel& model, Backend backend, gpu::Context* ctx) {
    if (backend == Backend::Cpu) return residual_mean_square_error_cpu(in, diffuse, options, model);
    const ResidualSamples rs = residual_samples(in, diffuse, options, backend, ctx);
    return {.mean_square = material_mean_square_error(model, rs.samples), .counts = rs.counts, .seconds = rs.seconds};
}

void thin_for_fit(std::vector<ResidualSample>& samples, std::size_t max_samples) {
    if (max_samples == 0) return;
    const std::size_t stride = used_sample_stride(samples, max_samples);
    std::size_t kept = 0, used = 0;
    for (const ResidualSample& s : samples)
        if (s.status == shared::kResidualUsed && used++ % stride == 0) samples[kept++] = s;
    samples.resize(kept);
    samples.shrink_to_fit();
}

bool residual_particle_usable(const LambertParticleResult& r, const ResidualOptions& o) {
    if (!(r.status & shared::kLambertOk)) return false;
    if (o.drop_view_outliers && (r.status & shared::kLambertViewsRejected)) return false;
    if (o.max_albedo_spread < 0.0f) return true;
    const glm::vec3 a(r.albedo_best), b(r.albedo_robust);
    const glm::vec3 d = glm::abs(a - b);
    return d.x + d.y + d.z <= o.max_albedo_spread * (a.x + a.y + a.z);
}

std::uint64_t residual_keep_stride(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o,
                                   std::uint64_t* lit_slots) {
    if (lit_slots != nullptr) *lit_slots = 0;
    if ((o.max_kept_samples == 0 && lit_slots == nullptr) || in.visibility == nullptr) return 1;
    const Visibility& vis = *in.visibility;
    std::uint64_t lit = 0;
    for (std::uint32_t p = 0; p < in.particles.size() && p < diffuse.particles.size(); ++p) {
        if (!residual_particle_usable(diffuse.particles[p], o)) continue;
        for (std::uint32_t v = 0; v < in.views.size(); ++v) {
            if (!vis.sees(p, v)) continue;
            for (std::uint32_t f : in.views[v].frames) lit += vis.lights(p, f) ? 1u : 0u;
        }
    }
    if (lit_slots != nullptr) *lit_slots = lit;
    if (o.max_kept_samples == 0) return 1;
    return std::max<std::uint64_t>(1, (lit + o.max_kept_samples - 1) / o.max_kept_samples);
}

std::size_t used_sample_stride(std::size_t used, std::size_t max_samples) {
    return max_samples != 0 && used > max_samples ? (used + max_samples - 1) / max_samples : 1;
}

std::size_t used_sample_stride(std::span<const ResidualSample> samples, std::size_t max_samples) {
    if (max_samples == 0) return 1;
    return used_sample_stride(static_cast<std::size_t>(std::count_if(samples.begin(), samples.end(), [](const ResidualSample& s) {
                                  return s.status == shared::kResidualUsed;
                              })),
                              max_samples);
}

std::vector<LafortuneSample> to_lafortune_samples(std::span<const ResidualSample> samples, std::size_t max_samples) {
    const std::size_t stride = used_sample_stride(samples, max_samples);
    std::vector<LafortuneSample> out;
    out.reserve(samples.size() / stride + 1);
    std::size_t k = 0;
    for (const ResidualSample& s : samples) {
        if (s.status != shared::kResidualUsed || k++ % stride != 0) continue;
        out.push_back({.u = glm::vec3(s.u), .v = glm::vec3(s.v), .f = s.f, .weight = s.u.w});
    }
    return out;
}

ResidualEnergy residual_energy(std::span<const ResidualSample> samples, double noise_sigma, double threshold) {
    ResidualEnergySums sums;
    for (const ResidualSample& s : samples)
        if (s.status == shared::kResidualUsed) sums.add(s.f, s.v.w);
    return residual_energy(sums, noise_sigma, threshold);
}

ResidualEnergy residual_energy(const ResidualEnergySums& sums, double noise_sigma, double threshold) {
    ResidualEnergy e;
    e.noise_sigma = noise_sigma;
    e.threshold = threshold;
    const std::uint64_t n = sums.samples;
    if (n == 0) return e;
    e.mean_square = sums.square / (3.0 * static_cast<double>(n));
    e.mean = sums.sum / (3.0 * static_cast<double>(n));
    // Floor the noise at one 16-bit step so noise-free captures still compare against quantization.
    const double sigma = std::max(noise_sigma, 1.0 / 65535.0);
    e.ratio = e.mean_square / (sigma * sigma);
    e.has_specular = e.ratio > threshold;
    return e;
}

} // namespace specula
