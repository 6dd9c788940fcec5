#pragma once
/// \file
/// The albedo fitted to the train pixels through the renderer's own atlas read (an addition to
/// the thesis; docs/pipeline.md section 3.8).
///
/// Why. The diffuse solve reads each particle bilinearly from the images and the renderer reads
/// the atlas bilinearly again: a sharp albedo edge comes back as a ramp that held-out views and
/// lights see at another sub-pixel phase. What a render shows at a pixel is the bilinear mix of
/// the 4 texels around the atlas point that the pixel's centre ray hits; a captured pixel shows
/// the surface at that same point. So the atlas that best reproduces the train frames is the
/// least-squares fit, over every train pixel of every view, of that bilinear mix to the albedo
/// the pixel shows:
///
///     min_A  sum_i w_i (sum_k b_ik A_{p_ik} - a_i)^2  +  mu sum_p d_p (A_p - A0_p)^2
///
/// with, for pixel i of a view: a_i the albedo its lit frames show (the known material's
/// specular light subtracted, its diffuse factor applied, the solve's band test against
/// highlights and shadow edges, least squares over the frames: rho / pi = sum c e / sum e^2),
/// w_i = sum over its kept frames of e^2 (the squared error in image units), b_ik the bilinear
/// weights of its atlas point's 4 texels p_ik (texels without a solved particle left out, the
/// others' weights renormalised), A0 the solve's albedo and d_p = sum_i w_i b_ip the data weight
/// of particle p (mu: a faint prior where few pixels touch a texel).
///
/// How. Jacobi iterations preconditioned by the data weight: A_p <- clamp(A_p + (g_p - mu d_p
/// (A_p - A0_p)) / ((1 + mu) d_p), lo_p, hi_p), g_p = sum_i w_i b_ip r_i, r_i the pixel's
/// residual, [lo_p, hi_p] the least and the largest albedo of the pixels that read particle p. The
/// weight dominates the normal matrix's rows, so each step minimises a separable quadratic above
/// the objective (within the bounds too): the objective never rises, and a texel that only
/// grazing views touch moves little, it is never amplified (the back-projection of
/// albedo_refine.h had to be damped for that). The bounds keep a texel within what its pixels
/// show: where few pixels at one phase read a texel, the least squares alone overshoot (the can's
/// label at 128 px: 1.79 against a truth at most 0.86; one view of 48 lights: 0.53% RMSE on
/// resolved texels, 0.01% within the bounds). Deterministic for any thread count: each particle
/// gathers its pixels in a fixed order. No renders, no Vulkan device: one ray per pixel of the
/// train views (Embree) and a few passes over the pixels.
#include "capture/capture.h"
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "capture/mesh.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "refine/albedo_refine.h"
#include "visibility/visibility.h"

#include <cstdint>
#include <span>

namespace specula {

struct PixelFitOptions {
    std::uint32_t iterations = 8; ///< Jacobi iterations
    float prior = 0.05f;          ///< mu, toward the solve's albedo
    unsigned threads = 2;
    /// Per view of the inputs (LambertInputs::views), the pixel hits the visibility kept
    /// (Visibility::pixel_hits); empty: the rays are cast here.
    std::span<const PixelHits> view_hits;
};

struct PixelFitStats {
    std::uint64_t pixels = 0;        ///< train-view pixels whose centre ray hits the object
    std::uint64_t pixels_used = 0;   ///< of those, with an albedo (some lit frame kept, not on a silhouette)
    std::uint64_t samples_used = 0;  ///< (pixel, frame) samples kept
    std::vector<double> rms;         ///< before each iteration and after the last: the weighted RMS residual (albedo units)
    double ray_seconds = 0.0;        ///< the pixels' atlas points
    double sample_seconds = 0.0;     ///< the pixels' albedos
    double fit_seconds = 0.0;        ///< the iterations
};

/// The fit above, from the last diffuse solve (`inputs`, `solve`, solved with `options`: its
/// material, thresholds and frames). Returns the refined albedo per particle (the solve's where
/// no pixel touches it) in AlbedoRefineResult's layout, one round per iteration.
[[nodiscard]] AlbedoRefineResult fit_albedo_to_pixels(const Mesh& mesh, const RayScene& scene, const Atlas& atlas,
                                                      std::span<const Particle> particles, const LambertInputs& inputs,
                                                      const LambertOutputs& solve, const LambertOptions& options,
                                                      const PixelFitOptions& fit, PixelFitStats* stats = nullptr);

} // namespace specula
