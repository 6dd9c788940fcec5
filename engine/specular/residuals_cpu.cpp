// Reference of the residual samples: the method of shared/residuals.h, step for step as
// shaders/specular/residuals.comp does it, in double (the bilinear taps through the shared
// helpers instantiated in double, shared::f64), rounded to the float layout at the end.
// Inputs the GPU gets in float (camera, lights, rho/pi) are rounded to float first.
#include "specular/residuals.h"

#include "core/error.h"
#include "diffuse/lambert_solve_detail.h"
#include "diffuse/view_batches.h"
#include "core/timer.h"
#include "shared/prelude.h"
#include "shared/tangent_frame.h"

#include <cmath>

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
    out.keep_stride = residual_keep_stride(in, diffuse, o);
    for (std::uint32_t vi = 0; vi < in.views.size(); ++vi) {
        const LambertView& view = in.views[vi];
        if (view.frames.empty()) continue;
        const Intrinsics& k = view.camera.intrinsics;
        const glm::dmat4 w2c = glm::dmat4(glm::mat4(view.camera.world_to_camera));
        const glm::dvec4 kf(glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx),
                                      static_cast<float>(k.cy)));
        const glm::dvec3 center(glm::vec3(view.camera.center()));
        for (std::uint32_t p = 0; p < in.particles.size(); ++p) {
            if (!vis.sees(p, vi)) continue;
            cnt.candidates += view.frames.size();
            if (!residual_particle_usable(diffuse.particles[p], o)) {
                cnt.dropped_no_diffuse += view.frames.size();
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
            for (std::uint32_t f : view.frames) {
                if (!vis.lights(p, f)) {
                    ++cnt.dropped_shadow;
                    continue;
                }
                const PointLight& light = in.lights[f];
                const glm::dvec3 L = glm::dvec3(glm::vec3(light.position)) - P;
                const double d2 = glm::dot(L, L);
                const glm::dvec3 u = L / std::sqrt(d2);
                const double cosl = glm::dot(n, u);
                if (!(cosl >= min_cos)) {
                    ++cnt.dropped_grazing;
                    continue;
                }
                const detail::SampleRead read =
                    detail::lambert_read_sample(in.images[f], t, surfaces != nullptr ? &(*surfaces)[vi] : nullptr,
                                                glm::dvec3(glm::vec3(light.position)), cosl / d2, min_cos);
                if (read.status == detail::SampleStatus::Missing) {
                    ++cnt.dropped_missing;
                    continue;
                }
                if (read.status == detail::SampleStatus::Clipped) {
                    ++cnt.dropped_clipped;
                    continue;
                }
                if (read.status == detail::SampleStatus::Grazing) {
                    ++cnt.dropped_grazing;
                    continue;
                }
                const glm::dvec3 c = read.c;
                const glm::dvec3 E = glm::dvec3(glm::vec3(light.intensity)) * (std::max(0.0, cosl) / d2);
                const double kd = f64::material_diffuse_factor(known, cosl, nv);
                const glm::dvec3 r = c - (rpi * kd) * E;
                const glm::dvec3 fs(E.x > 0.0 ? r.x / E.x : 0.0, E.y > 0.0 ? r.y / E.y : 0.0, E.z > 0.0 ? r.z / E.z : 0.0);
                const double ebar = (E.x + E.y + E.z) / 3.0;
                ResidualSample s{};
                s.u = glm::vec4(glm::vec3(f64::to_tangent_frame(n, u)), static_cast<float>(ebar * ebar));
                s.v = glm::vec4(glm::vec3(vl), static_cast<float>(ebar));
                s.f = glm::vec3(fs);
                s.status = shared::kResidualUsed;
                s.d = glm::vec4(glm::vec3(rpi), static_cast<float>(kd));
                if (cnt.used++ % out.keep_stride != 0) continue; // memory bound (ResidualOptions::max_kept_samples)
                out.samples.push_back(s);
                if (sample_particle != nullptr) sample_particle->push_back(p);
            }
        }
    }
    out.seconds = sw.seconds();
    return out;
}

} // namespace specula
