#include "gpu/pipeline.h"

#include "gpu/pipeline_layout.h"

#include <algorithm>
#include <vector>

namespace specula::gpu {

ComputePipeline::ComputePipeline(Context& ctx, const ComputePipelineDesc& desc)
    : m_name(desc.name), m_storage_buffers(desc.storage_buffers), m_push_constant_bytes(desc.push_constant_bytes),
      m_workgroup_size(desc.workgroup_size) {
    const VkDevice dev = ctx.device();
    const std::string what = "pipeline '" + m_name + "'";
    detail::check_push_constant_bytes(ctx, desc.push_constant_bytes, what);
    if (desc.workgroup_size == 0 || desc.workgroup_size > ctx.limits().maxComputeWorkGroupInvocations ||
        desc.workgroup_size > ctx.limits().maxComputeWorkGroupSize[0])
        throw LimitError(what + ": workgroup size " + std::to_string(desc.workgroup_size) + " exceeds the device limits");

    std::vector<VkDescriptorSetLayoutBinding> bindings(desc.storage_buffers);
    for (uint32_t i = 0; i < desc.storage_buffers; ++i)
        bindings[i] = {.binding = i,
                       .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                       .descriptorCount = 1,
                       .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
    detail::PipelineLayouts layouts =
        detail::make_pipeline_layouts(dev, bindings, desc.push_constant_bytes, VK_SHADER_STAGE_COMPUTE_BIT, what);
    m_set_layout = std::move(layouts.set);
    m_layout = std::move(layouts.layout);
    const UniqueShaderModule module = detail::make_shader_module(dev, desc.spirv, what + ": shader module");

    const VkSpecializationMapEntry entry{.constantID = 0, .offset = 0, .size = sizeof(uint32_t)};
    const VkSpecializationInfo spec{.mapEntryCount = 1,
                                    .pMapEntries = &entry,
                                    .dataSize = sizeof(uint32_t),
                                    .pData = &m_workgroup_size};
    const VkComputePipelineCreateInfo pipeline_info{
        .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                  .module = module.get(),
                  .pName = "main",
                  .pSpecializationInfo = &spec},
        .layout = m_layout.get()};
    VkPipeline pipeline = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &pipeline_info, nullptr, &pipeline),
                     what + ": compute pipeline");
    m_pipeline = UniquePipeline(dev, pipeline);
}

} // namespace specula::gpu
