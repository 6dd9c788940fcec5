// Vulkan side of the residual samples (memory plan in residuals.h):
//  1. particles, `lit` masks and rho/pi per particle are uploaded once;
//  2. views are cut into batches whose images fit one binding (RGBA32: rgb floats and the
//     flags word, exactly as the diffuse solve packs them, lambert_solve_vk.cpp);
//  3. per batch: the host lists the (particle, view) pairs (view-major, as the reference)
//     and their slots (one per lit frame), cuts them into chunks whose slots fit one
//     binding, and per chunk dispatches residuals.comp, downloads the slots and keeps the
//     used samples in slot order.
#include "specular/residuals.h"

#include "diffuse/view_batches.h"

#include "core/error.h"
#include "core/timer.h"
#include "shared/prelude.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"

#include "specular/residuals.comp.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace specula {

namespace {

} // namespace

struct ResidualsVk::Impl {
    gpu::Context* ctx;
    gpu::ComputePipeline kernel;
    explicit Impl(gpu::Context& c)
        : ctx(&c), kernel(c, gpu::ComputePipelineDesc{.name = "residuals",
                                                      .spirv = specular_residuals_comp,
                                                      .storage_buffers = 8,
                                                      .push_constant_bytes = sizeof(shared::ResidualPush),
                                                      .workgroup_size = 64}) {}
};

ResidualsVk::ResidualsVk(gpu::Context& ctx) : m_impl(std::make_unique<Impl>(ctx)) {}
ResidualsVk::~ResidualsVk() = default;

ResidualSamples ResidualsVk::run(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o) {
    const Stopwatch sw;
    lambert_validate(in);
    if (diffuse.particles.size() != in.particles.size())
        throw Error("residual_samples: the diffuse solution has " + std::to_string(diffuse.particles.size()) +
                    " particles, the inputs " + std::to_string(in.particles.size()));
    gpu::Context& ctx = *m_impl->ctx;
    const Visibility& vis = *in.visibility;
    ResidualSamples out;
    ResidualCounts& cnt = out.counts;
    const std::size_t count = in.particles.size();
    if (count == 0) return out;
    const std::uint64_t device_limit = ctx.info().max_storage_buffer_range;
    std::uint64_t limit = device_limit;
    if (o.max_binding_bytes != 0) limit = std::min(limit, o.max_binding_bytes);
    if (count * sizeof(Particle) > device_limit || vis.lit.size() * sizeof(std::uint32_t) > device_limit)
        throw gpu::LimitError("residual_samples: " + std::to_string(count) +
                              " particles (or their lit masks) exceed one storage binding; particle chunking is not implemented");
    const std::uint64_t max_slots = limit / sizeof(ResidualSample);
    if (max_slots < shared::kLambertMaxFramesPerView)
        throw gpu::LimitError("residual_samples: the binding limit holds fewer slots than one pair needs");

    // Per particle: rho/pi (w = 1 when the particle has a diffuse solution).
    std::vector<glm::vec4> rpi(count, glm::vec4(0.0f));
    for (std::size_t p = 0; p < count; ++p)
        if (residual_particle_usable(diffuse.particles[p], o))
            rpi[p] = glm::vec4(diffuse.albedo(p) / static_cast<float>(kPi), 1.0f);

    gpu::Buffer particles_buf = gpu::Buffer::of<Particle>(ctx, count, "residual particles");
    particles_buf.upload(in.particles);
    gpu::Buffer lit_buf = gpu::Buffer::of<std::uint32_t>(ctx, vis.lit.size(), "residual lit masks");
    lit_buf.upload(vis.lit);
    gpu::Buffer rpi_buf = gpu::Buffer::of<glm::vec4>(ctx, count, "residual rho/pi");
    rpi_buf.upload(rpi);

    // View batches whose images fit one binding (diffuse/view_batches.h).
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const std::vector<ViewBatch> batches = plan_view_batches(in, surfaces, limit, "residual_samples");
    out.view_batches = static_cast<std::uint32_t>(batches.size());

    double gpu_ns = 0.0;
    bool timed = true;
    PackedViewBatch packed;
    std::vector<ResidualSample> slots;
    for (const ViewBatch& b : batches) {
        // Pairs of the batch, view-major (the reference's order), with their slot counts.
        std::vector<shared::LambertPairKey> keys;
        std::vector<std::uint64_t> key_slots; // first slot of key i within the batch; back() = total
        key_slots.push_back(0);
        for (std::uint32_t v = b.first; v < b.last; ++v) {
            const LambertView& lv = in.views[v];
            if (lv.frames.empty()) continue;
            for (std::uint32_t p = 0; p < count; ++p) {
                if (!vis.sees(p, v)) continue;
                cnt.candidates += lv.frames.size();
                if (rpi[p].w == 0.0f) {
                    cnt.dropped_no_diffuse += lv.frames.size();
                    continue;
                }
                std::uint32_t lit = 0;
                for (std::uint32_t f : lv.frames) lit += vis.lights(p, f) ? 1u : 0u;
                cnt.dropped_shadow += lv.frames.size() - lit;
                if (lit == 0) continue;
                keys.push_back({p, v - b.first, 0u});
                key_slots.push_back(key_slots.back() + lit);
            }
        }
        if (keys.empty()) continue;

        pack_view_batch(in, surfaces, b, packed);
        const auto& views = packed.views;
        const auto& frames = packed.frames;
        const auto& pixel_words = packed.pixel_words;
        gpu::Buffer views_buf = gpu::Buffer::of<shared::LambertViewGpu>(ctx, views.size(), "residual views");
        views_buf.upload(views);
        gpu::Buffer frames_buf = gpu::Buffer::of<shared::LambertFrameGpu>(ctx, frames.size(), "residual frames");
        frames_buf.upload(frames);
        gpu::Buffer pixels_buf = gpu::Buffer::of<std::uint32_t>(ctx, pixel_words.size(), "residual images");
        pixels_buf.upload(pixel_words);

        // Chunks of whole pairs whose slots fit one binding.
        for (std::size_t first = 0; first < keys.size();) {
            std::size_t last = first;
            while (last < keys.size() && key_slots[last + 1] - key_slots[first] <= max_slots) ++last;
            const std::uint64_t base = key_slots[first];
            const std::uint64_t n_slots = key_slots[last] - base;
            std::vector<shared::LambertPairKey> chunk_keys(keys.begin() + static_cast<std::ptrdiff_t>(first),
                                                           keys.begin() + static_cast<std::ptrdiff_t>(last));
            for (std::size_t i = 0; i < chunk_keys.size(); ++i)
                chunk_keys[i].slot = static_cast<std::uint32_t>(key_slots[first + i] - base);
            gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertPairKey>(ctx, chunk_keys.size(), "residual pair keys");
            keys_buf.upload(chunk_keys);
            gpu::Buffer samples_buf = gpu::Buffer::of<ResidualSample>(ctx, n_slots, "residual samples");
            const shared::ResidualPush push{.dispatch = {}, .frame_words = vis.frame_words, .min_light_cos = o.min_light_cos};
            gpu::Sequence seq(ctx, 2);
            seq.dispatch_1d(m_impl->kernel,
                            {particles_buf, lit_buf, rpi_buf, views_buf, frames_buf, pixels_buf, keys_buf, samples_buf},
                            static_cast<std::uint32_t>(chunk_keys.size()), push, "residuals")
                .barrier(gpu::Barrier::ComputeToHost)
                .submit_and_wait();
            for (const auto& t : seq.timings()) {
                if (t.ns) gpu_ns += *t.ns;
                else timed = false;
            }
            ++out.chunks;
            slots.resize(n_slots);
            samples_buf.download(std::span<ResidualSample>(slots));
            for (const ResidualSample& s : slots) {
                switch (s.status) {
                case shared::kResidualUsed: out.samples.push_back(s); ++cnt.used; break;
                case shared::kResidualGrazing: ++cnt.dropped_grazing; break;
                case shared::kResidualMissing: ++cnt.dropped_missing; break;
                case shared::kResidualClipped: ++cnt.dropped_clipped; break;
                default: throw Error("residual_samples: the kernel wrote an unknown status " + std::to_string(s.status));
                }
            }
            first = last;
        }
    }
    if (timed) out.gpu_ms = gpu_ns * 1e-6;
    out.seconds = sw.seconds();
    return out;
}

} // namespace specula
