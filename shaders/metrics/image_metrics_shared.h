// Image quality metrics (pipeline.md section 8; thesis chapter 5): the constants,
// buffer layouts and per-pixel math that the shaders (shaders/metrics/*.comp) and the
// CPU reference (engine/metrics/image_metrics_cpu.cpp) share. Dual-use (shared/prelude.h).
//
// Definitions (A = captured, B = rendered, P = the pixel set: the mask's nonzero
// pixels or the full frame, N = |P|, C = colour channels used: 1, or 3 of RGB/RGBA):
//   per-pixel sums over P, c < C:   count, sum (A-B)^2, sum |A-B|, sum_p ||A_p-B_p||_2,
//                                   sum A B, sum A^2, sum B^2   (the 7 fields below)
//   SSIM (Wang, Bovik, Sheikh, Simoncelli 2004, IEEE TIP 13(4), eq. 13 and section III.C):
//     on linear luminance Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709), an 11x11
//     Gaussian window, sigma 1.5, normalised to sum 1; K1 = 0.01, K2 = 0.03,
//     C1 = (K1 L)^2, C2 = (K2 L)^2 with L = the peak (1.0); sigma^2 = E[Y^2] - mu^2 as in
//     Wang's ssim_index.m. At the image border the window is truncated to the image
//     and renormalised (Wang's code drops a 5-pixel border instead; we need the map at
//     every masked pixel, and small test images). The window is separable and the
//     truncated window is a rectangle, so two 1D passes renormalised per pass are exact.
#ifndef SPECULA_METRICS_IMAGE_METRICS_SHARED_H
#define SPECULA_METRICS_IMAGE_METRICS_SHARED_H
#include "shared/prelude.h"
#include "shared/dispatch.h"

SPECULA_SHARED_BEGIN

// Workgroup size of every metrics kernel (their shared-memory reductions are sized by it).
const uint kMetricsGroupSize = 256u;

const int kSsimRadius = 5; // 11x11 window
const float kSsimSigma = 1.5f;
const float kSsimK1 = 0.01f;
const float kSsimK2 = 0.03f;
const float kLumaR = 0.2126f;
const float kLumaG = 0.7152f;
const float kLumaB = 0.0722f;

// Per-workgroup partial sums of the per-pixel pass (std430: 8 floats, stride 32).
struct MetricsPartial {
    float count;
    float sum_sq;  // sum over P, c of (A - B)^2
    float sum_abs; // sum over P, c of |A - B|
    float sum_l2;  // sum over P of sqrt(sum_c (A - B)^2)   (eq. 5.1, r = 2)
    float sum_ab;  // sum over P, c of A B                 (eq. 5.4)
    float sum_aa;
    float sum_bb;
    float reserved;
};

// Horizontally filtered SSIM moments of one pixel (std430: 5 floats, stride 20).
struct SsimMoments {
    float mu_a;
    float mu_b;
    float aa; // E[Y_A^2]
    float bb;
    float ab;
};

// Push constants of the four kernels.
struct MetricsSumsPush { // image_metrics.comp
    DispatchHeader dispatch;
    uint width;
    uint height;
    uint channels;
    uint color_channels;
    uint has_mask;
    uint pad;
};
struct SsimHPush { // image_metrics_ssim_h.comp
    DispatchHeader dispatch;
    uint width;
    uint height;
};
struct SsimVPush { // image_metrics_ssim_v.comp
    DispatchHeader dispatch;
    uint width;
    uint height;
    uint has_mask;
    float c1;
    float c2;
    uint pad;
};
struct HausdorffPush { // image_metrics_hausdorff.comp
    DispatchHeader dispatch;
    uint width;
    uint height;
    uint channels;
    uint color_channels;
    uint has_mask;
    int max_radius;
    float delta;
    uint pad;
};

// The scalar math, written once over METRICS_REAL: float here (GLSL and C++),
// double in namespace specula::shared::f64 (the CPU reference).
#define METRICS_REAL float
#include "metrics/image_metrics_impl.h"
#undef METRICS_REAL

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::MetricsPartial) == 32);
static_assert(sizeof(specula::shared::SsimMoments) == 20 && offsetof(specula::shared::SsimMoments, ab) == 16);
static_assert(sizeof(specula::shared::MetricsSumsPush) == 32);
static_assert(sizeof(specula::shared::SsimHPush) == 16);
static_assert(sizeof(specula::shared::SsimVPush) == 32 && offsetof(specula::shared::SsimVPush, c1) == 20);
static_assert(sizeof(specula::shared::HausdorffPush) == 40 && offsetof(specula::shared::HausdorffPush, delta) == 32);
namespace specula::shared::f64 {
using namespace glm;
#define METRICS_REAL double
#include "metrics/image_metrics_impl.h"
#undef METRICS_REAL
} // namespace specula::shared::f64
#endif

#endif
