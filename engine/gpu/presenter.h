#pragma once
// Frames shown in a window: a Swapchain, a window-sized offscreen RenderTarget that the
// caller records each frame into, and the per-frame command buffer and synchronization
// that blit the target (or another image) to an acquired swapchain image and present it;
// on request, what was presented is read back (a screenshot of what the window shows).
//
//   gpu::Presenter p(ctx, surface, gpu::PresentPacing::Vsync, "the viewer window");
//   p.resize(fb_width, fb_height);        // at the start, after a resize, when stale(); false: minimized
//   if (p.ready()) {
//       const bool ok = p.present_target([&](VkCommandBuffer cmd, const gpu::RenderTarget& target) {
//           renderer.record(cmd, target, camera, light, settings);    // leaves COLOR_ATTACHMENT_OPTIMAL
//           return std::optional<gpu::PixelRect>{};                    // or the rectangle it drew
//       }, gpu::Readback::Shown);
//       // or p.present_image(photo, rect, ...): a texture scaled into rect, the rest black
//       if (ok) specula::Image shot = p.shown_image();   // else: out of date, resize and draw again
//   }
//
// One frame in flight: every present waits until its frame has executed, so a frame's
// wall time is its whole cost, the next frame's input is applied with no frame of lag,
// and the renderer's per-frame parameters and the target can be reused every frame.
//
// Colour: the target is linear float; the blit into an sRGB swapchain format encodes it
// exactly as an sRGB PNG writer does (a warning is logged when the surface offers no
// sRGB format). Same-size blits are texel-exact (nearest filtering).
#include "core/image.h"
#include "gpu/image.h"
#include "gpu/render_target.h"
#include "gpu/swapchain.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::gpu {

/// What a present also copies back to the host.
enum class Readback {
    None,
    Shown,  ///< the presented swapchain image (8-bit, as shown): shown_image()
    Target, ///< the render target's linear colour (present_target only): target_image()
};

/// A rectangle of the swapchain image, in pixels: [x0, x1) x [y0, y1), row 0 at the top.
struct PixelRect {
    int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

class Presenter {
public:
    /// The context must have been created with the surface's instance extensions and
    /// VK_KHR_swapchain. No images yet: call resize(). Throws DeviceError when the queue
    /// cannot present to the surface or the target's format cannot be blitted.
    Presenter(Context& ctx, VkSurfaceKHR surface, PresentPacing pacing, std::string name);
    /// Waits for the device: nothing may be in flight when the swapchain and target go.
    ~Presenter();
    Presenter(const Presenter&) = delete;
    Presenter& operator=(const Presenter&) = delete;

    /// (Re)creates the swapchain, and the target when the size changed, for a framebuffer of
    /// width x height pixels. false: the surface is 0 x 0 (minimized); draw nothing.
    bool resize(uint32_t width, uint32_t height);
    /// A swapchain and a target exist: frames can be presented.
    [[nodiscard]] bool ready() const noexcept { return m_chain.valid() && m_target != nullptr; }
    [[nodiscard]] uint32_t width() const noexcept { return m_chain.width(); }
    [[nodiscard]] uint32_t height() const noexcept { return m_chain.height(); }
    [[nodiscard]] const Swapchain& chain() const noexcept { return m_chain; }
    /// "fifo", "mailbox" or "immediate": how presents are paced (benchmark reports).
    [[nodiscard]] const char* present_mode_name() const noexcept;

    /// Records into `cmd` the commands that draw into the window-sized target: every barrier
    /// they need, no render pass left open, the colour left in COLOR_ATTACHMENT_OPTIMAL
    /// after colour-attachment writes (as render::Renderer::record leaves it). Returns the
    /// rectangle of the target it drew, outside which the target holds 0 (a clear to 0, as
    /// Renderer::record's passes begin), or nullopt: the whole target may hold anything.
    using RecordFrame = std::function<std::optional<PixelRect>(VkCommandBuffer cmd, const RenderTarget& target)>;

    /// Presents one frame: `record` draws into the target, which is blitted 1:1 to the
    /// swapchain image: only the rectangle `record` returns, the rest of the swapchain image
    /// cleared to 0, the bytes the whole blit would give (lavapipe converts each texel it
    /// blits; at 1024 px the whole blit took about 2 ms more). Returns false when the
    /// swapchain is out of date (nothing was recorded or presented: resize() and draw again).
    /// A present that reports the swapchain suboptimal or out of date still returns true and
    /// marks stale().
    bool present_target(const RecordFrame& record, Readback readback = Readback::None);

    /// Presents `image` (a Texture2D in SHADER_READ_ONLY_OPTIMAL, left so) scaled into `rect`
    /// with linear filtering, the rest of the window cleared to `background` (letterboxing).
    /// Readback::Target is refused (the target is not drawn). Returns as present_target.
    bool present_image(const Image& image, const PixelRect& rect, Readback readback = Readback::None,
                       const glm::vec4& background = {0.0f, 0.0f, 0.0f, 1.0f});

    /// The last present's Readback::Shown copy: RGB, linear (the swapchain's sRGB encoding
    /// decoded, so an sRGB 8-bit writer reproduces the bytes shown), row 0 at the top.
    [[nodiscard]] specula::Image shown_image() const;
    /// The last present's Readback::Target copy: the target's linear colour, RGB.
    [[nodiscard]] specula::Image target_image() const;

    /// A present reported the swapchain out of date or suboptimal: resize() before the next frame.
    [[nodiscard]] bool stale() const noexcept { return m_stale; }
    void clear_stale() noexcept { m_stale = false; }

private:
    using RecordToSwap = std::function<void(VkCommandBuffer cmd, VkImage swap)>;
    bool present(const RecordToSwap& record, Readback readback);

    Context* m_ctx;
    std::string m_name;
    Swapchain m_chain;
    std::unique_ptr<RenderTarget> m_target;
    std::unique_ptr<HostBuffer> m_shot; // Readback::Shown
    uint32_t m_shot_width = 0, m_shot_height = 0;
    UniqueSemaphore m_acquired;
    UniqueFence m_done;
    UniqueCommandPool m_pool;
    VkCommandBuffer m_cmd = VK_NULL_HANDLE; // freed with the pool
    bool m_stale = false;
};

} // namespace specula::gpu
