#pragma once
// Where a stage's per-element work runs: the C++ reference (the definition of what every
// kernel computes, accumulating in double) or the Vulkan kernel (the product). One enum for
// the whole pipeline: the diffuse solve, the residual samples, the factorization and the
// metrics all take it, and the planner may choose a different one per stage.
#include <optional>
#include <string_view>

namespace specula {

enum class Backend { Cpu, Vulkan };

/// "cpu" or "vulkan": the spelling of the command line and of report.json.
[[nodiscard]] constexpr const char* to_string(Backend backend) noexcept {
    return backend == Backend::Vulkan ? "vulkan" : "cpu";
}

/// The inverse of to_string; nullopt for anything else.
[[nodiscard]] constexpr std::optional<Backend> backend_from_string(std::string_view s) noexcept {
    if (s == "cpu") return Backend::Cpu;
    if (s == "vulkan") return Backend::Vulkan;
    return std::nullopt;
}

} // namespace specula
