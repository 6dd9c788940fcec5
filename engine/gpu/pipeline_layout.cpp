#include "gpu/pipeline_layout.h"

#include "gpu/vk_check.h"

#include <algorithm>

namespace specula::gpu::detail {

UniqueShaderModule make_shader_module(VkDevice dev, std::span<const uint32_t> spirv, const std::string& what) {
    if (spirv.empty() || spirv[0] != 0x07230203u)
        throw Error(what + ": the SPIR-V code is empty or lacks the SPIR-V magic number");
    const VkShaderModuleCreateInfo info{.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
                                        .codeSize = spirv.size_bytes(),
                                        .pCode = spirv.data()};
    VkShaderModule module = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateShaderModule(dev, &info, nullptr, &module), what);
    return UniqueShaderModule(dev, module);
}

void check_push_constant_bytes(const Context& ctx, uint32_t bytes, const std::string& what) {
    const uint32_t limit = std::min<uint32_t>(128u, ctx.limits().maxPushConstantsSize);
    if (bytes > limit || bytes % 4 != 0)
        throw LimitError(what + ": " + std::to_string(bytes) + " push-constant bytes (must be a multiple of 4 and at most " +
                         std::to_string(limit) + ")");
}

PipelineLayouts make_pipeline_layouts(VkDevice dev, std::span<const VkDescriptorSetLayoutBinding> bindings,
                                      uint32_t push_bytes, VkShaderStageFlags push_stages, const std::string& what) {
    PipelineLayouts out;
    const VkDescriptorSetLayoutCreateInfo set_info{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
                                                   .bindingCount = static_cast<uint32_t>(bindings.size()),
                                                   .pBindings = bindings.data()};
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateDescriptorSetLayout(dev, &set_info, nullptr, &set_layout), what + ": set layout");
    out.set = UniqueDescriptorSetLayout(dev, set_layout);

    const VkPushConstantRange range{.stageFlags = push_stages, .offset = 0, .size = push_bytes};
    const VkPipelineLayoutCreateInfo layout_info{.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                                 .setLayoutCount = 1,
                                                 .pSetLayouts = &set_layout,
                                                 .pushConstantRangeCount = push_bytes > 0 ? 1u : 0u,
                                                 .pPushConstantRanges = &range};
    VkPipelineLayout layout = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreatePipelineLayout(dev, &layout_info, nullptr, &layout), what + ": pipeline layout");
    out.layout = UniquePipelineLayout(dev, layout);
    return out;
}

} // namespace specula::gpu::detail
