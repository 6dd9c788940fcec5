// Vulkan side of the indirect-light gather (transfer.h; shaders/indirect/indirect_gather.comp).
// Memory plan, every binding within the storage-buffer range `limit`:
//  - frames go in batches whose radiosity, all rows of each frame (a row may reach any
//    particle), fits one binding: rows x 16 bytes a frame;
//  - rows go in chunks whose entries (8 bytes each) and row offsets fit one binding; a chunk's
//    output, batch frames x chunk rows x 16 bytes, is at most a batch's radiosity;
//  - per chunk its offsets and entries go up once; per (chunk, batch) one dispatch (one
//    invocation per row of the chunk, shared/indirect.h), whose output comes down into `out`.
//    A batch's radiosity goes up once when there is one batch (the usual case: 16 frames of
//    200k particles are 51 MB), else once per chunk.
#include "indirect/transfer.h"

#include "core/error.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "shared/indirect.h"

#include "indirect/indirect_gather.comp.h"

#include <algorithm>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace specula {

static_assert(sizeof(TransferEntry) == sizeof(shared::IndirectEntry) &&
                  offsetof(TransferEntry, weight) == offsetof(shared::IndirectEntry, weight),
              "TransferEntry is uploaded as shared::IndirectEntry");

namespace {

// Chunks of rows whose entries fit `limit` bytes. Their row offsets fit too, and so does any
// one row: a row has at most `rows` entries (its sources rise), 8 bytes each, and a chunk at
// most rows + 1 offsets of 4 bytes, both below one frame's radiosity (16 bytes a row), which
// the caller has checked against `limit`.
std::vector<detail::TransferRowChunk> plan_row_chunks(const IndirectTransfer& t, std::uint64_t limit) {
    return detail::transfer_row_chunks(t, limit / sizeof(TransferEntry));
}

} // namespace

struct IndirectGatherVk::Impl {
    gpu::Context* ctx;
    std::uint64_t limit;
    gpu::ComputePipeline pipeline;
    IndirectGatherStats stats;
    Impl(gpu::Context& c, std::uint64_t max_binding_bytes)
        : ctx(&c),
          limit(max_binding_bytes == 0 ? c.info().max_storage_buffer_range
                                       : std::min<std::uint64_t>(max_binding_bytes, c.info().max_storage_buffer_range)),
          pipeline(c, gpu::ComputePipelineDesc{.name = "indirect_gather",
                                               .spirv = indirect_indirect_gather_comp,
                                               .storage_buffers = 4,
                                               .push_constant_bytes = sizeof(shared::IndirectGatherPush),
                                               .workgroup_size = 64}) {}
};

IndirectGatherVk::IndirectGatherVk(gpu::Context& ctx, std::uint64_t max_binding_bytes)
    : m_impl(std::make_unique<Impl>(ctx, max_binding_bytes)) {}
IndirectGatherVk::~IndirectGatherVk() = default;

const IndirectGatherStats& IndirectGatherVk::last_run() const noexcept { return m_impl->stats; }

void IndirectGatherVk::run(const IndirectTransfer& t, std::span<const glm::vec4> radiosity, std::uint32_t frames,
                           std::span<glm::vec4> out) {
    validate_gather(t, radiosity.size(), frames, out.size(), "indirect_gather");
    Impl& im = *m_impl;
    gpu::Context& ctx = *im.ctx;
    im.stats = {};
    if (t.rows == 0 || frames == 0) return;
    const std::uint64_t limit = im.limit;
    const std::uint64_t frame_bytes = std::uint64_t{t.rows} * sizeof(glm::vec4);
    if (frame_bytes > limit)
        throw gpu::LimitError("indirect_gather: one frame's radiosity of " + std::to_string(t.rows) + " particles (" +
                              std::to_string(frame_bytes) + " bytes) exceeds one storage binding (" + std::to_string(limit) +
                              " bytes); splitting the sources is not implemented");
    const auto batch = static_cast<std::uint32_t>(std::min<std::uint64_t>(frames, limit / frame_bytes));
    const std::vector<detail::TransferRowChunk> chunks = plan_row_chunks(t, limit);
    im.stats.row_chunks = static_cast<std::uint32_t>(chunks.size());
    im.stats.frame_batches = (frames + batch - 1) / batch;

    const std::size_t rows = t.rows;
    double ns = 0.0;
    bool timed = true;
    std::optional<gpu::Buffer> batch_radiosity;
    std::uint32_t batch_first = frames; // the frames batch_radiosity holds: [batch_first, + batch)
    for (const detail::TransferRowChunk& c : chunks) {
        const std::uint32_t n = c.last - c.first;
        const std::uint32_t entry_base = t.row_begin[c.first];
        const std::uint32_t entry_count = t.row_begin[c.last] - entry_base;
        gpu::Buffer offsets = gpu::Buffer::of<std::uint32_t>(ctx, n + 1, "indirect row offsets");
        offsets.upload(std::span(t.row_begin).subspan(c.first, n + 1));
        gpu::Buffer entries = gpu::Buffer::of<TransferEntry>(ctx, entry_count, "indirect transfer entries");
        if (entry_count > 0) entries.upload(std::span(t.entries).subspan(entry_base, entry_count));
        for (std::uint32_t f0 = 0; f0 < frames; f0 += batch) {
            const std::uint32_t nf = std::min(batch, frames - f0);
            if (batch_first != f0) {
                batch_radiosity.reset(); // before the next one is allocated: one batch held at a time
                batch_radiosity.emplace(gpu::Buffer::of<glm::vec4>(ctx, std::size_t{nf} * rows, "indirect radiosity"));
                batch_radiosity->upload(radiosity.subspan(std::size_t{f0} * rows, std::size_t{nf} * rows));
                batch_first = f0;
            }
            gpu::Buffer gathered = gpu::Buffer::of<glm::vec4>(ctx, std::size_t{nf} * n, "indirect gathered");
            const shared::IndirectGatherPush push{.dispatch = {}, .rows = n, .entry_base = entry_base, .frames = nf,
                                                  .sources = t.rows};
            gpu::Sequence seq(ctx, 1);
            seq.dispatch_1d(im.pipeline, {offsets, entries, *batch_radiosity, gathered}, n, push, "indirect_gather")
                .barrier(gpu::Barrier::ComputeToHost)
                .submit_and_wait();
            for (const gpu::GpuTiming& timing : seq.timings()) {
                if (timing.ns) ns += *timing.ns;
                else timed = false;
            }
            for (std::uint32_t f = 0; f < nf; ++f)
                gathered.download(out.subspan((f0 + f) * rows + c.first, n), std::size_t{f} * n);
        }
    }
    if (timed) im.stats.gpu_ms = ns * 1e-6;
}

} // namespace specula
