#pragma once
// A window's swapchain: the images a frame is presented from, recreated when the
// window changes size or the surface says it is out of date.
//
//   gpu::Swapchain chain(ctx, surface, "viewer window");   // ctx built with VK_KHR_swapchain
//   chain.recreate(w, h);                                  // false: 0 x 0 (minimized), draw nothing
//   if (auto i = chain.acquire(acquired)) {                // nullopt: out of date, recreate
//       ... record: image(*i) UNDEFINED -> TRANSFER_DST, blit, -> PRESENT_SRC ...
//       ... submit waiting `acquired` (transfer stage), signalling chain.ready(*i) ...
//       if (!chain.present(*i)) recreate on the next frame;
//   }
//
// gpu::Presenter (presenter.h) does all of this for a window, with a render target to
// draw into and screenshots. The surface is the window system's (glfwCreateWindowSurface);
// Surface owns it.
// Images are written by transfers (a blit from an offscreen target), so the format
// must support BLIT_DST; an sRGB format is preferred, so the blit encodes linear
// colour exactly as an sRGB PNG writer does. recreate() waits for the device to be
// idle: nothing may still use the old images.
#include "gpu/context.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace specula::gpu {

/// Owner of a VkSurfaceKHR (an instance-level object, destroyed with the instance's
/// vkDestroySurfaceKHR; the Context must outlive it).
class Surface {
public:
    Surface() noexcept = default;
    Surface(VkInstance instance, VkSurfaceKHR surface) noexcept : m_instance(instance), m_surface(surface) {}
    Surface(Surface&& o) noexcept;
    Surface& operator=(Surface&& o) noexcept;
    Surface(const Surface&) = delete;
    Surface& operator=(const Surface&) = delete;
    ~Surface() { reset(); }
    void reset() noexcept;
    [[nodiscard]] VkSurfaceKHR get() const noexcept { return m_surface; }

private:
    VkInstance m_instance = VK_NULL_HANDLE;
    VkSurfaceKHR m_surface = VK_NULL_HANDLE;
};

enum class PresentPacing {
    Vsync,    ///< FIFO: waits for the display (always available)
    Unpaced,  ///< IMMEDIATE, else MAILBOX, else FIFO: for benchmarks
};

class Swapchain {
public:
    /// Checks that the context's queue can present to `surface` and picks the format
    /// (B8G8R8A8_SRGB or R8G8B8A8_SRGB when offered) and present mode. No images yet:
    /// call recreate(). Throws DeviceError when the queue cannot present or no format
    /// can be blitted to.
    Swapchain(Context& ctx, VkSurfaceKHR surface, PresentPacing pacing, std::string name);
    Swapchain(Swapchain&&) noexcept = default;
    Swapchain& operator=(Swapchain&&) noexcept = default;
    Swapchain(const Swapchain&) = delete;
    Swapchain& operator=(const Swapchain&) = delete;

    /// (Re)creates the images for a framebuffer of width x height pixels (clamped to
    /// what the surface allows). Returns false and keeps no images when the surface is
    /// 0 x 0 (a minimized window). Waits for the device to be idle first.
    bool recreate(uint32_t width, uint32_t height);
    [[nodiscard]] bool valid() const noexcept { return static_cast<bool>(m_swapchain); }

    /// Acquires the next image, signalling `acquired` when it may be written. nullopt:
    /// the swapchain is out of date (recreate, then try again); nothing was signalled.
    [[nodiscard]] std::optional<uint32_t> acquire(VkSemaphore acquired);
    /// Presents image `index` once ready(index) is signalled. false: out of date or
    /// suboptimal, recreate before the next frame.
    [[nodiscard]] bool present(uint32_t index);

    /// Signalled by the frame's submit, waited on by present (one per image, so a
    /// semaphore is never re-signalled while a presentation may still wait on it).
    [[nodiscard]] VkSemaphore ready(uint32_t index) const { return m_ready.at(index).get(); }
    [[nodiscard]] VkImage image(uint32_t index) const { return m_images.at(index); }
    [[nodiscard]] uint32_t image_count() const noexcept { return static_cast<uint32_t>(m_images.size()); }
    [[nodiscard]] uint32_t width() const noexcept { return m_extent.width; }
    [[nodiscard]] uint32_t height() const noexcept { return m_extent.height; }
    [[nodiscard]] VkFormat format() const noexcept { return m_format.format; }
    /// Whether the format encodes sRGB (a blit from linear float then writes display values).
    [[nodiscard]] bool srgb() const noexcept { return m_srgb; }
    /// Whether images can be copied out (TRANSFER_SRC usage): screenshots of what is shown.
    [[nodiscard]] bool readable() const noexcept { return (m_usage & VK_IMAGE_USAGE_TRANSFER_SRC_BIT) != 0; }
    [[nodiscard]] VkPresentModeKHR present_mode() const noexcept { return m_present_mode; }

private:
    Context* m_ctx;
    VkSurfaceKHR m_surface;
    std::string m_name;
    VkSurfaceFormatKHR m_format{};
    bool m_srgb = false;
    VkPresentModeKHR m_present_mode = VK_PRESENT_MODE_FIFO_KHR;
    VkImageUsageFlags m_usage = 0;
    VkExtent2D m_extent{0, 0};
    UniqueSwapchain m_swapchain;
    std::vector<VkImage> m_images; // owned by the swapchain
    std::vector<UniqueSemaphore> m_ready;
};

/// Creates a binary semaphore (frame synchronization with the swapchain).
[[nodiscard]] UniqueSemaphore make_semaphore(Context& ctx, const std::string& name);
/// Creates a fence, signalled or not.
[[nodiscard]] UniqueFence make_fence(Context& ctx, bool signalled, const std::string& name);

} // namespace specula::gpu
