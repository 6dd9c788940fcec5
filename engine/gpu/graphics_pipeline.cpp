#include "gpu/graphics_pipeline.h"

#include "gpu/pipeline_layout.h"

#include <algorithm>
#include <array>

namespace specula::gpu {

namespace {

constexpr VkShaderStageFlags kPushStages = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;

} // namespace

GraphicsPipeline::GraphicsPipeline(Context& ctx, const GraphicsPipelineDesc& desc)
    : m_name(desc.name), m_bindings(desc.bindings), m_push_constant_bytes(desc.push_constant_bytes) {
    const VkDevice dev = ctx.device();
    const std::string what = "graphics pipeline '" + m_name + "'";
    if (desc.render_pass == VK_NULL_HANDLE) throw Error(what + ": no render pass given");
    detail::check_push_constant_bytes(ctx, desc.push_constant_bytes, what);

    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (uint32_t i = 0; i < desc.bindings.size(); ++i)
        bindings.push_back({.binding = i,
                            .descriptorType = desc.bindings[i].type,
                            .descriptorCount = 1,
                            .stageFlags = desc.bindings[i].stages});
    detail::PipelineLayouts layouts = detail::make_pipeline_layouts(dev, bindings, desc.push_constant_bytes, kPushStages, what);
    m_set_layout = std::move(layouts.set);
    m_layout = std::move(layouts.layout);

    // The modules are only needed until the pipeline exists.
    const UniqueShaderModule vert = detail::make_shader_module(dev, desc.vertex_spirv, what + ": vertex shader module");
    const bool depth_only = desc.fragment_spirv.empty();
    const UniqueShaderModule frag =
        depth_only ? UniqueShaderModule{} : detail::make_shader_module(dev, desc.fragment_spirv, what + ": fragment shader module");
    std::vector<VkSpecializationMapEntry> entries;
    for (uint32_t i = 0; i < desc.fragment_constants.size(); ++i)
        entries.push_back({.constantID = i, .offset = i * static_cast<uint32_t>(sizeof(uint32_t)), .size = sizeof(uint32_t)});
    const VkSpecializationInfo fragment_spec{.mapEntryCount = static_cast<uint32_t>(entries.size()),
                                             .pMapEntries = entries.data(),
                                             .dataSize = desc.fragment_constants.size() * sizeof(uint32_t),
                                             .pData = desc.fragment_constants.data()};
    const std::array stages{
        VkPipelineShaderStageCreateInfo{.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                                        .stage = VK_SHADER_STAGE_VERTEX_BIT,
                                        .module = vert.get(),
                                        .pName = "main"},
        VkPipelineShaderStageCreateInfo{.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                                        .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
                                        .module = frag.get(),
                                        .pName = "main",
                                        .pSpecializationInfo = entries.empty() ? nullptr : &fragment_spec}};

    for (const VkVertexInputAttributeDescription& a : desc.vertex_attributes)
        if (a.binding != 0 || desc.vertex_stride == 0)
            throw Error(what + ": vertex attributes need binding 0 and a vertex stride");
    const VkVertexInputBindingDescription vertex_binding{
        .binding = 0, .stride = desc.vertex_stride, .inputRate = VK_VERTEX_INPUT_RATE_VERTEX};
    const bool has_input = !desc.vertex_attributes.empty();
    const VkPipelineVertexInputStateCreateInfo vertex_input{
        .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
        .vertexBindingDescriptionCount = has_input ? 1u : 0u,
        .pVertexBindingDescriptions = has_input ? &vertex_binding : nullptr,
        .vertexAttributeDescriptionCount = static_cast<uint32_t>(desc.vertex_attributes.size()),
        .pVertexAttributeDescriptions = desc.vertex_attributes.data()};
    const VkPipelineInputAssemblyStateCreateInfo assembly{
        .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
        .topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST};
    const VkPipelineViewportStateCreateInfo viewport{.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
                                                     .viewportCount = 1,
                                                     .scissorCount = 1};
    const VkPipelineRasterizationStateCreateInfo raster{
        .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
        .depthClampEnable = VK_FALSE,
        .rasterizerDiscardEnable = VK_FALSE,
        .polygonMode = VK_POLYGON_MODE_FILL,
        .cullMode = desc.cull_mode,
        .frontFace = desc.front_face,
        .depthBiasEnable = (desc.depth_bias_constant != 0.0f || desc.depth_bias_slope != 0.0f) ? VK_TRUE : VK_FALSE,
        .depthBiasConstantFactor = desc.depth_bias_constant,
        .depthBiasClamp = 0.0f,
        .depthBiasSlopeFactor = desc.depth_bias_slope,
        .lineWidth = 1.0f};
    const VkPipelineMultisampleStateCreateInfo multisample{
        .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
        .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT};
    const VkPipelineDepthStencilStateCreateInfo depth{
        .sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
        .depthTestEnable = desc.depth_test ? VK_TRUE : VK_FALSE,
        .depthWriteEnable = desc.depth_write ? VK_TRUE : VK_FALSE,
        .depthCompareOp = desc.depth_compare,
        .depthBoundsTestEnable = VK_FALSE,
        .stencilTestEnable = VK_FALSE,
        .minDepthBounds = 0.0f,
        .maxDepthBounds = 1.0f};
    const VkColorComponentFlags rgba = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                                       VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    const uint32_t color_count = depth_only ? 0u : desc.color_attachments;
    if (!depth_only && (color_count == 0 || color_count > 4))
        throw Error(what + ": " + std::to_string(color_count) + " colour attachments (1 to 4)");
    VkPipelineColorBlendAttachmentState attachment{.blendEnable = VK_FALSE, .colorWriteMask = rgba};
    if (desc.blend == BlendMode::Additive)
        attachment = {.blendEnable = VK_TRUE,
                      .srcColorBlendFactor = VK_BLEND_FACTOR_ONE,
                      .dstColorBlendFactor = VK_BLEND_FACTOR_ONE,
                      .colorBlendOp = VK_BLEND_OP_ADD,
                      .srcAlphaBlendFactor = VK_BLEND_FACTOR_ZERO,
                      .dstAlphaBlendFactor = VK_BLEND_FACTOR_ONE,
                      .alphaBlendOp = VK_BLEND_OP_ADD,
                      .colorWriteMask = rgba};
    const std::vector<VkPipelineColorBlendAttachmentState> attachments(color_count, attachment);
    const VkPipelineColorBlendStateCreateInfo blend{.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
                                                    .logicOpEnable = VK_FALSE,
                                                    .attachmentCount = color_count,
                                                    .pAttachments = attachments.data()};
    const std::array dynamic_states{VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
    const VkPipelineDynamicStateCreateInfo dynamic{.sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO,
                                                   .dynamicStateCount = static_cast<uint32_t>(dynamic_states.size()),
                                                   .pDynamicStates = dynamic_states.data()};
    const VkGraphicsPipelineCreateInfo info{.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                            .stageCount = depth_only ? 1u : static_cast<uint32_t>(stages.size()),
                                            .pStages = stages.data(),
                                            .pVertexInputState = &vertex_input,
                                            .pInputAssemblyState = &assembly,
                                            .pViewportState = &viewport,
                                            .pRasterizationState = &raster,
                                            .pMultisampleState = &multisample,
                                            .pDepthStencilState = &depth,
                                            .pColorBlendState = &blend,
                                            .pDynamicState = &dynamic,
                                            .layout = m_layout.get(),
                                            .renderPass = desc.render_pass,
                                            .subpass = desc.subpass};
    VkPipeline pipeline = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateGraphicsPipelines(dev, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline), what);
    m_pipeline = UniquePipeline(dev, pipeline);
}

// ---------------------------------------------------------------------------------------------

DescriptorSet::DescriptorSet(Context& ctx, const GraphicsPipeline& pipeline)
    : m_ctx(&ctx), m_name(pipeline.name()), m_bindings(pipeline.bindings()) {
    const VkDevice dev = ctx.device();
    std::vector<VkDescriptorPoolSize> sizes; // one entry per descriptor type used
    for (const DescriptorBinding& b : m_bindings) {
        auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& s) { return s.type == b.type; });
        if (it == sizes.end()) sizes.push_back({b.type, 1});
        else ++it->descriptorCount;
    }
    const VkDescriptorPoolCreateInfo pool_info{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                               .maxSets = 1,
                                               .poolSizeCount = static_cast<uint32_t>(sizes.size()),
                                               .pPoolSizes = sizes.data()};
    VkDescriptorPool pool = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateDescriptorPool(dev, &pool_info, nullptr, &pool), "descriptor pool of '" + m_name + "'");
    m_pool = UniqueDescriptorPool(dev, pool);
    const VkDescriptorSetLayout layout = pipeline.set_layout();
    const VkDescriptorSetAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                            .descriptorPool = pool,
                                            .descriptorSetCount = 1,
                                            .pSetLayouts = &layout};
    SPECULA_VK_CHECK(vkAllocateDescriptorSets(dev, &alloc, &m_set), "descriptor set of '" + m_name + "'");
}

void DescriptorSet::check_binding(uint32_t binding, VkDescriptorType type) const {
    if (binding >= m_bindings.size() || m_bindings[binding].type != type)
        throw Error("descriptor set of '" + m_name + "': binding " + std::to_string(binding) +
                    " does not exist or has another type");
}

void DescriptorSet::write_buffer(uint32_t binding, const Buffer& buffer) {
    check_binding(binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
    const VkDescriptorBufferInfo info{.buffer = buffer.handle(), .offset = 0, .range = VK_WHOLE_SIZE};
    const VkWriteDescriptorSet write{.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                     .dstSet = m_set,
                                     .dstBinding = binding,
                                     .descriptorCount = 1,
                                     .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                     .pBufferInfo = &info};
    vkUpdateDescriptorSets(m_ctx->device(), 1, &write, 0, nullptr);
}

void DescriptorSet::write_image(uint32_t binding, const Image& image, VkSampler sampler) {
    check_binding(binding, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER);
    const VkDescriptorImageInfo info{.sampler = sampler,
                                     .imageView = image.view(),
                                     .imageLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkWriteDescriptorSet write{.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                     .dstSet = m_set,
                                     .dstBinding = binding,
                                     .descriptorCount = 1,
                                     .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                     .pImageInfo = &info};
    vkUpdateDescriptorSets(m_ctx->device(), 1, &write, 0, nullptr);
}

void DescriptorSet::write_input_attachment(uint32_t binding, const Image& image) {
    check_binding(binding, VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT);
    const VkDescriptorImageInfo info{.imageView = image.view(), .imageLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkWriteDescriptorSet write{.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                     .dstSet = m_set,
                                     .dstBinding = binding,
                                     .descriptorCount = 1,
                                     .descriptorType = VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT,
                                     .pImageInfo = &info};
    vkUpdateDescriptorSets(m_ctx->device(), 1, &write, 0, nullptr);
}

void bind_vertex_buffer(VkCommandBuffer cmd, const Buffer& buffer) {
    const VkBuffer b = buffer.handle();
    const VkDeviceSize offset = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &b, &offset);
}

} // namespace specula::gpu
