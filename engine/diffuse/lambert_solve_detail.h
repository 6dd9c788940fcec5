#pragma once
// Internal pieces of the Lambert solve's reference, for the tests (one pair, one combine).
#include "diffuse/lambert_solve.h"

namespace specula::detail {

/// The surface under a pair's 4 taps in its view's surface map (the same for every frame of
/// the view: read once per pair). missing: a tap's pixel holds no surface.
struct TapSurface {
    bool missing = false;
    glm::dvec3 x[4];
    glm::dvec3 n[4];
};
[[nodiscard]] TapSurface lambert_tap_surface(const SurfaceMap& surface, const shared::f64::LambertTaps& t);

/// One sample as shaders/shared/lambert_sample.glsl reads it, in double: the 4 bilinear
/// taps of `im`, their flags, finiteness and saturation, and with `surface` (the pair's
/// lambert_tap_surface, or null) each tap's irradiance gain toward e_particle = n.u / d^2.
enum class SampleStatus { Ok, Missing, Clipped, Grazing };
struct SampleRead {
    glm::dvec3 c{0.0};
    SampleStatus status = SampleStatus::Ok;
};
[[nodiscard]] SampleRead lambert_read_sample(const FrameImage& im, const shared::f64::LambertTaps& t, const TapSurface* surface,
                                             const glm::dvec3& light, double e_particle, double min_cos);

/// The band test on the channel sums (shared/lambert.h), in double: q_i = cs_i / Es_i and Es_i
/// per sample; from the lower median, at most `iterations` refits on the kept samples. Sets
/// kept[i] (1 kept, 0 a highlight above the band or a shadow edge below it) and returns the
/// last estimate.
[[nodiscard]] double lambert_band_test(std::span<const double> q, std::span<const double> es, double tau, double k_sigma,
                                       std::uint32_t iterations, std::vector<std::uint8_t>& kept);

/// The pair step of one (particle, view) in double.
[[nodiscard]] shared::LambertPairResult lambert_pair_cpu(const LambertInputs& in, const LambertOptions& o,
                                                         std::uint32_t particle, std::uint32_t view);
/// The combine step of one particle over its pairs (in view order).
[[nodiscard]] LambertParticleResult lambert_combine_cpu(std::span<const shared::LambertPairResult> pairs,
                                                        const LambertOptions& o, const Particle& particle);

} // namespace specula::detail
