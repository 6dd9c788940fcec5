// Vulkan side of the Lambert solve (memory plan in lambert_solve.h):
//  1. particles and the `lit` masks are uploaded once, with the table of all views and
//     their train frames;
//  2. particles are cut into chunks whose records and pair results each fit one binding,
//     the train frames into image batches that fit one binding (a view may span batches);
//  3. per image batch: its images go up (RGBA32: rgb floats, flags word), then per chunk one
//     dispatch of lambert_gather.comp writes the records of the batch's frames;
//  4. per chunk: one dispatch of lambert_solve.comp over its pairs, one of
//     lambert_solve_combine.comp over its particles, and the results come down.
#include "diffuse/lambert_solve.h"
#include "diffuse/view_batches.h"

#include "core/error.h"
#include "core/timer.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"

#include "diffuse/lambert_gather.comp.h"
#include "diffuse/lambert_solve.comp.h"
#include "diffuse/lambert_solve_combine.comp.h"

#include <algorithm>
#include <cstring>
#include <optional>

namespace specula {

namespace {

struct Chunk {
    std::uint32_t first = 0, last = 0; // particles [first, last)
    std::uint64_t pair_base = 0;       // global pair index of the chunk's first pair
    std::uint64_t pairs = 0;
    std::uint64_t record_base = 0;     // global record index of the chunk's first record
    std::uint64_t records = 0;
};

} // namespace

struct LambertSolveVk::Impl {
    gpu::Context* ctx;
    gpu::ComputePipeline gather;
    gpu::ComputePipeline pair;
    gpu::ComputePipeline combine;
    explicit Impl(gpu::Context& c)
        : ctx(&c),
          gather(c, gpu::ComputePipelineDesc{.name = "lambert_gather",
                                             .spirv = diffuse_lambert_gather_comp,
                                             .storage_buffers = 7,
                                             .push_constant_bytes = sizeof(shared::LambertGatherPush),
                                             .workgroup_size = 64}),
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

    // Pairs: particle-major, views in order; offsets[p] = first pair of p. Each pair owns one
    // record per train frame of its view; records[p] = first record of p.
    const std::uint32_t view_count = static_cast<std::uint32_t>(in.views.size());
    std::vector<std::uint32_t> offsets(count + 1, 0);
    std::vector<std::uint64_t> records(count + 1, 0);
    for (std::size_t p = 0; p < count; ++p) {
        std::uint32_t n = 0;
        std::uint64_t r = 0;
        for (std::uint32_t v = 0; v < view_count; ++v)
            if (!in.views[v].frames.empty() && vis.sees(p, v)) {
                ++n;
                r += in.views[v].frames.size();
            }
        offsets[p + 1] = offsets[p] + n;
        records[p + 1] = records[p] + r;
    }
    // Each pair's records, in the order of the pairs (visits `fn(particle, view, slot, record)`,
    // slot and record relative to the chunk).
    const auto for_pairs = [&](const Chunk& c, const auto& fn) {
        for (std::uint32_t p = c.first; p < c.last; ++p) {
            std::uint32_t slot = offsets[p] - static_cast<std::uint32_t>(c.pair_base);
            std::uint64_t record = records[p] - c.record_base;
            for (std::uint32_t v = 0; v < view_count; ++v) {
                if (in.views[v].frames.empty() || !vis.sees(p, v)) continue;
                fn(p, v, slot++, static_cast<std::uint32_t>(record));
                record += in.views[v].frames.size();
            }
        }
    };

    // Chunks of particles whose pair results, records (and combine results) fit one binding.
    std::vector<Chunk> chunks;
    {
        const std::uint64_t max_pairs = limit / sizeof(shared::LambertPairResult);
        const std::uint64_t max_records = limit / sizeof(glm::vec4);
        const std::uint64_t max_particles = std::min<std::uint64_t>(limit / sizeof(LambertParticleResult), limit / 4 - 1);
        std::uint32_t first = 0;
        while (first < count) {
            std::uint32_t last = first;
            while (last < count && last - first < max_particles && offsets[last + 1] - offsets[first] <= max_pairs &&
                   records[last + 1] - records[first] <= max_records)
                ++last;
            if (last == first)
                throw gpu::LimitError("lambert_solve: the " + std::to_string(records[first + 1] - records[first]) +
                                      " samples of particle " + std::to_string(first) + " (" + std::to_string(sizeof(glm::vec4)) +
                                      " bytes each) exceed one storage binding (" + std::to_string(limit) + " bytes)");
            chunks.push_back({first, last, offsets[first], offsets[last] - offsets[first], records[first],
                              records[last] - records[first]});
            first = last;
        }
    }
    // Image batches that fit one binding (diffuse/view_batches.h).
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const std::vector<ViewBatch> batches = plan_view_batches(in, surfaces, limit, "lambert_solve");
    out.summary.pair_chunks = static_cast<std::uint32_t>(chunks.size());
    out.summary.view_batches = static_cast<std::uint32_t>(batches.size());

    gpu::Buffer particles_buf = gpu::Buffer::of<Particle>(ctx, count, "lambert particles");
    particles_buf.upload(in.particles);
    gpu::Buffer lit_buf = gpu::Buffer::of<std::uint32_t>(ctx, vis.lit.size(), "lambert lit masks");
    lit_buf.upload(vis.lit);
    double gpu_ns = 0.0;
    bool timed = true;
    double gather_ns = 0.0, pair_ns = 0.0, combine_ns = 0.0;
    const auto run = [&](gpu::Sequence& seq, double& bucket) {
        seq.submit_and_wait();
        for (const auto& t : seq.timings()) {
            if (t.ns) {
                gpu_ns += *t.ns;
                bucket += *t.ns;
            } else {
                timed = false;
            }
        }
    };

    // The table of all views and their train frames, for the pair step.
    std::vector<shared::LambertViewGpu> all_views;
    std::vector<shared::LambertFrameGpu> all_frames;
    for (std::uint32_t v = 0; v < view_count; ++v) {
        shared::LambertViewGpu g = gpu_view(in, v);
        g.frame_first = static_cast<std::uint32_t>(all_frames.size());
        g.frame_count = static_cast<std::uint32_t>(in.views[v].frames.size());
        all_views.push_back(g);
        for (std::uint32_t f : in.views[v].frames) all_frames.push_back(gpu_frame(in, f));
    }
    gpu::Buffer all_views_buf = gpu::Buffer::of<shared::LambertViewGpu>(ctx, all_views.size(), "lambert all views");
    all_views_buf.upload(all_views);
    gpu::Buffer all_frames_buf = gpu::Buffer::of<shared::LambertFrameGpu>(ctx, all_frames.size(), "lambert all frames");
    if (!all_frames.empty()) all_frames_buf.upload(all_frames);

    const std::uint64_t group_limit = o.max_record_group_bytes != 0 ? o.max_record_group_bytes : kLambertRecordGroupBytes;
    const shared::LambertGatherPush gather_push{
        .dispatch = {}, .frame_words = vis.frame_words, .min_light_cos = o.min_light_cos, .material = material_gpu(o.material)};
    const shared::LambertPairPush pair_push{.dispatch = {},
                                            .mode = static_cast<std::uint32_t>(o.mode),
                                            .iterations = o.highlight_iterations,
                                            .tau = o.highlight_tau,
                                            .k_sigma = o.highlight_k * o.noise_sigma,
                                            .min_rcond = o.min_rcond,
                                            .pad0 = 0};
    // Chunks in groups whose records, alive from the gather to the pair step, stay within
    // kLambertRecordGroupBytes (the images go up once per group: a photometric rig's records,
    // 16 bytes per pair and frame, would otherwise all be held at once).
    PackedViewBatch packed;
    std::vector<std::int32_t> segment_of(view_count, -1); // view -> its segment in the batch
    for (std::size_t g0 = 0; g0 < chunks.size();) {
        std::size_t g1 = g0 + 1;
        std::uint64_t group_bytes = chunks[g0].records * sizeof(glm::vec4);
        while (g1 < chunks.size() && group_bytes + chunks[g1].records * sizeof(glm::vec4) <= group_limit)
            group_bytes += chunks[g1++].records * sizeof(glm::vec4);
        ++out.summary.record_groups;
        std::vector<std::optional<gpu::Buffer>> record_bufs(chunks.size());
        for (std::size_t ci = g0; ci < g1; ++ci)
            record_bufs[ci].emplace(gpu::Buffer::of<glm::vec4>(ctx, chunks[ci].records, "lambert sample records"));

        // Gather: the records of each batch's frames.
        for (const ViewBatch& b : batches) {
            pack_view_batch(in, surfaces, b, packed);
            gpu::Buffer views_buf = gpu::Buffer::of<shared::LambertViewGpu>(ctx, packed.views.size(), "lambert views");
            views_buf.upload(packed.views);
            gpu::Buffer frames_buf = gpu::Buffer::of<shared::LambertFrameGpu>(ctx, packed.frames.size(), "lambert frames");
            frames_buf.upload(packed.frames);
            gpu::Buffer pixels_buf = gpu::Buffer::of<std::uint32_t>(ctx, packed.pixel_words.size(), "lambert images");
            pixels_buf.upload(packed.pixel_words);
            std::fill(segment_of.begin(), segment_of.end(), -1);
            for (std::size_t i = 0; i < b.segments.size(); ++i) segment_of[b.segments[i].view] = static_cast<std::int32_t>(i);
            for (std::size_t ci = g0; ci < g1; ++ci) {
                std::vector<shared::LambertPairKey> keys;
                for_pairs(chunks[ci], [&](std::uint32_t p, std::uint32_t v, std::uint32_t, std::uint32_t record) {
                    if (const std::int32_t si = segment_of[v]; si >= 0)
                        keys.push_back({p, static_cast<std::uint32_t>(si), record + b.segments[std::size_t(si)].frame_first});
                });
                if (keys.empty()) continue;
                gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertPairKey>(ctx, keys.size(), "lambert gather keys");
                keys_buf.upload(keys);
                gpu::Sequence seq(ctx, 2);
                seq.dispatch_1d(m_impl->gather, {particles_buf, lit_buf, views_buf, frames_buf, pixels_buf, keys_buf, *record_bufs[ci]},
                                static_cast<std::uint32_t>(keys.size()), gather_push, "lambert_solve gather")
                    .barrier(gpu::Barrier::ComputeToCompute);
                run(seq, gather_ns);
            }
        }

        // Pair and combine steps, per chunk of the group.
        for (std::size_t ci = g0; ci < g1; ++ci) {
            const Chunk& c = chunks[ci];
            const std::uint32_t n = c.last - c.first;
            gpu::Buffer pair_buf = gpu::Buffer::of<shared::LambertPairResult>(ctx, c.pairs, "lambert pair results");
            std::vector<shared::LambertSolveKey> keys;
            keys.reserve(c.pairs);
            for_pairs(c, [&](std::uint32_t p, std::uint32_t v, std::uint32_t slot, std::uint32_t record) {
                keys.push_back({p, v, slot, record});
            });
            if (!keys.empty()) {
                gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertSolveKey>(ctx, keys.size(), "lambert pair keys");
                keys_buf.upload(keys);
                gpu::Buffer scratch_buf = gpu::Buffer::of<float>(ctx, c.records, "lambert selection scratch");
                gpu::Sequence seq(ctx, 2);
                seq.dispatch_1d(m_impl->pair,
                                {particles_buf, all_views_buf, all_frames_buf, *record_bufs[ci], scratch_buf, keys_buf, pair_buf},
                                static_cast<std::uint32_t>(keys.size()), pair_push, "lambert_solve pairs")
                    .barrier(gpu::Barrier::ComputeToCompute);
                run(seq, pair_ns);
            }
            record_bufs[ci].reset(); // the chunk's records are no longer needed
            std::vector<std::uint32_t> local(n + 1);
            for (std::uint32_t i = 0; i <= n; ++i) local[i] = offsets[c.first + i] - static_cast<std::uint32_t>(c.pair_base);
            gpu::Buffer off_buf = gpu::Buffer::of<std::uint32_t>(ctx, local.size(), "lambert pair offsets");
            off_buf.upload(local);
            gpu::Buffer res_buf = gpu::Buffer::of<LambertParticleResult>(ctx, n, "lambert particle results");
            const shared::LambertCombinePush push{
                .dispatch = {}, .particle_base = c.first, .view_tau = o.view_tau, .view_abs = o.view_abs};
            gpu::Sequence seq(ctx, 2);
            seq.dispatch_1d(m_impl->combine, {off_buf, pair_buf, particles_buf, res_buf}, n, push, "lambert_solve combine")
                .barrier(gpu::Barrier::ComputeToHost);
            run(seq, combine_ns);
            res_buf.download(std::span<LambertParticleResult>(out.particles).subspan(c.first, n));
        }
        g0 = g1;
    }
    if (timed) {
        out.summary.gpu_ms = gpu_ns * 1e-6;
        out.summary.gpu_dispatch_ms = {{"gather", gather_ns * 1e-6}, {"pairs", pair_ns * 1e-6}, {"combine", combine_ns * 1e-6}};
    }
    out.summary.seconds = sw.seconds();
    summarize(out);
    out.summary.tap_irradiance = surfaces != nullptr;
    return out;
}

} // namespace specula
