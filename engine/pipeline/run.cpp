#include "pipeline/run.h"

#include "gpu/context.h"
#include "pipeline/planner.h"

namespace specula {

using nlohmann::json;

PipelineRun::PipelineRun(const ReconstructConfig& c, ReconstructResult& r)
    : config(c), result(r), m_particle_backend(c.backend) {}

PipelineRun::~PipelineRun() = default;

void PipelineRun::finish_stage(const std::string& name, double seconds) {
    result.stages.push_back({name, seconds});
    log::info("[" + name + "] " + std::to_string(seconds) + " s");
}

double PipelineRun::seconds(const std::string& name) const {
    double s = 0.0;
    for (const StageRecord& st : result.stages)
        if (st.name == name) s += st.seconds;
    return s;
}

void PipelineRun::leave_out(std::string what, std::string why) { result.left_out.push_back({std::move(what), std::move(why)}); }

void PipelineRun::warn(std::string message) {
    log::warn(message);
    result.warnings.push_back(std::move(message));
}

gpu::Context* PipelineRun::compute_context() {
    if (config.backend != Backend::Vulkan) return nullptr;
    if (!m_compute_tried) {
        m_compute_tried = true;
        m_compute = stage("vulkan init", [&] { return std::make_unique<gpu::Context>(gpu::ContextOptions{.device = config.device}); });
        log::info("Vulkan device: " + m_compute->info().name);
        PlanDecision d{.name = "particle_backend", .value = to_string(m_particle_backend), .forced = !config.backend_auto};
        d.reason = config.backend_auto ? "a GPU: the compute kernels" : "--backend vulkan";
        if (config.backend_auto && m_compute->info().kind == gpu::DeviceKind::Cpu) {
            // Measured on the knot at 384 px (120 train frames): 37.9 s with the C++ passes against
            // 44.2 s with lavapipe's kernels, 1.37 GB against 2.13 GB, the same test PSNR (35.856 dB).
            m_particle_backend = Backend::Cpu;
            d.value = to_string(m_particle_backend);
            d.reason = "the device (" + m_compute->info().name + ") is a CPU Vulkan driver, where the kernels run slower than "
                       "the C++ reference; --backend vulkan runs them anyway";
        }
        log::info("plan: particle_backend = " + d.value + " (" + (d.forced ? "forced" : "auto") + "): " + d.reason);
        plan().add(std::move(d));
    }
    return m_compute.get();
}

gpu::Context* PipelineRun::render_context() {
    if (m_compute) return m_compute.get();
    if (!m_render_only && m_no_device.empty()) {
        try {
            m_render_only = std::make_unique<gpu::Context>(gpu::ContextOptions{.device = config.device});
        } catch (const std::exception& e) {
            m_no_device = e.what();
        }
    }
    return m_render_only.get();
}

json PipelineRun::device_json() const {
    if (!m_compute) return nullptr;
    const gpu::Context& ctx = *m_compute;
    return {{"name", ctx.info().name},
            {"kind", gpu::device_kind_name(ctx.info().kind)},
            {"api_version", gpu::version_string(ctx.info().api_version)},
            {"validation", ctx.validation_enabled()},
            {"validation_messages", ctx.validation_message_count()}};
}

void PipelineRun::fall_back_to_cpu(const std::string& what, const gpu::LimitError& e) {
    m_particle_backend = Backend::Cpu;
    const std::string why = std::string(e.what()) + ": the C++ reference ran instead";
    leave_out("Vulkan " + what + " and the later per-particle passes", why);
    log::warn("Vulkan " + what + ": " + why);
}

void PipelineRun::add_gpu_dispatch(const std::string& stage_name, const std::string& dispatch, double ms) {
    m_gpu_dispatches.push_back({{"stage", stage_name}, {"dispatch", dispatch}, {"ms", ms}});
}

} // namespace specula
