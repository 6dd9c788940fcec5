// Reference of the residual samples: the method of shared/residuals.h, step for step as
// shaders/specular/residuals.comp does it, in double (the bilinear taps through the shared
// helpers instantiated in double, shared::f64), rounded to the float layout at the end.
// Inputs the GPU gets in float (camera, lights, rho/pi) are rounded to float first.
#include "specular/residuals.h"

#include "core/error.h"
#include "core/parallel.h"
#include "diffuse/lambert_solve_detail.h"
#include "diffuse/view_batches.h"
#include "core/timer.h"
#include "shared/prelude.h"
#include "shared/tangent_frame.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace specula {

namespace {

namespace f64 = shared::f64;

} // namespace

ResidualSamples residual_samples_cpu(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o,
                                     std::vector<std::uint32_t>* sample_particle) {
    if (sample_particle != nullptr) sample_particle->clear();
    const Stopwatch sw;
    lambert_validate(in);
    if (diffuse.particles.size() != in.particles.size())
        throw Error("residual_samples: the diffuse solution has " + std::to_string(diffuse.particles.size()) +
                    " particles, the inputs " + std::to_string(in.particles.size()));
    const Visibility& vis = *in.visibility;
    ResidualSamples out;
    ResidualCounts& cnt = out.counts;
    const double min_cos = static_cast<double>(o.min_light_cos);
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const shared::MaterialGpu known = material_gpu(o.material);
    std::uint64_t lit = 0;
    out.keep_stride = residual_keep_stride(in, diffuse, o, &lit);
    // Room for every lit slot's sample, an upper bound: pages never written take no memory,
    // where doubling growth copied the samples and held up to three times them at once.
    out.samples.reserve(static_cast<std::size_t>(lit / out.keep_stride + 1));
    if (sample_particle != nullptr) sample_particle->reserve(static_cast<std::size_t>(lit / out.keep_stride + 1));
    // Each view's particles are cut into fixed chunks that the workers share; a chunk keeps
    // every used sample it finds, and the chunks are then taken in order, every keep_stride-th
    // sample kept: the slot order of one serial loop, whatever the thread count.
    constexpr std::size_t kChunk = 2048;
    struct Chunk {
        ResidualCounts counts;
        std::vector<ResidualSample> samples;
        std::vector<std::uint32_t> particles;
    };
    std::vector<Chunk> chunks((in.particles.size() + kChunk - 1) / kChunk);
    for (std::uint32_t vi = 0; vi < in.views.size(); ++vi) {
        const LambertView& view = in.views[vi];
        if (view.frames.empty()) continue;
        const Intrinsics& k = view.camera.intrinsics;
        const glm::dmat4 w2c = glm::dmat4(glm::mat4(view.camera.world_to_camera));
        const glm::dvec4 kf(glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx),
                                      static_cast<float>(k.cy)));
        const glm::dvec3 center(glm::vec3(view.camera.center()));
        parallel_for_chunks(in.particles.size(), std::max(o.threads, 1u), kChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            Chunk& chunk = chunks[begin / kChunk];
            chunk.counts = {};
            chunk.samples.clear();
            chunk.particles.clear();
            ResidualCounts& c = chunk.counts;
            for (auto p = static_cast<std::uint32_t>(begin); p < end; ++p) {
                if (!vis.sees(p, vi)) continue;
                c.candidates += view.frames.size();
                if (!residual_particle_usable(diffuse.particles[p], o)) {
                    c.dropped_no_diffuse += view.frames.size();
                    continue;
                }
                const Particle& part = in.particles[p];
                const glm::dvec3 P(part.p());
                const glm::dvec3 n(part.n());
                const glm::dvec3 rpi(glm::vec3(diffuse.albedo(p) / static_cast<float>(kPi)));
                const glm::dvec3 xc(w2c * glm::dvec4(P, 1.0));
                const glm::dvec2 pos(kf.z + kf.x * xc.x / (-xc.z), kf.w - kf.y * xc.y / (-xc.z));
                const f64::LambertTaps t = f64::lambert_taps(pos, k.w, k.h);
                const glm::dvec3 vdir = glm::normalize(center - P);
                const glm::dvec3 vl = f64::to_tangent_frame(n, vdir);
                const double nv = glm::dot(n, vdir);
                const std::optional<detail::TapSurface> surface =
                    surfaces != nullptr ? std::optional(detail::lambert_tap_surface((*surfaces)[vi], t)) : std::nullopt;
                for (std::uint32_t f : view.frames) {
                    if (!vis.lights(p, f)) {
                        ++c.dropped_shadow;
                        continue;
                    }
                    const PointLight& light = in.lights[f];
                    const glm::dvec3 L = glm::dvec3(glm::vec3(light.position)) - P;
                    const double d2 = glm::dot(L, L);
                    const glm::dvec3 u = L / std::sqrt(d2);
                    const double cosl = glm::dot(n, u);
                    if (!(cosl >= min_cos)) {
                        ++c.dropped_grazing;
                        continue;
                    }
                    const detail::SampleRead read =
                        detail::lambert_read_sample(in.images[f], t, surface ? &*surface : nullptr,
                                                    glm::dvec3(glm::vec3(light.position)), cosl / d2, min_cos);
                    if (read.status == detail::SampleStatus::Missing) {
                        ++c.dropped_missing;
                        continue;
                    }
                    if (read.status == detail::SampleStatus::Clipped) {
                        ++c.dropped_clipped;
                        continue;
                    }
                    if (read.status == detail::SampleStatus::Grazing) {
                        ++c.dropped_grazing;
                        continue;
                    }
                    const glm::dvec3 E = glm::dvec3(glm::vec3(light.intensity)) * (std::max(0.0, cosl) / d2);
                    const double kd = f64::material_diffuse_factor(known, cosl, nv);
                    const glm::dvec3 r = read.c - (rpi * kd) * E;
                    const glm::dvec3 fs(E.x > 0.0 ? r.x / E.x : 0.0, E.y > 0.0 ? r.y / E.y : 0.0, E.z > 0.0 ? r.z / E.z : 0.0);
                    const double ebar = (E.x + E.y + E.z) / 3.0;
                    ResidualSample s{};
                    s.u = glm::vec4(glm::vec3(f64::to_tangent_frame(n, u)), static_cast<float>(ebar * ebar));
                    s.v = glm::vec4(glm::vec3(vl), static_cast<float>(ebar));
                    s.f = glm::vec3(fs);
                    s.status = shared::kResidualUsed;
                    s.d = glm::vec4(glm::vec3(rpi), static_cast<float>(kd));
                    ++c.used;
                    chunk.samples.push_back(s);
                    if (sample_particle != nullptr) chunk.particles.push_back(p);
                }
            }
        });
        for (const Chunk& chunk : chunks) {
            ResidualCounts c = chunk.counts;
            c.used = 0; // counted below, sample by sample: the stride runs over the slots of every view
            cnt += c;
            for (std::size_t i = 0; i < chunk.samples.size(); ++i) {
                if (cnt.used++ % out.keep_stride != 0) continue; // memory bound (ResidualOptions::max_kept_samples)
                out.samples.push_back(chunk.samples[i]);
                if (sample_particle != nullptr) sample_particle->push_back(chunk.particles[i]);
            }
        }
    }
    out.seconds = sw.seconds();
    return out;
}

} // namespace specula
