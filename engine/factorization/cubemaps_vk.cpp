// Vulkan side of cubemaps: one dispatch over 6 res^2 texels per cube-map.
#include "factorization/cubemaps.h"

#include "core/error.h"

#include "factorization/cubemaps.comp.h"

namespace specula::factorization {

CubemapsVk::CubemapsVk(gpu::Context& ctx, uint32_t workgroup_size)
    : m_ctx(&ctx),
      m_pipeline(ctx, gpu::ComputePipelineDesc{.name = "cubemaps",
                                               .spirv = factorization_cubemaps_comp,
                                               .storage_buffers = 2,
                                               .push_constant_bytes = sizeof(shared::CubemapPush),
                                               .workgroup_size = workgroup_size}) {}

void CubemapsVk::record(gpu::Sequence& seq, const gpu::Buffer& grid, const gpu::Buffer& cube, uint32_t grid_res,
                        uint32_t cube_res, std::string_view label) const {
    const shared::CubemapPush push{.dispatch = {}, .grid_res = grid_res, .cube_res = cube_res};
    seq.dispatch_1d(m_pipeline, {grid, cube}, 6 * cube_res * cube_res, push, label);
}

CubeMap CubemapsVk::run(const CubemapInputs& in) {
    cubemap_validate(in);
    const std::size_t texels = std::size_t{6} * in.cube_res * in.cube_res;
    gpu::Buffer grid = gpu::Buffer::of<glm::vec3>(*m_ctx, in.grid.size(), "factorization grid");
    gpu::Buffer cube = gpu::Buffer::of<glm::vec3>(*m_ctx, texels, "factorization cube-map");
    grid.upload(in.grid);
    gpu::Sequence seq(*m_ctx, 2);
    record(seq, grid, cube, in.grid_res, in.cube_res, "cubemaps");
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
    CubeMap out{.resolution = in.cube_res, .texels = cube.download<glm::vec3>(texels)};
    m_last_gpu_ns.reset();
    if (!seq.timings().empty()) m_last_gpu_ns = seq.timings().front().ns;
    return out;
}

} // namespace specula::factorization
