#include "pipeline/albedo_refine.h"

#include "core/error.h"
#include "core/timer.h"
#include "diffuse/albedo_texture.h"
#include "render/renderer.h"

#include <algorithm>
#include <cmath>

namespace specula {

AlbedoRefineResult refine_albedo(gpu::Context& ctx, const Capture& capture, const Atlas& atlas,
                                 std::span<const Particle> particles, const LambertInputs& inputs, const LambertOutputs& solve,
                                 const LafortuneRgb& lobe, std::uint32_t rounds, const SolveFn& solve_fn) {
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

    for (std::uint32_t round = 0; round < rounds; ++round) {
        AlbedoRefineRound rr;
        // R(A): the train frames rendered from the current atlas (inpainted as the bundle will be).
        const Stopwatch render_watch;
        const AlbedoTexture texture = make_albedo_texture(atlas, particles, out.albedo, out.valid);
        render::Renderer renderer(ctx, render::Scene{.mesh = &capture.mesh, .corner_uv = atlas.corner_uv, .albedo = &texture.image,
                                                     .lobe = lobe});
        std::vector<FrameImage> images(capture.desc.frames.size());
        for (std::size_t v = 0; v < inputs.views.size(); ++v)
            for (const std::uint32_t f : inputs.views[v].frames) {
                const FrameImage& captured = capture.images[f];
                // Fused: both terms in one pass, the same arithmetic as the thesis's two passes (the
                // same images here) at half the raster work: 1.7 s instead of 3.4 s for the can's 120 frames.
                render::Frame frame =
                    renderer.render(inputs.views[v].camera, inputs.lights[f],
                                    render::Settings{.mode = render::Mode::Both, .passes = render::Passes::Fused, .shadows = false});
                FrameImage& im = images[f];
                im.color = std::move(frame.color);
                if (std::isfinite(captured.saturation))
                    for (float& x : im.color.pixels) x = std::min(x, captured.saturation);
                im.flags = captured.flags; // the same taps are dropped (mask, missing, clipped)
                im.saturation = captured.saturation;
            }
        rr.render_seconds = render_watch.seconds();

        // S(R(A)), then A += S(captured) - S(R(A)) where both exist.
        const Stopwatch solve_watch;
        LambertInputs rendered = inputs;
        rendered.images = images;
        const LambertOutputs again = solve_fn(rendered);
        rr.solve_seconds = solve_watch.seconds();
        double change = 0.0;
        for (std::size_t p = 0; p < n; ++p) {
            const LambertParticleResult& r = again.particles[p];
            if (!has_target[p] || !(r.status & shared::kLambertOk) || !(r.albedo_robust.w > 0.0f)) continue;
            const glm::vec3 delta = target[p] - glm::vec3(r.albedo_robust);
            out.albedo[p] = glm::max(out.albedo[p] + delta, glm::vec3(0.0f));
            change += (std::abs(delta.x) + std::abs(delta.y) + std::abs(delta.z)) / 3.0;
            ++rr.corrected;
        }
        rr.mean_abs_change = rr.corrected > 0 ? change / static_cast<double>(rr.corrected) : 0.0;
        out.rounds.push_back(rr);
    }
    return out;
}

} // namespace specula
