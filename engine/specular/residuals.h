#pragma once
// Stage 5 (specular), residual samples (pipeline.md section 4): per particle with a diffuse solution,
// per train frame of every view that sees it where its light reaches it, the specular BRDF
// sample f_s = (c - (rho/pi) E) / E with the light and view directions in the particle's
// tangent frame. Method, weight and drop rules: shaders/shared/residuals.h.
//
//   ResidualSamples rs = residual_samples(lambert_in, diffuse_out, {}, Backend::Vulkan, &ctx);
//   LafortuneFitRgb fit = fit_lafortune(to_lafortune_samples(rs), {});
//
// Slots, not a count pass: the visibility masks (seen, lit) live on the host, so the host
// knows before the dispatch exactly which (particle, frame) pairs are candidates; it lays
// out one slot per candidate (order: view, then particle, then the view's frames) and the
// kernel writes a sample or a drop status into each. A GPU count + prefix sum would only
// save the slots of samples dropped as grazing, missing or clipped (a few percent). The
// host then compacts the used samples, in slot order, so both backends return the same
// sequence.
//
// Memory (Vulkan): as the diffuse solve (lambert_solve.h), the images are batched per view
// so that one batch fits maxStorageBufferRange (128 MiB on lavapipe); the slots of one
// batch are cut into chunks of whole pairs that fit one binding, one dispatch per chunk.
#include "diffuse/lambert_solve.h"
#include "specular/lafortune_fit.h"

#include "shared/residuals.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula {

using ResidualSample = shared::ResidualSample;

struct ResidualOptions {
    float min_light_cos = 0.1f; ///< drop n.u below this (the diffuse solve's min_light_cos)
    /// The material of the solve the albedo came from (LambertOptions::material): its diffuse
    /// factor k_d weights rho / pi (shared/residuals.h). Absent: Lambertian (k_d = 1).
    std::optional<SpecularModel> material;
    /// Per-tap irradiance as in the diffuse solve (LambertOptions::tap_irradiance): keep the two equal.
    bool tap_irradiance = true;
    /// Vulkan: upper bound on the bytes of one images or samples binding (0 = maxStorageBufferRange); tests lower it.
    std::uint64_t max_binding_bytes = 0;
    /// Particles whose best-view and robust (all-view) albedo differ by more than this,
    /// relative to their sum over channels, are left out: their albedo depends on the view
    /// (a texture finer than the pixels resampled differently per view), so their residuals
    /// hold that resampling error, not specular light. < 0 keeps every solved particle.
    float max_albedo_spread = 0.02f;
    /// Leave out particles whose diffuse solve rejected a view as an outlier. On a shiny
    /// object the rejected view is mostly the one that sees the highlight, i.e. the lobe's
    /// peak, so dropping them leaves the fit the lobe's tail (issue 4); but on a textured
    /// Lambertian object the outlier views are texture resampling, and keeping them raises
    /// the residual energy above the noise (pipeline_tests LambertianSkips...). Default on
    /// (the previous behaviour) until the albedo bias (issue 4 report) is fixed.
    bool drop_view_outliers = true;
    /// Memory bound: when the lit (particle, frame) slots exceed this, only every k-th used
    /// sample is kept, in slot order, k = ceil(lit slots / max_kept_samples) (residual_keep_stride;
    /// 0: keep all). The fits take a stride subsample of at most 200,000 anyway (material_fit.h),
    /// and the energy test a mean; a photometric rig's 87 million samples (20 views x 64
    /// lights, 256 px) would take 5.6 GB at 64 bytes each. 4 million: 256 MB.
    std::uint64_t max_kept_samples = 4'000'000;
    /// Not 0: only the kept samples a fit of at most this many takes are returned, every
    /// used_sample_stride-th from the first: the same samples, in the same order, as
    /// to_material_samples(all kept, fit_samples) converts (counts.used still counts every
    /// used one). The C++ pass names each used sample (12 bytes) and makes only those: the
    /// joint rounds' 3.1 million samples on the knot at 384 px held 200 MB for the fit's 200,000.
    std::size_t fit_samples = 0;
    /// C++ reference: worker threads over the particles of each view (the samples, their order
    /// and the counts are the same for any count).
    unsigned threads = 1;
};

/// True when particle result r gives residual samples under `options` (both backends use it).
[[nodiscard]] bool residual_particle_usable(const LambertParticleResult& r, const ResidualOptions& options);

/// The stride at which used samples are kept (ResidualOptions::max_kept_samples): from the
/// lit (particle, frame) slots of the pairs whose particle is usable; their count, an upper
/// bound on the used samples, in *lit_slots when given.
[[nodiscard]] std::uint64_t residual_keep_stride(const LambertInputs& in, const LambertOutputs& diffuse,
                                                 const ResidualOptions& options, std::uint64_t* lit_slots = nullptr);

struct ResidualCounts {
    std::uint64_t candidates = 0;        ///< (particle, frame) of seeing views, particle with a diffuse solution
    std::uint64_t used = 0;
    std::uint64_t dropped_shadow = 0;    ///< lit bit clear (Embree occlusion or facing away)
    std::uint64_t dropped_grazing = 0;   ///< n.u < min_light_cos
    std::uint64_t dropped_missing = 0;   ///< a tap missing, outside the mask, or not finite
    std::uint64_t dropped_clipped = 0;   ///< a tap at saturation
    std::uint64_t dropped_no_diffuse = 0; ///< (particle, frame) of particles without a (view-consistent) diffuse solution
    ResidualCounts& operator+=(const ResidualCounts& o) noexcept {
        candidates += o.candidates;
        used += o.used;
        dropped_shadow += o.dropped_shadow;
        dropped_grazing += o.dropped_grazing;
        dropped_missing += o.dropped_missing;
        dropped_clipped += o.dropped_clipped;
        dropped_no_diffuse += o.dropped_no_diffuse;
        return *this;
    }
};

/// The sums the energy test reads (residual_energy), over the kept used samples in slot order:
/// r = f_s Ebar per channel from the samples' float values.
struct ResidualEnergySums {
    double square = 0.0;    ///< sum r^2 over samples and channels
    double sum = 0.0;       ///< sum r
    std::uint64_t samples = 0;
    void add(const glm::vec3& f, float ebar) noexcept {
        const auto e = static_cast<double>(ebar); // r = f_s E; with a white light E = Ebar on every channel
        for (int c = 0; c < 3; ++c) {
            const double r = static_cast<double>(f[c]) * e;
            square += r * r;
            sum += r;
        }
        ++samples;
    }
};

struct ResidualSamples {
    std::vector<ResidualSample> samples; ///< used samples only, in slot order (every keep_stride-th)
    /// Over every kept sample, also those fit_samples left out (both backends).
    ResidualEnergySums energy;
    std::uint64_t keep_stride = 1;       ///< see ResidualOptions::max_kept_samples
    ResidualCounts counts;
    double seconds = 0.0;               ///< wall clock (layout, upload, dispatch, download, compaction)
    std::optional<double> gpu_ms;       ///< Vulkan with timestamps
    std::uint32_t view_batches = 0;
    std::uint32_t chunks = 0;           ///< dispatches
};

/// The reference: double precision, single thread, rounded to the float layout.
/// `sample_particle`, when given, receives the particle index of every returned sample.
[[nodiscard]] ResidualSamples residual_samples_cpu(const LambertInputs& in, const LambertOutputs& diffuse,
                                                   const ResidualOptions& options = {},
                                                   std::vector<std::uint32_t>* sample_particle = nullptr);

/// A validation error without the samples: material_mean_square_error of `model` over every
/// kept sample of the pass (options.fit_samples is not read), each one's part summed in their
/// order as it is made (the same value to the last bit), with the pass's counts. The demo can's
/// validation passes held up to 2 million samples (130 MB) for that one number, written from one
/// thread.
struct ResidualScore {
    double mean_square = 0.0;
    ResidualCounts counts;
    double seconds = 0.0;
};
[[nodiscard]] ResidualScore residual_mean_square_error_cpu(const LambertInputs& in, const LambertOutputs& diffuse,
                                                           const ResidualOptions& options, const SpecularModel& model);

/// The Vulkan kernel (shaders/specular/residuals.comp). Owns its pipeline.
class ResidualsVk {
public:
    explicit ResidualsVk(gpu::Context& ctx);
    ~ResidualsVk();
    ResidualsVk(const ResidualsVk&) = delete;
    ResidualsVk& operator=(const ResidualsVk&) = delete;
    [[nodiscard]] ResidualSamples run(const LambertInputs& in, const LambertOutputs& diffuse,
                                      const ResidualOptions& options = {});

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// Runs on a backend (ctx is required for Vulkan).
[[nodiscard]] ResidualSamples residual_samples(const LambertInputs& in, const LambertOutputs& diffuse,
                                               const ResidualOptions& options, Backend backend,
                                               gpu::Context* ctx = nullptr);
/// The validation error on a backend: Vulkan makes the samples and scores them.
[[nodiscard]] ResidualScore residual_mean_square_error(const LambertInputs& in, const LambertOutputs& diffuse,
                                                       const ResidualOptions& options, const SpecularModel& model,
                                                       Backend backend, gpu::Context* ctx = nullptr);

/// The stride that keeps at most max_samples of the used samples, every k-th from the first (as
/// stride_subsample takes them from the converted list; 0 or no more used than that: 1).
[[nodiscard]] std::size_t used_sample_stride(std::span<const ResidualSample> samples, std::size_t max_samples);
/// The same from the count of used samples.
[[nodiscard]] std::size_t used_sample_stride(std::size_t used, std::size_t max_samples);

/// Only the used samples a fit of at most max_samples takes, every used_sample_stride-th, in
/// place (0: all kept); the fits' conversions with that bound then take every one of them.
void thin_for_fit(std::vector<ResidualSample>& samples, std::size_t max_samples);

/// The samples as the fit takes them (weight Ebar^2): with max_samples, only every
/// used_sample_stride-th used one, converted (the same as stride_subsample of all of them,
/// without the copy of all: 125 MB for the knot's 3.1 million at 384 px).
[[nodiscard]] std::vector<LafortuneSample> to_lafortune_samples(std::span<const ResidualSample> samples,
                                                               std::size_t max_samples = 0);

/// Residual energy against the noise (pipeline.md section 9): the weighted mean square of
/// f_s with weight Ebar^2, i.e. the mean squared residual in image units (channel mean),
/// against noise_sigma^2. Specular energy is present when the ratio exceeds `threshold`.
struct ResidualEnergy {
    double mean_square = 0.0; ///< sum w f^2 / (3 sum_samples 1), image units squared
    double mean = 0.0;        ///< mean signed residual in image units (specular light only adds: > 0)
    double noise_sigma = 0.0;
    double ratio = 0.0;       ///< mean_square / noise_sigma^2
    double threshold = 0.0;
    bool has_specular = false;
};
[[nodiscard]] ResidualEnergy residual_energy(std::span<const ResidualSample> samples, double noise_sigma,
                                             double threshold = 4.0);
/// The same from a pass's sums (ResidualSamples::energy): every kept sample's, thinned or not.
[[nodiscard]] ResidualEnergy residual_energy(const ResidualEnergySums& sums, double noise_sigma, double threshold = 4.0);

} // namespace specula
