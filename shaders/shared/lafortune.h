// One isotropic Lafortune lobe, per colour channel (thesis eq. 2.1 with rho_d = 0;
// Lafortune et al. 1997, "Non-Linear Approximation of Reflectance Functions"):
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N
// u, v: unit light and view directions in the local tangent frame (z = normal).
// The base is clamped at zero before the power: a negative base to a real
// power is NaN. The lobe is isotropic, so its value does not depend on how the
// tangent frame is rotated about the normal.
#ifndef SPECULA_SHARED_LAFORTUNE_H
#define SPECULA_SHARED_LAFORTUNE_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// The lobe's base, Cx (ux vx + uy vy) + Cz uz vz, before clamping.
SHARED_FN float lafortune_base(float cx, float cz, vec3 u, vec3 v) {
    return cx * (u.x * v.x + u.y * v.y) + cz * (u.z * v.z);
}

SHARED_FN float lafortune_eval(float cx, float cz, float n, vec3 u, vec3 v) {
    float base = lafortune_base(cx, cz, u, v);
    return base > 0.0f ? pow(base, n) : 0.0f;
}

// All three channels at once: cx, cz, n hold (r, g, b).
SHARED_FN vec3 lafortune_eval_rgb(vec3 cx, vec3 cz, vec3 n, vec3 u, vec3 v) {
    return vec3(lafortune_eval(cx.x, cz.x, n.x, u, v),
                lafortune_eval(cx.y, cz.y, n.y, u, v),
                lafortune_eval(cx.z, cz.z, n.z, u, v));
}

// The lobe's radial factor |C u|^N, C = diag(Cx, Cx, Cz) (shared/gshd.h part 5):
// f(u, v) = lafortune_radial(u) * lafortune_normalized(u, v). Clamped at 3e38 (a lobe whose
// height overflows float stays finite), 0 where C u = 0.
SHARED_FN float lafortune_radial(float cx, float cz, float n, vec3 u) {
    float s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    return s > 0.0f ? min(pow(s, 0.5f * n), 3.0e38f) : 0.0f;
}

// f / |C u|^N = max(0, (C u / |C u|).v)^N in [0, 1]: what F tabulates in the warped
// parametrization (shared/gshd.h part 5; the CPU reference's double twin is
// engine/factorization/lobe.h lafortune_normalized_f64). 0 where C u = 0.
SHARED_FN float lafortune_normalized(float cx, float cz, float n, vec3 u, vec3 v) {
    float s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    if (!(s > 0.0f)) return 0.0f;
    float base = lafortune_base(cx, cz, u, v) * inversesqrt(s);
    return base > 0.0f ? pow(min(base, 1.0f), n) : 0.0f;
}

SHARED_FN vec3 lafortune_radial_rgb(vec3 cx, vec3 cz, vec3 n, vec3 u) {
    return vec3(lafortune_radial(cx.x, cz.x, n.x, u), lafortune_radial(cx.y, cz.y, n.y, u),
                lafortune_radial(cx.z, cz.z, n.z, u));
}

SPECULA_SHARED_END
#endif
