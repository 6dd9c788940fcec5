// Vulkan side of normalized_decomposition: pass 0 (G, one invocation per row and channel),
// a compute->compute barrier, pass 1 (H, one invocation per column and channel).
#include "factorization/normalized_decomposition.h"

#include "core/error.h"

#include "factorization/normalized_decomposition.comp.h"

namespace specula::factorization {

NormalizedDecompositionVk::NormalizedDecompositionVk(gpu::Context& ctx, uint32_t workgroup_size)
    : m_ctx(&ctx),
      m_pipeline(ctx, gpu::ComputePipelineDesc{.name = "normalized_decomposition",
                                               .spirv = factorization_normalized_decomposition_comp,
                                               .storage_buffers = 3,
                                               .push_constant_bytes = sizeof(shared::DecompositionPush),
                                               .workgroup_size = workgroup_size}) {}

void NormalizedDecompositionVk::record(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g,
                                       const gpu::Buffer& h, uint32_t res_h, uint32_t res_d, float p,
                                       DecompositionWeighting weighting) const {
    const uint32_t rows = res_h * res_h;
    const uint32_t cols = res_d * res_d;
    shared::DecompositionPush push{.dispatch = {}, .rows = rows, .cols = cols, .pass_index = 0, .p = p,
                           .weighting = static_cast<uint32_t>(weighting)};
    seq.dispatch_1d(m_pipeline, {matrix, g, h}, 3 * rows, push, "decomposition_g");
    seq.barrier(gpu::Barrier::ComputeToCompute);
    push.pass_index = 1;
    seq.dispatch_1d(m_pipeline, {matrix, g, h}, 3 * cols, push, "decomposition_h");
}

Decomposition NormalizedDecompositionVk::run(const DecompositionInputs& in) {
    decomposition_validate(in);
    const BrdfMatrix& m = *in.matrix;
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, m.values.size(), "factorization F");
    gpu::Buffer g = gpu::Buffer::of<glm::vec3>(*m_ctx, m.rows(), "factorization G grid");
    gpu::Buffer h = gpu::Buffer::of<glm::vec3>(*m_ctx, m.cols(), "factorization H grid");
    matrix.upload(m.values);
    gpu::Sequence seq(*m_ctx, 4);
    record(seq, matrix, g, h, m.res_h, m.res_d, in.p, in.weighting);
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
    Decomposition out{.res_h = m.res_h, .res_d = m.res_d, .g = g.download<glm::vec3>(m.rows()),
                      .h = h.download<glm::vec3>(m.cols()), .param = m.param, .warp = m.warp};
    m_last_gpu_ns.reset();
    double ns = 0.0;
    for (const auto& t : seq.timings()) {
        if (!t.ns) return out;
        ns += *t.ns;
    }
    m_last_gpu_ns = ns;
    return out;
}

} // namespace specula::factorization
