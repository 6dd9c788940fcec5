// Vulkan side of brdf_matrix: one dispatch over rows * cols entries (split by
// Sequence::dispatch_1d beyond maxComputeWorkGroupCount). F must fit one binding.
#include "factorization/brdf_matrix.h"

#include "core/error.h"

#include "factorization/brdf_matrix.comp.h"

namespace specula::factorization {

BrdfMatrixVk::BrdfMatrixVk(gpu::Context& ctx, uint32_t workgroup_size)
    : m_ctx(&ctx),
      m_pipeline(ctx, gpu::ComputePipelineDesc{.name = "brdf_matrix",
                                               .spirv = factorization_brdf_matrix_comp,
                                               .storage_buffers = 1,
                                               .push_constant_bytes = sizeof(shared::BrdfMatrixPush),
                                               .workgroup_size = workgroup_size}) {}

void BrdfMatrixVk::record(gpu::Sequence& seq, const gpu::Buffer& matrix, const BrdfMatrixInputs& in) const {
    brdf_matrix_validate(in);
    const uint64_t entries = uint64_t{in.res_h} * in.res_h * in.res_d * in.res_d;
    if (matrix.size() < entries * 3 * sizeof(float))
        throw Error("brdf_matrix: buffer '" + matrix.name() + "' too small for the matrix");
    const shared::BrdfMatrixPush push{.dispatch = {}, .res_h = in.res_h, .res_d = in.res_d,
                                      .material = material_gpu(in.model), .param = static_cast<uint32_t>(in.param),
                                      .warp_s = in.warp.x, .warp_k = {in.warp.y, in.warp.z, in.warp.w},
                                      .weight_q = in.weight_q};
    seq.dispatch_1d(m_pipeline, {matrix}, static_cast<uint32_t>(entries), push, "brdf_matrix");
}

BrdfMatrix BrdfMatrixVk::run(const BrdfMatrixInputs& in) {
    brdf_matrix_validate(in);
    BrdfMatrix m{.res_h = in.res_h, .res_d = in.res_d, .param = in.param, .warp = in.warp, .weight_q = in.weight_q, .values = {}};
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, 3 * m.rows() * m.cols(), "factorization F");
    gpu::Sequence seq(*m_ctx, 2);
    record(seq, matrix, in);
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
    m.values = matrix.download<float>(3 * m.rows() * m.cols());
    m_last_gpu_ns.reset();
    if (!seq.timings().empty()) m_last_gpu_ns = seq.timings().front().ns;
    return m;
}

} // namespace specula::factorization
