#include "gpu/presenter.h"

#include "core/log.h"

#include <algorithm>
#include <cstddef>
#include <utility>

namespace specula::gpu {

namespace {

void swap_image_barrier(VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags src_stage,
                        VkAccessFlags src_access, VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    image_barrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT, 1, from, to, src_stage, src_access, dst_stage, dst_access);
}

VkImageBlit blit_region(uint32_t src_width, uint32_t src_height, const PixelRect& dst) {
    VkImageBlit r{};
    r.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    r.srcOffsets[1] = {static_cast<int32_t>(src_width), static_cast<int32_t>(src_height), 1};
    r.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    r.dstOffsets[0] = {dst.x0, dst.y0, 0};
    r.dstOffsets[1] = {dst.x1, dst.y1, 1};
    return r;
}

/// The 8-bit RGBA / BGRA formats a screenshot can be decoded from (4 bytes a texel).
bool bgra(VkFormat f) { return f == VK_FORMAT_B8G8R8A8_SRGB || f == VK_FORMAT_B8G8R8A8_UNORM; }
bool rgba(VkFormat f) { return f == VK_FORMAT_R8G8B8A8_SRGB || f == VK_FORMAT_R8G8B8A8_UNORM; }

} // namespace

Presenter::Presenter(Context& ctx, VkSurfaceKHR surface, PresentPacing pacing, std::string name)
    : m_ctx(&ctx), m_name(name), m_chain(ctx, surface, pacing, name), m_acquired(make_semaphore(ctx, name + ": image acquired")),
      m_done(make_fence(ctx, true, name + ": frame done")) {
    const VkCommandPoolCreateInfo pool{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                       .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                       .queueFamilyIndex = ctx.queue_family()};
    VkCommandPool p = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateCommandPool(ctx.device(), &pool, nullptr, &p), "creating the command pool of " + name);
    m_pool = UniqueCommandPool(ctx.device(), p);
    const VkCommandBufferAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                            .commandPool = p,
                                            .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                            .commandBufferCount = 1};
    SPECULA_VK_CHECK(vkAllocateCommandBuffers(ctx.device(), &alloc, &m_cmd), "allocating the command buffer of " + name);
    VkFormatProperties props{};
    vkGetPhysicalDeviceFormatProperties(ctx.physical_device(), choose_color_target_format(ctx), &props);
    if (!(props.optimalTilingFeatures & VK_FORMAT_FEATURE_BLIT_SRC_BIT))
        throw DeviceError(ctx.info().name + ": the render target's format cannot be blitted to " + name);
    if (!m_chain.srgb()) log::warn(name + " offers no sRGB format: colours are shown without sRGB encoding");
}

Presenter::~Presenter() {
    if (m_ctx != nullptr) vkDeviceWaitIdle(m_ctx->device()); // nothing may be in flight when the members go
}

bool Presenter::resize(uint32_t width, uint32_t height) {
    if (!m_chain.recreate(width, height)) {
        m_target.reset();
        return false;
    }
    if (!m_target || m_target->width() != m_chain.width() || m_target->height() != m_chain.height())
        m_target = std::make_unique<RenderTarget>(*m_ctx, m_chain.width(), m_chain.height(), "target of " + m_name);
    return true;
}

const char* Presenter::present_mode_name() const noexcept {
    switch (m_chain.present_mode()) {
    case VK_PRESENT_MODE_FIFO_KHR: return "fifo";
    case VK_PRESENT_MODE_MAILBOX_KHR: return "mailbox";
    case VK_PRESENT_MODE_IMMEDIATE_KHR: return "immediate";
    default: return "other";
    }
}

bool Presenter::present_target(const RecordFrame& record, Readback readback) {
    if (!ready()) throw Error("Presenter::present_target before a successful resize()");
    return present(
        [&](VkCommandBuffer cmd, VkImage swap) {
            const std::optional<PixelRect> drawn = record(cmd, *m_target);
            if (readback == Readback::Target) {
                m_target->record_readback(cmd); // leaves the colour in TRANSFER_SRC
            } else {
                image_barrier(cmd, m_target->color(), VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                              VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                              VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            }
            // Same size: a texel-exact copy with the format conversion (linear float -> sRGB bytes),
            // of the rectangle drawn; the rest is 0 in the target, so a clear to 0 gives its bytes.
            const PixelRect whole{.x0 = 0, .y0 = 0, .x1 = static_cast<int32_t>(m_chain.width()),
                                  .y1 = static_cast<int32_t>(m_chain.height())};
            PixelRect r = whole;
            if (drawn) {
                r = {.x0 = std::clamp(drawn->x0, 0, whole.x1), .y0 = std::clamp(drawn->y0, 0, whole.y1),
                     .x1 = std::clamp(drawn->x1, 0, whole.x1), .y1 = std::clamp(drawn->y1, 0, whole.y1)};
                const VkClearColorValue zero{{0.0f, 0.0f, 0.0f, 0.0f}};
                const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
                vkCmdClearColorImage(cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1, &all);
                swap_image_barrier(cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                                   VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                   VK_ACCESS_TRANSFER_WRITE_BIT);
            }
            if (r.x1 > r.x0 && r.y1 > r.y0) {
                VkImageBlit region{};
                region.srcSubresource = region.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
                region.srcOffsets[0] = region.dstOffsets[0] = {r.x0, r.y0, 0};
                region.srcOffsets[1] = region.dstOffsets[1] = {r.x1, r.y1, 1};
                vkCmdBlitImage(cmd, m_target->color().handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, swap,
                               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region, VK_FILTER_NEAREST);
            }
        },
        readback);
}

bool Presenter::present_image(const Image& image, const PixelRect& rect, Readback readback, const glm::vec4& background) {
    if (!ready()) throw Error("Presenter::present_image before a successful resize()");
    if (readback == Readback::Target) throw Error("Presenter::present_image: the target is not drawn, so it cannot be read back");
    if (image.kind() != ImageKind::Texture2D) throw Error("Presenter::present_image: '" + image.name() + "' is not a 2D texture");
    return present(
        [&](VkCommandBuffer cmd, VkImage swap) {
            // Letterbox: clear, then the image scaled into its rectangle.
            const VkClearColorValue clear{{background.r, background.g, background.b, background.a}};
            const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
            vkCmdClearColorImage(cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &clear, 1, &all);
            swap_image_barrier(cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                               VK_ACCESS_TRANSFER_WRITE_BIT);
            // Nothing else uses the texture while a frame is in flight (one frame at a time,
            // uploads wait), so its layout changes need no memory dependency.
            image_barrier(cmd, image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                          VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            const VkImageBlit region = blit_region(image.width(), image.height(), rect);
            vkCmdBlitImage(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &region, VK_FILTER_LINEAR);
            image_barrier(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                          VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, 0);
        },
        readback);
}

bool Presenter::present(const RecordToSwap& record, Readback readback) {
    const VkDevice dev = m_ctx->device();
    const VkFence fence = m_done.get();
    SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "waiting for the previous frame");
    if (readback == Readback::Shown) {
        if (!m_chain.readable()) throw DeviceError("the window's images cannot be read back for a screenshot");
        if (!bgra(m_chain.format()) && !rgba(m_chain.format()))
            throw DeviceError("the window's image format is not 8-bit RGBA or BGRA: no screenshot of it");
    }
    const std::optional<uint32_t> index = m_chain.acquire(m_acquired.get());
    if (!index) return false;
    const VkImage swap = m_chain.image(*index);
    const uint32_t w = m_chain.width(), h = m_chain.height();
    SPECULA_VK_CHECK(vkResetFences(dev, 1, &fence), "resetting the frame fence");
    SPECULA_VK_CHECK(vkResetCommandBuffer(m_cmd, 0), "resetting the presenter's command buffer");
    const VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                         .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    SPECULA_VK_CHECK(vkBeginCommandBuffer(m_cmd, &begin), "beginning the presenter's command buffer");

    // The swapchain image: whatever it held -> transfer destination. The acquire
    // semaphore is waited on at the transfer stage, which this barrier chains to.
    swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT,
                       0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    record(m_cmd, swap);
    if (readback == Readback::Shown) {
        const VkDeviceSize bytes = VkDeviceSize{w} * h * 4;
        if (!m_shot || m_shot->size() < bytes) m_shot = std::make_unique<HostBuffer>(*m_ctx, bytes, "screenshot");
        m_shot_width = w;
        m_shot_height = h;
        swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                           VK_ACCESS_TRANSFER_READ_BIT);
        const VkBufferImageCopy copy{.bufferOffset = 0,
                                     .bufferRowLength = 0,
                                     .bufferImageHeight = 0,
                                     .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                                     .imageOffset = {0, 0, 0},
                                     .imageExtent = {w, h, 1}};
        vkCmdCopyImageToBuffer(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, m_shot->handle(), 1, &copy);
        const VkMemoryBarrier to_host{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                      .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                      .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
        vkCmdPipelineBarrier(m_cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0,
                             nullptr);
        swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                           VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
    } else {
        // Presentation is ordered by the semaphore; the layout change must follow the writes.
        swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                           VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
    }
    SPECULA_VK_CHECK(vkEndCommandBuffer(m_cmd), "ending the presenter's command buffer");

    const VkSemaphore wait = m_acquired.get();
    const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
    const VkSemaphore signal = m_chain.ready(*index);
    const VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                              .waitSemaphoreCount = 1,
                              .pWaitSemaphores = &wait,
                              .pWaitDstStageMask = &wait_stage,
                              .commandBufferCount = 1,
                              .pCommandBuffers = &m_cmd,
                              .signalSemaphoreCount = 1,
                              .pSignalSemaphores = &signal};
    SPECULA_VK_CHECK(vkQueueSubmit(m_ctx->queue(), 1, &submit, fence), "submitting a frame");
    const bool presented = m_chain.present(*index);
    // Wait here rather than at the next frame: the frame time then is this frame's
    // whole cost, and the next frame's input is applied with no frame of lag.
    SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "waiting for a frame");
    if (!presented) m_stale = true;
    return true;
}

specula::Image Presenter::shown_image() const {
    if (!m_shot) throw Error("Presenter::shown_image before a present with Readback::Shown");
    const uint32_t w = m_shot_width, h = m_shot_height;
    specula::Image img(static_cast<int>(w), static_cast<int>(h), 3);
    const auto* px = reinterpret_cast<const unsigned char*>(m_shot->data());
    const bool bgr = bgra(m_chain.format());
    for (std::size_t i = 0; i < static_cast<std::size_t>(w) * h; ++i)
        for (std::size_t c = 0; c < 3; ++c) {
            const float v = static_cast<float>(px[4 * i + (bgr ? 2 - c : c)]) / 255.0f;
            img.pixels[3 * i + c] = m_chain.srgb() ? srgb_to_linear(v) : v;
        }
    return img;
}

specula::Image Presenter::target_image() const {
    if (!m_target) throw Error("Presenter::target_image without a target");
    const std::vector<glm::vec4> rgba = m_target->read_color();
    specula::Image img(static_cast<int>(m_target->width()), static_cast<int>(m_target->height()), 3);
    for (std::size_t i = 0; i < rgba.size(); ++i)
        for (int c = 0; c < 3; ++c) img.pixels[3 * i + static_cast<std::size_t>(c)] = rgba[i][c];
    return img;
}

} // namespace specula::gpu
