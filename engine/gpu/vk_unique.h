#pragma once
// One move-only RAII owner per Vulkan handle (style.md, habit 5). Lower layers
// receive the raw handle as a non-owning view via get().
#include <vulkan/vulkan.h>

#include <utility>

namespace specula::gpu {

/// Owner of a handle created from a VkDevice, destroyed by Destroy(device, handle, nullptr).
template <class H, auto Destroy>
class VkUnique {
public:
    VkUnique() noexcept = default;
    VkUnique(VkDevice device, H handle) noexcept : m_device(device), m_handle(handle) {}
    VkUnique(VkUnique&& o) noexcept
        : m_device(o.m_device), m_handle(std::exchange(o.m_handle, H{})) {}
    VkUnique& operator=(VkUnique&& o) noexcept {
        if (this != &o) {
            reset();
            m_device = o.m_device;
            m_handle = std::exchange(o.m_handle, H{});
        }
        return *this;
    }
    VkUnique(const VkUnique&) = delete;
    VkUnique& operator=(const VkUnique&) = delete;
    ~VkUnique() { reset(); }

    void reset() noexcept {
        if (m_handle != H{}) Destroy(m_device, m_handle, nullptr);
        m_handle = H{};
    }
    [[nodiscard]] H get() const noexcept { return m_handle; }
    [[nodiscard]] explicit operator bool() const noexcept { return m_handle != H{}; }

private:
    VkDevice m_device = VK_NULL_HANDLE;
    H m_handle{};
};

/// Owner of a root handle (VkInstance, VkDevice), destroyed by Destroy(handle, nullptr).
template <class H, auto Destroy>
class VkRootUnique {
public:
    VkRootUnique() noexcept = default;
    explicit VkRootUnique(H handle) noexcept : m_handle(handle) {}
    VkRootUnique(VkRootUnique&& o) noexcept : m_handle(std::exchange(o.m_handle, H{})) {}
    VkRootUnique& operator=(VkRootUnique&& o) noexcept {
        if (this != &o) {
            reset();
            m_handle = std::exchange(o.m_handle, H{});
        }
        return *this;
    }
    VkRootUnique(const VkRootUnique&) = delete;
    VkRootUnique& operator=(const VkRootUnique&) = delete;
    ~VkRootUnique() { reset(); }

    void reset() noexcept {
        if (m_handle != H{}) Destroy(m_handle, nullptr);
        m_handle = H{};
    }
    [[nodiscard]] H get() const noexcept { return m_handle; }
    [[nodiscard]] explicit operator bool() const noexcept { return m_handle != H{}; }

private:
    H m_handle{};
};

using UniqueInstance = VkRootUnique<VkInstance, vkDestroyInstance>;
using UniqueDevice = VkRootUnique<VkDevice, vkDestroyDevice>;
using UniqueBuffer = VkUnique<VkBuffer, vkDestroyBuffer>;
using UniqueMemory = VkUnique<VkDeviceMemory, vkFreeMemory>;
using UniqueShaderModule = VkUnique<VkShaderModule, vkDestroyShaderModule>;
using UniqueDescriptorSetLayout = VkUnique<VkDescriptorSetLayout, vkDestroyDescriptorSetLayout>;
using UniquePipelineLayout = VkUnique<VkPipelineLayout, vkDestroyPipelineLayout>;
using UniquePipeline = VkUnique<VkPipeline, vkDestroyPipeline>;
using UniqueDescriptorPool = VkUnique<VkDescriptorPool, vkDestroyDescriptorPool>;
using UniqueCommandPool = VkUnique<VkCommandPool, vkDestroyCommandPool>;
using UniqueFence = VkUnique<VkFence, vkDestroyFence>;
using UniqueQueryPool = VkUnique<VkQueryPool, vkDestroyQueryPool>;
// Graphics (image.h, graphics_pipeline.h, render_target.h).
using UniqueImage = VkUnique<VkImage, vkDestroyImage>;
using UniqueImageView = VkUnique<VkImageView, vkDestroyImageView>;
using UniqueSampler = VkUnique<VkSampler, vkDestroySampler>;
using UniqueRenderPass = VkUnique<VkRenderPass, vkDestroyRenderPass>;
using UniqueFramebuffer = VkUnique<VkFramebuffer, vkDestroyFramebuffer>;
// Presentation (swapchain.h).
using UniqueSemaphore = VkUnique<VkSemaphore, vkDestroySemaphore>;
using UniqueSwapchain = VkUnique<VkSwapchainKHR, vkDestroySwapchainKHR>;

/// Owner of a VkDebugUtilsMessengerEXT (an extension object: destroyed through
/// the instance's function pointer, so it is not a VkUnique).
class UniqueDebugMessenger {
public:
    UniqueDebugMessenger() noexcept = default;
    UniqueDebugMessenger(VkInstance instance, VkDebugUtilsMessengerEXT messenger,
                         PFN_vkDestroyDebugUtilsMessengerEXT destroy) noexcept
        : m_instance(instance), m_messenger(messenger), m_destroy(destroy) {}
    UniqueDebugMessenger(UniqueDebugMessenger&& o) noexcept
        : m_instance(o.m_instance), m_messenger(std::exchange(o.m_messenger, VK_NULL_HANDLE)),
          m_destroy(o.m_destroy) {}
    UniqueDebugMessenger& operator=(UniqueDebugMessenger&& o) noexcept {
        if (this != &o) {
            reset();
            m_instance = o.m_instance;
            m_messenger = std::exchange(o.m_messenger, VK_NULL_HANDLE);
            m_destroy = o.m_destroy;
        }
        return *this;
    }
    UniqueDebugMessenger(const UniqueDebugMessenger&) = delete;
    UniqueDebugMessenger& operator=(const UniqueDebugMessenger&) = delete;
    ~UniqueDebugMessenger() { reset(); }

    void reset() noexcept {
        if (m_messenger != VK_NULL_HANDLE && m_destroy != nullptr) m_destroy(m_instance, m_messenger, nullptr);
        m_messenger = VK_NULL_HANDLE;
    }
    [[nodiscard]] VkDebugUtilsMessengerEXT get() const noexcept { return m_messenger; }

private:
    VkInstance m_instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT m_messenger = VK_NULL_HANDLE;
    PFN_vkDestroyDebugUtilsMessengerEXT m_destroy = nullptr;
};

} // namespace specula::gpu
