#include "gpu/shadow_map.h"

namespace specula::gpu {

namespace {

UniqueRenderPass make_depth_pass(VkDevice dev, VkFormat format, const std::string& what) {
    const VkAttachmentDescription depth{.format = format,
                                        .samples = VK_SAMPLE_COUNT_1_BIT,
                                        .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
                                        .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
                                        .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                                        .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
                                        .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED, // cleared: the old map is discarded
                                        .finalLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkAttachmentReference ref{.attachment = 0, .layout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    const VkSubpassDescription subpass{.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                       .colorAttachmentCount = 0,
                                       .pDepthStencilAttachment = &ref};
    constexpr VkPipelineStageFlags kTests =
        VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
    const VkSubpassDependency deps[2] = {
        // The previous frame's passes sampled the map: their reads finish before it is cleared.
        {.srcSubpass = VK_SUBPASS_EXTERNAL,
         .dstSubpass = 0,
         .srcStageMask = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
         .dstStageMask = kTests,
         .srcAccessMask = 0,
         .dstAccessMask = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT},
        // The depth writes are visible to the fragment shaders of the passes that follow.
        {.srcSubpass = 0,
         .dstSubpass = VK_SUBPASS_EXTERNAL,
         .srcStageMask = kTests,
         .dstStageMask = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
         .srcAccessMask = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
         .dstAccessMask = VK_ACCESS_SHADER_READ_BIT}};
    const VkRenderPassCreateInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                      .attachmentCount = 1,
                                      .pAttachments = &depth,
                                      .subpassCount = 1,
                                      .pSubpasses = &subpass,
                                      .dependencyCount = 2,
                                      .pDependencies = deps};
    VkRenderPass pass = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateRenderPass(dev, &info, nullptr, &pass), what);
    return UniqueRenderPass(dev, pass);
}

} // namespace

ShadowMap::ShadowMap(Context& ctx, uint32_t size, std::string name)
    : m_depth(ctx, {.name = name, .kind = ImageKind::ShadowMap, .width = size, .height = size,
                    .format = choose_shadow_map_format(ctx)}),
      m_filtered(depth_filters_linearly(ctx, m_depth.format())),
      m_sampler(make_shadow_compare_sampler(ctx, m_filtered, name + " compare sampler")) {
    const VkDevice dev = ctx.device();
    m_pass = make_depth_pass(dev, m_depth.format(), "render pass of '" + name + "'");
    const VkImageView view = m_depth.view();
    const VkFramebufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                       .renderPass = m_pass.get(),
                                       .attachmentCount = 1,
                                       .pAttachments = &view,
                                       .width = size,
                                       .height = size,
                                       .layers = 1};
    VkFramebuffer fb = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateFramebuffer(dev, &info, nullptr, &fb), "framebuffer of '" + name + "'");
    m_framebuffer = UniqueFramebuffer(dev, fb);
    // An empty pass: the map is cleared (everything lit) and in SHADER_READ_ONLY_OPTIMAL.
    ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            begin(cmd);
            end(cmd);
        },
        "clearing a shadow map");
}

void ShadowMap::begin(VkCommandBuffer cmd) const {
    VkClearValue clear{};
    clear.depthStencil = {1.0f, 0};
    const VkRenderPassBeginInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                                     .renderPass = m_pass.get(),
                                     .framebuffer = m_framebuffer.get(),
                                     .renderArea = {{0, 0}, {size(), size()}},
                                     .clearValueCount = 1,
                                     .pClearValues = &clear};
    vkCmdBeginRenderPass(cmd, &info, VK_SUBPASS_CONTENTS_INLINE);
    const VkViewport viewport{.x = 0.0f, .y = 0.0f, .width = static_cast<float>(size()),
                              .height = static_cast<float>(size()), .minDepth = 0.0f, .maxDepth = 1.0f};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    const VkRect2D scissor{{0, 0}, {size(), size()}};
    vkCmdSetScissor(cmd, 0, 1, &scissor);
}

void ShadowMap::end(VkCommandBuffer cmd) const { vkCmdEndRenderPass(cmd); }

} // namespace specula::gpu
