#pragma once
/// \file
/// Albedo refinement by back-projection (an addition to the thesis; Irani and Peleg 1991,
/// "Improving resolution by image registration", iterative back-projection).
///
/// Why. The diffuse solve reads each particle's value by bilinear interpolation of the
/// image pixels around its projection (shared/lambert.h), and the renderer reads the atlas
/// by bilinear interpolation again. Both are low-pass: a sharp albedo edge, which a
/// captured pixel samples at its centre, comes back as a ramp about two pixels wide, and
/// a held-out view or light that sees the edge at another sub-pixel phase shows the
/// difference. On the can at 512 px this is most of the masked test-frame error: with the
/// TRUE albedo written into the same atlas (one texel per pixel) the test frames score
/// 41.6 dB; estimated by the solve, 39.8 dB.
///
/// What. With S the solve's robust combination (the mean over the views that see a
/// particle, weighted by their used samples: LambertParticleResult::albedo_robust) and
/// R(A) the train frames rendered from atlas A with the lobe the solve subtracted, the
/// albedo that reproduces the captured images through the solve's own sampling satisfies
/// S(R(A)) = S(captured). Each round moves toward it:
///     A <- A + S(captured) - S(R(A))          per particle, rho in linear RGB
/// starting from the solve's albedo (the best view, the thesis's choice). The renders have
/// no cast shadows: the solve drops shadowed samples by the visibility masks, and a shadow
/// map's edges (a texel wide, biased) would differ from the captures' ray-traced ones.
/// Pixel flags (mask, missing, clipped) are the captured frame's, so both solves read the
/// same taps. The difference S(captured) - S(R(A)) is per view a mean over the frames of
/// that view, so it averages the views' sampling phases: the multi-view information that
/// one bilinear read of the best view leaves out.
///
/// Damped and confidence-weighted (an addition to the back-projection above). Undamped, the
/// update is a Van Cittert iteration toward the albedo that reproduces the train images
/// through the renderer's bilinear atlas read. That albedo is pre-sharpened: at an edge its
/// texel-centre values overshoot what the surface holds there, as much as the solve's blurred
/// ones undershoot. Where S(R(.)) barely responds to a particle (texels that only grazing
/// views see: one pixel stretches over several texels), the mismatch between renders and
/// captures is amplified round after round. Measured with bench/seen_texels on the
/// Lambertian knot at 512 px: RMSE over seen texels 2.77% -> 3.29% (2 rounds) -> 4.13% (4),
/// the largest texel error 0.69 -> 1.66 -> 2.75. So each round is
///     A <- A + s [ w_p (S(captured) - S(R(A))) - lambda (A - A_0) ]
/// with A_0 the solve's albedo and
///   w_p     the confidence of particle p: the cosine n.v of its best view, ramped from 0 at
///           `grazing_cos` to 1 at `resolved_cos`: texels that only grazing views see keep the
///           solve's value;
///   lambda  a Tikhonov prior toward A_0. The fixed point is (w K + lambda) A = w b + lambda A_0
///           (K = S R linearised, b = S(captured)): a mode that K barely passes is no longer
///           amplified without bound, and in the smooth regime (K = 1 + 2 a D, b = A_0 = 1 + a D
///           for a blur of second moment a, D the Laplacian) the fixed point is t - a D t (1 -
///           lambda) / (1 + lambda): lambda = 0 the renderer-optimal (overshooting) albedo,
///           lambda = 1 the texel-centre truth t;
///   s       a step < 1: with lambda the iteration converges for every mode of K in [0, 1];
///   stop    a particle whose correction does not shrink by 10% from one round to the next
///           (|delta_k| > 0.9 |delta_{k-1}|) is diverging, or sits in a mode the solve of the
///           renders barely passes (its correction stays, and each round would add it again up
///           to 1/lambda times over): it keeps its value from then on.
/// Defaults (s 0.7, lambda 0.3, ramp 0.3 -> 0.6, stop on): see README.md "How the albedo is
/// sharpened" for the trade-off between the rendered error and the texel-centre error.
/// Options{.step = 1, .prior = 0, .grazing_cos = -1, .resolved_cos = -1, .stop_growing =
/// false} is the undamped update.
///
/// Undamped, measured on the can preset (512 px, 20 train views x 6 lights, noise free png8):
/// masked test PSNR 39.80 dB, Q1 98.86 without; 41.43 / 99.04 after 1 round, 41.72 / 99.07
/// after 2, 41.72 after 3 (train 49.26 -> 50.79 dB). Each round costs one render of every
/// train frame and one diffuse solve (the can: about 2 s + 4 s on lavapipe, 2 cores).
#include "capture/capture.h"
#include "material/lafortune.h"
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <vector>

namespace specula {
namespace gpu {
class Context;
}

/// The damping of the update (see above).
struct AlbedoRefineOptions {
    float step = 0.7f;           ///< s
    float prior = 0.3f;          ///< lambda, toward the solve's albedo
    float grazing_cos = 0.3f;    ///< best view n.v at or below: w = 0 (both <= 0: w = 1 everywhere)
    float resolved_cos = 0.6f;   ///< at or above: w = 1
    bool stop_growing = true;    ///< freeze a particle whose correction does not shrink round to round
};

struct AlbedoRefineRound {
    double mean_abs_change = 0.0; ///< mean over corrected particles of |delta rho| applied (channel mean)
    std::size_t corrected = 0;    ///< particles with a value in both solves
    std::size_t stopped = 0;      ///< of those, frozen so far because their correction grew
    double render_seconds = 0.0;  ///< rendering the train frames
    double solve_seconds = 0.0;   ///< the diffuse solve of the renders
};

struct AlbedoRefineResult {
    std::vector<glm::vec3> albedo;  ///< per particle, rho (linear RGB)
    std::vector<std::uint8_t> valid; ///< per particle: the solve found a value (else inpainted by the texture step)
    std::vector<AlbedoRefineRound> rounds;
};

/// The diffuse solve with fixed options on other images (the pipeline passes its backend choice).
using SolveFn = std::function<LambertOutputs(const LambertInputs&)>;

/// `rounds` rounds of the update above. `inputs` and `solve` are the pipeline's last diffuse
/// solve (its images are the capture's) and `lobe` the lobe that solve subtracted (zero:
/// diffuse renders). rounds == 0 returns the solve's albedo unchanged.
[[nodiscard]] AlbedoRefineResult refine_albedo(gpu::Context& ctx, const Capture& capture, const Atlas& atlas,
                                               std::span<const Particle> particles, const LambertInputs& inputs,
                                               const LambertOutputs& solve, const LafortuneRgb& lobe, std::uint32_t rounds,
                                               const SolveFn& solve_fn, const AlbedoRefineOptions& options = {});

} // namespace specula
