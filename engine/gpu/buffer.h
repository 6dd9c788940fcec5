#pragma once
// Storage buffers. Every buffer has a name, used in every error about it.
//
// Memory: when the device has a device-local memory type the host can map
// (lavapipe, integrated GPUs, ReBAR), the buffer lives there, stays mapped, and
// upload/download are memcpy. Otherwise (or with BufferAccess::Staged, which
// tests use to exercise the path on lavapipe) the buffer is device-local only and
// upload/download go through a temporary staging buffer and a copy.
//
// Host/device ordering: upload() before a Sequence is submitted needs no barrier
// (vkQueueSubmit makes host writes visible). Reading results back needs
// Sequence::barrier(Barrier::ComputeToHost) at the end of the sequence; the
// staged path adds its own transfer barriers.
#include "gpu/context.h"

#include <cstddef>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace specula::gpu {

enum class BufferAccess {
    Auto,   // mapped device-local memory when there is such a type, else staged
    Staged, // always device-local only + staging copies
};

class Buffer {
public:
    /// A storage buffer of `bytes` (> 0). Throws LimitError naming the buffer when
    /// `bytes` exceeds maxStorageBufferRange (split the work) or maxMemoryAllocationSize.
    Buffer(Context& ctx, VkDeviceSize bytes, std::string name, BufferAccess access = BufferAccess::Auto);
    ~Buffer();
    Buffer(Buffer&& o) noexcept;
    Buffer& operator=(Buffer&& o) noexcept;
    Buffer(const Buffer&) = delete;
    Buffer& operator=(const Buffer&) = delete;

    /// A buffer sized for `count` elements of T.
    template <class T>
    static Buffer of(Context& ctx, std::size_t count, std::string name, BufferAccess access = BufferAccess::Auto) {
        return Buffer(ctx, static_cast<VkDeviceSize>(sizeof(T) * (count == 0 ? 1 : count)), std::move(name), access);
    }

    [[nodiscard]] VkBuffer handle() const noexcept { return m_buffer.get(); }
    [[nodiscard]] VkDeviceSize size() const noexcept { return m_size; }
    [[nodiscard]] const std::string& name() const noexcept { return m_name; }
    /// True when upload/download are plain copies into mapped memory.
    [[nodiscard]] bool mapped() const noexcept { return m_mapped != nullptr; }

    void upload_bytes(std::span<const std::byte> data, VkDeviceSize offset = 0);
    void download_bytes(std::span<std::byte> out, VkDeviceSize offset = 0) const;

    template <class T>
    void upload(std::span<const T> data, std::size_t first_element = 0) {
        static_assert(std::is_trivially_copyable_v<T>);
        upload_bytes(std::as_bytes(data), first_element * sizeof(T));
    }
    template <class T>
    void upload(const std::vector<T>& data, std::size_t first_element = 0) {
        upload(std::span<const T>(data), first_element);
    }
    template <class T>
    void download(std::span<T> out, std::size_t first_element = 0) const {
        static_assert(std::is_trivially_copyable_v<T>);
        download_bytes(std::as_writable_bytes(out), first_element * sizeof(T));
    }
    template <class T>
    [[nodiscard]] std::vector<T> download(std::size_t count, std::size_t first_element = 0) const {
        std::vector<T> out(count);
        download(std::span<T>(out), first_element);
        return out;
    }

private:
    void check_range(VkDeviceSize offset, VkDeviceSize bytes, const char* op) const;

    Context* m_ctx;
    std::string m_name;
    VkDeviceSize m_size = 0;
    UniqueMemory m_memory; // declared first: destroyed after the buffer bound to it
    UniqueBuffer m_buffer;
    void* m_mapped = nullptr; // persistently mapped when host-visible; unmapped by freeing the memory
};

} // namespace specula::gpu
