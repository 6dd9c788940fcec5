// Shared host side of the Lambert solve: inputs from a capture, validation, the
// summary, and the backend switch.
#include "diffuse/lambert_solve.h"

#include "core/error.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

namespace specula {

static_assert(shared::kLambertPixClipped == kClippedAny && shared::kLambertPixMissing == kMissing &&
              shared::kLambertPixOutside == kOutsideMask, "shared/lambert.h pixel flags must match capture.h");

const char* to_string(LambertMode mode) noexcept {
    return mode == LambertMode::Photometric ? "photometric" : "albedo";
}

LambertInputs lambert_inputs(const Capture& capture, std::span<const Particle> particles, const Visibility& visibility) {
    LambertInputs in;
    in.particles = particles;
    in.visibility = &visibility;
    in.views.reserve(capture.views.size());
    for (const View& v : capture.views) {
        LambertView lv;
        lv.camera = v.camera;
        for (std::size_t f : v.frames)
            if (capture.desc.frames[f].split == Split::Train) lv.frames.push_back(static_cast<std::uint32_t>(f));
        in.views.push_back(std::move(lv));
    }
    in.lights.reserve(capture.desc.frames.size());
    for (const FrameDesc& f : capture.desc.frames) in.lights.push_back(f.light);
    in.images = capture.images;
    return in;
}

void lambert_validate(const LambertInputs& in) {
    if (in.visibility == nullptr) throw Error("lambert_solve: no visibility given");
    const Visibility& vis = *in.visibility;
    if (vis.particle_count != in.particles.size())
        throw Error("lambert_solve: visibility has " + std::to_string(vis.particle_count) + " particles, inputs " +
                    std::to_string(in.particles.size()));
    if (vis.view_count != in.views.size())
        throw Error("lambert_solve: visibility has " + std::to_string(vis.view_count) + " views, inputs " +
                    std::to_string(in.views.size()));
    if (vis.frame_count != in.lights.size() || in.images.size() != in.lights.size())
        throw Error("lambert_solve: visibility has " + std::to_string(vis.frame_count) + " frames, inputs " +
                    std::to_string(in.lights.size()) + " lights and " + std::to_string(in.images.size()) + " images");
    if (!vis.surfaces.empty() && vis.surfaces.size() != in.views.size())
        throw Error("lambert_solve: visibility has " + std::to_string(vis.surfaces.size()) + " surface maps for " +
                    std::to_string(in.views.size()) + " views");
    for (std::size_t v = 0; v < in.views.size(); ++v) {
        const LambertView& view = in.views[v];
        if (!vis.surfaces.empty()) {
            const SurfaceMap& m = vis.surfaces[v];
            const Intrinsics& k = view.camera.intrinsics;
            if (m.width != k.w || m.height != k.h || m.words.size() != std::size_t(k.w) * std::size_t(k.h) * 4)
                throw Error("lambert_solve: view " + std::to_string(v) + ": surface map is " + std::to_string(m.width) + "x" +
                            std::to_string(m.height) + ", image " + std::to_string(k.w) + "x" + std::to_string(k.h));
        }
        const Intrinsics& k = view.camera.intrinsics;
        for (std::uint32_t f : view.frames) {
            if (f >= in.images.size()) throw Error("lambert_solve: view " + std::to_string(v) + " names frame " + std::to_string(f) + " out of range");
            const FrameImage& im = in.images[f];
            if (im.color.width != k.w || im.color.height != k.h || im.color.channels != 3 ||
                im.flags.size() != static_cast<std::size_t>(k.w) * static_cast<std::size_t>(k.h))
                throw Error("lambert_solve: frame " + std::to_string(f) + ": image is not " + std::to_string(k.w) + "x" +
                            std::to_string(k.h) + " RGB with flags (images not loaded?)");
        }
    }
}

void summarize(LambertOutputs& out) {
    LambertSummary& s = out.summary;
    const double seconds = s.seconds;
    const auto gpu_ms = s.gpu_ms;
    const auto dispatch = s.gpu_dispatch_ms;
    const auto batches = s.view_batches, chunks = s.pair_chunks, groups = s.record_groups;
    s = LambertSummary{};
    s.seconds = seconds;
    s.gpu_ms = gpu_ms;
    s.gpu_dispatch_ms = dispatch;
    s.view_batches = batches;
    s.pair_chunks = chunks;
    s.record_groups = groups;
    s.particles = out.particles.size();
    double angle_sum = 0.0;
    std::size_t angle_n = 0;
    for (const LambertParticleResult& r : out.particles) {
        s.pairs += r.views;
        if (r.status & shared::kLambertOk) ++s.ok;
        if (r.status & shared::kLambertFallback) ++s.fallback;
        if (r.status & shared::kLambertNoSample) ++s.no_sample;
        if (r.status & shared::kLambertNotSeen) ++s.not_seen;
        if (r.status & shared::kLambertViewsRejected) ++s.views_rejected;
        s.used += r.used;
        s.rejected_shadow += r.rejected_shadow;
        s.rejected_clipped += r.rejected_clipped;
        s.rejected_missing += r.rejected_missing;
        s.rejected_grazing += r.rejected_grazing;
        s.rejected_highlight += r.rejected_highlight;
        s.rejected_view += r.rejected_view;
        s.rejected_low += r.rejected_low;
        if (out.mode == LambertMode::Photometric && (r.status & shared::kLambertOk) && !(r.status & shared::kLambertFallback)) {
            angle_sum += r.normal.w;
            ++angle_n;
        }
    }
    s.mean_normal_angle_deg = angle_n ? angle_sum / static_cast<double>(angle_n) : 0.0;
}

std::string describe(const LambertSummary& s, LambertMode mode) {
    std::ostringstream o;
    const auto pct = [&](std::size_t n) { return s.particles ? 100.0 * static_cast<double>(n) / static_cast<double>(s.particles) : 0.0; };
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "lambert solve (%s): %zu particles, %zu (particle, view) pairs, %.3f s", to_string(mode), s.particles,
                  s.pairs, s.seconds);
    o << buf;
    if (s.gpu_ms) {
        std::snprintf(buf, sizeof buf, " (GPU %.3f ms, %u image batches, %u pair chunks in %u record groups)", *s.gpu_ms,
                      s.view_batches, s.pair_chunks, s.record_groups);
        o << buf;
    }
    std::snprintf(buf, sizeof buf,
                  "\n  ok %zu (%.2f%%), photometric fallback %zu, no valid sample %zu, seen by no view %zu (%.2f%%), "
                  "outlier views in %zu\n  samples used %llu; rejected: shadow %llu, clipped %llu, missing %llu, grazing %llu, "
                  "highlight %llu, shadow edge %llu, outlier view %llu\n",
                  s.ok, pct(s.ok), s.fallback, s.no_sample, s.not_seen, pct(s.not_seen), s.views_rejected,
                  static_cast<unsigned long long>(s.used), static_cast<unsigned long long>(s.rejected_shadow),
                  static_cast<unsigned long long>(s.rejected_clipped), static_cast<unsigned long long>(s.rejected_missing),
                  static_cast<unsigned long long>(s.rejected_grazing), static_cast<unsigned long long>(s.rejected_highlight),
                  static_cast<unsigned long long>(s.rejected_low), static_cast<unsigned long long>(s.rejected_view));
    o << buf;
    if (mode == LambertMode::Photometric) {
        std::snprintf(buf, sizeof buf, "  mean refined-normal angle to the mesh normal: %.3f deg\n", s.mean_normal_angle_deg);
        o << buf;
    }
    return o.str();
}

LambertOutputs lambert_solve(const LambertInputs& in, const LambertOptions& options, Backend backend, gpu::Context* ctx) {
    if (backend == Backend::Cpu) return lambert_solve_cpu(in, options);
    if (ctx == nullptr) throw Error("lambert_solve: the Vulkan backend needs a gpu::Context");
    LambertSolveVk kernel(*ctx);
    return kernel.run(in, options);
}

} // namespace specula
