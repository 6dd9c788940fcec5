// Vulkan side of the Lambert solve (memory plan in lambert_solve.h):
//  1. particles and the `lit` masks are uploaded once;
//  2. particles are cut into chunks whose pair results fit one binding, views into
//     batches whose images fit one binding;
//  3. per view batch: its images go up (RGBA32: rgb floats, flags word), then per chunk one
//     dispatch of lambert_solve.comp over the chunk's pairs with a view in the batch;
//  4. per chunk: one dispatch of lambert_solve_combine.comp, results come down.
#include "diffuse/lambert_solve.h"
#include "diffuse/view_batches.h"

#include "core/error.h"
#include "core/timer.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"

#include "diffuse/lambert_solve.comp.h"
#include "diffuse/lambert_solve_combine.comp.h"

#include <algorithm>
#include <cstring>

namespace specula {

namespace {

struct Chunk {
    std::uint32_t first = 0, last = 0; // particles [first, last)
    std::uint64_t pair_base = 0;       // global pair index of the chunk's first pair
    std::uint64_t pairs = 0;
};

} // namespace

struct LambertSolveVk::Impl {
    gpu::Context* ctx;
    gpu::ComputePipeline pair;
    gpu::ComputePipeline combine;
    explicit Impl(gpu::Context& c)
        : ctx(&c),
          pair(c, gpu::ComputePipelineDesc{.name = "lambert_solve",
                                           .spirv = diffuse_lambert_solve_comp,
                                           .storage_buffers = 7,
                                           .push_constant_bytes = sizeof(shared::LambertPairPush),
                                           .workgroup_size = 64}),
          combine(c, gpu::ComputePipelineDesc{.name = "lambert_solve_combine",
                                              .spirv = diffuse_lambert_solve_combine_comp,
                                              .storage_buffers = 4,
                                              .push_constant_bytes = sizeof(shared::LambertCombinePush),
                                              .workgroup_size = 64}) {}
};

LambertSolveVk::LambertSolveVk(gpu::Context& ctx) : m_impl(std::make_unique<Impl>(ctx)) {}
LambertSolveVk::~LambertSolveVk() = default;

LambertOutputs LambertSolveVk::run(const LambertInputs& in, const LambertOptions& o) {
    const Stopwatch sw;
    lambert_validate(in);
    gpu::Context& ctx = *m_impl->ctx;
    const Visibility& vis = *in.visibility;
    LambertOutputs out;
    out.mode = o.mode;
    out.choice = o.choice;
    const std::size_t count = in.particles.size();
    out.particles.resize(count);
    if (count == 0) {
        summarize(out);
        return out;
    }
    const std::uint64_t device_limit = ctx.info().max_storage_buffer_range;
    std::uint64_t limit = device_limit; // for the batched bindings: images, pair results
    if (o.max_binding_bytes != 0) limit = std::min(limit, o.max_binding_bytes);
    if (count * sizeof(Particle) > device_limit || vis.lit.size() * sizeof(std::uint32_t) > device_limit)
        throw gpu::LimitError("lambert_solve: " + std::to_string(count) + " particles (or their lit masks) exceed one storage binding (" +
                         std::to_string(device_limit) + " bytes); particle chunking of these inputs is not implemented");

    // Pairs: particle-major, views in order; offsets[p] = first pair of p.
    const std::uint32_t view_count = static_cast<std::uint32_t>(in.views.size());
    std::vector<std::uint32_t> offsets(count + 1, 0);
    for (std::size_t p = 0; p < count; ++p) {
        std::uint32_t n = 0;
        for (std::uint32_t v = 0; v < view_count; ++v)
            if (!in.views[v].frames.empty() && vis.sees(p, v)) ++n;
        offsets[p + 1] = offsets[p] + n;
    }
    const std::uint64_t total_pairs = offsets.back();

    // Chunks of particles whose pair results (and combine results) fit one binding.
    std::vector<Chunk> chunks;
    {
        const std::uint64_t max_pairs = limit / sizeof(shared::LambertPairResult);
        const std::uint64_t max_particles = std::min<std::uint64_t>(limit / sizeof(LambertParticleResult), limit / 4 - 1);
        std::uint32_t first = 0;
        while (first < count) {
            std::uint32_t last = first;
            while (last < count && last - first < max_particles && offsets[last + 1] - offsets[first] <= max_pairs) ++last;
            if (last == first) throw gpu::LimitError("lambert_solve: one particle's pairs exceed one binding");
            chunks.push_back({first, last, offsets[first], offsets[last] - offsets[first]});
            first = last;
        }
    }
    // View batches whose images fit one binding (diffuse/view_batches.h).
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const std::vector<ViewBatch> batches = plan_view_batches(in, surfaces, limit, "lambert_solve");
    out.summary.pair_chunks = static_cast<std::uint32_t>(chunks.size());

    gpu::Buffer particles_buf = gpu::Buffer::of<Particle>(ctx, count, "lambert particles");
    particles_buf.upload(in.particles);
    gpu::Buffer lit_buf = gpu::Buffer::of<std::uint32_t>(ctx, vis.lit.size(), "lambert lit masks");
    lit_buf.upload(vis.lit);
    std::vector<gpu::Buffer> pair_bufs;
    for (const Chunk& c : chunks)
        pair_bufs.push_back(gpu::Buffer::of<shared::LambertPairResult>(ctx, c.pairs, "lambert pair results"));

    double gpu_ns = 0.0;
    bool timed = true;
    double pair_ns = 0.0, combine_ns = 0.0;
    const auto add_time = [&](const gpu::Sequence& seq, double& bucket) {
        for (const auto& t : seq.timings()) {
            if (t.ns) {
                gpu_ns += *t.ns;
                bucket += *t.ns;
            } else {
                timed = false;
            }
        }
    };

    PackedViewBatch packed;
    for (const ViewBatch& b : batches) {
        // Views, frames and pixels of the batch.
        pack_view_batch(in, surfaces, b, packed);
        const auto& views = packed.views;
        const auto& frames = packed.frames;
        const auto& pixel_words = packed.pixel_words;
        gpu::Buffer views_buf = gpu::Buffer::of<shared::LambertViewGpu>(ctx, views.size(), "lambert views");
        views_buf.upload(views);
        gpu::Buffer frames_buf = gpu::Buffer::of<shared::LambertFrameGpu>(ctx, frames.size(), "lambert frames");
        if (!frames.empty()) frames_buf.upload(frames);
        gpu::Buffer pixels_buf = gpu::Buffer::of<std::uint32_t>(ctx, pixel_words.size(), "lambert images");
        if (!pixel_words.empty()) pixels_buf.upload(pixel_words);

        for (std::size_t ci = 0; ci < chunks.size(); ++ci) {
            const Chunk& c = chunks[ci];
            std::vector<shared::LambertPairKey> keys;
            for (std::uint32_t p = c.first; p < c.last; ++p) {
                std::uint32_t slot = offsets[p] - static_cast<std::uint32_t>(c.pair_base);
                for (std::uint32_t v = 0; v < view_count; ++v) {
                    if (in.views[v].frames.empty() || !vis.sees(p, v)) continue;
                    if (v >= b.first && v < b.last) keys.push_back({p, v - b.first, slot});
                    ++slot;
                }
            }
            if (keys.empty()) continue;
            gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertPairKey>(ctx, keys.size(), "lambert pair keys");
            keys_buf.upload(keys);
            const shared::LambertPairPush push{.dispatch = {},
                                .frame_words = vis.frame_words,
                                .mode = static_cast<std::uint32_t>(o.mode),
                                .iterations = o.highlight_iterations,
                                .min_light_cos = o.min_light_cos,
                                .tau = o.highlight_tau,
                                .k_sigma = o.highlight_k * o.noise_sigma,
                                .min_rcond = o.min_rcond,
                                .global_view_base = b.first,
                                .lobe = {o.lobe.cx.x, o.lobe.cx.y, o.lobe.cx.z, o.lobe.cz.x, o.lobe.cz.y, o.lobe.cz.z,
                                         o.lobe.n.x, o.lobe.n.y, o.lobe.n.z}};
            gpu::Sequence seq(ctx, 2);
            seq.dispatch_1d(m_impl->pair, {particles_buf, lit_buf, views_buf, frames_buf, pixels_buf, keys_buf, pair_bufs[ci]},
                            static_cast<std::uint32_t>(keys.size()), push, "lambert_solve pairs")
                .barrier(gpu::Barrier::ComputeToCompute)
                .submit_and_wait();
            add_time(seq, pair_ns);
        }
    }
    out.summary.view_batches = static_cast<std::uint32_t>(batches.size());

    for (std::size_t ci = 0; ci < chunks.size(); ++ci) {
        const Chunk& c = chunks[ci];
        const std::uint32_t n = c.last - c.first;
        std::vector<std::uint32_t> local(n + 1);
        for (std::uint32_t i = 0; i <= n; ++i) local[i] = offsets[c.first + i] - static_cast<std::uint32_t>(c.pair_base);
        gpu::Buffer off_buf = gpu::Buffer::of<std::uint32_t>(ctx, local.size(), "lambert pair offsets");
        off_buf.upload(local);
        gpu::Buffer res_buf = gpu::Buffer::of<LambertParticleResult>(ctx, n, "lambert particle results");
        const shared::LambertCombinePush push{.dispatch = {}, .particle_base = c.first, .view_tau = o.view_tau, .view_abs = o.view_abs};
        gpu::Sequence seq(ctx, 2);
        seq.dispatch_1d(m_impl->combine, {off_buf, pair_bufs[ci], particles_buf, res_buf}, n, push, "lambert_solve combine")
            .barrier(gpu::Barrier::ComputeToHost)
            .submit_and_wait();
        add_time(seq, combine_ns);
        res_buf.download(std::span<LambertParticleResult>(out.particles).subspan(c.first, n));
    }
    (void)total_pairs;
    if (timed) {
        out.summary.gpu_ms = gpu_ns * 1e-6;
        out.summary.gpu_dispatch_ms = {{"pairs", pair_ns * 1e-6}, {"combine", combine_ns * 1e-6}};
    }
    out.summary.seconds = sw.seconds();
    summarize(out);
    out.summary.tap_irradiance = surfaces != nullptr;
    return out;
}

} // namespace specula
