#pragma once
// Compute pipelines from SPIR-V embedded at build time (shaders/CMakeLists.txt:
// build/spirv/<stage>/<name>.comp.h defines <stage>_<name>_comp[]).
//
// Layout convention: set 0 holds `storage_buffers` storage buffers at bindings
// 0..N-1, in the order Sequence::dispatch receives them; one push-constant range
// of `push_constant_bytes` (<= 128, the Vulkan minimum guarantee) for the compute stage.
// The workgroup size is specialization constant 0: declare
//   layout(local_size_x_id = 0) in;
// in the shader, so the host and the shader agree on it by construction.
#include "gpu/context.h"

#include <cstdint>
#include <span>
#include <string>

namespace specula::gpu {

struct ComputePipelineDesc {
    std::string name;
    std::span<const uint32_t> spirv;
    uint32_t storage_buffers = 1;
    uint32_t push_constant_bytes = 0;
    uint32_t workgroup_size = 64;
};

class ComputePipeline {
public:
    ComputePipeline(Context& ctx, const ComputePipelineDesc& desc);
    ComputePipeline(ComputePipeline&&) noexcept = default;
    ComputePipeline& operator=(ComputePipeline&&) noexcept = default;
    ComputePipeline(const ComputePipeline&) = delete;
    ComputePipeline& operator=(const ComputePipeline&) = delete;

    [[nodiscard]] VkPipeline pipeline() const noexcept { return m_pipeline.get(); }
    [[nodiscard]] VkPipelineLayout layout() const noexcept { return m_layout.get(); }
    [[nodiscard]] VkDescriptorSetLayout set_layout() const noexcept { return m_set_layout.get(); }
    [[nodiscard]] const std::string& name() const noexcept { return m_name; }
    [[nodiscard]] uint32_t storage_buffers() const noexcept { return m_storage_buffers; }
    [[nodiscard]] uint32_t push_constant_bytes() const noexcept { return m_push_constant_bytes; }
    [[nodiscard]] uint32_t workgroup_size() const noexcept { return m_workgroup_size; }

private:
    std::string m_name;
    uint32_t m_storage_buffers = 0;
    uint32_t m_push_constant_bytes = 0;
    uint32_t m_workgroup_size = 0;
    UniqueDescriptorSetLayout m_set_layout;
    UniquePipelineLayout m_layout;
    UniquePipeline m_pipeline;
};

} // namespace specula::gpu
