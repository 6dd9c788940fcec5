#include "gpu/render_target.h"

#include <array>
#include <span>

namespace specula::gpu {

namespace {

constexpr VkPipelineStageFlags kAttachmentStages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                                   VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                                   VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
constexpr VkAccessFlags kAttachmentWrites =
    VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
constexpr VkAccessFlags kAttachmentAccess = kAttachmentWrites | VK_ACCESS_COLOR_ATTACHMENT_READ_BIT |
                                            VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT;

UniqueRenderPass make_render_pass(VkDevice dev, VkFormat color, VkFormat depth, bool clear, const std::string& what) {
    const VkAttachmentLoadOp load = clear ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
    const std::array attachments{
        VkAttachmentDescription{.format = color,
                                .samples = VK_SAMPLE_COUNT_1_BIT,
                                .loadOp = load,
                                .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
                                .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                                .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
                                // A cleared pass discards what the previous frame left (it was read back).
                                .initialLayout = clear ? VK_IMAGE_LAYOUT_UNDEFINED : VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                                .finalLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
        VkAttachmentDescription{.format = depth,
                                .samples = VK_SAMPLE_COUNT_1_BIT,
                                .loadOp = load,
                                .storeOp = VK_ATTACHMENT_STORE_OP_STORE, // later passes test against it
                                .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                                .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
                                .initialLayout = clear ? VK_IMAGE_LAYOUT_UNDEFINED
                                                       : VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                                .finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL}};
    const VkAttachmentReference color_ref{.attachment = 0, .layout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    const VkAttachmentReference depth_ref{.attachment = 1, .layout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    const VkSubpassDescription subpass{.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                       .colorAttachmentCount = 1,
                                       .pColorAttachments = &color_ref,
                                       .pDepthStencilAttachment = &depth_ref};
    // Before the pass: the previous pass's attachment writes (write -> read/write), and the
    // previous frame's readback copy (a read: an execution dependency suffices).
    const VkSubpassDependency before{.srcSubpass = VK_SUBPASS_EXTERNAL,
                                     .dstSubpass = 0,
                                     .srcStageMask = kAttachmentStages | VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     .dstStageMask = kAttachmentStages,
                                     .srcAccessMask = kAttachmentWrites,
                                     .dstAccessMask = kAttachmentAccess};
    const VkRenderPassCreateInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                      .attachmentCount = static_cast<uint32_t>(attachments.size()),
                                      .pAttachments = attachments.data(),
                                      .subpassCount = 1,
                                      .pSubpasses = &subpass,
                                      .dependencyCount = 1,
                                      .pDependencies = &before};
    VkRenderPass pass = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateRenderPass(dev, &info, nullptr, &pass), what);
    return UniqueRenderPass(dev, pass);
}

// The deferred pass: subpass 0 draws the mesh into the two G-buffer images (attachments 2
// and 3) with the depth test; subpass 1 reads them back per pixel as input attachments and
// writes the colour (attachment 0). The G-buffer is stored after the pass, so that `reuse`, a
// compatible pass (the same attachments and subpasses; only the load operations and initial
// layouts differ, so the same pipelines and framebuffer serve), can load it and the depth as
// the last deferred pass left them and shade again with an empty subpass 0.
UniqueRenderPass make_deferred_render_pass(VkDevice dev, VkFormat color, VkFormat depth, VkFormat gbuffer, bool reuse,
                                           const std::string& what) {
    const auto attachment = [](VkFormat format, bool load, VkImageLayout layout) {
        return VkAttachmentDescription{.format = format,
                                       .samples = VK_SAMPLE_COUNT_1_BIT,
                                       .loadOp = load ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR,
                                       .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
                                       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                                       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
                                       .initialLayout = load ? layout : VK_IMAGE_LAYOUT_UNDEFINED,
                                       .finalLayout = layout};
    };
    // Colour and depth end as the other passes leave them (later passes may test and blend).
    const std::array attachments{attachment(color, false, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL),
                                 attachment(depth, reuse, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL),
                                 attachment(gbuffer, reuse, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL),
                                 attachment(gbuffer, reuse, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL)};
    const std::array gbuffer_out{VkAttachmentReference{2, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
                                 VkAttachmentReference{3, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL}};
    const std::array gbuffer_in{VkAttachmentReference{2, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
                                VkAttachmentReference{3, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}};
    const VkAttachmentReference color_ref{.attachment = 0, .layout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    const VkAttachmentReference depth_ref{.attachment = 1, .layout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    const std::array subpasses{VkSubpassDescription{.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                                    .colorAttachmentCount = static_cast<uint32_t>(gbuffer_out.size()),
                                                    .pColorAttachments = gbuffer_out.data(),
                                                    .pDepthStencilAttachment = &depth_ref},
                               VkSubpassDescription{.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                                    .inputAttachmentCount = static_cast<uint32_t>(gbuffer_in.size()),
                                                    .pInputAttachments = gbuffer_in.data(),
                                                    .colorAttachmentCount = 1,
                                                    .pColorAttachments = &color_ref}};
    // Before either subpass: as make_render_pass (previous attachment writes, previous readback),
    // and the previous deferred pass's input reads of the G-buffer (before it is written again)
    // and its G-buffer writes (before a reusing pass's subpass 1 reads them).
    // Between them: the G-buffer's colour writes -> the shading subpass's input reads, per pixel.
    const auto from_outside = [](uint32_t subpass) {
        return VkSubpassDependency{.srcSubpass = VK_SUBPASS_EXTERNAL,
                                   .dstSubpass = subpass,
                                   .srcStageMask = kAttachmentStages | VK_PIPELINE_STAGE_TRANSFER_BIT |
                                                   VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                                   .dstStageMask = kAttachmentStages | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                                   .srcAccessMask = kAttachmentWrites,
                                   .dstAccessMask = kAttachmentAccess | VK_ACCESS_INPUT_ATTACHMENT_READ_BIT};
    };
    const std::array dependencies{from_outside(0), from_outside(1),
                                  VkSubpassDependency{.srcSubpass = 0,
                                                      .dstSubpass = 1,
                                                      .srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                                                      .dstStageMask = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                                                      .srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                                                      .dstAccessMask = VK_ACCESS_INPUT_ATTACHMENT_READ_BIT,
                                                      .dependencyFlags = VK_DEPENDENCY_BY_REGION_BIT}};
    const VkRenderPassCreateInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                      .attachmentCount = static_cast<uint32_t>(attachments.size()),
                                      .pAttachments = attachments.data(),
                                      .subpassCount = static_cast<uint32_t>(subpasses.size()),
                                      .pSubpasses = subpasses.data(),
                                      .dependencyCount = static_cast<uint32_t>(dependencies.size()),
                                      .pDependencies = dependencies.data()};
    VkRenderPass pass = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateRenderPass(dev, &info, nullptr, &pass), what);
    return UniqueRenderPass(dev, pass);
}

UniqueFramebuffer make_framebuffer(VkDevice dev, VkRenderPass pass, std::span<const VkImageView> views,
                                   const Image& color, const std::string& what) {
    const VkFramebufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                       .renderPass = pass,
                                       .attachmentCount = static_cast<uint32_t>(views.size()),
                                       .pAttachments = views.data(),
                                       .width = color.width(),
                                       .height = color.height(),
                                       .layers = 1};
    VkFramebuffer fb = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateFramebuffer(dev, &info, nullptr, &fb), what);
    return UniqueFramebuffer(dev, fb);
}

} // namespace

RenderTarget::RenderTarget(Context& ctx, uint32_t width, uint32_t height, std::string name)
    : m_color(ctx, {.name = name + " colour", .kind = ImageKind::ColorTarget, .width = width, .height = height,
                    .format = choose_color_target_format(ctx)}),
      m_depth(ctx, {.name = name + " depth", .kind = ImageKind::DepthTarget, .width = width, .height = height,
                    .format = choose_depth_format(ctx)}),
      m_gbuffer{Image(ctx, {.name = name + " G-buffer 0", .kind = ImageKind::GBuffer, .width = width, .height = height,
                            .format = choose_color_target_format(ctx)}),
                Image(ctx, {.name = name + " G-buffer 1", .kind = ImageKind::GBuffer, .width = width, .height = height,
                            .format = choose_color_target_format(ctx)})},
      m_readback(ctx, m_color.byte_size(), name + " readback") {
    const VkDevice dev = ctx.device();
    m_clear_pass = make_render_pass(dev, m_color.format(), m_depth.format(), true, "render pass (clear) of '" + name + "'");
    m_keep_pass = make_render_pass(dev, m_color.format(), m_depth.format(), false, "render pass (keep) of '" + name + "'");
    m_deferred_pass = make_deferred_render_pass(dev, m_color.format(), m_depth.format(), m_gbuffer[0].format(), false,
                                                "render pass (deferred) of '" + name + "'");
    m_deferred_reuse_pass = make_deferred_render_pass(dev, m_color.format(), m_depth.format(), m_gbuffer[0].format(),
                                                      true, "render pass (deferred, G-buffer kept) of '" + name + "'");
    const std::array views{m_color.view(), m_depth.view()};
    m_clear_framebuffer = make_framebuffer(dev, m_clear_pass.get(), views, m_color, "framebuffer of '" + name + "'");
    m_keep_framebuffer = make_framebuffer(dev, m_keep_pass.get(), views, m_color, "framebuffer of '" + name + "'");
    const std::array deferred_views{m_color.view(), m_depth.view(), m_gbuffer[0].view(), m_gbuffer[1].view()};
    m_deferred_framebuffer = make_framebuffer(dev, m_deferred_pass.get(), deferred_views, m_color,
                                              "deferred framebuffer of '" + name + "'");
}

void RenderTarget::begin(VkCommandBuffer cmd, Load load, const glm::vec4& clear_color) const {
    std::array<VkClearValue, 2> clears{};
    clears[0].color = {{clear_color.r, clear_color.g, clear_color.b, clear_color.a}};
    clears[1].depthStencil = {0.0f, 0}; // reversed-Z: the far end
    const bool clear = load == Load::Clear;
    const VkRenderPassBeginInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                                     .renderPass = clear ? m_clear_pass.get() : m_keep_pass.get(),
                                     .framebuffer = clear ? m_clear_framebuffer.get() : m_keep_framebuffer.get(),
                                     .renderArea = {{0, 0}, {width(), height()}},
                                     .clearValueCount = clear ? 2u : 0u,
                                     .pClearValues = clear ? clears.data() : nullptr};
    vkCmdBeginRenderPass(cmd, &info, VK_SUBPASS_CONTENTS_INLINE);
    set_viewport(cmd);
}

void RenderTarget::begin_deferred(VkCommandBuffer cmd, GbufferLoad load) const {
    std::array<VkClearValue, 4> clears{}; // colour, G-buffer: 0 (not covered); depth: 0, the far end
    const VkRenderPassBeginInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                                     .renderPass = load == GbufferLoad::Keep ? m_deferred_reuse_pass.get()
                                                                             : m_deferred_pass.get(),
                                     .framebuffer = m_deferred_framebuffer.get(),
                                     .renderArea = {{0, 0}, {width(), height()}},
                                     .clearValueCount = static_cast<uint32_t>(clears.size()),
                                     .pClearValues = clears.data()};
    vkCmdBeginRenderPass(cmd, &info, VK_SUBPASS_CONTENTS_INLINE);
    set_viewport(cmd);
}

void RenderTarget::next_subpass(VkCommandBuffer cmd) const { vkCmdNextSubpass(cmd, VK_SUBPASS_CONTENTS_INLINE); }

void RenderTarget::set_viewport(VkCommandBuffer cmd) const {
    // Framebuffer x right, y down; pixel (i, j) covers [i, i+1) x [j, j+1) with its sample at the centre.
    const VkViewport viewport{.x = 0.0f,
                              .y = 0.0f,
                              .width = static_cast<float>(width()),
                              .height = static_cast<float>(height()),
                              .minDepth = 0.0f,
                              .maxDepth = 1.0f};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    const VkRect2D scissor{{0, 0}, {width(), height()}};
    vkCmdSetScissor(cmd, 0, 1, &scissor);
}

void RenderTarget::end(VkCommandBuffer cmd) const { vkCmdEndRenderPass(cmd); }

void RenderTarget::record_readback(VkCommandBuffer cmd) const {
    image_barrier(cmd, m_color, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
    m_color.record_copy_to(cmd, m_readback);
    const VkMemoryBarrier to_host{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                  .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                  .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr,
                         0, nullptr);
}

std::vector<glm::vec4> RenderTarget::read_color() const {
    return unpack_rgba(std::span<const std::byte>(m_readback.data(), m_color.byte_size()), m_color.format());
}

} // namespace specula::gpu
