#include "gpu/context.h"

#include "core/log.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <mutex>

namespace specula::gpu {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr uint32_t kMinApiVersion = VK_API_VERSION_1_2;

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

bool env_flag(const char* name) {
    const char* v = std::getenv(name);
    if (v == nullptr) return false;
    const std::string s = lower(v);
    return s == "1" || s == "true" || s == "on" || s == "yes";
}

DeviceKind to_kind(VkPhysicalDeviceType type) {
    switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return DeviceKind::Discrete;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return DeviceKind::Integrated;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return DeviceKind::Virtual;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return DeviceKind::Cpu;
    default: return DeviceKind::Other;
    }
}

int kind_rank(DeviceKind kind) { // lower is preferred
    switch (kind) {
    case DeviceKind::Discrete: return 0;
    case DeviceKind::Integrated: return 1;
    case DeviceKind::Virtual: return 2;
    case DeviceKind::Cpu: return 3;
    default: return 4;
    }
}

bool has_instance_extension(const char* name) {
    uint32_t count = 0;
    if (vkEnumerateInstanceExtensionProperties(nullptr, &count, nullptr) != VK_SUCCESS) return false;
    std::vector<VkExtensionProperties> props(count);
    if (vkEnumerateInstanceExtensionProperties(nullptr, &count, props.data()) != VK_SUCCESS) return false;
    return std::any_of(props.begin(), props.end(),
                       [&](const VkExtensionProperties& p) { return std::strcmp(p.extensionName, name) == 0; });
}

bool has_layer(const char* name) {
    uint32_t count = 0;
    if (vkEnumerateInstanceLayerProperties(&count, nullptr) != VK_SUCCESS) return false;
    std::vector<VkLayerProperties> props(count);
    if (vkEnumerateInstanceLayerProperties(&count, props.data()) != VK_SUCCESS) return false;
    return std::any_of(props.begin(), props.end(),
                       [&](const VkLayerProperties& p) { return std::strcmp(p.layerName, name) == 0; });
}

// Instance creation shared by enumerate_devices() (no validation) and Context.
// `next` is chained into VkInstanceCreateInfo (validation features + messenger info).
UniqueInstance create_instance(const std::string& app_name, bool validation, const void* next,
                               const std::vector<std::string>& extra_extensions = {}) {
    uint32_t loader_version = VK_API_VERSION_1_0;
    SPECULA_VK_CHECK(vkEnumerateInstanceVersion(&loader_version), "querying the Vulkan loader version");
    if (loader_version < kMinApiVersion)
        throw DeviceError("the Vulkan loader supports only version " + version_string(loader_version) +
                          "; Specula needs 1.2 or newer");

    std::vector<const char*> extensions;
    std::vector<const char*> layers;
    VkInstanceCreateFlags flags = 0;
    // MoltenVK and other portability drivers are listed only on request.
    if (has_instance_extension(VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME)) {
        extensions.push_back(VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME);
        flags |= VK_INSTANCE_CREATE_ENUMERATE_PORTABILITY_BIT_KHR;
    }
    if (validation) {
        if (!has_layer(kValidationLayer))
            throw DeviceError(std::string("validation was requested (SPECULA_VALIDATION or the validation option) "
                                          "but the layer ") +
                              kValidationLayer +
                              " is not installed (Debian: apt install vulkan-validationlayers)");
        if (!has_instance_extension(VK_EXT_DEBUG_UTILS_EXTENSION_NAME))
            throw DeviceError("validation was requested but the instance extension VK_EXT_debug_utils is missing");
        layers.push_back(kValidationLayer);
        extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    }
    for (const std::string& e : extra_extensions) {
        if (!has_instance_extension(e.c_str()))
            throw DeviceError("the Vulkan instance extension " + e + " is required (" + app_name +
                              ") but the loader does not offer it");
        if (std::none_of(extensions.begin(), extensions.end(), [&](const char* x) { return e == x; }))
            extensions.push_back(e.c_str());
    }
    const VkApplicationInfo app{.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
                                .pApplicationName = app_name.c_str(),
                                .applicationVersion = VK_MAKE_API_VERSION(0, 0, 1, 0),
                                .pEngineName = "specula",
                                .engineVersion = VK_MAKE_API_VERSION(0, 0, 1, 0),
                                .apiVersion = VK_API_VERSION_1_3};
    const VkInstanceCreateInfo info{.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                    .pNext = next,
                                    .flags = flags,
                                    .pApplicationInfo = &app,
                                    .enabledLayerCount = static_cast<uint32_t>(layers.size()),
                                    .ppEnabledLayerNames = layers.data(),
                                    .enabledExtensionCount = static_cast<uint32_t>(extensions.size()),
                                    .ppEnabledExtensionNames = extensions.data()};
    VkInstance instance = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateInstance(&info, nullptr, &instance), "creating the Vulkan instance");
    return UniqueInstance(instance);
}

DeviceInfo describe(VkPhysicalDevice physical, uint32_t index) {
    VkPhysicalDeviceProperties props{};
    vkGetPhysicalDeviceProperties(physical, &props);
    VkPhysicalDeviceMemoryProperties mem{};
    vkGetPhysicalDeviceMemoryProperties(physical, &mem);

    DeviceInfo d;
    d.index = index;
    d.name = props.deviceName;
    d.kind = to_kind(props.deviceType);
    d.api_version = props.apiVersion;
    d.driver_version = props.driverVersion;
    d.vendor_id = props.vendorID;
    d.max_storage_buffer_range = props.limits.maxStorageBufferRange;
    for (int i = 0; i < 3; ++i) d.max_compute_work_group_count[i] = props.limits.maxComputeWorkGroupCount[i];
    d.max_compute_work_group_invocations = props.limits.maxComputeWorkGroupInvocations;
    d.max_push_constants_size = props.limits.maxPushConstantsSize;
    d.timestamp_period = props.limits.timestampPeriod;

    VkPhysicalDeviceMaintenance3Properties m3{.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
    VkPhysicalDeviceProperties2 props2{.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, .pNext = &m3};
    vkGetPhysicalDeviceProperties2(physical, &props2);
    d.max_memory_allocation_size = m3.maxMemoryAllocationSize;

    for (uint32_t h = 0; h < mem.memoryHeapCount; ++h)
        if (mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
            d.device_local_bytes = std::max<uint64_t>(d.device_local_bytes, mem.memoryHeaps[h].size);
    for (uint32_t t = 0; t < mem.memoryTypeCount; ++t) {
        const VkMemoryPropertyFlags f = mem.memoryTypes[t].propertyFlags;
        const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT | VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                           VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        if ((f & want) == want) d.host_visible_device_local = true;
    }

    uint32_t family_count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &family_count, nullptr);
    std::vector<VkQueueFamilyProperties> families(family_count);
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &family_count, families.data());
    // Prefer a family with graphics and compute (later raster passes share it).
    for (uint32_t pass = 0; pass < 2 && !d.queue_family; ++pass) {
        for (uint32_t f = 0; f < family_count; ++f) {
            const VkQueueFlags q = families[f].queueFlags;
            if (!(q & VK_QUEUE_COMPUTE_BIT) || families[f].queueCount == 0) continue;
            if (pass == 0 && !(q & VK_QUEUE_GRAPHICS_BIT)) continue;
            d.queue_family = f;
            d.queue_has_graphics = (q & VK_QUEUE_GRAPHICS_BIT) != 0;
            d.timestamp_valid_bits = families[f].timestampValidBits;
            break;
        }
    }
    if (props.apiVersion < kMinApiVersion)
        d.unusable_reason = "Vulkan " + version_string(props.apiVersion) + " < 1.2";
    else if (!d.queue_family)
        d.unusable_reason = "no queue family with compute";
    return d;
}

std::vector<std::string> device_extension_names(VkPhysicalDevice physical) {
    uint32_t count = 0;
    SPECULA_VK_CHECK(vkEnumerateDeviceExtensionProperties(physical, nullptr, &count, nullptr), "counting device extensions");
    std::vector<VkExtensionProperties> exts(count);
    SPECULA_VK_CHECK(vkEnumerateDeviceExtensionProperties(physical, nullptr, &count, exts.data()), "listing device extensions");
    std::vector<std::string> names;
    for (const VkExtensionProperties& e : exts) names.emplace_back(e.extensionName);
    return names;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
    uint32_t count = 0;
    SPECULA_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, nullptr), "counting physical devices");
    std::vector<VkPhysicalDevice> list(count);
    SPECULA_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, list.data()), "listing physical devices");
    list.resize(count);
    return list;
}

} // namespace

const char* device_kind_name(DeviceKind kind) noexcept {
    switch (kind) {
    case DeviceKind::Discrete: return "discrete";
    case DeviceKind::Integrated: return "integrated";
    case DeviceKind::Virtual: return "virtual";
    case DeviceKind::Cpu: return "cpu";
    default: return "other";
    }
}

std::string version_string(uint32_t v) {
    return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
           std::to_string(VK_API_VERSION_PATCH(v));
}

std::vector<DeviceInfo> enumerate_devices() {
    UniqueInstance instance;
    try {
        instance = create_instance("specula-devices", false, nullptr);
    } catch (const VulkanError& e) {
        // No driver installed (or none that loads): an empty list, not an error.
        if (e.result() == VK_ERROR_INCOMPATIBLE_DRIVER || e.result() == VK_ERROR_INITIALIZATION_FAILED) return {};
        throw;
    }
    std::vector<DeviceInfo> out;
    const auto list = physical_devices(instance.get());
    for (uint32_t i = 0; i < list.size(); ++i) out.push_back(describe(list[i], i));
    return out;
}

DeviceSelection select_device(const std::vector<DeviceInfo>& devices, const std::string& selector) {
    DeviceSelection sel;
    if (devices.empty()) {
        sel.reason = "no Vulkan device found (is a Vulkan driver installed? for the CPU driver: apt install "
                     "mesa-vulkan-drivers)";
        return sel;
    }
    if (!selector.empty()) {
        const bool numeric = std::all_of(selector.begin(), selector.end(),
                                         [](unsigned char c) { return std::isdigit(c) != 0; });
        std::vector<const DeviceInfo*> matches;
        for (const auto& d : devices) {
            if (numeric ? std::to_string(d.index) == selector
                        : lower(d.name).find(lower(selector)) != std::string::npos)
                matches.push_back(&d);
        }
        if (matches.empty()) {
            sel.reason = "no Vulkan device matches \"" + selector + "\" (devices:";
            for (const auto& d : devices) sel.reason += " [" + std::to_string(d.index) + "] " + d.name;
            sel.reason += ")";
            return sel;
        }
        for (const DeviceInfo* d : matches) {
            if (d->unusable_reason.empty()) {
                sel.index = d->index;
                sel.reason = "selected by \"" + selector + "\"";
                return sel;
            }
        }
        sel.reason = "device \"" + matches.front()->name + "\" matches \"" + selector +
                     "\" but cannot be used: " + matches.front()->unusable_reason;
        return sel;
    }
    const DeviceInfo* best = nullptr;
    for (const auto& d : devices) {
        if (!d.unusable_reason.empty()) continue;
        if (best == nullptr || kind_rank(d.kind) < kind_rank(best->kind)) best = &d;
    }
    if (best == nullptr) {
        sel.reason = "no usable Vulkan device (need Vulkan 1.2 and a compute queue)";
        return sel;
    }
    sel.index = best->index;
    sel.reason = std::string("default preference (discrete > integrated > virtual > cpu): ") +
                 device_kind_name(best->kind);
    return sel;
}

// ---------------------------------------------------------------------------------------------
// Validation messages

struct Context::ValidationState {
    mutable std::mutex mutex;
    std::vector<ValidationMessage> messages;
    ValidationCounts counts;
    std::function<void(const ValidationMessage&)> handler;
};

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL on_debug_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                                const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    auto* state = static_cast<Context::ValidationState*>(user);
    ValidationMessage msg;
    msg.severity = (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT)     ? MessageSeverity::Error
                   : (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) ? MessageSeverity::Warning
                   : (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_INFO_BIT_EXT)    ? MessageSeverity::Info
                                                                                  : MessageSeverity::Verbose;
    if (msg.severity != MessageSeverity::Error && msg.severity != MessageSeverity::Warning) return VK_FALSE;
    if (data != nullptr) {
        msg.id_name = data->pMessageIdName != nullptr ? data->pMessageIdName : "";
        msg.id_number = data->messageIdNumber;
        msg.text = data->pMessage != nullptr ? data->pMessage : "";
    }
    std::function<void(const ValidationMessage&)> handler;
    {
        std::lock_guard lock(state->mutex);
        (msg.severity == MessageSeverity::Error ? state->counts.errors : state->counts.warnings) += 1;
        state->messages.push_back(msg);
        handler = state->handler;
    }
    if (handler) handler(msg);
    return VK_FALSE; // never abort the call: the caller sees the message, Vulkan goes on
}

} // namespace

ValidationCounts Context::validation_counts() const {
    std::lock_guard lock(m_validation_state->mutex);
    return m_validation_state->counts;
}

std::vector<ValidationMessage> Context::validation_messages(std::size_t first) const {
    std::lock_guard lock(m_validation_state->mutex);
    const auto& all = m_validation_state->messages;
    if (first >= all.size()) return {};
    return {all.begin() + static_cast<std::ptrdiff_t>(first), all.end()};
}

std::size_t Context::validation_message_count() const {
    std::lock_guard lock(m_validation_state->mutex);
    return m_validation_state->messages.size();
}

void Context::set_validation_handler(std::function<void(const ValidationMessage&)> handler) {
    std::lock_guard lock(m_validation_state->mutex);
    m_validation_state->handler = std::move(handler);
}

// ---------------------------------------------------------------------------------------------

Context::Context(const ContextOptions& options) : m_validation_state(std::make_unique<ValidationState>()) {
    m_validation = options.validation.value_or(env_flag("SPECULA_VALIDATION"));

    const VkValidationFeatureEnableEXT enables[] = {VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
    const VkDebugUtilsMessengerCreateInfoEXT messenger_info{
        .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
        .messageSeverity =
            VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
        .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT,
        .pfnUserCallback = on_debug_message,
        .pUserData = m_validation_state.get()};
    // The messenger info chained into the instance also reports instance creation/destruction.
    const VkValidationFeaturesEXT features{.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT,
                                           .pNext = &messenger_info,
                                           .enabledValidationFeatureCount = 1,
                                           .pEnabledValidationFeatures = enables};
    m_instance = create_instance(options.application_name, m_validation, m_validation ? &features : nullptr,
                                 options.instance_extensions);

    if (m_validation) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(m_instance.get(), "vkCreateDebugUtilsMessengerEXT"));
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(m_instance.get(), "vkDestroyDebugUtilsMessengerEXT"));
        if (create == nullptr || destroy == nullptr)
            throw DeviceError("VK_EXT_debug_utils is enabled but its functions are missing");
        VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
        SPECULA_VK_CHECK(create(m_instance.get(), &messenger_info, nullptr, &messenger),
                         "creating the validation messenger");
        m_messenger = UniqueDebugMessenger(m_instance.get(), messenger, destroy);
    }

    const auto list = physical_devices(m_instance.get());
    std::vector<DeviceInfo> devices;
    for (uint32_t i = 0; i < list.size(); ++i) {
        devices.push_back(describe(list[i], i));
        if (!devices.back().unusable_reason.empty()) continue;
        const std::vector<std::string> offered = device_extension_names(list[i]);
        for (const std::string& e : options.device_extensions)
            if (std::find(offered.begin(), offered.end(), e) == offered.end()) {
                devices.back().unusable_reason = "no device extension " + e;
                break;
            }
    }
    std::string selector = options.device;
    if (selector.empty())
        if (const char* env = std::getenv("SPECULA_DEVICE")) selector = env;
    const DeviceSelection sel = select_device(devices, selector);
    if (!sel.index) throw DeviceError(sel.reason);
    m_info = devices[*sel.index];
    m_physical = list[*sel.index];
    VkPhysicalDeviceProperties props{};
    vkGetPhysicalDeviceProperties(m_physical, &props);
    m_limits = props.limits;
    vkGetPhysicalDeviceMemoryProperties(m_physical, &m_memory);

    const float priority = 1.0f;
    const VkDeviceQueueCreateInfo queue_info{.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                             .queueFamilyIndex = *m_info.queue_family,
                                             .queueCount = 1,
                                             .pQueuePriorities = &priority};
    std::vector<const char*> device_extensions;
    for (const std::string& e : options.device_extensions) device_extensions.push_back(e.c_str());
    // Portability drivers (MoltenVK) require this extension to be enabled when offered.
    {
        uint32_t count = 0;
        SPECULA_VK_CHECK(vkEnumerateDeviceExtensionProperties(m_physical, nullptr, &count, nullptr),
                         "counting device extensions");
        std::vector<VkExtensionProperties> exts(count);
        SPECULA_VK_CHECK(vkEnumerateDeviceExtensionProperties(m_physical, nullptr, &count, exts.data()),
                         "listing device extensions");
        for (const auto& e : exts)
            if (std::strcmp(e.extensionName, "VK_KHR_portability_subset") == 0)
                device_extensions.push_back("VK_KHR_portability_subset");
    }
    const VkDeviceCreateInfo device_info{.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                                         .queueCreateInfoCount = 1,
                                         .pQueueCreateInfos = &queue_info,
                                         .enabledExtensionCount = static_cast<uint32_t>(device_extensions.size()),
                                         .ppEnabledExtensionNames = device_extensions.data()};
    VkDevice device = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateDevice(m_physical, &device_info, nullptr, &device),
                     "creating the logical device on " + m_info.name);
    m_device = UniqueDevice(device);
    vkGetDeviceQueue(device, *m_info.queue_family, 0, &m_queue);

    const VkCommandPoolCreateInfo pool_info{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                            .flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT,
                                            .queueFamilyIndex = *m_info.queue_family};
    VkCommandPool pool = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateCommandPool(device, &pool_info, nullptr, &pool), "creating the one-shot command pool");
    m_one_shot_pool = UniqueCommandPool(device, pool);

    log::debug("Vulkan device: " + m_info.name + " (" + device_kind_name(m_info.kind) + ", Vulkan " +
               version_string(m_info.api_version) + "), " + sel.reason +
               (m_validation ? ", validation on" : ""));
}

Context::~Context() {
    if (m_device) vkDeviceWaitIdle(m_device.get()); // best effort; a destructor cannot report
}

std::optional<uint32_t> Context::find_memory_type(uint32_t type_bits, VkMemoryPropertyFlags required) const {
    for (uint32_t t = 0; t < m_memory.memoryTypeCount; ++t)
        if ((type_bits & (1u << t)) && (m_memory.memoryTypes[t].propertyFlags & required) == required) return t;
    return std::nullopt;
}

void Context::submit_and_wait(const std::function<void(VkCommandBuffer)>& record, const char* what) {
    const VkDevice dev = m_device.get();
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    const VkCommandBufferAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                            .commandPool = m_one_shot_pool.get(),
                                            .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                            .commandBufferCount = 1};
    SPECULA_VK_CHECK(vkAllocateCommandBuffers(dev, &alloc, &cmd), std::string("allocating commands for ") + what);
    // The command buffer goes back to the pool however this function ends.
    struct FreeCmd {
        VkDevice dev;
        VkCommandPool pool;
        VkCommandBuffer cmd;
        ~FreeCmd() { vkFreeCommandBuffers(dev, pool, 1, &cmd); }
    } free_cmd{dev, m_one_shot_pool.get(), cmd};

    const VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                         .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    SPECULA_VK_CHECK(vkBeginCommandBuffer(cmd, &begin), std::string("beginning commands for ") + what);
    record(cmd);
    SPECULA_VK_CHECK(vkEndCommandBuffer(cmd), std::string("ending commands for ") + what);

    const VkFenceCreateInfo fence_info{.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence_handle = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateFence(dev, &fence_info, nullptr, &fence_handle), std::string("fence for ") + what);
    const UniqueFence fence(dev, fence_handle);
    const VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &cmd};
    SPECULA_VK_CHECK(vkQueueSubmit(m_queue, 1, &submit, fence.get()), std::string("submitting ") + what);
    SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence_handle, VK_TRUE, UINT64_MAX), std::string("waiting for ") + what);
}

} // namespace specula::gpu
