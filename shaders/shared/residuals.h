// Residual samples (pipeline.md section 4): layout, status codes and the per-sample
// math shared by shaders/specular/residuals.comp and engine/specular/residuals_cpu.cpp.
//
// For particle p (diffuse solution rho, status kLambertOk), view j that sees it, and
// train frame i of view j whose light reaches p (visibility `lit` bit):
//     E_i = I_i max(0, n.u_i) / d_i^2               irradiance factor (per channel)
//     r_i = c_i - (rho / pi) E_i                    residual (c_i: bilinear pixel value, each
//                                                   tap scaled to the particle's irradiance
//                                                   as the diffuse solve does, shared/lambert.h)
//     f_s = r_i / E_i = r_i d_i^2 / (I_i n.u_i)     specular BRDF sample
// The thesis's "r = c / d^2" is a slip (pipeline.md section 4): undoing the falloff
// multiplies by d^2, and the cosine and the intensity divide.
// u, v: unit light and view directions in the particle's tangent frame (shared/tangent_frame.h).
//
// Dropped (status, counted per reason):
//   grazing  n.u < min_light_cos (the diffuse solve's threshold, default 0.1): f_s = r / E
//            amplifies the image noise by 1 / E without bound as n.u -> 0; also when a tap's
//            surface (surface map) gets n.u below it,
//   missing  a bilinear tap is kMissing / kOutsideMask, not finite, or shows no surface,
//   clipped  a tap has a channel at or above saturation (or a kClipped flag): the value is
//            only a lower bound (the diffuse solve drops the whole sample the same way).
// (Shadowed frames, lit bit clear, and particles without a diffuse solution get no slot:
// the host counts them from the visibility masks before the dispatch.)
//
// Weight: w = Ebar^2, Ebar = (E_r + E_g + E_b) / 3. With additive image noise of sigma,
// f_s has noise sigma / E, so w = E^2 is the maximum-likelihood weight: the fit's weighted
// residual sqrt(w) (model - f_s) is the residual in image units, grazing samples count
// little, and the fit's noise_sigma at weight 1 is the image noise sigma.
#ifndef SPECULA_SHARED_RESIDUALS_H
#define SPECULA_SHARED_RESIDUALS_H
#include "shared/prelude.h"
#include "shared/dispatch.h"
#include "shared/tangent_frame.h"

SPECULA_SHARED_BEGIN

const uint kResidualUsed = 0u;
const uint kResidualGrazing = 1u;
const uint kResidualMissing = 2u;
const uint kResidualClipped = 3u;

// One sample slot (std430, 48 bytes).
struct ResidualSample {
    vec4 u; // xyz: light direction (tangent frame); w: weight (Ebar^2; 0 when dropped)
    vec4 v; // xyz: view direction (tangent frame); w: Ebar
    vec3 f; // f_s per channel
    uint status; // kResidual*
};

// Push constants of specular/residuals.comp.
struct ResidualPush {
    DispatchHeader dispatch;
    uint frame_words;
    float min_light_cos;
};

// Irradiance factor E = I max(0, n.u) / d^2 (the diffuse solve's, shared/lambert.h).
SHARED_FN vec3 residual_irradiance(vec3 intensity, float cos_light, float d2) {
    return intensity * (max(0.0f, cos_light) / d2);
}

// f_s = (c - (rho/pi) E) / E per channel; 0 where E = 0 (a dark channel of the light).
SHARED_FN vec3 residual_brdf(vec3 c, vec3 rho_over_pi, vec3 e) {
    vec3 r = c - rho_over_pi * e;
    return vec3(e.x > 0.0f ? r.x / e.x : 0.0f, e.y > 0.0f ? r.y / e.y : 0.0f, e.z > 0.0f ? r.z / e.z : 0.0f);
}

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::ResidualSample) == 48);
static_assert(offsetof(specula::shared::ResidualSample, v) == 16 && offsetof(specula::shared::ResidualSample, f) == 32 &&
              offsetof(specula::shared::ResidualSample, status) == 44);
static_assert(sizeof(specula::shared::ResidualPush) == 16);
#endif

#endif
