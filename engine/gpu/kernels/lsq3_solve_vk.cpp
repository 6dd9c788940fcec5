// Vulkan side of lsq3_solve: uploads the CSR offsets and rows, dispatches
// shaders/core/lsq3_solve.comp over the elements (split by Sequence::dispatch_1d
// beyond maxComputeWorkGroupCount), reads the results back. Problems whose rows
// exceed one binding (maxStorageBufferRange) are solved in chunks of whole elements.
#include "gpu/kernels/lsq3_solve.h"

#include "core/error.h"

#include "core/lsq3_solve.comp.h"

#include <algorithm>

namespace specula::gpu {

namespace {

struct Lsq3Push {
    DispatchHeader dispatch; // bytes 0..7 (shared/dispatch.h)
    uint32_t row_base;       // row_offsets[first element of the chunk]
    uint32_t pad = 0;
};
static_assert(sizeof(Lsq3Push) == 16 && offsetof(Lsq3Push, row_base) == 8);

// Grows `buffer` to hold at least `bytes` (never shrinks; reallocation is the slow part).
void ensure(std::optional<Buffer>& buffer, Context& ctx, uint64_t bytes, const char* name) {
    if (buffer && buffer->size() >= bytes) return;
    buffer.reset();
    buffer.emplace(ctx, std::max<uint64_t>(bytes, 4), name);
}

} // namespace

Lsq3SolveVk::Lsq3SolveVk(Context& ctx, Lsq3SolveVkOptions options)
    : m_ctx(&ctx), m_options(options),
      m_pipeline(ctx, ComputePipelineDesc{.name = "lsq3_solve",
                                          .spirv = core_lsq3_solve_comp,
                                          .storage_buffers = 3,
                                          .push_constant_bytes = sizeof(Lsq3Push),
                                          .workgroup_size = options.workgroup_size}),
      m_sequence(ctx, 4) {}

std::vector<Lsq3Result> Lsq3SolveVk::run(const Lsq3Inputs& in) {
    lsq3_validate(in);
    const std::size_t count = in.element_count();
    std::vector<Lsq3Result> out(count);
    m_last_gpu_ns.reset();
    m_last_chunks = 0;
    if (count == 0) return out;

    uint64_t limit = m_ctx->info().max_storage_buffer_range;
    if (m_options.max_binding_bytes != 0) limit = std::min(limit, m_options.max_binding_bytes);
    const uint64_t max_rows = limit / sizeof(Lsq3Row);
    // Elements per chunk: offsets (n + 1 uints) and results (n records) must fit too.
    const uint64_t max_elements = std::min<uint64_t>(limit / sizeof(Lsq3Result), limit / sizeof(uint32_t) - 1);
    if (max_rows == 0 || max_elements == 0) throw LimitError("lsq3_solve: binding limit too small for one row");

    double gpu_ns = 0.0;
    bool timed = true;
    std::size_t first = 0;
    while (first < count) {
        // Largest chunk [first, last) whose rows fit one binding.
        const uint32_t row_begin = in.row_offsets[first];
        const std::size_t last_cap = std::min<std::size_t>(count, first + max_elements);
        const auto bound = std::upper_bound(in.row_offsets.begin() + static_cast<std::ptrdiff_t>(first) + 1,
                                            in.row_offsets.begin() + static_cast<std::ptrdiff_t>(last_cap) + 1,
                                            static_cast<uint64_t>(row_begin) + max_rows);
        const std::size_t last = static_cast<std::size_t>(bound - in.row_offsets.begin()) - 1;
        if (last <= first)
            throw LimitError("lsq3_solve: element " + std::to_string(first) + " has " +
                             std::to_string(in.row_offsets[first + 1] - row_begin) +
                             " rows, more than one storage binding holds (" + std::to_string(max_rows) + ")");
        const std::size_t n = last - first;
        const uint32_t row_count = in.row_offsets[last] - row_begin;

        ensure(m_offsets, *m_ctx, (n + 1) * sizeof(uint32_t), "lsq3 row offsets");
        ensure(m_rows, *m_ctx, uint64_t{row_count} * sizeof(Lsq3Row), "lsq3 rows");
        ensure(m_results, *m_ctx, n * sizeof(Lsq3Result), "lsq3 results");
        m_offsets->upload(in.row_offsets.subspan(first, n + 1));
        if (row_count > 0) m_rows->upload(in.rows.subspan(row_begin, row_count));

        const Lsq3Push push{.dispatch = {}, .row_base = row_begin};
        m_sequence.reset();
        m_sequence.dispatch_1d(m_pipeline, {*m_offsets, *m_rows, *m_results}, static_cast<uint32_t>(n), push, "lsq3_solve")
            .barrier(Barrier::ComputeToHost)
            .submit_and_wait();
        m_results->download(std::span<Lsq3Result>(out).subspan(first, n));
        const auto& t = m_sequence.timings();
        if (!t.empty() && t.front().ns)
            gpu_ns += *t.front().ns;
        else
            timed = false;
        ++m_last_chunks;
        first = last;
    }
    if (timed) m_last_gpu_ns = gpu_ns;
    return out;
}

} // namespace specula::gpu
