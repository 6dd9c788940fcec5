#pragma once
// Stage 4, the diffuse solve (pipeline.md section 3; thesis section 3.1, eq. 3.1):
// per surface particle, the Lambertian albedo from the train images of the views that
// see it, with shadowed, grazing, missing, clipped and highlight samples rejected.
// The method, thresholds and layouts are in shaders/shared/lambert.h (one source for
// the shader and the reference).
//
//   LambertInputs in = lambert_inputs(capture, particles.particles, visibility);
//   LambertOutputs out = lambert_solve(in, {.mode = LambertMode::Photometric}, Backend::Vulkan, &ctx);
//   out.albedo(p)   // rho (linear RGB) of the chosen combination
//
// Three steps: the gather step reads every (particle, view, train frame) sample into a
// record, the pair step solves every (particle, view) pair from its records (the view's
// frames only, any number of them), the combine step chooses the best view and the robust
// mean per particle.
//
// Memory (Vulkan): the images of a capture do not fit one storage binding (120 frames
// of 512^2 RGBA float = 480 MiB; lavapipe allows 128 MiB per binding). Images are kept
// as RGBA32 (rgb float, flags in the 4th word: exact, so the GPU reads what the reference
// reads) and FRAMES ARE BATCHED (diffuse/view_batches.h): consecutive frames, in view order,
// whose pixels fit maxStorageBufferRange go in one buffer (a view with more is split over
// batches), one gather dispatch per batch writes the records of that batch's frames; the
// records (16 bytes per pair and frame of its view) persist across batches, then one pair
// and one combine dispatch. Particles are chunked so that a chunk's records and pair results
// each fit one binding.
#include "capture/capture.h"
#include "core/backend.h"
#include "material/material.h"
#include "geometry/particles.h"
#include "visibility/visibility.h"

#include "shared/lambert.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula {
namespace gpu {
class Context;
}

enum class LambertMode : std::uint32_t {
    Albedo = shared::kLambertModeAlbedo,           ///< known normals, rho/pi per channel
    Photometric = shared::kLambertModePhotometric, ///< g = (rho/pi) n (eq. 3.1), albedo-mode fallback
};
enum class ViewChoice { BestView, Robust };

[[nodiscard]] const char* to_string(LambertMode mode) noexcept;

struct LambertOptions {
    LambertMode mode = LambertMode::Albedo;
    ViewChoice choice = ViewChoice::BestView; ///< which of the two combinations LambertOutputs::albedo returns
    float min_light_cos = 0.1f;   ///< grazing light below this n.u is rejected
    float highlight_tau = 0.1f;   ///< relative margin above the robust fit
    float noise_sigma = 0.004f;   ///< image noise (full scale 1.0) for the absolute margin
    float highlight_k = 3.0f;     ///< margin in noise sigmas
    std::uint32_t highlight_iterations = 3;
    float min_rcond = 1e-3f;      ///< photometric conditioning floor (shared/solve3.h rcond)
    float view_tau = 0.15f;       ///< cross-view outlier margin, relative
    float view_abs = 0.02f;       ///< cross-view outlier margin, absolute (albedo units)
    /// Known material (joint estimate, shared/lambert.h "known material"): its specular light
    /// f_s E is subtracted from every sample and its diffuse angular factor k_d multiplies the
    /// irradiance factor E, so the solve gives the albedo rho of f = (rho/pi) k_d + f_s. Absent
    /// (the default): the thesis's solve (Lambertian, nothing subtracted).
    std::optional<SpecularModel> material;
    /// Per-tap irradiance (shared/lambert.h): scale each bilinear tap by the irradiance of the
    /// surface its pixel shows, from the visibility's surface maps (when it has them; without
    /// them, or false, the taps are mixed as they are: the thesis's sampling).
    bool tap_irradiance = true;
    /// Vulkan: upper bound on the bytes of the batched bindings, images and pair results
    /// (0 = maxStorageBufferRange); tests lower it. Particles and lit masks take one binding each.
    std::uint64_t max_binding_bytes = 0;
    /// Vulkan: bytes of sample records held at once (0 = kLambertRecordGroupBytes); tests lower it.
    std::uint64_t max_record_group_bytes = 0;
    /// C++ reference: threads over the particles (each particle's result is the same for any count).
    unsigned threads = 2;
};

/// Sample records (16 bytes per pair and frame of its view) held at once by the Vulkan solve:
/// particle chunks are processed in groups within this, the images uploaded once per group.
inline constexpr std::uint64_t kLambertRecordGroupBytes = std::uint64_t{512} << 20;

/// One view as the solve sees it: its camera and its train frames (global frame indices).
struct LambertView {
    Camera camera;
    std::vector<std::uint32_t> frames;
};

/// Plain-data inputs. `visibility` views and `views` are parallel (capture.views order);
/// `lights` and `images` are indexed by global frame (capture.desc.frames order).
struct LambertInputs {
    std::span<const Particle> particles;
    const Visibility* visibility = nullptr;
    std::vector<LambertView> views;
    std::vector<PointLight> lights;
    std::span<const FrameImage> images;
};

/// Inputs from a loaded capture: train frames only (test frames are for evaluation).
[[nodiscard]] LambertInputs lambert_inputs(const Capture& capture, std::span<const Particle> particles,
                                           const Visibility& visibility);

/// Throws Error when the inputs are inconsistent (sizes, images missing). Any number of frames per view.
void lambert_validate(const LambertInputs& in);

using LambertParticleResult = shared::LambertParticleResult;

struct LambertSummary {
    std::size_t particles = 0;
    std::size_t pairs = 0;
    std::size_t ok = 0;
    std::size_t fallback = 0;     ///< photometric: the best view fell back to albedo mode
    std::size_t no_sample = 0;    ///< seen but nothing usable (albedo 0)
    std::size_t not_seen = 0;     ///< no view sees them (albedo 0; the texture step inpaints them)
    std::size_t views_rejected = 0; ///< particles with at least one outlier view
    std::uint64_t used = 0, rejected_shadow = 0, rejected_clipped = 0, rejected_missing = 0, rejected_grazing = 0,
                  rejected_highlight = 0, rejected_view = 0,
                  rejected_low = 0; ///< shadow edges: far below the fit
    bool tap_irradiance = false;  ///< the taps were scaled by their surfaces' irradiance (LambertOptions::tap_irradiance and surface maps)
    double mean_normal_angle_deg = 0.0; ///< photometric, over ok particles whose best view solved photometrically
    double seconds = 0.0;         ///< wall clock of the whole solve (upload, dispatch, download)
    std::optional<double> gpu_ms; ///< sum of the dispatches' GPU time (Vulkan with timestamps)
    std::vector<std::pair<std::string, double>> gpu_dispatch_ms; ///< per labelled dispatch
    std::uint32_t view_batches = 0;
    std::uint32_t pair_chunks = 0;
    std::uint32_t record_groups = 0; ///< groups of chunks whose records were held at once (the images went up once per group)
};

struct LambertOutputs {
    LambertMode mode = LambertMode::Albedo;
    ViewChoice choice = ViewChoice::BestView;
    std::vector<LambertParticleResult> particles;
    LambertSummary summary;

    /// rho of particle p for the chosen combination (0 when it has no sample).
    [[nodiscard]] glm::vec3 albedo(std::size_t p) const {
        const auto& r = particles[p];
        return glm::vec3(choice == ViewChoice::BestView ? r.albedo_best : r.albedo_robust);
    }
};

/// The reference: double precision, single thread.
[[nodiscard]] LambertOutputs lambert_solve_cpu(const LambertInputs& in, const LambertOptions& options = {});

/// The Vulkan kernel. Owns its pipelines; buffers are made per run.
class LambertSolveVk {
public:
    explicit LambertSolveVk(gpu::Context& ctx);
    ~LambertSolveVk();
    LambertSolveVk(const LambertSolveVk&) = delete;
    LambertSolveVk& operator=(const LambertSolveVk&) = delete;
    [[nodiscard]] LambertOutputs run(const LambertInputs& in, const LambertOptions& options = {});

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// Runs the solve on a backend (ctx is required for Vulkan).
[[nodiscard]] LambertOutputs lambert_solve(const LambertInputs& in, const LambertOptions& options, Backend backend,
                                           gpu::Context* ctx = nullptr);

/// Fills the summary's counts from the per-particle results (both backends call it).
void summarize(LambertOutputs& out);

/// Multi-line text of the summary for logs and the report.
[[nodiscard]] std::string describe(const LambertSummary& summary, LambertMode mode);

} // namespace specula
