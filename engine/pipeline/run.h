#pragma once
// What every stage of one reconstruction shares (pipeline/stages.h): the configuration, the
// result being filled (stage times, the plan, what was left out, warnings), the Vulkan
// devices, the backend of the per-particle passes, and the GPU time of every dispatch.
// A stage function takes a PipelineRun& and its typed inputs and returns its typed output.
#include "core/backend.h"
#include "core/log.h"
#include "core/timer.h"
#include "gpu/vk_check.h"
#include "pipeline/reconstruct.h"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>
#include <type_traits>
#include <utility>

namespace specula {
namespace gpu {
class Context;
}

class PipelineRun {
public:
    PipelineRun(const ReconstructConfig& config, ReconstructResult& result);
    ~PipelineRun();
    PipelineRun(const PipelineRun&) = delete;
    PipelineRun& operator=(const PipelineRun&) = delete;

    const ReconstructConfig& config;
    ReconstructResult& result;
    [[nodiscard]] Plan& plan() noexcept { return result.plan; }

    /// Runs fn as the stage `name`: logged, timed, recorded in result.stages. On a terminal a
    /// stage that runs longer than a second shows its elapsed time (log::Ticker).
    template <class Fn>
    auto stage(const std::string& name, Fn&& fn) {
        log::info("[" + name + "] ...");
        log::Ticker ticker(name);
        Stopwatch watch;
        if constexpr (std::is_void_v<decltype(fn())>) {
            fn();
            finish_stage(name, watch.seconds());
        } else {
            auto value = fn();
            finish_stage(name, watch.seconds());
            return value;
        }
    }
    /// The summed time of every stage called `name`.
    [[nodiscard]] double seconds(const std::string& name) const;

    void leave_out(std::string what, std::string why);
    void warn(std::string message);

    /// The compute device when config.backend is Vulkan (made on first call, as the stage
    /// "vulkan init"); nullptr with the CPU backend.
    gpu::Context* compute_context();
    /// A device for rendering (refinement, evaluation): the compute one, else one made now;
    /// nullptr when none can be had (no_device() says why).
    gpu::Context* render_context();
    [[nodiscard]] const std::string& no_device() const noexcept { return m_no_device; }
    /// report.json "device": the compute device's name, kind, API version, validation.
    [[nodiscard]] nlohmann::json device_json() const;

    /// Backend of the per-particle passes (diffuse solve, residual samples): config.backend until
    /// a Vulkan pass would exceed a storage binding of the device (gpu::LimitError: knot_hd's
    /// 2.8 M particles need 134 MB, lavapipe allows 128 MiB); from then on the C++ reference
    /// runs them, and the report says so.
    [[nodiscard]] Backend particle_backend() const noexcept { return m_particle_backend; }
    template <class Fn>
    auto on_particle_backend(const std::string& what, Fn&& fn) {
        if (m_particle_backend == Backend::Vulkan) {
            try {
                return fn(Backend::Vulkan);
            } catch (const gpu::LimitError& e) {
                fall_back_to_cpu(what, e);
            }
        }
        return fn(Backend::Cpu);
    }

    /// report.json "gpu_dispatches": one entry per timed dispatch.
    void add_gpu_dispatch(const std::string& stage, const std::string& dispatch, double ms);
    [[nodiscard]] const nlohmann::json& gpu_dispatches() const noexcept { return m_gpu_dispatches; }

private:
    void finish_stage(const std::string& name, double seconds);
    void fall_back_to_cpu(const std::string& what, const gpu::LimitError& e);

    std::unique_ptr<gpu::Context> m_compute;
    std::unique_ptr<gpu::Context> m_render_only;
    bool m_compute_tried = false;
    std::string m_no_device;
    Backend m_particle_backend;
    nlohmann::json m_gpu_dispatches = nlohmann::json::array();
};

} // namespace specula
