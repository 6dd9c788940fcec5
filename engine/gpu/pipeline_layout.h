#pragma once
// What compute and graphics pipelines build the same way (internal to engine/gpu):
// the shader module, the push-constant limit check, the set-0 descriptor layout and
// the pipeline layout.
#include "gpu/context.h"
#include "gpu/vk_unique.h"

#include <span>
#include <string>

namespace specula::gpu::detail {

/// Checks the SPIR-V magic number and creates the module.
[[nodiscard]] UniqueShaderModule make_shader_module(VkDevice dev, std::span<const uint32_t> spirv, const std::string& what);

/// Throws LimitError unless `bytes` is a multiple of 4 and within min(128, the device's limit).
void check_push_constant_bytes(const Context& ctx, uint32_t bytes, const std::string& what);

struct PipelineLayouts {
    UniqueDescriptorSetLayout set;
    UniquePipelineLayout layout;
};

/// One descriptor set (set 0) of `bindings` and one push-constant range of `push_bytes`
/// (none when 0) visible to `push_stages`.
[[nodiscard]] PipelineLayouts make_pipeline_layouts(VkDevice dev, std::span<const VkDescriptorSetLayoutBinding> bindings,
                                                    uint32_t push_bytes, VkShaderStageFlags push_stages,
                                                    const std::string& what);

} // namespace specula::gpu::detail
