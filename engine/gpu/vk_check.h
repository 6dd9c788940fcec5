#pragma once
// Every VkResult is checked where it is returned, with a message naming what
// was being done (style.md, habit 6). Errors are exceptions; library code
// never exits the process.
#include "core/error.h"

#include <vulkan/vulkan.h>

#include <string>

namespace specula::gpu {

/// A Vulkan call failed. what() = "FILE:LINE: WHAT: vkResultName (code)".
class VulkanError : public Error {
public:
    VulkanError(VkResult result, const std::string& what, const char* file, int line);
    [[nodiscard]] VkResult result() const noexcept { return m_result; }

private:
    VkResult m_result;
};

/// A limit of the device would be exceeded (a binding larger than
/// maxStorageBufferRange, too many push-constant bytes, ...). Callers split work.
class LimitError : public Error {
public:
    using Error::Error;
};

/// No device matches the selection, or the chosen one cannot run Specula.
class DeviceError : public Error {
public:
    using Error::Error;
};

/// The VkResult's enumerator name, e.g. "VK_ERROR_OUT_OF_DEVICE_MEMORY".
[[nodiscard]] const char* vk_result_name(VkResult result) noexcept;

} // namespace specula::gpu

/// Throws specula::gpu::VulkanError unless `expr` returns VK_SUCCESS. `what` names the object or step.
#define SPECULA_VK_CHECK(expr, what)                                                   \
    do {                                                                               \
        if (const VkResult r_ = (expr); r_ != VK_SUCCESS)                              \
            throw ::specula::gpu::VulkanError(r_, (what), __FILE__, __LINE__);         \
    } while (0)
