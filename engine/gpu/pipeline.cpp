#include "gpu/pipeline.h"

#include <algorithm>
#include <vector>

namespace specula::gpu {

ComputePipeline::ComputePipeline(Context& ctx, const ComputePipelineDesc& desc)
    : m_name(desc.name), m_storage_buffers(desc.storage_buffers), m_push_constant_bytes(desc.push_constant_bytes),
      m_workgroup_size(desc.workgroup_size) {
    const VkDevice dev = ctx.device();
    const std::string what = "pipeline '" + m_name + "'";
    if (desc.spirv.empty() || desc.spirv[0] != 0x07230203u)
        throw Error(what + ": the SPIR-V code is empty or lacks the SPIR-V magic number");
    const uint32_t push_limit = std::min<uint32_t>(128u, ctx.limits().maxPushConstantsSize);
    if (desc.push_constant_bytes > push_limit || desc.push_constant_bytes % 4 != 0)
        throw LimitError(what + ": " + std::to_string(desc.push_constant_bytes) +
                         " push-constant bytes (must be a multiple of 4 and at most " + std::to_string(push_limit) + ")");
    if (desc.workgroup_size == 0 || desc.workgroup_size > ctx.limits().maxComputeWorkGroupInvocations ||
        desc.workgroup_size > ctx.limits().maxComputeWorkGroupSize[0])
        throw LimitError(what + ": workgroup size " + std::to_string(desc.workgroup_size) + " exceeds the device limits");

    std::vector<VkDescriptorSetLayoutBinding> bindings(desc.storage_buffers);
    for (uint32_t i = 0; i < desc.storage_buffers; ++i)
        bindings[i] = {.binding = i,
                       .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                       .descriptorCount = 1,
                       .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
    const VkDescriptorSetLayoutCreateInfo set_info{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
                                                   .bindingCount = desc.storage_buffers,
                                                   .pBindings = bindings.data()};
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateDescriptorSetLayout(dev, &set_info, nullptr, &set_layout), what + ": set layout");
    m_set_layout = UniqueDescriptorSetLayout(dev, set_layout);

    const VkPushConstantRange range{.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT,
                                    .offset = 0,
                                    .size = desc.push_constant_bytes};
    const VkPipelineLayoutCreateInfo layout_info{.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                                 .setLayoutCount = 1,
                                                 .pSetLayouts = &set_layout,
                                                 .pushConstantRangeCount = desc.push_constant_bytes > 0 ? 1u : 0u,
                                                 .pPushConstantRanges = &range};
    VkPipelineLayout layout = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreatePipelineLayout(dev, &layout_info, nullptr, &layout), what + ": pipeline layout");
    m_layout = UniquePipelineLayout(dev, layout);

    const VkShaderModuleCreateInfo module_info{.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
                                               .codeSize = desc.spirv.size_bytes(),
                                               .pCode = desc.spirv.data()};
    VkShaderModule module_handle = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateShaderModule(dev, &module_info, nullptr, &module_handle), what + ": shader module");
    const UniqueShaderModule module(dev, module_handle); // only needed until the pipeline exists

    const VkSpecializationMapEntry entry{.constantID = 0, .offset = 0, .size = sizeof(uint32_t)};
    const VkSpecializationInfo spec{.mapEntryCount = 1,
                                    .pMapEntries = &entry,
                                    .dataSize = sizeof(uint32_t),
                                    .pData = &m_workgroup_size};
    const VkComputePipelineCreateInfo pipeline_info{
        .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                  .module = module_handle,
                  .pName = "main",
                  .pSpecializationInfo = &spec},
        .layout = layout};
    VkPipeline pipeline = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &pipeline_info, nullptr, &pipeline),
                     what + ": compute pipeline");
    m_pipeline = UniquePipeline(dev, pipeline);
}

} // namespace specula::gpu
