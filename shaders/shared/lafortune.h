// One isotropic Lafortune lobe, per colour channel (thesis eq. 2.1 with rho_d = 0;
// Lafortune et al. 1997, "Non-Linear Approximation of Reflectance Functions"):
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N
// u, v: unit light and view directions in the local tangent frame (z = normal).
// The base is clamped at zero before the power: a negative base to a real
// power is NaN. The lobe is isotropic, so its value does not depend on how the
// tangent frame is rotated about the normal.
//
// The body is in lafortune_impl.h, written over LAFORTUNE_REAL / LAFORTUNE_VEC3 and
// instantiated for float (GLSL and C++: namespace specula::shared) and, in C++ only, for
// double (namespace specula::shared::f64: the CPU references, the fit and the error
// measurements), like gshd.h, lambert.h and solve3.h. This is the one place the formula is written.
#ifndef SPECULA_SHARED_LAFORTUNE_H
#define SPECULA_SHARED_LAFORTUNE_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

#define LAFORTUNE_REAL float
#define LAFORTUNE_VEC3 vec3
#define LAFORTUNE_MAX_FINITE 3.0e38
#include "shared/lafortune_impl.h"
#undef LAFORTUNE_REAL
#undef LAFORTUNE_VEC3
#undef LAFORTUNE_MAX_FINITE

// All three channels at once: cx, cz, n hold (r, g, b).
SHARED_FN vec3 lafortune_eval_rgb(vec3 cx, vec3 cz, vec3 n, vec3 u, vec3 v) {
    return vec3(lafortune_eval(cx.x, cz.x, n.x, u, v),
                lafortune_eval(cx.y, cz.y, n.y, u, v),
                lafortune_eval(cx.z, cz.z, n.z, u, v));
}

SHARED_FN vec3 lafortune_radial_rgb(vec3 cx, vec3 cz, vec3 n, vec3 u) {
    return vec3(lafortune_radial(cx.x, cz.x, n.x, u), lafortune_radial(cx.y, cz.y, n.y, u),
                lafortune_radial(cx.z, cz.z, n.z, u));
}

SPECULA_SHARED_END

#ifdef __cplusplus
namespace specula::shared::f64 {
using namespace glm;
#define LAFORTUNE_REAL double
#define LAFORTUNE_VEC3 dvec3
#define LAFORTUNE_MAX_FINITE 1.0e300
#include "shared/lafortune_impl.h"
#undef LAFORTUNE_REAL
#undef LAFORTUNE_VEC3
#undef LAFORTUNE_MAX_FINITE
} // namespace specula::shared::f64
#endif

#endif
