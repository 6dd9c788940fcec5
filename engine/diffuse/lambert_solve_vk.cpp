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

namespace {

// The pairs of a solve: particle-major, views in order; offsets[p] = first pair of p. Each
// pair owns one record per train frame of its view; records[p] = first record of p. Chunks
// of particles whose pair results, records (and combine results) fit one binding.
struct PairPlan {
    std::vector<std::uint32_t> offsets;
    std::vector<std::uint64_t> records;
    std::vector<Chunk> chunks;
};

PairPlan plan_pairs(const LambertInputs& in, std::uint64_t limit) {
    const Visibility& vis = *in.visibility;
    const std::size_t count = in.particles.size();
    PairPlan plan;
    plan.offsets.assign(count + 1, 0);
    plan.records.assign(count + 1, 0);
    for (std::size_t p = 0; p < count; ++p) {
        std::uint32_t n = 0;
        std::uint64_t r = 0;
        for (std::uint32_t v = 0; v < in.views.size(); ++v)
            if (!in.views[v].frames.empty() && vis.sees(p, v)) {
                ++n;
                r += in.views[v].frames.size();
            }
        plan.offsets[p + 1] = plan.offsets[p] + n;
        plan.records[p + 1] = plan.records[p] + r;
    }
    const auto& offsets = plan.offsets;
    const auto& records = plan.records;
    const std::uint64_t max_pairs = limit / sizeof(shared::LambertPairResult);
    const std::uint64_t max_records = limit / sizeof(glm::vec4);
    const std::uint64_t max_particles = std::min<std::uint64_t>(limit / sizeof(LambertParticleResult), limit / 4 - 1);
    for (std::uint32_t first = 0; first < count;) {
        std::uint32_t last = first;
        while (last < count && last - first < max_particles && offsets[last + 1] - offsets[first] <= max_pairs &&
               records[last + 1] - records[first] <= max_records)
            ++last;
        if (last == first)
            throw gpu::LimitError("lambert_solve: the " + std::to_string(records[first + 1] - records[first]) +
                                  " samples of particle " + std::to_string(first) + " (" + std::to_string(sizeof(glm::vec4)) +
                                  " bytes each) exceed one storage binding (" + std::to_string(limit) + " bytes)");
        plan.chunks.push_back(
            {first, last, offsets[first], offsets[last] - offsets[first], records[first], records[last] - records[first]});
        first = last;
    }
    return plan;
}

// One run of the three steps (memory plan at the top of the file).
class SolveRun {
public:
    SolveRun(gpu::Context& ctx, const gpu::ComputePipeline& gather, const gpu::ComputePipeline& pair,
             const gpu::ComputePipeline& combine, const LambertInputs& in, const LambertOptions& o, std::uint64_t limit)
        : m_ctx(ctx), m_gather(gather), m_pair(pair), m_combine(combine), m_in(in), m_o(o), m_plan(plan_pairs(in, limit)),
          m_surfaces(tap_surfaces(in, o.tap_irradiance)),
          m_batches(plan_view_batches(in, m_surfaces, limit, "lambert_solve")),
          m_particles(gpu::Buffer::of<Particle>(ctx, in.particles.size(), "lambert particles")),
          m_lit(gpu::Buffer::of<std::uint32_t>(ctx, in.visibility->lit.size(), "lambert lit masks")),
          m_all_views(gpu::Buffer::of<shared::LambertViewGpu>(ctx, in.views.size(), "lambert all views")),
          m_all_frames(gpu::Buffer::of<shared::LambertFrameGpu>(ctx, frame_count(in), "lambert all frames")) {
        m_particles.upload(in.particles);
        m_lit.upload(in.visibility->lit);
        // The table of all views and their train frames, for the pair step.
        std::vector<shared::LambertViewGpu> views;
        std::vector<shared::LambertFrameGpu> frames;
        for (std::uint32_t v = 0; v < in.views.size(); ++v) {
            shared::LambertViewGpu g = gpu_view(in, v);
            g.frame_first = static_cast<std::uint32_t>(frames.size());
            g.frame_count = static_cast<std::uint32_t>(in.views[v].frames.size());
            views.push_back(g);
            for (std::uint32_t f : in.views[v].frames) frames.push_back(gpu_frame(in, f));
        }
        m_all_views.upload(views);
        if (!frames.empty()) m_all_frames.upload(frames);
    }

    // Chunks in groups whose records, alive from the gather to the pair step, stay within
    // `group_limit` bytes (the images go up once per group: a photometric rig's records,
    // 16 bytes per pair and frame, would otherwise all be held at once).
    void run(std::span<LambertParticleResult> out, std::uint64_t group_limit, LambertSummary& summary) {
        const std::vector<Chunk>& chunks = m_plan.chunks;
        for (std::size_t g0 = 0; g0 < chunks.size();) {
            std::size_t g1 = g0 + 1;
            std::uint64_t bytes = chunks[g0].records * sizeof(glm::vec4);
            while (g1 < chunks.size() && bytes + chunks[g1].records * sizeof(glm::vec4) <= group_limit)
                bytes += chunks[g1++].records * sizeof(glm::vec4);
            ++summary.record_groups;
            std::vector<std::optional<gpu::Buffer>> records(chunks.size());
            for (std::size_t ci = g0; ci < g1; ++ci)
                records[ci].emplace(gpu::Buffer::of<glm::vec4>(m_ctx, chunks[ci].records, "lambert sample records"));
            for (const ViewBatch& b : m_batches) gather(b, g0, g1, records);
            for (std::size_t ci = g0; ci < g1; ++ci) {
                solve_chunk(chunks[ci], *records[ci], out);
                records[ci].reset(); // the chunk's records are no longer needed
            }
            g0 = g1;
        }
        summary.pair_chunks = static_cast<std::uint32_t>(chunks.size());
        summary.view_batches = static_cast<std::uint32_t>(m_batches.size());
        if (m_timed) {
            summary.gpu_ms = (m_gather_ns + m_pair_ns + m_combine_ns) * 1e-6;
            summary.gpu_dispatch_ms = {{"gather", m_gather_ns * 1e-6}, {"pairs", m_pair_ns * 1e-6}, {"combine", m_combine_ns * 1e-6}};
        }
    }

private:
    static std::size_t frame_count(const LambertInputs& in) {
        std::size_t n = 0;
        for (const LambertView& v : in.views) n += v.frames.size();
        return n;
    }

    // Each pair of chunk c in order: fn(particle, view, slot, record), slot and record relative to the chunk.
    template <class Fn>
    void for_pairs(const Chunk& c, const Fn& fn) const {
        const Visibility& vis = *m_in.visibility;
        for (std::uint32_t p = c.first; p < c.last; ++p) {
            std::uint32_t slot = m_plan.offsets[p] - static_cast<std::uint32_t>(c.pair_base);
            std::uint64_t record = m_plan.records[p] - c.record_base;
            for (std::uint32_t v = 0; v < m_in.views.size(); ++v) {
                if (m_in.views[v].frames.empty() || !vis.sees(p, v)) continue;
                fn(p, v, slot++, static_cast<std::uint32_t>(record));
                record += m_in.views[v].frames.size();
            }
        }
    }

    void submit(gpu::Sequence& seq, double& bucket) {
        seq.submit_and_wait();
        for (const auto& t : seq.timings()) {
            if (t.ns) bucket += *t.ns;
            else m_timed = false;
        }
    }

    // The records of batch b's frames for the chunks [g0, g1).
    void gather(const ViewBatch& b, std::size_t g0, std::size_t g1, std::vector<std::optional<gpu::Buffer>>& records) {
        pack_view_batch(m_in, m_surfaces, b, m_packed);
        const UploadedViewBatch up = upload_view_batch(m_ctx, m_packed, "lambert");
        std::vector<std::int32_t> segment_of(m_in.views.size(), -1); // view -> its segment in the batch
        for (std::size_t i = 0; i < b.segments.size(); ++i) segment_of[b.segments[i].view] = static_cast<std::int32_t>(i);
        const shared::LambertGatherPush push{.dispatch = {},
                                             .frame_words = m_in.visibility->frame_words,
                                             .min_light_cos = m_o.min_light_cos,
                                             .material = material_gpu(m_o.material)};
        for (std::size_t ci = g0; ci < g1; ++ci) {
            std::vector<shared::LambertPairKey> keys;
            for_pairs(m_plan.chunks[ci], [&](std::uint32_t p, std::uint32_t v, std::uint32_t, std::uint32_t record) {
                if (const std::int32_t si = segment_of[v]; si >= 0)
                    keys.push_back({p, static_cast<std::uint32_t>(si), record + b.segments[std::size_t(si)].frame_first});
            });
            if (keys.empty()) continue;
            gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertPairKey>(m_ctx, keys.size(), "lambert gather keys");
            keys_buf.upload(keys);
            gpu::Sequence seq(m_ctx, 2);
            seq.dispatch_1d(m_gather, {m_particles, m_lit, up.views, up.frames, up.pixels, keys_buf, *records[ci]},
                            static_cast<std::uint32_t>(keys.size()), push, "lambert_solve gather")
                .barrier(gpu::Barrier::ComputeToCompute);
            submit(seq, m_gather_ns);
        }
    }

    // The pair and combine steps of one chunk, whose records are complete; its particles' results into `out`.
    void solve_chunk(const Chunk& c, const gpu::Buffer& records, std::span<LambertParticleResult> out) {
        const std::uint32_t n = c.last - c.first;
        gpu::Buffer pair_buf = gpu::Buffer::of<shared::LambertPairResult>(m_ctx, c.pairs, "lambert pair results");
        std::vector<shared::LambertSolveKey> keys;
        keys.reserve(c.pairs);
        for_pairs(c, [&](std::uint32_t p, std::uint32_t v, std::uint32_t slot, std::uint32_t record) {
            keys.push_back({p, v, slot, record});
        });
        if (!keys.empty()) {
            gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertSolveKey>(m_ctx, keys.size(), "lambert pair keys");
            keys_buf.upload(keys);
            gpu::Buffer scratch = gpu::Buffer::of<float>(m_ctx, c.records, "lambert selection scratch");
            const shared::LambertPairPush push{.dispatch = {},
                                               .mode = static_cast<std::uint32_t>(m_o.mode),
                                               .iterations = m_o.highlight_iterations,
                                               .tau = m_o.highlight_tau,
                                               .k_sigma = m_o.highlight_k * m_o.noise_sigma,
                                               .min_rcond = m_o.min_rcond,
                                               .pad0 = 0};
            gpu::Sequence seq(m_ctx, 2);
            seq.dispatch_1d(m_pair, {m_particles, m_all_views, m_all_frames, records, scratch, keys_buf, pair_buf},
                            static_cast<std::uint32_t>(keys.size()), push, "lambert_solve pairs")
                .barrier(gpu::Barrier::ComputeToCompute);
            submit(seq, m_pair_ns);
        }
        std::vector<std::uint32_t> local(n + 1);
        for (std::uint32_t i = 0; i <= n; ++i) local[i] = m_plan.offsets[c.first + i] - static_cast<std::uint32_t>(c.pair_base);
        gpu::Buffer off_buf = gpu::Buffer::of<std::uint32_t>(m_ctx, local.size(), "lambert pair offsets");
        off_buf.upload(local);
        gpu::Buffer res_buf = gpu::Buffer::of<LambertParticleResult>(m_ctx, n, "lambert particle results");
        const shared::LambertCombinePush push{.dispatch = {}, .particle_base = c.first, .view_tau = m_o.view_tau, .view_abs = m_o.view_abs};
        gpu::Sequence seq(m_ctx, 2);
        seq.dispatch_1d(m_combine, {off_buf, pair_buf, m_particles, res_buf}, n, push, "lambert_solve combine")
            .barrier(gpu::Barrier::ComputeToHost);
        submit(seq, m_combine_ns);
        res_buf.download(out.subspan(c.first, n));
    }

    gpu::Context& m_ctx;
    const gpu::ComputePipeline& m_gather;
    const gpu::ComputePipeline& m_pair;
    const gpu::ComputePipeline& m_combine;
    const LambertInputs& m_in;
    const LambertOptions& m_o;
    PairPlan m_plan;
    const std::vector<SurfaceMap>* m_surfaces;
    std::vector<ViewBatch> m_batches;
    gpu::Buffer m_particles, m_lit, m_all_views, m_all_frames;
    PackedViewBatch m_packed;
    double m_gather_ns = 0.0, m_pair_ns = 0.0, m_combine_ns = 0.0;
    bool m_timed = true;
};

} // namespace

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
    std::uint64_t limit = device_limit; // for the batched bindings: images, records, pair results
    if (o.max_binding_bytes != 0) limit = std::min(limit, o.max_binding_bytes);
    if (count * sizeof(Particle) > device_limit || vis.lit.size() * sizeof(std::uint32_t) > device_limit)
        throw gpu::LimitError("lambert_solve: " + std::to_string(count) + " particles (or their lit masks) exceed one storage binding (" +
                         std::to_string(device_limit) + " bytes); particle chunking of these inputs is not implemented");
    SolveRun run(ctx, m_impl->gather, m_impl->pair, m_impl->combine, in, o, limit);
    run.run(out.particles, o.max_record_group_bytes != 0 ? o.max_record_group_bytes : kLambertRecordGroupBytes, out.summary);
    out.summary.seconds = sw.seconds();
    summarize(out);
    out.summary.tap_irradiance = tap_surfaces(in, o.tap_irradiance) != nullptr;
    return out;
}

} // namespace specula
