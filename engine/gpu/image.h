#pragma once
// Images for the raster passes: sampled 2D textures, cube-maps, colour and depth
// render targets; host transfer buffers for uploads and readbacks; samplers.
//
// Texel data on the host is tightly packed: layer after layer (cube faces in
// Vulkan's order +X, -X, +Y, -Y, +Z, -Z), rows top to bottom (row 0 first, the
// capture's convention), texels left to right, in the image's format.
//
// Layouts. Textures and cube-maps live in SHADER_READ_ONLY_OPTIMAL once upload()
// returns. Render targets are the caller's to transition (image_barrier); see
// render_target.h, which does it for the offscreen renderer.
#include "gpu/context.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace specula::gpu {

/// A host-visible, mapped buffer for transfers (staging uploads, readbacks). Unlike
/// Buffer it is not a storage buffer, so maxStorageBufferRange does not limit it.
class HostBuffer {
public:
    HostBuffer(Context& ctx, VkDeviceSize bytes, std::string name);
    HostBuffer(HostBuffer&&) noexcept = default;
    HostBuffer& operator=(HostBuffer&&) noexcept = default;
    HostBuffer(const HostBuffer&) = delete;
    HostBuffer& operator=(const HostBuffer&) = delete;

    [[nodiscard]] VkBuffer handle() const noexcept { return m_buffer.get(); }
    [[nodiscard]] VkDeviceSize size() const noexcept { return m_size; }
    [[nodiscard]] const std::string& name() const noexcept { return m_name; }
    /// The mapped bytes (host-coherent, mapped for the buffer's lifetime).
    [[nodiscard]] std::byte* data() noexcept { return static_cast<std::byte*>(m_mapped); }
    [[nodiscard]] const std::byte* data() const noexcept { return static_cast<const std::byte*>(m_mapped); }

private:
    std::string m_name;
    VkDeviceSize m_size = 0;
    UniqueMemory m_memory; // destroyed after the buffer bound to it
    UniqueBuffer m_buffer;
    void* m_mapped = nullptr;
};

enum class ImageKind {
    Texture2D,   // sampled, one layer
    CubeMap,     // sampled, six square layers, viewed as a cube
    ColorTarget, // colour attachment, copied out with a transfer
    GBuffer,     // colour attachment that a later subpass reads as an input attachment
    DepthTarget, // depth attachment
    ShadowMap,   // depth attachment that later passes sample (with a depth-compare sampler)
};

struct ImageDesc {
    std::string name;
    ImageKind kind = ImageKind::Texture2D;
    uint32_t width = 0;  // cube-maps: the face resolution; height must equal it
    uint32_t height = 0;
    VkFormat format = VK_FORMAT_R32G32B32A32_SFLOAT;
};

class Image {
public:
    /// Creates the image (device-local) and its view. Throws LimitError when the size
    /// exceeds the device's limits, DeviceError when the format lacks the features the
    /// kind needs (see the choose_* functions below for formats that have them).
    Image(Context& ctx, const ImageDesc& desc);
    Image(Image&&) noexcept = default;
    Image& operator=(Image&&) noexcept = default;
    Image(const Image&) = delete;
    Image& operator=(const Image&) = delete;

    [[nodiscard]] VkImage handle() const noexcept { return m_image.get(); }
    [[nodiscard]] VkImageView view() const noexcept { return m_view.get(); }
    [[nodiscard]] VkFormat format() const noexcept { return m_format; }
    [[nodiscard]] ImageKind kind() const noexcept { return m_kind; }
    [[nodiscard]] uint32_t width() const noexcept { return m_width; }
    [[nodiscard]] uint32_t height() const noexcept { return m_height; }
    [[nodiscard]] uint32_t layers() const noexcept { return m_layers; }
    [[nodiscard]] VkImageAspectFlags aspect() const noexcept { return m_aspect; }
    [[nodiscard]] const std::string& name() const noexcept { return m_name; }
    /// Bytes of all layers, tightly packed.
    [[nodiscard]] VkDeviceSize byte_size() const noexcept;
    [[nodiscard]] uint32_t texel_bytes() const noexcept { return m_texel_bytes; }

    /// Textures and cube-maps: replaces every texel of every layer (size must be
    /// byte_size()) and leaves the image in SHADER_READ_ONLY_OPTIMAL. Waits.
    void upload(std::span<const std::byte> texels);
    /// Textures and cube-maps after upload(): every layer back to the host. Waits.
    [[nodiscard]] std::vector<std::byte> download() const;

    /// Records a copy of the whole image, which must be in TRANSFER_SRC_OPTIMAL, into
    /// `dst` at offset 0 (tightly packed).
    void record_copy_to(VkCommandBuffer cmd, const HostBuffer& dst) const;

private:
    Context* m_ctx;
    std::string m_name;
    ImageKind m_kind = ImageKind::Texture2D;
    VkFormat m_format = VK_FORMAT_UNDEFINED;
    uint32_t m_width = 0, m_height = 0, m_layers = 1, m_texel_bytes = 0;
    VkImageAspectFlags m_aspect = VK_IMAGE_ASPECT_COLOR_BIT;
    bool m_uploaded = false;
    UniqueMemory m_memory; // destroyed after the image and view
    UniqueImage m_image;
    UniqueImageView m_view;
};

/// One pipeline barrier with one image memory barrier over mip 0 and `layers` layers of a
/// raw image (e.g. a swapchain image, which no gpu::Image owns).
void image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, uint32_t layers, VkImageLayout old_layout,
                   VkImageLayout new_layout, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                   VkPipelineStageFlags dst_stage, VkAccessFlags dst_access);

/// One pipeline barrier with one image memory barrier over all layers of `image`.
void image_barrier(VkCommandBuffer cmd, const Image& image, VkImageLayout old_layout, VkImageLayout new_layout,
                   VkPipelineStageFlags src_stage, VkAccessFlags src_access, VkPipelineStageFlags dst_stage,
                   VkAccessFlags dst_access);

/// Bytes per texel of the formats this layer uses (RGBA32F/16F, R32F, depth formats); 0 otherwise.
[[nodiscard]] uint32_t format_texel_bytes(VkFormat format) noexcept;

/// RGBA32F when the device filters it linearly, else RGBA16F (always filterable).
[[nodiscard]] VkFormat choose_float_texture_format(const Context& ctx);
/// RGBA32F when it can be a blended colour attachment, else RGBA16F.
[[nodiscard]] VkFormat choose_color_target_format(const Context& ctx);
/// D32_SFLOAT, else D24 / D16 (whatever the device offers as a depth attachment).
[[nodiscard]] VkFormat choose_depth_format(const Context& ctx);
/// A shadow map's format: D32_SFLOAT where it is a depth attachment that can be sampled with
/// linear filtering (the compare sampler's 2x2 PCF), else D16_UNORM (attachment and sampled
/// on every Vulkan device). Float depth keeps the light-space depth step far below the bias.
[[nodiscard]] VkFormat choose_shadow_map_format(const Context& ctx);
/// Whether `format` (a depth format) can be sampled with linear filtering.
[[nodiscard]] bool depth_filters_linearly(const Context& ctx, VkFormat format);

/// Packs `count` texels of `channels` (1..4) floats each into RGBA32F or RGBA16F
/// texels (missing channels: 0, alpha 1).
[[nodiscard]] std::vector<std::byte> pack_rgba(std::span<const float> values, int channels, std::size_t count,
                                               VkFormat format);
/// The inverse for RGBA32F / RGBA16F texels.
[[nodiscard]] std::vector<glm::vec4> unpack_rgba(std::span<const std::byte> texels, VkFormat format);

/// Bilinear filtering, clamp to edge on every axis, no mipmaps (textures here have one level).
[[nodiscard]] UniqueSampler make_linear_clamp_sampler(Context& ctx, const std::string& name);
/// Depth-compare sampler for sampler2DShadow: result = (reference <= stored) ? 1 : 0 per texel,
/// bilinearly weighted over the 2x2 nearest texels when `linear` (percentage-closer filtering);
/// clamp to an opaque white border (depth 1: outside the map is lit).
[[nodiscard]] UniqueSampler make_shadow_compare_sampler(Context& ctx, bool linear, const std::string& name);

} // namespace specula::gpu
