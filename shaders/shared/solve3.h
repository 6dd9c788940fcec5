// Weighted 3x3 linear least squares per element (the photometric-stereo solve of
// pipeline.md section 3, thesis eq. 3.1; reused for any 3-vector fit):
//
//     g = argmin_g  sum_i w_i (a_i . g - b_i)^2      a_i in R^3, b_i, w_i >= 0
//
// solved through the normal equations M g = r,  M = sum w a a^T,  r = sum w b a.
//
// Conditioning (scale-aware). With D = diag(M), the Jacobi-scaled matrix
// C = D^-1/2 M D^-1/2 has a unit diagonal and does not change when an unknown's
// units change (van der Sluis 1969: this diagonal scaling is within a factor 3 of
// the best one). The reported condition estimate is
//     rcond = 3 / (|C|_F |C^-1|_F) = 3 det(C) / (|C|_F |adj(C)|_F)
// which is 1 for C = I and, since |X|_2 <= |X|_F <= sqrt(3) |X|_2 for 3x3,
//     lambda_min/lambda_max  <=  rcond  <=  3 lambda_min/lambda_max.
// It needs only +, -, *, / and sqrt: Vulkan allows sin/cos/acos an absolute error of
// 2^-11, far too loose for a closed-form eigenvalue near a 1e-4 threshold; det(C)
// has an absolute error of a few eps, so rcond is resolved well below the threshold.
//
// Threshold: rcond < kLsq3MinRcond = 1e-4 is ill-conditioned (cond_2(C) > 1e4 to 3e4:
// the scaled design matrix has cond > 100 to 170, i.e. the lights are nearly coplanar
// seen from the particle). This is a numerical floor: above it the float32 solve's
// relative error is at most about cond_2(C) (K + 8) eps32 (eps32 = 6e-8) in data units.
// A caller with noisy data wants a stricter limit on the reported rcond: noise in b is
// amplified by up to sqrt(3 / rcond).
//
// Statuses (never NaN: every status but ok returns g = 0):
//   kLsq3Ok              solved
//   kLsq3IllConditioned  rcond below the threshold, or a zero column (a diagonal of M is 0)
//   kLsq3TooFewRows      fewer than 3 rows with w > 0
//   kLsq3InvalidInput    a row had a non-finite value or a negative weight, or a sum overflowed
//
// The body lives in solve3_impl.h, written once over the macro types SOLVE3_REAL /
// SOLVE3_VEC3 and instantiated for float (GLSL and C++: namespace specula::shared) and,
// in C++ only, for double (namespace specula::shared::f64: the CPU reference).
#ifndef SPECULA_SHARED_SOLVE3_H
#define SPECULA_SHARED_SOLVE3_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

const uint kLsq3Ok = 0u;
const uint kLsq3IllConditioned = 1u;
const uint kLsq3TooFewRows = 2u;
const uint kLsq3InvalidInput = 3u;
const uint kLsq3MinRows = 3u;
const float kLsq3MinRcond = 1.0e-4f;

// One row (std430: five scalars, alignment 4, array stride 20 bytes; a vec3 member
// would be aligned to 16 and make it 32).
struct Lsq3Row {
    float a_x;
    float a_y;
    float a_z;
    float b;
    float w;
};

// One element's result (std430: eight 4-byte scalars, stride 32).
struct Lsq3Result {
    float g_x;
    float g_y;
    float g_z;
    float rcond;  // 3 / (|C|_F |C^-1|_F) of the Jacobi-scaled normal matrix C, in [0, 1]; 0 when not computed
    float rss;    // sum w (a.g - b)^2 of the returned g when status is ok, else 0
    uint status;  // kLsq3*
    uint rows;    // rows with w > 0 and finite values
    uint reserved;
};

#define SOLVE3_REAL float
#define SOLVE3_VEC3 vec3
#define SOLVE3_MAX_FINITE 3.0e38
#include "shared/solve3_impl.h"
#undef SOLVE3_REAL
#undef SOLVE3_VEC3
#undef SOLVE3_MAX_FINITE

SPECULA_SHARED_END

#ifdef __cplusplus
static_assert(sizeof(specula::shared::Lsq3Row) == 20 && alignof(specula::shared::Lsq3Row) == 4);
static_assert(sizeof(specula::shared::Lsq3Result) == 32 && alignof(specula::shared::Lsq3Result) == 4);
namespace specula::shared::f64 {
using namespace glm;
#define SOLVE3_REAL double
#define SOLVE3_VEC3 dvec3
#define SOLVE3_MAX_FINITE 1.0e300
#include "shared/solve3_impl.h"
#undef SOLVE3_REAL
#undef SOLVE3_VEC3
#undef SOLVE3_MAX_FINITE
} // namespace specula::shared::f64
#endif

#endif
