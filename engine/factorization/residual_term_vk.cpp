// Vulkan side of residual_term: per term, the start pass and `iterations` (G, H) pass pairs,
// each one dispatch separated by compute->compute barriers.
#include "factorization/residual_term.h"

#include "core/error.h"

#include "factorization/residual_term.comp.h"

#include <string>

namespace specula::factorization {

ResidualTermsVk::ResidualTermsVk(gpu::Context& ctx, uint32_t workgroup_size)
    : m_ctx(&ctx),
      m_pipeline(ctx, gpu::ComputePipelineDesc{.name = "residual_term",
                                               .spirv = factorization_residual_term_comp,
                                               .storage_buffers = 3,
                                               .push_constant_bytes = sizeof(shared::ResidualTermPush),
                                               .workgroup_size = workgroup_size}) {}

void ResidualTermsVk::record_als(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                                 uint32_t rows, uint32_t cols, uint32_t term, uint32_t iterations) const {
    shared::ResidualTermPush push{.dispatch = {}, .rows = rows, .cols = cols, .term = term, .pass_index = 1};
    for (uint32_t it = 0; it < iterations; ++it) {
        seq.barrier(gpu::Barrier::ComputeToCompute);
        push.pass_index = 1;
        seq.dispatch_1d(m_pipeline, {matrix, g, h}, 3 * rows, push);
        seq.barrier(gpu::Barrier::ComputeToCompute);
        push.pass_index = 2;
        seq.dispatch_1d(m_pipeline, {matrix, g, h}, 3 * cols, push);
    }
}

void ResidualTermsVk::record(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g, const gpu::Buffer& h,
                             uint32_t res_h, uint32_t res_d, uint32_t terms, uint32_t iterations) const {
    const uint32_t rows = res_h * res_h;
    const uint32_t cols = res_d * res_d;
    for (uint32_t k = 1; k < terms; ++k) {
        seq.time_begin("residual_term_" + std::to_string(k + 1));
        const shared::ResidualTermPush push{.dispatch = {}, .rows = rows, .cols = cols, .term = k, .pass_index = 0};
        seq.dispatch_1d(m_pipeline, {matrix, g, h}, 3 * cols, push);
        record_als(seq, matrix, g, h, rows, cols, k, iterations);
        seq.time_end();
        seq.barrier(gpu::Barrier::ComputeToCompute);
    }
}

void ResidualTermsVk::record_refine_first(gpu::Sequence& seq, const gpu::Buffer& matrix, const gpu::Buffer& g,
                                          const gpu::Buffer& h, uint32_t res_h, uint32_t res_d, uint32_t iterations) const {
    const uint32_t rows = res_h * res_h;
    const uint32_t cols = res_d * res_d;
    seq.time_begin("first_term_als");
    record_als(seq, matrix, g, h, rows, cols, 0, iterations);
    seq.time_end();
}

Decomposition ResidualTermsVk::run_refine_first(const BrdfMatrix& m, const Decomposition& first, uint32_t iterations) {
    residual_terms_validate({.matrix = &m, .first = &first, .terms = 2, .iterations = iterations});
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, m.values.size(), "factorization F");
    gpu::Buffer g = gpu::Buffer::of<glm::vec3>(*m_ctx, m.rows(), "factorization G grid");
    gpu::Buffer h = gpu::Buffer::of<glm::vec3>(*m_ctx, m.cols(), "factorization H grid");
    matrix.upload(m.values);
    g.upload(first.g);
    h.upload(first.h);
    gpu::Sequence seq(*m_ctx, 2);
    record_refine_first(seq, matrix, g, h, m.res_h, m.res_d, iterations);
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
    return Decomposition{.res_h = m.res_h, .res_d = m.res_d, .g = g.download<glm::vec3>(m.rows()),
                         .h = h.download<glm::vec3>(m.cols()), .param = m.param, .warp = m.warp};
}

std::vector<Decomposition> ResidualTermsVk::run(const ResidualTermsInputs& in) {
    residual_terms_validate(in);
    const BrdfMatrix& m = *in.matrix;
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, m.values.size(), "factorization F");
    gpu::Buffer g = gpu::Buffer::of<glm::vec3>(*m_ctx, in.terms * rows, "factorization G grids");
    gpu::Buffer h = gpu::Buffer::of<glm::vec3>(*m_ctx, in.terms * cols, "factorization H grids");
    matrix.upload(m.values);
    g.upload(in.first->g);
    h.upload(in.first->h);
    gpu::Sequence seq(*m_ctx, 4);
    record(seq, matrix, g, h, m.res_h, m.res_d, in.terms, in.iterations);
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
    const std::vector<glm::vec3> ga = g.download<glm::vec3>(in.terms * rows);
    const std::vector<glm::vec3> ha = h.download<glm::vec3>(in.terms * cols);
    std::vector<Decomposition> out;
    for (uint32_t k = 1; k < in.terms; ++k)
        out.push_back(Decomposition{.res_h = m.res_h, .res_d = m.res_d,
                                    .g = {ga.begin() + k * rows, ga.begin() + (k + 1) * rows},
                                    .h = {ha.begin() + k * cols, ha.begin() + (k + 1) * cols},
                                    .param = m.param, .warp = m.warp});
    return out;
}

} // namespace specula::factorization
