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
/// Measured on the can preset (512 px, 20 train views x 6 lights, noise free png8): masked
/// test PSNR 39.80 dB, Q1 98.86 without; 41.43 / 99.04 after 1 round, 41.72 / 99.07 after 2,
/// 41.72 after 3 (train 49.26 -> 50.79 dB). A simulation of the solve on exact albedo images
/// (tests/evaluate/psnr_diag.cpp --sim) agrees, and shows that past ~5 rounds the correction
/// starts to amplify itself at edges. Each round costs one render of every train frame and
/// one diffuse solve (the can: about 2 s + 4 s on lavapipe, 2 cores).
#include "capture/capture.h"
#include "core/lafortune.h"
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

struct AlbedoRefineRound {
    double mean_abs_change = 0.0; ///< mean over corrected particles of |delta rho| (channel mean)
    std::size_t corrected = 0;    ///< particles with a value in both solves
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
                                               const SolveFn& solve_fn);

} // namespace specula
