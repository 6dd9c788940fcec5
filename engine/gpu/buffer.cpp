#include "gpu/buffer.h"

#include <cstdio>
#include <utility>

namespace specula::gpu {

namespace {

std::string mib(VkDeviceSize bytes) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%llu bytes (%.1f MiB)", static_cast<unsigned long long>(bytes),
                  static_cast<double>(bytes) / (1024.0 * 1024.0));
    return buf;
}

struct RawBuffer {
    UniqueBuffer buffer;
    UniqueMemory memory;
    void* mapped = nullptr;
};

// Creates a buffer and binds memory of a type with `required` properties. Returns an
// empty RawBuffer (no throw) when allocation fails for lack of memory, so the caller can fall back.
RawBuffer create_raw(Context& ctx, VkDeviceSize bytes, VkBufferUsageFlags usage, VkMemoryPropertyFlags required,
                     const std::string& name, bool map) {
    const VkDevice dev = ctx.device();
    const VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                  .size = bytes,
                                  .usage = usage,
                                  .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
    VkBuffer buffer = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateBuffer(dev, &info, nullptr, &buffer), "creating buffer '" + name + "'");
    RawBuffer raw;
    raw.buffer = UniqueBuffer(dev, buffer);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(dev, buffer, &req);
    const auto type = ctx.find_memory_type(req.memoryTypeBits, required);
    if (!type) return {};
    const VkMemoryAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                     .allocationSize = req.size,
                                     .memoryTypeIndex = *type};
    VkDeviceMemory memory = VK_NULL_HANDLE;
    const VkResult r = vkAllocateMemory(dev, &alloc, nullptr, &memory);
    if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY) return {}; // e.g. a small BAR heap: fall back to staging
    SPECULA_VK_CHECK(r, "allocating " + mib(req.size) + " for buffer '" + name + "'");
    raw.memory = UniqueMemory(dev, memory);
    SPECULA_VK_CHECK(vkBindBufferMemory(dev, buffer, memory, 0), "binding memory of buffer '" + name + "'");
    if (map) SPECULA_VK_CHECK(vkMapMemory(dev, memory, 0, VK_WHOLE_SIZE, 0, &raw.mapped), "mapping buffer '" + name + "'");
    return raw;
}

constexpr VkMemoryPropertyFlags kMappable = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
// Every buffer may also be a vertex or index buffer (the raster passes' meshes).
constexpr VkBufferUsageFlags kStorageUsage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_VERTEX_BUFFER_BIT |
                                             VK_BUFFER_USAGE_INDEX_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                                             VK_BUFFER_USAGE_TRANSFER_DST_BIT;

RawBuffer create_staging(Context& ctx, VkDeviceSize bytes, const std::string& name) {
    RawBuffer s = create_raw(ctx, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                             kMappable | VK_MEMORY_PROPERTY_HOST_CACHED_BIT, name + " (staging)", true);
    if (!s.memory) s = create_raw(ctx, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  kMappable, name + " (staging)", true);
    if (!s.memory) throw VulkanError(VK_ERROR_OUT_OF_HOST_MEMORY, "no host-visible memory for staging of '" + name + "'",
                                     __FILE__, __LINE__);
    return s;
}

} // namespace

Buffer::Buffer(Context& ctx, VkDeviceSize bytes, std::string name, BufferAccess access)
    : m_ctx(&ctx), m_name(std::move(name)), m_size(bytes) {
    const DeviceInfo& info = ctx.info();
    if (bytes == 0) throw LimitError("storage buffer '" + m_name + "': size 0 (a buffer needs at least one byte)");
    if (bytes > info.max_storage_buffer_range)
        throw LimitError("storage buffer '" + m_name + "' needs " + mib(bytes) + " but " + info.name +
                         " binds at most " + mib(info.max_storage_buffer_range) +
                         " per storage buffer (maxStorageBufferRange): split the work into smaller batches");
    if (info.max_memory_allocation_size != 0 && bytes > info.max_memory_allocation_size)
        throw LimitError("storage buffer '" + m_name + "' needs " + mib(bytes) + " but " + info.name +
                         " allocates at most " + mib(info.max_memory_allocation_size) + " (maxMemoryAllocationSize)");
    RawBuffer raw;
    if (access == BufferAccess::Auto)
        raw = create_raw(ctx, bytes, kStorageUsage, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT | kMappable, m_name, true);
    if (!raw.memory) raw = create_raw(ctx, bytes, kStorageUsage, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, m_name, false);
    if (!raw.memory) raw = create_raw(ctx, bytes, kStorageUsage, 0, m_name, false); // any memory at all
    if (!raw.memory)
        throw VulkanError(VK_ERROR_OUT_OF_DEVICE_MEMORY, "no memory for buffer '" + m_name + "' of " + mib(bytes),
                          __FILE__, __LINE__);
    m_buffer = std::move(raw.buffer);
    m_memory = std::move(raw.memory);
    m_mapped = raw.mapped;
}

Buffer::~Buffer() = default; // freeing the memory unmaps it

Buffer::Buffer(Buffer&& o) noexcept
    : m_ctx(o.m_ctx), m_name(std::move(o.m_name)), m_size(std::exchange(o.m_size, 0)),
      m_memory(std::move(o.m_memory)), m_buffer(std::move(o.m_buffer)), m_mapped(std::exchange(o.m_mapped, nullptr)) {}

Buffer& Buffer::operator=(Buffer&& o) noexcept {
    if (this != &o) {
        m_buffer = std::move(o.m_buffer); // destroys the old buffer before its memory
        m_memory = std::move(o.m_memory);
        m_ctx = o.m_ctx;
        m_name = std::move(o.m_name);
        m_size = std::exchange(o.m_size, 0);
        m_mapped = std::exchange(o.m_mapped, nullptr);
    }
    return *this;
}

void Buffer::check_range(VkDeviceSize offset, VkDeviceSize bytes, const char* op) const {
    if (offset > m_size || bytes > m_size - offset)
        throw LimitError(std::string(op) + " of " + mib(bytes) + " at offset " + std::to_string(offset) +
                         " overruns buffer '" + m_name + "' of " + mib(m_size));
}

void Buffer::upload_bytes(std::span<const std::byte> data, VkDeviceSize offset) {
    check_range(offset, data.size(), "upload");
    if (data.empty()) return;
    if (m_mapped != nullptr) {
        std::memcpy(static_cast<std::byte*>(m_mapped) + offset, data.data(), data.size());
        return;
    }
    RawBuffer staging = create_staging(*m_ctx, data.size(), m_name);
    std::memcpy(staging.mapped, data.data(), data.size());
    const VkBufferCopy region{.srcOffset = 0, .dstOffset = offset, .size = data.size()};
    const VkBuffer dst = m_buffer.get();
    m_ctx->submit_and_wait(
        [&](VkCommandBuffer cmd) {
            // Earlier device work on this buffer (any stage) finishes before the copy overwrites it.
            const VkMemoryBarrier before{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                         .srcAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT,
                                         .dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1,
                                 &before, 0, nullptr, 0, nullptr);
            vkCmdCopyBuffer(cmd, staging.buffer.get(), dst, 1, &region);
            // Later submissions (compute reads) see the copy.
            const VkMemoryBarrier after{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                        .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                        .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1,
                                 &after, 0, nullptr, 0, nullptr);
        },
        "staged upload");
}

void Buffer::download_bytes(std::span<std::byte> out, VkDeviceSize offset) const {
    check_range(offset, out.size(), "download");
    if (out.empty()) return;
    if (m_mapped != nullptr) {
        std::memcpy(out.data(), static_cast<const std::byte*>(m_mapped) + offset, out.size());
        return;
    }
    RawBuffer staging = create_staging(*m_ctx, out.size(), m_name);
    const VkBufferCopy region{.srcOffset = offset, .dstOffset = 0, .size = out.size()};
    const VkBuffer src = m_buffer.get();
    m_ctx->submit_and_wait(
        [&](VkCommandBuffer cmd) {
            const VkMemoryBarrier before{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                         .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
                                         .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1,
                                 &before, 0, nullptr, 0, nullptr);
            vkCmdCopyBuffer(cmd, src, staging.buffer.get(), 1, &region);
            const VkMemoryBarrier after{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                        .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                        .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &after, 0,
                                 nullptr, 0, nullptr);
        },
        "staged download");
    std::memcpy(out.data(), staging.mapped, out.size());
}

} // namespace specula::gpu
