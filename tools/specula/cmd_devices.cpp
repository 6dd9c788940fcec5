// `specula devices`: lists the Vulkan devices and marks the one Specula would use.
#include "commands.h"

#include "core/error.h"
#include "gpu/context.h"

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

namespace specula::cli {

namespace {

struct DevicesOptions {
    std::string device; // selector to try instead of SPECULA_DEVICE / the default
};

std::string mib(uint64_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
    return buf;
}

void run_devices(const DevicesOptions& options) {
    const auto devices = gpu::enumerate_devices();
    std::string selector = options.device;
    if (selector.empty())
        if (const char* env = std::getenv("SPECULA_DEVICE")) selector = env;
    const gpu::DeviceSelection selection = gpu::select_device(devices, selector);
    if (devices.empty()) {
        std::printf("%s\n", selection.reason.c_str());
        return;
    }
    for (const auto& d : devices) {
        const bool chosen = selection.index && *selection.index == d.index;
        std::printf("%s [%u] %s\n", chosen ? "*" : " ", d.index, d.name.c_str());
        std::printf("      type %s, Vulkan %s, driver 0x%x\n", gpu::device_kind_name(d.kind),
                    gpu::version_string(d.api_version).c_str(), d.driver_version);
        std::printf("      maxStorageBufferRange %s, maxComputeWorkGroupCount %u x %u x %u, push constants %u B\n",
                    mib(d.max_storage_buffer_range).c_str(), d.max_compute_work_group_count[0],
                    d.max_compute_work_group_count[1], d.max_compute_work_group_count[2], d.max_push_constants_size);
        std::printf("      device-local memory %s (%s), ", mib(d.device_local_bytes).c_str(),
                    d.host_visible_device_local ? "host-visible: no staging copies" : "staging copies");
        if (d.timestamps_supported())
            std::printf("timestamps %u bits, %.3g ns/tick\n", d.timestamp_valid_bits, d.timestamp_period);
        else
            std::printf("timestamps unavailable\n");
        if (!d.unusable_reason.empty()) std::printf("      unusable: %s\n", d.unusable_reason.c_str());
    }
    if (selection.index)
        std::printf("* = the device Specula uses (%s)\n", selection.reason.c_str());
    else
        throw Error(selection.reason);
}

} // namespace

void add_devices_command(CLI::App& app) {
    auto options = std::make_shared<DevicesOptions>();
    CLI::App* cmd = app.add_subcommand("devices", "List Vulkan devices and mark the one Specula would use");
    cmd->add_option("-d,--device", options->device,
                    "Selector to try: an index or a case-insensitive name substring (default: $SPECULA_DEVICE, "
                    "then discrete > integrated > virtual > cpu)");
    cmd->callback([options] { run_devices(*options); });
}

} // namespace specula::cli
