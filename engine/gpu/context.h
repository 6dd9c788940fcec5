#pragma once
// The Vulkan instance and device Specula computes on (lavapipe-friendly: one
// queue family, one host-visible device-local memory type is enough).
//
// Device choice: a selector string, from ContextOptions::device or else the
// environment variable SPECULA_DEVICE: an index ("0") or a case-insensitive
// substring of the device name ("llvmpipe", "nvidia"). Without one, the
// default prefers discrete > integrated > virtual > cpu (then the lower index).
//
// Validation: ContextOptions::validation, or else SPECULA_VALIDATION=1, enables
// VK_LAYER_KHRONOS_validation with synchronization validation and a
// VK_EXT_debug_utils messenger whose warnings and errors are counted and kept.
// Requested but missing layer = a DeviceError, never a silent fallback.
#include "gpu/vk_check.h"
#include "gpu/vk_unique.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::gpu {

enum class DeviceKind { Discrete, Integrated, Virtual, Cpu, Other };
[[nodiscard]] const char* device_kind_name(DeviceKind kind) noexcept;

/// What Specula needs to know about one physical device.
struct DeviceInfo {
    uint32_t index = 0; // in vkEnumeratePhysicalDevices order
    std::string name;
    DeviceKind kind = DeviceKind::Other;
    uint32_t api_version = 0; // VK_MAKE_API_VERSION encoded
    uint32_t driver_version = 0;
    uint32_t vendor_id = 0;
    uint64_t max_storage_buffer_range = 0;                 // bytes one storage binding may span
    std::array<uint32_t, 3> max_compute_work_group_count{}; // groups per dimension per dispatch
    uint32_t max_compute_work_group_invocations = 0;
    uint32_t max_push_constants_size = 0;
    uint64_t max_memory_allocation_size = 0;
    uint64_t device_local_bytes = 0; // largest device-local heap
    bool host_visible_device_local = false; // a device-local type that the host can map (UMA, ReBAR, lavapipe)
    float timestamp_period = 0.0f;          // ns per timestamp tick
    uint32_t timestamp_valid_bits = 0;      // of the compute queue family; 0 = no timestamps
    std::optional<uint32_t> queue_family;   // compute (+graphics when available); nullopt = unusable
    bool queue_has_graphics = false;
    [[nodiscard]] bool timestamps_supported() const noexcept {
        return timestamp_valid_bits > 0 && timestamp_period > 0.0f;
    }
    /// Nanoseconds between two timestamp queries' values (valid bits only, surviving one wrap);
    /// nullopt when not finite and non-negative.
    [[nodiscard]] std::optional<double> timestamp_ns(uint64_t begin, uint64_t end) const noexcept {
        const uint64_t mask = timestamp_valid_bits >= 64 ? ~uint64_t{0} : ((uint64_t{1} << timestamp_valid_bits) - 1);
        const double ns = static_cast<double>(((end & mask) - (begin & mask)) & mask) * timestamp_period;
        if (std::isfinite(ns) && ns >= 0.0) return ns;
        return std::nullopt;
    }
    /// Empty when Specula can run on the device; otherwise why not.
    std::string unusable_reason;
};

/// "1.3.239" from a VK_MAKE_API_VERSION value.
[[nodiscard]] std::string version_string(uint32_t api_version);

/// Every physical device of every installed driver. Empty when the loader finds
/// no driver at all; throws VulkanError on other failures.
[[nodiscard]] std::vector<DeviceInfo> enumerate_devices();

/// The outcome of applying a selector to a device list: a value, not an exception.
struct DeviceSelection {
    std::optional<uint32_t> index; // into the list (== DeviceInfo::index)
    std::string reason;            // why this one, or why none
};
/// selector empty = the default preference. Only usable devices are picked.
[[nodiscard]] DeviceSelection select_device(const std::vector<DeviceInfo>& devices, const std::string& selector);

struct ContextOptions {
    /// Device selector; empty = SPECULA_DEVICE, then the default preference.
    std::string device;
    /// nullopt = SPECULA_VALIDATION from the environment ("1", "true", "on").
    std::optional<bool> validation;
    std::string application_name = "specula";
    /// Extra instance extensions (a window system's surface extensions, e.g. from
    /// glfwGetRequiredInstanceExtensions). A missing one is a DeviceError naming it.
    std::vector<std::string> instance_extensions;
    /// Extra device extensions (VK_KHR_swapchain for a window). Devices that lack one
    /// are unusable for this context (DeviceInfo::unusable_reason says which).
    std::vector<std::string> device_extensions;
};

enum class MessageSeverity { Verbose, Info, Warning, Error };

struct ValidationMessage {
    MessageSeverity severity = MessageSeverity::Info;
    std::string id_name; // VUID or SYNC-HAZARD-* name
    int32_t id_number = 0;
    std::string text;
};

struct ValidationCounts {
    std::size_t warnings = 0;
    std::size_t errors = 0;
};

/// Instance, device and one compute queue. Not copyable or movable: hold it by
/// reference; every GPU object keeps a pointer to it and must not outlive it.
class Context {
public:
    explicit Context(const ContextOptions& options = {});
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    [[nodiscard]] VkInstance instance() const noexcept { return m_instance.get(); }
    [[nodiscard]] VkPhysicalDevice physical_device() const noexcept { return m_physical; }
    [[nodiscard]] VkDevice device() const noexcept { return m_device.get(); }
    [[nodiscard]] VkQueue queue() const noexcept { return m_queue; }
    [[nodiscard]] uint32_t queue_family() const noexcept { return *m_info.queue_family; }
    [[nodiscard]] const DeviceInfo& info() const noexcept { return m_info; }
    [[nodiscard]] const VkPhysicalDeviceLimits& limits() const noexcept { return m_limits; }
    [[nodiscard]] const VkPhysicalDeviceMemoryProperties& memory_properties() const noexcept { return m_memory; }

    // Validation messages (warnings and errors only). Thread-safe.
    [[nodiscard]] bool validation_enabled() const noexcept { return m_validation; }
    [[nodiscard]] ValidationCounts validation_counts() const;
    /// Messages received so far, from position `first` on (kept in arrival order).
    [[nodiscard]] std::vector<ValidationMessage> validation_messages(std::size_t first = 0) const;
    [[nodiscard]] std::size_t validation_message_count() const;
    /// Called for every warning or error as it arrives (after it is counted), on the
    /// thread that made the Vulkan call. Pass {} to remove. Must not throw.
    void set_validation_handler(std::function<void(const ValidationMessage&)> handler);

    /// Records commands into a one-shot command buffer, submits them and waits.
    /// For uploads, downloads and setup; compute work goes through Sequence.
    void submit_and_wait(const std::function<void(VkCommandBuffer)>& record, const char* what);

    /// Index of a memory type with all of `required` among `type_bits`; nullopt if none.
    [[nodiscard]] std::optional<uint32_t> find_memory_type(uint32_t type_bits, VkMemoryPropertyFlags required) const;

    struct ValidationState; // shared with the messenger callback

private:
    DeviceInfo m_info;
    VkPhysicalDeviceLimits m_limits{};
    VkPhysicalDeviceMemoryProperties m_memory{};
    bool m_validation = false;
    std::unique_ptr<ValidationState> m_validation_state; // stable address for the callback
    UniqueInstance m_instance;
    UniqueDebugMessenger m_messenger;
    VkPhysicalDevice m_physical = VK_NULL_HANDLE;
    UniqueDevice m_device;
    VkQueue m_queue = VK_NULL_HANDLE;
    UniqueCommandPool m_one_shot_pool; // for submit_and_wait
};

} // namespace specula::gpu
