// Reference of the residual samples: the method of shared/residuals.h, step for step as
// shaders/specular/residuals.comp does it, in double (the bilinear taps through the shared
// helpers instantiated in double, shared::f64), rounded to the float layout at the end.
// Inputs the GPU gets in float (camera, lights, rho/pi) are rounded to float first.
#include "specular/residuals.h"

#include "specular/coated_fit.h"

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

// One particle as one view sees it: what its samples in the view's frames share.
struct ParticleInView {
    glm::dvec3 P{0.0}, n{0.0}, rpi{0.0}, vl{0.0};
    double nv = 0.0;
    f64::LambertTaps taps;
    std::optional<detail::TapSurface> surface;
};

// The view's camera in the float the kernel gets it in.
struct ViewFrame {
    glm::dmat4 w2c{1.0};
    glm::dvec4 kf{0.0};
    glm::dvec3 center{0.0};
    int w = 0, h = 0;
};

ViewFrame view_frame(const LambertView& view) {
    const Intrinsics& k = view.camera.intrinsics;
    return {.w2c = glm::dmat4(glm::mat4(view.camera.world_to_camera)),
            .kf = glm::dvec4(glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx),
                                       static_cast<float>(k.cy))),
            .center = glm::dvec3(glm::vec3(view.camera.center())),
            .w = k.w,
            .h = k.h};
}

ParticleInView particle_in_view(const Particle& part, const glm::vec3& albedo, const ViewFrame& vf,
                                const SurfaceMap* surface) {
    ParticleInView q;
    q.P = glm::dvec3(part.p());
    q.n = glm::dvec3(part.n());
    q.rpi = glm::dvec3(glm::vec3(albedo / static_cast<float>(kPi)));
    const glm::dvec3 xc(vf.w2c * glm::dvec4(q.P, 1.0));
    const glm::dvec2 pos(vf.kf.z + vf.kf.x * xc.x / (-xc.z), vf.kf.w - vf.kf.y * xc.y / (-xc.z));
    q.taps = f64::lambert_taps(pos, vf.w, vf.h);
    const glm::dvec3 vdir = glm::normalize(vf.center - q.P);
    q.vl = f64::to_tangent_frame(q.n, vdir);
    q.nv = glm::dot(q.n, vdir);
    if (surface != nullptr) q.surface = detail::lambert_tap_surface(*surface, q.taps);
    return q;
}

enum class Drop : std::uint8_t { None, Grazing, Missing, Clipped };

// Frame f's sample of the particle (lit and seen: the caller tests vis.lights), or why it is
// dropped; `out` is written only when it is used.
Drop frame_sample(const ParticleInView& q, const FrameImage& image, const PointLight& light, const shared::MaterialGpu& known,
                  double min_cos, ResidualSample& out) {
    const glm::dvec3 L = glm::dvec3(glm::vec3(light.position)) - q.P;
    const double d2 = glm::dot(L, L);
    const glm::dvec3 u = L / std::sqrt(d2);
    const double cosl = glm::dot(q.n, u);
    if (!(cosl >= min_cos)) return Drop::Grazing;
    const detail::SampleRead read = detail::lambert_read_sample(image, q.taps, q.surface ? &*q.surface : nullptr,
                                                                glm::dvec3(glm::vec3(light.position)), cosl / d2, min_cos);
    if (read.status == detail::SampleStatus::Missing) return Drop::Missing;
    if (read.status == detail::SampleStatus::Clipped) return Drop::Clipped;
    if (read.status == detail::SampleStatus::Grazing) return Drop::Grazing;
    const glm::dvec3 E = glm::dvec3(glm::vec3(light.intensity)) * (std::max(0.0, cosl) / d2);
    const double kd = f64::material_diffuse_factor(known, cosl, q.nv);
    const glm::dvec3 r = read.c - (q.rpi * kd) * E;
    const glm::dvec3 fs(E.x > 0.0 ? r.x / E.x : 0.0, E.y > 0.0 ? r.y / E.y : 0.0, E.z > 0.0 ? r.z / E.z : 0.0);
    const double ebar = (E.x + E.y + E.z) / 3.0;
    out = ResidualSample{};
    out.u = glm::vec4(glm::vec3(f64::to_tangent_frame(q.n, u)), static_cast<float>(ebar * ebar));
    out.v = glm::vec4(glm::vec3(q.vl), static_cast<float>(ebar));
    out.f = glm::vec3(fs);
    out.status = shared::kResidualUsed;
    out.d = glm::vec4(glm::vec3(q.rpi), static_cast<float>(kd));
    return Drop::None;
}

// A used sample, named: its particle, view and frame.
struct SampleSlot {
    std::uint32_t particle, view, frame;
};

// The pass: with `score`, no sample is kept: each kept one's part of the material's square
// error is summed instead, in the samples' order, into score_sums (square, weight).
ResidualSamples residual_pass(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o,
                              std::vector<std::uint32_t>* sample_particle, const shared::MaterialGpu* score,
                              glm::dvec2* score_sums) {
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
    const unsigned threads = std::max(o.threads, 1u);
    std::uint64_t lit = 0;
    out.keep_stride = residual_keep_stride(in, diffuse, o, &lit);
    // With fit_samples the pass names the used samples (12 bytes each) and makes only those the
    // fit takes, once their count is known; else it makes every kept one. Room for every lit
    // slot's, an upper bound: pages never written take no memory, where doubling growth copied
    // the samples and held up to three times them at once.
    const bool named = o.fit_samples != 0 && score == nullptr;
    const bool slotted = named || sample_particle != nullptr; // the chunks name their samples
    std::vector<SampleSlot> slots;
    const auto room = static_cast<std::size_t>(lit / out.keep_stride + 1);
    if (named) slots.reserve(room);
    else if (score == nullptr) out.samples.reserve(room);
    if (sample_particle != nullptr && !named) sample_particle->reserve(room);
    std::vector<ViewFrame> frames;
    for (const LambertView& view : in.views) frames.push_back(view_frame(view));
    // Whether each particle gives samples, decided once (each view's loop asked again).
    std::vector<std::uint8_t> usable(in.particles.size());
    parallel_for_chunks(usable.size(), threads, 16384, [&](unsigned, std::size_t begin, std::size_t end) {
        for (std::size_t p = begin; p < end; ++p) usable[p] = residual_particle_usable(diffuse.particles[p], o) ? 1 : 0;
    });
    // Each view's particles are cut into fixed chunks that the workers share; a chunk keeps
    // every used sample it finds, and the chunks are then taken in order, every keep_stride-th
    // sample kept: the slot order of one serial loop, whatever the thread count.
    constexpr std::size_t kChunk = 2048;
    struct Chunk {
        ResidualCounts counts;
        std::vector<ResidualSample> samples;
        std::vector<SampleSlot> slots;
        std::vector<glm::vec4> energy; // named: each sample's f_s and Ebar (the energy sums')
        std::vector<glm::dvec2> error;  // score: each sample's weighted square error and weight
    };
    std::vector<Chunk> chunks((in.particles.size() + kChunk - 1) / kChunk);
    for (std::uint32_t vi = 0; vi < in.views.size(); ++vi) {
        const LambertView& view = in.views[vi];
        if (view.frames.empty()) continue;
        const ViewFrame& vf = frames[vi];
        const SurfaceMap* surface = surfaces != nullptr ? &(*surfaces)[vi] : nullptr;
        parallel_for_chunks(in.particles.size(), threads, kChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            Chunk& chunk = chunks[begin / kChunk];
            chunk.counts = {};
            chunk.samples.clear();
            chunk.slots.clear();
            chunk.energy.clear();
            chunk.error.clear();
            ResidualCounts& c = chunk.counts;
            for (auto p = static_cast<std::uint32_t>(begin); p < end; ++p) {
                if (!vis.sees(p, vi)) continue;
                c.candidates += view.frames.size();
                if (usable[p] == 0) {
                    c.dropped_no_diffuse += view.frames.size();
                    continue;
                }
                const ParticleInView q = particle_in_view(in.particles[p], diffuse.albedo(p), vf, surface);
                for (std::uint32_t f : view.frames) {
                    if (!vis.lights(p, f)) {
                        ++c.dropped_shadow;
                        continue;
                    }
                    ResidualSample s;
                    switch (frame_sample(q, in.images[f], in.lights[f], known, min_cos, s)) {
                    case Drop::None:
                        ++c.used;
                        if (slotted) chunk.slots.push_back({p, vi, f});
                        if (score != nullptr) {
                            glm::dvec2 e(0.0);
                            add_material_square_error(*score, s, e.x, e.y);
                            chunk.error.push_back(e);
                        } else if (named) chunk.energy.emplace_back(s.f, s.v.w);
                        else chunk.samples.push_back(s);
                        break;
                    case Drop::Grazing: ++c.dropped_grazing; break;
                    case Drop::Missing: ++c.dropped_missing; break;
                    case Drop::Clipped: ++c.dropped_clipped; break;
                    }
                }
            }
        });
        for (const Chunk& chunk : chunks) {
            ResidualCounts c = chunk.counts;
            c.used = 0; // counted below, sample by sample: the stride runs over the slots of every view
            cnt += c;
            const std::size_t n = score != nullptr ? chunk.error.size() : named ? chunk.slots.size() : chunk.samples.size();
            for (std::size_t i = 0; i < n; ++i) {
                if (cnt.used++ % out.keep_stride != 0) continue; // memory bound (ResidualOptions::max_kept_samples)
                if (score != nullptr) {
                    *score_sums += chunk.error[i];
                } else if (named) {
                    slots.push_back(chunk.slots[i]);
                    out.energy.add(glm::vec3(chunk.energy[i]), chunk.energy[i].w);
                } else {
                    out.samples.push_back(chunk.samples[i]);
                    out.energy.add(chunk.samples[i].f, chunk.samples[i].v.w);
                    if (sample_particle != nullptr) sample_particle->push_back(chunk.slots[i].particle);
                }
            }
        }
    }
    if (named) {
        // The kept samples the fit takes: every k-th from the first (used_sample_stride), made again.
        const std::size_t stride = used_sample_stride(slots.size(), o.fit_samples);
        out.samples.resize((slots.size() + stride - 1) / stride);
        parallel_for_chunks(out.samples.size(), threads, kChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t i = begin; i < end; ++i) {
                const SampleSlot& slot = slots[i * stride];
                const ParticleInView q = particle_in_view(in.particles[slot.particle], diffuse.albedo(slot.particle),
                                                          frames[slot.view],
                                                          surfaces != nullptr ? &(*surfaces)[slot.view] : nullptr);
                (void)frame_sample(q, in.images[slot.frame], in.lights[slot.frame], known, min_cos, out.samples[i]);
            }
        });
        if (sample_particle != nullptr)
            for (std::size_t i = 0; i < out.samples.size(); ++i) sample_particle->push_back(slots[i * stride].particle);
    }
    out.seconds = sw.seconds();
    return out;
}

} // namespace

ResidualSamples residual_samples_cpu(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o,
                                     std::vector<std::uint32_t>* sample_particle) {
    return residual_pass(in, diffuse, o, sample_particle, nullptr, nullptr);
}

ResidualScore residual_mean_square_error_cpu(const LambertInputs& in, const LambertOutputs& diffuse,
                                             const ResidualOptions& options, const SpecularModel& model) {
    const shared::MaterialGpu m = material_gpu(model);
    glm::dvec2 sums(0.0);
    const ResidualSamples pass = residual_pass(in, diffuse, options, nullptr, &m, &sums);
    return {.mean_square = sums.y > 0.0 ? sums.x / sums.y : 0.0, .counts = pass.counts, .seconds = pass.seconds};
}

} // namespace specula
