#include "gpu/swapchain.h"

#include <algorithm>
#include <utility>

namespace specula::gpu {

Surface::Surface(Surface&& o) noexcept
    : m_instance(o.m_instance), m_surface(std::exchange(o.m_surface, VK_NULL_HANDLE)) {}

Surface& Surface::operator=(Surface&& o) noexcept {
    if (this != &o) {
        reset();
        m_instance = o.m_instance;
        m_surface = std::exchange(o.m_surface, VK_NULL_HANDLE);
    }
    return *this;
}

void Surface::reset() noexcept {
    if (m_surface != VK_NULL_HANDLE) vkDestroySurfaceKHR(m_instance, m_surface, nullptr);
    m_surface = VK_NULL_HANDLE;
}

UniqueSemaphore make_semaphore(Context& ctx, const std::string& name) {
    const VkSemaphoreCreateInfo info{.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore s = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateSemaphore(ctx.device(), &info, nullptr, &s), "creating semaphore '" + name + "'");
    return UniqueSemaphore(ctx.device(), s);
}

UniqueFence make_fence(Context& ctx, bool signalled, const std::string& name) {
    const VkFenceCreateInfo info{.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO,
                                 .flags = signalled ? VkFenceCreateFlags{VK_FENCE_CREATE_SIGNALED_BIT} : 0u};
    VkFence f = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateFence(ctx.device(), &info, nullptr, &f), "creating fence '" + name + "'");
    return UniqueFence(ctx.device(), f);
}

Swapchain::Swapchain(Context& ctx, VkSurfaceKHR surface, PresentPacing pacing, std::string name)
    : m_ctx(&ctx), m_surface(surface), m_name(std::move(name)) {
    const VkPhysicalDevice phys = ctx.physical_device();
    VkBool32 can_present = VK_FALSE;
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfaceSupportKHR(phys, ctx.queue_family(), surface, &can_present),
                     "asking whether the queue can present to " + m_name);
    if (!can_present)
        throw DeviceError(ctx.info().name + ": queue family " + std::to_string(ctx.queue_family()) + " cannot present to " +
                          m_name);

    uint32_t count = 0;
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfaceFormatsKHR(phys, surface, &count, nullptr), "counting surface formats");
    std::vector<VkSurfaceFormatKHR> formats(count);
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfaceFormatsKHR(phys, surface, &count, formats.data()), "listing surface formats");
    const auto blittable = [&](VkFormat f) {
        VkFormatProperties props{};
        vkGetPhysicalDeviceFormatProperties(phys, f, &props);
        return (props.optimalTilingFeatures & VK_FORMAT_FEATURE_BLIT_DST_BIT) != 0;
    };
    bool found = false;
    for (const VkFormat want : {VK_FORMAT_B8G8R8A8_SRGB, VK_FORMAT_R8G8B8A8_SRGB})
        for (const VkSurfaceFormatKHR& f : formats)
            if (!found && f.format == want && f.colorSpace == VK_COLOR_SPACE_SRGB_NONLINEAR_KHR && blittable(f.format)) {
                m_format = f;
                m_srgb = found = true;
            }
    for (const VkSurfaceFormatKHR& f : formats)
        if (!found && blittable(f.format)) {
            m_format = f;
            found = true;
        }
    if (!found) throw DeviceError(m_name + ": the surface offers no format that a blit can write");

    std::vector<VkPresentModeKHR> modes;
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfacePresentModesKHR(phys, surface, &count, nullptr), "counting present modes");
    modes.resize(count);
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfacePresentModesKHR(phys, surface, &count, modes.data()), "listing present modes");
    m_present_mode = VK_PRESENT_MODE_FIFO_KHR; // the one every surface offers
    if (pacing == PresentPacing::Unpaced)
        for (const VkPresentModeKHR want : {VK_PRESENT_MODE_MAILBOX_KHR, VK_PRESENT_MODE_IMMEDIATE_KHR})
            if (std::find(modes.begin(), modes.end(), want) != modes.end()) m_present_mode = want;
}

bool Swapchain::recreate(uint32_t width, uint32_t height) {
    const VkDevice dev = m_ctx->device();
    SPECULA_VK_CHECK(vkDeviceWaitIdle(dev), "waiting for the device before recreating " + m_name);
    VkSurfaceCapabilitiesKHR caps{};
    SPECULA_VK_CHECK(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(m_ctx->physical_device(), m_surface, &caps),
                     "querying the surface of " + m_name);
    // currentExtent is the window's size, or 0xFFFFFFFF when the swapchain decides it.
    VkExtent2D extent = caps.currentExtent;
    if (extent.width == UINT32_MAX) {
        extent.width = std::clamp(width, caps.minImageExtent.width, caps.maxImageExtent.width);
        extent.height = std::clamp(height, caps.minImageExtent.height, caps.maxImageExtent.height);
    }
    if (extent.width == 0 || extent.height == 0 || width == 0 || height == 0) { // minimized
        m_images.clear();
        m_ready.clear();
        m_swapchain.reset();
        m_extent = {0, 0};
        return false;
    }
    m_usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | (caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT);
    if (!(caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT))
        throw DeviceError(m_name + ": the surface's images cannot be written by transfers (no TRANSFER_DST usage)");
    uint32_t images = caps.minImageCount + 1;
    if (caps.maxImageCount > 0) images = std::min(images, caps.maxImageCount);

    const VkSwapchainCreateInfoKHR info{.sType = VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR,
                                        .surface = m_surface,
                                        .minImageCount = images,
                                        .imageFormat = m_format.format,
                                        .imageColorSpace = m_format.colorSpace,
                                        .imageExtent = extent,
                                        .imageArrayLayers = 1,
                                        .imageUsage = m_usage,
                                        .imageSharingMode = VK_SHARING_MODE_EXCLUSIVE,
                                        .preTransform = caps.currentTransform,
                                        .compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR)
                                                              ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                                                              : VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR,
                                        .presentMode = m_present_mode,
                                        .clipped = VK_TRUE,
                                        .oldSwapchain = m_swapchain.get()};
    VkSwapchainKHR chain = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateSwapchainKHR(dev, &info, nullptr, &chain),
                     "creating the swapchain of " + m_name + " (" + std::to_string(extent.width) + "x" +
                         std::to_string(extent.height) + ")");
    m_swapchain = UniqueSwapchain(dev, chain); // retires and destroys the old one (the device is idle)
    m_extent = extent;
    uint32_t count = 0;
    SPECULA_VK_CHECK(vkGetSwapchainImagesKHR(dev, chain, &count, nullptr), "counting swapchain images");
    m_images.resize(count);
    SPECULA_VK_CHECK(vkGetSwapchainImagesKHR(dev, chain, &count, m_images.data()), "listing swapchain images");
    m_ready.clear();
    for (uint32_t i = 0; i < count; ++i) m_ready.push_back(make_semaphore(*m_ctx, m_name + " image ready"));
    return true;
}

std::optional<uint32_t> Swapchain::acquire(VkSemaphore acquired) {
    if (!m_swapchain) return std::nullopt;
    uint32_t index = 0;
    const VkResult r = vkAcquireNextImageKHR(m_ctx->device(), m_swapchain.get(), UINT64_MAX, acquired, VK_NULL_HANDLE, &index);
    if (r == VK_ERROR_OUT_OF_DATE_KHR) return std::nullopt;
    // SUBOPTIMAL still signals the semaphore and hands out an image: use it, and let
    // present() ask for a recreation.
    if (r != VK_SUBOPTIMAL_KHR) SPECULA_VK_CHECK(r, "acquiring an image of " + m_name);
    return index;
}

bool Swapchain::present(uint32_t index) {
    const VkSemaphore wait = ready(index);
    const VkSwapchainKHR chain = m_swapchain.get();
    const VkPresentInfoKHR info{.sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR,
                                .waitSemaphoreCount = 1,
                                .pWaitSemaphores = &wait,
                                .swapchainCount = 1,
                                .pSwapchains = &chain,
                                .pImageIndices = &index};
    const VkResult r = vkQueuePresentKHR(m_ctx->queue(), &info);
    if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR) return false;
    SPECULA_VK_CHECK(r, "presenting an image of " + m_name);
    return true;
}

} // namespace specula::gpu
