#pragma once
// A square depth-only target that a light's depth pass renders into and later passes
// sample (a shadow map):
//
//   begin(cmd) ... depth-only draws ... end(cmd)   clears depth to 1, leaves the image in
//                                                  SHADER_READ_ONLY_OPTIMAL for the fragment
//                                                  shaders of the passes recorded after it
//
// Standard depth (clear 1, nearer is smaller): the light's frustum hugs the object's
// bounding sphere, so near/far are close and float or 16-bit depth is plenty.
//
// Synchronization: the render pass's external dependencies order it after the previous
// frame's fragment-shader reads (write after read) and make its depth writes visible to
// later fragment-shader reads, with the layout transitions. The image starts in
// SHADER_READ_ONLY_OPTIMAL (cleared by the constructor), so a set that binds it is valid
// before the first shadow pass.
#include "gpu/image.h"

#include <string>

namespace specula::gpu {

class ShadowMap {
public:
    /// Format: choose_shadow_map_format. Sampler: make_shadow_compare_sampler (2x2 PCF where
    /// the format filters linearly). Waits for the initial clear.
    ShadowMap(Context& ctx, uint32_t size, std::string name);
    ShadowMap(ShadowMap&&) noexcept = default;
    ShadowMap& operator=(ShadowMap&&) noexcept = default;
    ShadowMap(const ShadowMap&) = delete;
    ShadowMap& operator=(const ShadowMap&) = delete;

    /// Build the depth pass's pipelines against this (depth only, no fragment shader).
    [[nodiscard]] VkRenderPass render_pass() const noexcept { return m_pass.get(); }
    [[nodiscard]] uint32_t size() const noexcept { return m_depth.width(); }
    [[nodiscard]] const Image& depth() const noexcept { return m_depth; }
    [[nodiscard]] VkSampler compare_sampler() const noexcept { return m_sampler.get(); }
    [[nodiscard]] bool filtered() const noexcept { return m_filtered; } ///< 2x2 PCF (linear compare)

    /// Begins the pass (clears depth to 1) and sets viewport and scissor over the map.
    void begin(VkCommandBuffer cmd) const;
    void end(VkCommandBuffer cmd) const;

private:
    Image m_depth;
    bool m_filtered = false;
    UniqueSampler m_sampler;
    UniqueRenderPass m_pass;
    UniqueFramebuffer m_framebuffer;
};

} // namespace specula::gpu
