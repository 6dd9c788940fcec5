// Vulkan side of the directed lobe's first bounce (lobe.h; shaders/indirect/indirect_lobe.comp).
// Memory plan, every binding within the storage-buffer range `limit` (as transfer_vk.cpp's):
//  - frames go in batches whose light geometry, all sources of each frame (a row may reach any
//    source), fits one binding: rows x 16 bytes a frame. With one batch the caller's array
//    (row-major, r * frames + f) goes up as it is; with several, each batch's frames are copied
//    out source by source first;
//  - the sources' normals (rows x 16 bytes, one frame's light geometry) go up once;
//  - rows go in chunks whose entries' directions (16 bytes each, against 8 for the entries and
//    4 for the row offsets) fit one binding; a chunk's output, batch frames x chunk rows x 16
//    bytes, is at most a batch's light geometry;
//  - per (chunk, batch) one dispatch (one invocation per row of the chunk), whose output goes up
//    (the term is added to it) and comes back into `out`.
#include "indirect/lobe.h"

#include "core/error.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "shared/indirect.h"

#include "indirect/indirect_lobe.comp.h"

#include <algorithm>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace specula {

namespace {

// Chunks of rows whose entries' directions fit `limit` bytes. Any one row's do: a row has at
// most `rows` entries (its sources rise), 16 bytes each, one frame's light geometry, which the
// caller has checked against `limit`; so do a chunk's entries and offsets (fewer bytes each).
std::vector<detail::TransferRowChunk> plan_row_chunks(const IndirectTransfer& t, std::uint64_t limit) {
    return detail::transfer_row_chunks(t, limit / sizeof(glm::vec4));
}

} // namespace

struct IndirectLobeVk::Impl {
    gpu::Context* ctx;
    std::uint64_t limit;
    gpu::ComputePipeline pipeline;
    IndirectLobeStats stats;
    Impl(gpu::Context& c, std::uint64_t max_binding_bytes)
        : ctx(&c),
          limit(max_binding_bytes == 0 ? c.info().max_storage_buffer_range
                                       : std::min<std::uint64_t>(max_binding_bytes, c.info().max_storage_buffer_range)),
          pipeline(c, gpu::ComputePipelineDesc{.name = "indirect_lobe",
                                               .spirv = indirect_indirect_lobe_comp,
                                               .storage_buffers = 7,
                                               .push_constant_bytes = sizeof(shared::IndirectLobePush),
                                               .workgroup_size = 64}) {}
};

IndirectLobeVk::IndirectLobeVk(gpu::Context& ctx, std::uint64_t max_binding_bytes)
    : m_impl(std::make_unique<Impl>(ctx, max_binding_bytes)) {}
IndirectLobeVk::~IndirectLobeVk() = default;

const IndirectLobeStats& IndirectLobeVk::last_run() const noexcept { return m_impl->stats; }

void IndirectLobeVk::run(const IndirectTransfer& t, const shared::MaterialGpu& material, std::span<const glm::vec3> row_normal,
                         std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity,
                         std::uint32_t frames, std::span<glm::vec4> out) {
    validate_directed_lobe(t, row_normal.size(), light_geometry.size(), intensity.size(), frames, out.size(), "indirect_lobe");
    Impl& im = *m_impl;
    gpu::Context& ctx = *im.ctx;
    im.stats = {};
    if (t.rows == 0 || frames == 0) return;
    const std::uint64_t limit = im.limit;
    const std::uint64_t frame_bytes = std::uint64_t{t.rows} * sizeof(glm::vec4);
    if (frame_bytes > limit)
        throw gpu::LimitError("indirect_lobe: one frame's light geometry of " + std::to_string(t.rows) + " rows (" +
                              std::to_string(frame_bytes) + " bytes) exceeds one storage binding (" + std::to_string(limit) +
                              " bytes); splitting the sources is not implemented");
    const auto batch = static_cast<std::uint32_t>(std::min<std::uint64_t>(frames, limit / frame_bytes));
    const std::vector<detail::TransferRowChunk> chunks = plan_row_chunks(t, limit);
    im.stats.row_chunks = static_cast<std::uint32_t>(chunks.size());
    im.stats.frame_batches = (frames + batch - 1) / batch;

    const std::size_t rows = t.rows;
    std::vector<glm::vec4> staged(rows); // std430 arrays of vec3 have a 16-byte stride
    for (std::size_t j = 0; j < rows; ++j) staged[j] = glm::vec4(row_normal[j], 0.0f);
    gpu::Buffer normals = gpu::Buffer::of<glm::vec4>(ctx, rows, "indirect lobe normals");
    normals.upload(staged);

    double ns = 0.0;
    bool timed = true;
    std::optional<gpu::Buffer> batch_light, batch_intensity;
    std::uint32_t batch_first = frames; // the frames batch_light holds: [batch_first, + batch)
    for (const detail::TransferRowChunk& c : chunks) {
        const std::uint32_t n = c.last - c.first;
        const std::uint32_t entry_base = t.row_begin[c.first];
        const std::uint32_t entry_count = t.row_begin[c.last] - entry_base;
        gpu::Buffer offsets = gpu::Buffer::of<std::uint32_t>(ctx, n + 1, "indirect lobe row offsets");
        offsets.upload(std::span(t.row_begin).subspan(c.first, n + 1));
        gpu::Buffer entries = gpu::Buffer::of<TransferEntry>(ctx, entry_count, "indirect lobe entries");
        gpu::Buffer directions = gpu::Buffer::of<glm::vec4>(ctx, entry_count, "indirect lobe entry directions");
        if (entry_count > 0) {
            entries.upload(std::span(t.entries).subspan(entry_base, entry_count));
            directions.upload(std::span(t.entry_direction).subspan(entry_base, entry_count));
        }
        for (std::uint32_t f0 = 0; f0 < frames; f0 += batch) {
            const std::uint32_t nf = std::min(batch, frames - f0);
            if (batch_first != f0) {
                batch_light.reset(); // before the next one is allocated: one batch held at a time
                batch_light.emplace(gpu::Buffer::of<glm::vec4>(ctx, std::size_t{nf} * rows, "indirect lobe light geometry"));
                if (nf == frames) {
                    batch_light->upload(light_geometry);
                } else {
                    staged.resize(std::size_t{nf} * rows);
                    for (std::size_t j = 0; j < rows; ++j)
                        std::copy_n(light_geometry.begin() + static_cast<std::ptrdiff_t>(j * frames + f0), nf,
                                    staged.begin() + static_cast<std::ptrdiff_t>(j * nf));
                    batch_light->upload(staged);
                }
                std::vector<glm::vec4> i(nf);
                for (std::uint32_t f = 0; f < nf; ++f) i[f] = glm::vec4(intensity[f0 + f], 0.0f);
                batch_intensity.reset();
                batch_intensity.emplace(gpu::Buffer::of<glm::vec4>(ctx, nf, "indirect lobe intensity"));
                batch_intensity->upload(i);
                batch_first = f0;
            }
            gpu::Buffer added = gpu::Buffer::of<glm::vec4>(ctx, std::size_t{nf} * n, "indirect lobe output");
            for (std::uint32_t f = 0; f < nf; ++f)
                added.upload(std::span<const glm::vec4>(out.subspan((f0 + f) * rows + c.first, n)), std::size_t{f} * n);
            const shared::IndirectLobePush push{
                .dispatch = {}, .rows = n, .entry_base = entry_base, .frames = nf, .material = material};
            gpu::Sequence seq(ctx, 1);
            seq.dispatch_1d(im.pipeline, {offsets, entries, directions, normals, *batch_light, *batch_intensity, added}, n,
                            push, "indirect_lobe")
                .barrier(gpu::Barrier::ComputeToHost)
                .submit_and_wait();
            for (const gpu::GpuTiming& timing : seq.timings()) {
                if (timing.ns) ns += *timing.ns;
                else timed = false;
            }
            for (std::uint32_t f = 0; f < nf; ++f) added.download(out.subspan((f0 + f) * rows + c.first, n), std::size_t{f} * n);
        }
    }
    if (timed) im.stats.gpu_ms = ns * 1e-6;
}

} // namespace specula
