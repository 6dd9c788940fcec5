#include "gpu/image.h"

#include <glm/gtc/packing.hpp>

#include <algorithm>
#include <cstring>

namespace specula::gpu {

namespace {

std::string mib(VkDeviceSize bytes) {
    return std::to_string(static_cast<double>(bytes) / (1024.0 * 1024.0)).substr(0, 6) + " MiB";
}

UniqueMemory allocate(Context& ctx, const VkMemoryRequirements& req, VkMemoryPropertyFlags preferred,
                      VkMemoryPropertyFlags required, const std::string& what) {
    std::optional<uint32_t> type = ctx.find_memory_type(req.memoryTypeBits, preferred | required);
    if (!type) type = ctx.find_memory_type(req.memoryTypeBits, required);
    if (!type) throw DeviceError("no memory type for " + what);
    const VkMemoryAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                     .allocationSize = req.size,
                                     .memoryTypeIndex = *type};
    VkDeviceMemory memory = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkAllocateMemory(ctx.device(), &alloc, nullptr, &memory), "allocating " + mib(req.size) + " for " + what);
    return UniqueMemory(ctx.device(), memory);
}

VkFormatFeatureFlags optimal_features(const Context& ctx, VkFormat format) {
    VkFormatProperties props{};
    vkGetPhysicalDeviceFormatProperties(ctx.physical_device(), format, &props);
    return props.optimalTilingFeatures;
}

bool is_depth(VkFormat f) {
    return f == VK_FORMAT_D32_SFLOAT || f == VK_FORMAT_D16_UNORM || f == VK_FORMAT_X8_D24_UNORM_PACK32 ||
           f == VK_FORMAT_D24_UNORM_S8_UINT || f == VK_FORMAT_D32_SFLOAT_S8_UINT;
}

const char* kind_name(ImageKind kind) {
    switch (kind) {
    case ImageKind::Texture2D: return "texture";
    case ImageKind::CubeMap: return "cube-map";
    case ImageKind::ColorTarget: return "colour target";
    case ImageKind::GBuffer: return "G-buffer";
    case ImageKind::DepthTarget: return "depth target";
    case ImageKind::ShadowMap: return "shadow map";
    }
    return "image";
}

} // namespace

// ---------------------------------------------------------------------------------------------

HostBuffer::HostBuffer(Context& ctx, VkDeviceSize bytes, std::string name) : m_name(std::move(name)), m_size(bytes) {
    if (bytes == 0) throw LimitError("host buffer '" + m_name + "': size 0");
    const VkDevice dev = ctx.device();
    const VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                  .size = bytes,
                                  .usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
    VkBuffer buffer = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateBuffer(dev, &info, nullptr, &buffer), "creating host buffer '" + m_name + "'");
    m_buffer = UniqueBuffer(dev, buffer);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(dev, buffer, &req);
    // Cached memory makes readbacks fast where it exists; coherent spares the flushes.
    m_memory = allocate(ctx, req, VK_MEMORY_PROPERTY_HOST_CACHED_BIT,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
                        "host buffer '" + m_name + "'");
    SPECULA_VK_CHECK(vkBindBufferMemory(dev, buffer, m_memory.get(), 0), "binding host buffer '" + m_name + "'");
    SPECULA_VK_CHECK(vkMapMemory(dev, m_memory.get(), 0, VK_WHOLE_SIZE, 0, &m_mapped),
                     "mapping host buffer '" + m_name + "'");
}

// ---------------------------------------------------------------------------------------------

uint32_t format_texel_bytes(VkFormat format) noexcept {
    switch (format) {
    case VK_FORMAT_R32G32B32A32_SFLOAT: return 16;
    case VK_FORMAT_R16G16B16A16_SFLOAT: return 8;
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_X8_D24_UNORM_PACK32:
    case VK_FORMAT_D24_UNORM_S8_UINT: return 4;
    case VK_FORMAT_D16_UNORM: return 2;
    case VK_FORMAT_R8G8B8A8_UNORM: return 4;
    default: return 0;
    }
}

Image::Image(Context& ctx, const ImageDesc& desc)
    : m_ctx(&ctx), m_name(desc.name), m_kind(desc.kind), m_format(desc.format), m_width(desc.width),
      m_height(desc.height) {
    const std::string what = std::string(kind_name(m_kind)) + " '" + m_name + "'";
    m_texel_bytes = format_texel_bytes(m_format);
    if (m_texel_bytes == 0) throw DeviceError(what + ": unsupported format " + std::to_string(m_format));
    if (m_width == 0 || m_height == 0) throw LimitError(what + ": size 0");
    const VkPhysicalDeviceLimits& lim = ctx.limits();
    VkImageUsageFlags usage = 0;
    VkFormatFeatureFlags needed = 0;
    VkImageCreateFlags flags = 0;
    switch (m_kind) {
    case ImageKind::Texture2D:
        usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        needed = VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
        if (m_width > lim.maxImageDimension2D || m_height > lim.maxImageDimension2D)
            throw LimitError(what + " is " + std::to_string(m_width) + "x" + std::to_string(m_height) +
                             ", over maxImageDimension2D " + std::to_string(lim.maxImageDimension2D));
        break;
    case ImageKind::CubeMap:
        usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        needed = VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
        flags = VK_IMAGE_CREATE_CUBE_COMPATIBLE_BIT;
        m_layers = 6;
        if (m_width != m_height) throw LimitError(what + ": cube faces must be square");
        if (m_width > lim.maxImageDimensionCube)
            throw LimitError(what + ": face " + std::to_string(m_width) + " over maxImageDimensionCube " +
                             std::to_string(lim.maxImageDimensionCube));
        break;
    case ImageKind::ColorTarget:
        usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        needed = VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT;
        [[fallthrough]];
    case ImageKind::GBuffer:
        if (m_kind == ImageKind::GBuffer) {
            usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_INPUT_ATTACHMENT_BIT;
            needed = VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT;
        }
        [[fallthrough]];
    case ImageKind::DepthTarget:
    case ImageKind::ShadowMap:
        if (m_kind == ImageKind::DepthTarget || m_kind == ImageKind::ShadowMap) {
            usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT;
            needed = VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT;
            if (m_kind == ImageKind::ShadowMap) {
                usage |= VK_IMAGE_USAGE_SAMPLED_BIT;
                needed |= VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
            }
            if (!is_depth(m_format)) throw DeviceError(what + ": not a depth format");
            m_aspect = VK_IMAGE_ASPECT_DEPTH_BIT;
        }
        if (m_width > lim.maxFramebufferWidth || m_height > lim.maxFramebufferHeight)
            throw LimitError(what + " is " + std::to_string(m_width) + "x" + std::to_string(m_height) +
                             ", over the framebuffer limit " + std::to_string(lim.maxFramebufferWidth) + "x" +
                             std::to_string(lim.maxFramebufferHeight));
        break;
    }
    if ((optimal_features(ctx, m_format) & needed) != needed)
        throw DeviceError(what + ": the device lacks the format features this kind of image needs (format " +
                          std::to_string(m_format) + "; see gpu::choose_*_format)");

    const VkDevice dev = ctx.device();
    const VkImageCreateInfo info{.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                                 .flags = flags,
                                 .imageType = VK_IMAGE_TYPE_2D,
                                 .format = m_format,
                                 .extent = {m_width, m_height, 1},
                                 .mipLevels = 1,
                                 .arrayLayers = m_layers,
                                 .samples = VK_SAMPLE_COUNT_1_BIT,
                                 .tiling = VK_IMAGE_TILING_OPTIMAL,
                                 .usage = usage,
                                 .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
                                 .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
    VkImage image = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateImage(dev, &info, nullptr, &image), "creating " + what);
    m_image = UniqueImage(dev, image);
    VkMemoryRequirements req{};
    vkGetImageMemoryRequirements(dev, image, &req);
    m_memory = allocate(ctx, req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, what);
    SPECULA_VK_CHECK(vkBindImageMemory(dev, image, m_memory.get(), 0), "binding memory of " + what);

    const VkImageViewCreateInfo view_info{
        .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
        .image = image,
        .viewType = m_kind == ImageKind::CubeMap ? VK_IMAGE_VIEW_TYPE_CUBE : VK_IMAGE_VIEW_TYPE_2D,
        .format = m_format,
        .subresourceRange = {.aspectMask = m_aspect, .baseMipLevel = 0, .levelCount = 1, .baseArrayLayer = 0,
                             .layerCount = m_layers}};
    VkImageView view = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateImageView(dev, &view_info, nullptr, &view), "creating the view of " + what);
    m_view = UniqueImageView(dev, view);
}

VkDeviceSize Image::byte_size() const noexcept {
    return VkDeviceSize{m_width} * m_height * m_layers * m_texel_bytes;
}

void image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, uint32_t layers, VkImageLayout old_layout,
                   VkImageLayout new_layout, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                   VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    const VkImageMemoryBarrier b{.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
                                 .srcAccessMask = src_access,
                                 .dstAccessMask = dst_access,
                                 .oldLayout = old_layout,
                                 .newLayout = new_layout,
                                 .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                                 .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                                 .image = image,
                                 .subresourceRange = {.aspectMask = aspect, .baseMipLevel = 0, .levelCount = 1,
                                                      .baseArrayLayer = 0, .layerCount = layers}};
    vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

void image_barrier(VkCommandBuffer cmd, const Image& image, VkImageLayout old_layout, VkImageLayout new_layout,
                   VkPipelineStageFlags src_stage, VkAccessFlags src_access, VkPipelineStageFlags dst_stage,
                   VkAccessFlags dst_access) {
    image_barrier(cmd, image.handle(), image.aspect(), image.layers(), old_layout, new_layout, src_stage, src_access,
                  dst_stage, dst_access);
}

namespace {
VkBufferImageCopy whole_image_region(const Image& image) {
    return VkBufferImageCopy{.bufferOffset = 0,
                             .bufferRowLength = 0, // tightly packed
                             .bufferImageHeight = 0,
                             .imageSubresource = {.aspectMask = image.aspect(), .mipLevel = 0, .baseArrayLayer = 0,
                                                  .layerCount = image.layers()},
                             .imageOffset = {0, 0, 0},
                             .imageExtent = {image.width(), image.height(), 1}};
}
constexpr VkPipelineStageFlags kSamplingStages =
    VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT;
} // namespace

void Image::upload(std::span<const std::byte> texels) {
    if (m_kind != ImageKind::Texture2D && m_kind != ImageKind::CubeMap)
        throw Error("Image::upload on " + std::string(kind_name(m_kind)) + " '" + m_name + "': only textures take uploads");
    if (texels.size() != byte_size())
        throw Error("upload to '" + m_name + "': " + std::to_string(texels.size()) + " bytes given, " +
                    std::to_string(byte_size()) + " expected");
    HostBuffer staging(*m_ctx, byte_size(), m_name + " (staging)");
    std::memcpy(staging.data(), texels.data(), texels.size());
    const bool first = !m_uploaded;
    m_ctx->submit_and_wait(
        [&](VkCommandBuffer cmd) {
            // Earlier sampling (a later upload replacing the texels) must finish before the copy writes.
            image_barrier(cmd, *this, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                          first ? VkPipelineStageFlags{VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT} : kSamplingStages, 0,
                          VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
            const VkBufferImageCopy region = whole_image_region(*this);
            vkCmdCopyBufferToImage(cmd, staging.handle(), m_image.get(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                                   &region);
            image_barrier(cmd, *this, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                          VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, kSamplingStages,
                          VK_ACCESS_SHADER_READ_BIT);
        },
        "texture upload");
    m_uploaded = true;
}

std::vector<std::byte> Image::download() const {
    if (!m_uploaded) throw Error("Image::download of '" + m_name + "' before any upload");
    HostBuffer staging(*m_ctx, byte_size(), m_name + " (readback)");
    m_ctx->submit_and_wait(
        [&](VkCommandBuffer cmd) {
            image_barrier(cmd, *this, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                          kSamplingStages, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            record_copy_to(cmd, staging);
            image_barrier(cmd, *this, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                          VK_PIPELINE_STAGE_TRANSFER_BIT, 0, kSamplingStages, VK_ACCESS_SHADER_READ_BIT);
            const VkMemoryBarrier to_host{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                          .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                          .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0,
                                 nullptr, 0, nullptr);
        },
        "texture download");
    std::vector<std::byte> out(byte_size());
    std::memcpy(out.data(), staging.data(), out.size());
    return out;
}

void Image::record_copy_to(VkCommandBuffer cmd, const HostBuffer& dst) const {
    if (dst.size() < byte_size())
        throw LimitError("copy of '" + m_name + "' (" + mib(byte_size()) + ") into '" + dst.name() + "' (" +
                         mib(dst.size()) + "): too small");
    const VkBufferImageCopy region = whole_image_region(*this);
    vkCmdCopyImageToBuffer(cmd, m_image.get(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, dst.handle(), 1, &region);
}

// ---------------------------------------------------------------------------------------------

VkFormat choose_float_texture_format(const Context& ctx) {
    const VkFormatFeatureFlags want = VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT |
                                      VK_FORMAT_FEATURE_TRANSFER_DST_BIT;
    if ((optimal_features(ctx, VK_FORMAT_R32G32B32A32_SFLOAT) & want) == want) return VK_FORMAT_R32G32B32A32_SFLOAT;
    return VK_FORMAT_R16G16B16A16_SFLOAT; // filterable and sampled on every Vulkan device
}

VkFormat choose_color_target_format(const Context& ctx) {
    const VkFormatFeatureFlags want = VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT |
                                      VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT | VK_FORMAT_FEATURE_TRANSFER_SRC_BIT;
    if ((optimal_features(ctx, VK_FORMAT_R32G32B32A32_SFLOAT) & want) == want) return VK_FORMAT_R32G32B32A32_SFLOAT;
    return VK_FORMAT_R16G16B16A16_SFLOAT; // a blendable attachment on every Vulkan device
}

VkFormat choose_depth_format(const Context& ctx) {
    for (VkFormat f : {VK_FORMAT_D32_SFLOAT, VK_FORMAT_X8_D24_UNORM_PACK32, VK_FORMAT_D16_UNORM})
        if (optimal_features(ctx, f) & VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT) return f;
    throw DeviceError("the device offers no depth attachment format");
}

std::vector<std::byte> pack_rgba(std::span<const float> values, int channels, std::size_t count, VkFormat format) {
    if (channels < 1 || channels > 4) throw Error("pack_rgba: 1 to 4 channels");
    if (values.size() != count * static_cast<std::size_t>(channels)) throw Error("pack_rgba: value count mismatch");
    const auto texel = [&](std::size_t i) {
        glm::vec4 t(0.0f, 0.0f, 0.0f, 1.0f);
        for (int c = 0; c < channels; ++c) t[c] = values[i * static_cast<std::size_t>(channels) + static_cast<std::size_t>(c)];
        return t;
    };
    std::vector<std::byte> out;
    if (format == VK_FORMAT_R32G32B32A32_SFLOAT) {
        out.resize(count * sizeof(glm::vec4));
        for (std::size_t i = 0; i < count; ++i) {
            const glm::vec4 t = texel(i);
            std::memcpy(out.data() + i * sizeof(glm::vec4), &t, sizeof t);
        }
    } else if (format == VK_FORMAT_R16G16B16A16_SFLOAT) {
        out.resize(count * 8);
        for (std::size_t i = 0; i < count; ++i) {
            const glm::vec4 t = texel(i);
            const uint16_t halves[4] = {static_cast<uint16_t>(glm::packHalf1x16(t.x)), static_cast<uint16_t>(glm::packHalf1x16(t.y)),
                                        static_cast<uint16_t>(glm::packHalf1x16(t.z)), static_cast<uint16_t>(glm::packHalf1x16(t.w))};
            std::memcpy(out.data() + i * 8, halves, 8);
        }
    } else {
        throw Error("pack_rgba: format must be RGBA32F or RGBA16F");
    }
    return out;
}

std::vector<glm::vec4> unpack_rgba(std::span<const std::byte> texels, VkFormat format) {
    std::vector<glm::vec4> out;
    if (format == VK_FORMAT_R32G32B32A32_SFLOAT) {
        out.resize(texels.size() / sizeof(glm::vec4));
        std::memcpy(out.data(), texels.data(), out.size() * sizeof(glm::vec4));
    } else if (format == VK_FORMAT_R16G16B16A16_SFLOAT) {
        out.resize(texels.size() / 8);
        for (std::size_t i = 0; i < out.size(); ++i) {
            uint16_t h[4];
            std::memcpy(h, texels.data() + i * 8, 8);
            for (int c = 0; c < 4; ++c) out[i][c] = glm::unpackHalf1x16(h[c]);
        }
    } else {
        throw Error("unpack_rgba: format must be RGBA32F or RGBA16F");
    }
    return out;
}

VkFormat choose_shadow_map_format(const Context& ctx) {
    const VkFormatFeatureFlags want = VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT |
                                      VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
    if ((optimal_features(ctx, VK_FORMAT_D32_SFLOAT) & want) == want) return VK_FORMAT_D32_SFLOAT;
    return VK_FORMAT_D16_UNORM; // a sampled depth attachment on every Vulkan device
}

bool depth_filters_linearly(const Context& ctx, VkFormat format) {
    return (optimal_features(ctx, format) & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT) != 0;
}

namespace {
UniqueSampler create_sampler(Context& ctx, const VkSamplerCreateInfo& info, const std::string& name) {
    VkSampler sampler = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateSampler(ctx.device(), &info, nullptr, &sampler), "creating sampler '" + name + "'");
    return UniqueSampler(ctx.device(), sampler);
}
} // namespace

UniqueSampler make_shadow_compare_sampler(Context& ctx, bool linear, const std::string& name) {
    const VkFilter filter = linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST;
    return create_sampler(ctx,
                          {.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
                           .magFilter = filter,
                           .minFilter = filter,
                           .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
                           .addressModeU = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER,
                           .addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER,
                           .addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER,
                           .compareEnable = VK_TRUE,
                           .compareOp = VK_COMPARE_OP_LESS_OR_EQUAL,
                           .maxLod = 0.0f,
                           .borderColor = VK_BORDER_COLOR_FLOAT_OPAQUE_WHITE},
                          name);
}

UniqueSampler make_linear_clamp_sampler(Context& ctx, const std::string& name) {
    return create_sampler(ctx,
                          {.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
                           .magFilter = VK_FILTER_LINEAR,
                           .minFilter = VK_FILTER_LINEAR,
                           .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
                           .addressModeU = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                           .addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                           .addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                           .maxLod = 0.0f,
                           .borderColor = VK_BORDER_COLOR_FLOAT_TRANSPARENT_BLACK},
                          name);
}

} // namespace specula::gpu
