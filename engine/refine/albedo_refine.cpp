#include "refine/albedo_refine.h"

#include "core/error.h"
#include "core/timer.h"
#include "diffuse/albedo_texture.h"
#include "render/renderer.h"

#include <algorithm>
#include <cmath>

namespace specula {

AlbedoRefineResult refine_albedo(gpu::Context& ctx, const Capture& capture, const Atlas& atlas,
                                 std::span<const Particle> particles, const LambertInputs& inputs, const LambertOutputs& solve,
                                 const std::optional<SpecularModel>& material, std::uint32_t rounds, const SolveFn& solve_fn,
                                 const AlbedoRefineOptions& options) {
    const std::size_t n = particles.size();
    if (solve.particles.size() != n) throw Error("refine_albedo: the solve has " + std::to_string(solve.particles.size()) +
                                                 " particles, " + std::to_string(n) + " given");
    if (capture.images.size() != capture.desc.frames.size()) throw Error("refine_albedo: the capture's images are not loaded");
    AlbedoRefineResult out;
    out.albedo.resize(n);
    out.valid.resize(n);
    // S(captured): the robust combination of the solve; only particles where it exists are corrected.
    std::vector<glm::vec3> target(n);
    std::vector<std::uint8_t> has_target(n);
    for (std::size_t p = 0; p < n; ++p) {
        const LambertParticleResult& r = solve.particles[p];
        out.albedo[p] = solve.albedo(p);
        out.valid[p] = (r.status & shared::kLambertOk) ? 1 : 0;
        target[p] = glm::vec3(r.albedo_robust);
        has_target[p] = out.valid[p] && r.albedo_robust.w > 0.0f ? 1 : 0;
    }
    // w_p: the best view's cosine n.v, ramped from grazing_cos (0) to resolved_cos (1).
    std::vector<float> weight(n, 1.0f);
    if (options.resolved_cos > 0.0f || options.grazing_cos > 0.0f) {
        const double lo = options.grazing_cos, hi = std::max(options.resolved_cos, options.grazing_cos + 1e-6f);
        for (std::size_t p = 0; p < n; ++p) {
            const std::uint32_t v = solve.particles[p].best_view;
            if (!has_target[p] || v >= inputs.views.size()) continue;
            const glm::dvec3 to_camera = glm::normalize(inputs.views[v].camera.center() - glm::dvec3(particles[p].p()));
            const double cos_v = glm::dot(glm::dvec3(particles[p].n()), to_camera);
            weight[p] = static_cast<float>(std::clamp((cos_v - lo) / (hi - lo), 0.0, 1.0));
        }
    }
    const std::vector<glm::vec3> initial = out.albedo; // A_0
    std::vector<float> last_correction(n, 0.0f);       // |w (S(captured) - S(R(A)))| of the previous round
    std::vector<std::uint8_t> stopped(n, 0);
    std::size_t stopped_count = 0;

    for (std::uint32_t round = 0; round < rounds; ++round) {
        AlbedoRefineRound rr;
        // R(A): the train frames rendered from the current atlas (inpainted as the bundle will be).
        const Stopwatch render_watch;
        const AlbedoTexture texture = make_albedo_texture(atlas, particles, out.albedo, out.valid);
        render::Renderer renderer(ctx, render::Scene{.mesh = &capture.mesh, .corner_uv = atlas.corner_uv, .albedo = &texture.image,
                                                     .material = {.specular = material}});
        std::vector<FrameImage> images(capture.desc.frames.size());
        for (std::size_t v = 0; v < inputs.views.size(); ++v)
            for (const std::uint32_t f : inputs.views[v].frames) {
                const FrameImage& captured = capture.images[f];
                // Deferred: the view's G-buffer drawn for its first light, its other lights shaded from
                // it (render::FrameInfo::gbuffer_kept); the same arithmetic as the thesis's two passes.
                render::Frame frame = renderer.render(
                    inputs.views[v].camera, inputs.lights[f],
                    render::Settings{.mode = render::Mode::Both, .passes = render::Passes::Deferred, .shadows = false});
                FrameImage& im = images[f];
                im.color = std::move(frame.color);
                if (std::isfinite(captured.saturation))
                    for (float& x : im.color.pixels) x = std::min(x, captured.saturation);
                im.flags = captured.flags; // the same taps are dropped (mask, missing, clipped)
                im.saturation = captured.saturation;
            }
        rr.render_seconds = render_watch.seconds();

        // S(R(A)), then A += s [w (S(captured) - S(R(A))) - lambda (A - A_0)] where both exist.
        const Stopwatch solve_watch;
        LambertInputs rendered = inputs;
        rendered.images = images;
        const LambertOutputs again = solve_fn(rendered);
        rr.solve_seconds = solve_watch.seconds();
        double change = 0.0;
        for (std::size_t p = 0; p < n; ++p) {
            const LambertParticleResult& r = again.particles[p];
            if (!has_target[p] || !(r.status & shared::kLambertOk) || !(r.albedo_robust.w > 0.0f)) continue;
            ++rr.corrected;
            if (stopped[p]) continue;
            const glm::vec3 correction = weight[p] * (target[p] - glm::vec3(r.albedo_robust));
            const float size = glm::length(correction);
            // A correction that does not shrink by 10%: the particle diverges, or the solve of the
            // renders barely sees it and each round would add the same step again (albedo_refine.h).
            // 1e-4: below that, rounding.
            if (options.stop_growing && round > 0 && size > 0.9f * last_correction[p] + 1e-4f) {
                stopped[p] = 1;
                ++stopped_count;
                continue;
            }
            last_correction[p] = size;
            const glm::vec3 next = glm::max(
                out.albedo[p] + options.step * (correction - options.prior * (out.albedo[p] - initial[p])), glm::vec3(0.0f));
            const glm::vec3 delta = next - out.albedo[p];
            out.albedo[p] = next;
            change += (std::abs(delta.x) + std::abs(delta.y) + std::abs(delta.z)) / 3.0;
        }
        rr.stopped = stopped_count;
        rr.mean_abs_change = rr.corrected > 0 ? change / static_cast<double>(rr.corrected) : 0.0;
        out.rounds.push_back(rr);
    }
    return out;
}

} // namespace specula
