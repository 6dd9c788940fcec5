// Lambert solve (pipeline.md section 3; thesis section 3.1, eq. 3.1): buffer layouts,
// constants and the scalar math that the shader (shaders/diffuse/lambert_solve*.comp)
// and the C++ reference (engine/diffuse/lambert_solve_cpu.cpp) share.
//
// Radiometry (capture-format.md): a Lambertian surface gives, per channel,
//     c_i = (rho / pi) E_i,     E_i = I_i max(0, n.u_i) / d_i^2
// for frame i lit by a point light of intensity I_i at distance d_i, direction u_i.
//
// Per (particle, view) pair, per frame of the view, a sample is REJECTED as
//   shadow     the visibility `lit` bit is clear (Embree occlusion or n.u <= 0),
//   grazing    n.u_i < min_light_cos (default 0.1, 84 degrees): E is tiny, noise/E huge,
//   missing    any of the 4 bilinear taps has kMissing or kOutsideMask, or a non-finite value,
//   clipped    any tap has any channel at or above saturation (or a kClipped* flag): the whole
//              sample goes, not only that channel: a channel clips where a highlight adds
//              light, so the other channels of that sample carry the highlight too,
//   (tap surface: when the views have surface maps (visibility.h), each tap's pixel value is
//              first scaled by gain_j = E(particle) / E(tap surface), so the 4 taps are brought to
//              the particle's irradiance before they are mixed; a sample whose tap shows no
//              surface is `missing`, one whose tap surface gets n.u below min_light_cos is
//              `grazing`; see "Per-tap irradiance" below)
//   highlight  robust fit (the specular term only adds light), on the channel sums
//              cs_i = c_r + c_g + c_b and Es_i = E_r + E_g + E_b, ratio q_i = cs_i / Es_i:
//                est_0 = lower median of q_i over the remaining samples
//                keep i  iff  q_i <= est (1 + tau) + k_sigma sqrt(3) / Es_i   (else: highlight)
//                        and  q_i >= est (1 - tau) - k_sigma sqrt(3) / Es_i   (else: shadow edge, a
//                        lit particle whose bilinear taps reach into a cast shadow)
//                est   = sum cs Es / sum Es^2 over the kept samples; repeat (at most
//                        `iterations` times, stops when the kept set does not change)
//              defaults tau = 0.1, k_sigma = 3 x 0.004 (k = 3 times the noise sigma of
//              full scale 1.0; 0.004 is about one 8-bit sRGB step at mid grey).
// Per-tap irradiance (an addition to the thesis). The sample is a bilinear mix of 4 pixels,
// and each pixel shows its own surface point x_j with its own normal n_j, lit by
// E_j = I max(0, n_j.u_j) / d_j^2. Dividing the mix by the particle's E alone is biased
// wherever E changes across the taps faster than linearly: where the normal turns within
// a pixel (a rim, a lip, a crease) and where a grazing view stretches a pixel over the
// surface. With the view's surface map (per pixel: the position and interpolated normal
// that the ray through its centre hits; visibility.h) each tap's value is scaled by
//     gain_j = (n.u / d^2) / (n_j.u_j / d_j^2)
// (the intensity cancels) before the bilinear mix: for a Lambertian surface each scaled tap
// is (rho_j / pi) E, so the mix is the mix of the taps' albedos, lit like the particle.
// The specular residuals (shared/residuals.h) apply the same gains, so the lobe fit sees the
// samples the albedo came from.
// Known material (joint estimate, an addition to the thesis): when a material is given (the
// previous round's fit, shared/material.h), its specular light f_s(u_i, v) E_i is subtracted
// from every sample before the highlight test and the solve, so the albedo no longer absorbs
// the part of a broad lobe that the highlight test cannot tell from diffuse light, and its
// diffuse angular factor k_d(n.u_i, n.v) multiplies E_i (and the photometric rows), so the
// solve gives rho of f = (rho / pi) k_d + f_s: the coated family's Fresnel-weighted diffuse
// term (shared/coated.h) is folded into each sample's irradiance factor. A sample whose k_d is 0
// is dropped as grazing. The zero material (lafortune, all parameters 0) changes nothing.
// Then, on the kept samples, per channel:
//   albedo mode        rho/pi = sum c E / sum E^2                         (needs 1 sample)
//   photometric mode   g = (rho/pi) n from c_i = g . (I_i u_i / d_i^2)    (eq. 3.1; shared/solve3.h)
//                      rho = pi |g|, refined normal = normalize(g_r + g_g + g_b). Falls back to
//                      albedo mode (kLambertPairFallback) with fewer than 3 samples, an lsq3
//                      status other than ok, rcond < min_rcond (default 1e-3: lights nearly
//                      coplanar seen from the particle; noise is amplified by up to
//                      sqrt(3 / rcond) = 55), or a refined normal facing away from the mesh normal.
//
// Per particle (combine step), over the views that see it and kept >= 1 sample:
//   L_j = rho_r + rho_g + rho_b of view j; ref = lower median of L_j weighted by the views'
//   used samples (a view that kept one sample, e.g. taps on a shadow edge the visibility
//   missed, cannot outvote one that kept five);
//   view j is an outlier when |L_j - ref| > view_tau ref + view_abs (defaults 0.15, 0.02):
//   a view whose samples are all highlights (the camera near the mirror direction of
//   every light of its ring) stands out against the other views. ref itself is always kept.
//   best view (thesis 3.1.2): the kept view closest to the normal (largest n.v; ties: lower index)
//   robust: the mean of the kept views weighted by their used sample counts.
#ifndef SPECULA_SHARED_LAMBERT_H
#define SPECULA_SHARED_LAMBERT_H
#include "shared/prelude.h"
#include "shared/dispatch.h"
#include "shared/material.h"

SPECULA_SHARED_BEGIN

const uint kLambertModeAlbedo = 0u;
const uint kLambertModePhotometric = 1u;
const uint kLambertNoView = 0xFFFFFFFFu;

// Pixel flags (must equal capture.h's PixelFlag bits; checked by static_assert there).
const uint kLambertPixClipped = 7u;   // kClippedR | kClippedG | kClippedB
const uint kLambertPixMissing = 8u;   // kMissing
const uint kLambertPixOutside = 16u;  // kOutsideMask

// Per-pair status bits.
const uint kLambertPairHasSample = 1u;  // at least one sample kept
const uint kLambertPairFallback = 2u;   // photometric mode fell back to albedo mode
const uint kLambertPairPhotometric = 4u; // photometric solve used

// Per-particle status bits.
const uint kLambertOk = 1u;            // albedo from at least one kept sample
const uint kLambertFallback = 2u;      // photometric mode: the best view fell back to albedo mode
const uint kLambertNoSample = 4u;      // seen, but no view kept a sample: albedo 0
const uint kLambertNotSeen = 8u;       // no view sees the particle: albedo 0 (inpainted later)
const uint kLambertViewsRejected = 16u; // some views were outliers against the cross-view median

// Surface maps (visibility.h): 4 words per pixel, the hit position's float bits (xyz) and
// its interpolated unit normal, octahedral, packed as 2 x snorm16 (packSnorm2x16). A pixel
// whose ray hits nothing holds kLambertNoHit in the 4th word (packSnorm2x16 never writes
// -32768, so no normal packs to it).
const uint kLambertNoHit = 0x80008000u;
const uint kLambertNoSurface = 0xFFFFFFFFu; // LambertViewGpu::surface_offset: the view has no surface map
// Sample records (the gather step's output, the pair step's input): one per (pair, train
// frame of the view), 4 floats: the sample's value with the known material's specular light
// subtracted (rgb), and in w the known diffuse factor k_d (> 0) of a usable sample, or minus
// a kLambertRecord* reason of a rejected one. Any number of frames per view: the records of a
// pair are a contiguous run of the chunk's record buffer, the frames of a view may come from
// several image batches (diffuse/view_batches.h).
const uint kLambertRecordShadow = 1u;
const uint kLambertRecordGrazing = 2u;
const uint kLambertRecordMissing = 3u;
const uint kLambertRecordClipped = 4u;

// One view of a batch (std430, 112 bytes): a segment of a view's frames in an image batch
// (gather step), or a whole view in the table of all views (pair step).
struct LambertViewGpu {
    vec4 w2c0; // rows of world_to_camera (float)
    vec4 w2c1;
    vec4 w2c2;
    vec4 intrinsics; // fl_x, fl_y, cx, cy
    vec4 center;     // camera center (xyz)
    uint width;
    uint height;
    uint frame_first; // into the batch's frame array
    uint frame_count;
    uint surface_offset; // first pixel of the view's surface map in the batch's pixel buffer, or kLambertNoSurface
    uint pad0;
    uint pad1;
    uint pad2;
};

// One frame of a batch (std430, 48 bytes).
struct LambertFrameGpu {
    vec4 light;      // xyz position, w = saturation (linear; 3e38 for none)
    vec4 intensity;  // rgb
    uint frame;      // global frame index (bit of the `lit` mask)
    uint pixel_offset; // first pixel of the frame in the batch's pixel buffer
    uint pad0;
    uint pad1;
};

// Work item of the gather step and of the residual samples (std430, 12 bytes).
struct LambertPairKey {
    uint particle; // global particle index
    uint view;     // index into the batch's views (segments)
    uint slot;     // gather: record of the segment's first frame; residuals: first output slot
};

// Work item of the pair step (std430, 16 bytes).
struct LambertSolveKey {
    uint particle; // global particle index
    uint view;     // global view index (into the table of all views)
    uint slot;     // index into the chunk's pair results
    uint record;   // the pair's first record (the view's frame 0) in the chunk's record buffer
};

// Result of one (particle, view) pair (std430, 80 bytes).
struct LambertPairResult {
    vec4 albedo;  // rgb: rho (not rho/pi); w: n.v of the view (cosine to the camera)
    vec4 normal;  // xyz: refined normal (photometric), else the mesh normal; w: its angle to the mesh normal (deg)
    uint used;    // samples kept
    uint shadow;  // rejected samples by reason (shared/lambert.h)
    uint clipped;
    uint missing;
    uint grazing;
    uint highlight;
    uint frames;  // train frames of the view
    uint low;     // shadow edges (below the fit)
    uint status;  // kLambertPair*
    uint view;    // global view index
    uint pad0;
    uint pad1;
};

// Result of one particle (std430, 96 bytes).
struct LambertParticleResult {
    vec4 albedo_best;   // rgb rho of the best view; w: index of the best view as float (-1 none)
    vec4 albedo_robust; // rgb weighted mean of kept views; w: number of kept views
    vec4 normal;        // refined normal of the best view (mesh normal in albedo mode); w: angle (deg)
    uint status;        // kLambert*
    uint best_view;     // global view index or kLambertNoView
    uint views;         // views that see it (pairs)
    uint used;          // samples used in kept views
    uint rejected_shadow;
    uint rejected_clipped;
    uint rejected_missing;
    uint rejected_grazing;
    uint rejected_highlight;
    uint rejected_view;  // samples of views rejected as outliers by the combine step
    uint rejected_low;   // samples far below the fit (shadow edges)
    uint pad1;
};

// Push constants of the gather step (diffuse/lambert_gather.comp).
struct LambertGatherPush {
    DispatchHeader dispatch;
    uint frame_words;
    float min_light_cos;
    uint pad0;
    uint pad1;
    uint pad2;
    uint pad3;
    MaterialGpu material;  // the known material (the zero material: none; see "Known material" above)
};

// Push constants of the pair step (diffuse/lambert_solve.comp).
struct LambertPairPush {
    DispatchHeader dispatch;
    uint mode;             // kLambertModeAlbedo or kLambertModePhotometric
    uint iterations;
    float tau;
    float k_sigma;
    float min_rcond;
    uint pad0;
};

// Push constants of the combine step (diffuse/lambert_solve_combine.comp).
struct LambertCombinePush {
    DispatchHeader dispatch;
    uint particle_base; // global index of the chunk's first particle
    float view_tau;
    float view_abs;
};

#define LAMBERT_REAL float
#define LAMBERT_VEC2 vec2
#define LAMBERT_VEC3 vec3
#include "shared/lambert_impl.h"
#undef LAMBERT_REAL
#undef LAMBERT_VEC2
#undef LAMBERT_VEC3

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::LambertViewGpu) == 112);
static_assert(sizeof(specula::shared::LambertFrameGpu) == 48);
static_assert(sizeof(specula::shared::LambertPairKey) == 12);
static_assert(sizeof(specula::shared::LambertSolveKey) == 16);
static_assert(sizeof(specula::shared::LambertPairResult) == 80);
static_assert(sizeof(specula::shared::LambertParticleResult) == 96);
static_assert(sizeof(specula::shared::LambertGatherPush) == 96 && offsetof(specula::shared::LambertGatherPush, material) == 32);
static_assert(sizeof(specula::shared::LambertPairPush) == 32);
static_assert(sizeof(specula::shared::LambertCombinePush) == 20);
namespace specula::shared::f64 {
using namespace glm;
#define LAMBERT_REAL double
#define LAMBERT_VEC2 dvec2
#define LAMBERT_VEC3 dvec3
#include "shared/lambert_impl.h"
#undef LAMBERT_REAL
#undef LAMBERT_VEC2
#undef LAMBERT_VEC3
} // namespace specula::shared::f64
#endif

#endif
