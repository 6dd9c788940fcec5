#pragma once
// An offscreen colour + depth target for raster passes, with two compatible
// render passes and the host readback of the colour:
//
//   begin(cmd, Load::Clear) ... draws ... end(cmd)    first pass: clears colour and depth
//   begin(cmd, Load::Keep)  ... draws ... end(cmd)    later passes: test against the depth,
//                                                     blend onto the colour
//   begin_deferred(cmd) ... draws ... next_subpass(cmd) ... draws ... end(cmd)
//                                                     the deferred pass: the mesh into the
//                                                     G-buffer, then one shading draw that
//                                                     reads it per pixel and writes the colour
//   begin_deferred(cmd, GbufferLoad::Keep) next_subpass(cmd) ... draw ... end(cmd)
//                                                     shades again from the G-buffer the last
//                                                     deferred pass drew (same camera)
//   record_readback(cmd)                              colour -> host buffer (barriers included)
//   ... submit and wait ...
//   read_color()                                      RGBA per pixel, row 0 at the top
//
// Depth is reversed-Z (clears to 0, nearer fragments have larger depth): with a
// float depth buffer it keeps precision at every distance.
//
// Synchronization: the render passes' external dependencies order each pass after
// the previous one's attachment writes and after the previous frame's readback;
// record_readback moves the colour to TRANSFER_SRC, copies it, and makes the copy
// visible to the host. Nothing else may use the images between frames.
#include "gpu/image.h"

#include <glm/glm.hpp>

#include <string>
#include <vector>

namespace specula::gpu {

class RenderTarget {
public:
    enum class Load { Clear, Keep };
    /// The deferred pass's G-buffer and depth: cleared for subpass 0 to draw, or kept as the last
    /// deferred pass left them (subpass 0 then draws nothing; the colour is cleared either way).
    enum class GbufferLoad { Clear, Keep };

    /// Formats: choose_color_target_format / choose_depth_format.
    RenderTarget(Context& ctx, uint32_t width, uint32_t height, std::string name);
    RenderTarget(RenderTarget&&) noexcept = default;
    RenderTarget& operator=(RenderTarget&&) noexcept = default;
    RenderTarget(const RenderTarget&) = delete;
    RenderTarget& operator=(const RenderTarget&) = delete;

    /// Build pipelines against this (both passes are compatible with it).
    [[nodiscard]] VkRenderPass render_pass() const noexcept { return m_clear_pass.get(); }
    /// Build the deferred pass's pipelines against this: subpass 0 writes the two G-buffer
    /// images (colour attachments 0 and 1, with depth), subpass 1 reads them as input
    /// attachments 0 and 1 and writes the colour.
    [[nodiscard]] VkRenderPass deferred_render_pass() const noexcept { return m_deferred_pass.get(); }
    [[nodiscard]] uint32_t width() const noexcept { return m_color.width(); }
    [[nodiscard]] uint32_t height() const noexcept { return m_color.height(); }
    [[nodiscard]] const Image& color() const noexcept { return m_color; }
    [[nodiscard]] const Image& depth() const noexcept { return m_depth; }
    /// G-buffer image 0 or 1 (colour-target format), the input attachments of the deferred pass.
    [[nodiscard]] const Image& gbuffer(int i) const noexcept { return m_gbuffer[i]; }

    /// Begins a render pass over the whole target and sets the viewport and scissor
    /// (viewport depth range [0, 1]). Clear: colour to `clear_color`, depth to 0.
    void begin(VkCommandBuffer cmd, Load load, const glm::vec4& clear_color = glm::vec4(0.0f)) const;
    /// Begins the deferred pass in its subpass 0, everything cleared (colour and G-buffer to
    /// 0, depth to 0), with the viewport and scissor set; next_subpass moves to subpass 1.
    /// GbufferLoad::Keep: the G-buffer and depth as the last deferred pass on this target left
    /// them (the caller knows they hold its camera's view), only the colour cleared.
    void begin_deferred(VkCommandBuffer cmd, GbufferLoad load = GbufferLoad::Clear) const;
    void next_subpass(VkCommandBuffer cmd) const;
    void end(VkCommandBuffer cmd) const;
    /// After the last pass of a frame: colour -> TRANSFER_SRC -> host buffer -> host.
    void record_readback(VkCommandBuffer cmd) const;
    /// The colour copied by the last submitted record_readback (call after the wait).
    [[nodiscard]] std::vector<glm::vec4> read_color() const;

private:
    void set_viewport(VkCommandBuffer cmd) const;

    Image m_color;
    Image m_depth;
    Image m_gbuffer[2];
    UniqueRenderPass m_clear_pass;
    UniqueRenderPass m_keep_pass;
    UniqueRenderPass m_deferred_pass;
    UniqueRenderPass m_deferred_reuse_pass; // compatible with m_deferred_pass: its framebuffer serves
    UniqueFramebuffer m_clear_framebuffer;
    UniqueFramebuffer m_keep_framebuffer;
    UniqueFramebuffer m_deferred_framebuffer;
    HostBuffer m_readback;
};

} // namespace specula::gpu
