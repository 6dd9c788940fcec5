#include "gpu/vk_check.h"

#include <cstdio>

namespace specula::gpu {

namespace {
std::string format_vulkan_error(VkResult result, const std::string& what, const char* file, int line) {
    char buf[96];
    std::snprintf(buf, sizeof buf, ": %s (%d)", vk_result_name(result), static_cast<int>(result));
    return std::string(file) + ":" + std::to_string(line) + ": " + what + buf;
}
} // namespace

VulkanError::VulkanError(VkResult result, const std::string& what, const char* file, int line)
    : Error(format_vulkan_error(result, what, file, line)), m_result(result) {}

const char* vk_result_name(VkResult result) noexcept {
    switch (result) {
#define SPECULA_CASE(x) \
    case x:             \
        return #x;
        SPECULA_CASE(VK_SUCCESS)
        SPECULA_CASE(VK_NOT_READY)
        SPECULA_CASE(VK_TIMEOUT)
        SPECULA_CASE(VK_EVENT_SET)
        SPECULA_CASE(VK_EVENT_RESET)
        SPECULA_CASE(VK_INCOMPLETE)
        SPECULA_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
        SPECULA_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
        SPECULA_CASE(VK_ERROR_INITIALIZATION_FAILED)
        SPECULA_CASE(VK_ERROR_DEVICE_LOST)
        SPECULA_CASE(VK_ERROR_MEMORY_MAP_FAILED)
        SPECULA_CASE(VK_ERROR_LAYER_NOT_PRESENT)
        SPECULA_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
        SPECULA_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
        SPECULA_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
        SPECULA_CASE(VK_ERROR_TOO_MANY_OBJECTS)
        SPECULA_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
        SPECULA_CASE(VK_ERROR_FRAGMENTED_POOL)
        SPECULA_CASE(VK_ERROR_UNKNOWN)
        SPECULA_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
        SPECULA_CASE(VK_ERROR_INVALID_EXTERNAL_HANDLE)
        SPECULA_CASE(VK_ERROR_FRAGMENTATION)
        SPECULA_CASE(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
        SPECULA_CASE(VK_PIPELINE_COMPILE_REQUIRED)
#undef SPECULA_CASE
    default:
        return "VkResult(unknown)";
    }
}

} // namespace specula::gpu
