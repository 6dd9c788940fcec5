// Body of lafortune.h, included once per scalar type (no include guard on purpose).
// Needs LAFORTUNE_REAL, LAFORTUNE_VEC3 and LAFORTUNE_MAX_FINITE (the clamp of the radial
// factor: float's range in float, effectively none in double). See lafortune.h.

// The lobe from the isotropic products a = ux vx + uy vy and b = uz vz (a = u.v - (n.u)(n.v),
// b = (n.u)(n.v) in world space, so no tangent is needed: the joint estimate's known lobe).
SHARED_FN LAFORTUNE_REAL lafortune_eval_ab(LAFORTUNE_REAL cx, LAFORTUNE_REAL cz, LAFORTUNE_REAL n, LAFORTUNE_REAL a,
                                           LAFORTUNE_REAL b) {
    LAFORTUNE_REAL base = cx * a + cz * b;
    return base > LAFORTUNE_REAL(0.0) ? pow(base, n) : LAFORTUNE_REAL(0.0);
}

// The lobe's base, Cx (ux vx + uy vy) + Cz uz vz, before clamping.
SHARED_FN LAFORTUNE_REAL lafortune_base(LAFORTUNE_REAL cx, LAFORTUNE_REAL cz, LAFORTUNE_VEC3 u, LAFORTUNE_VEC3 v) {
    return cx * (u.x * v.x + u.y * v.y) + cz * (u.z * v.z);
}

SHARED_FN LAFORTUNE_REAL lafortune_eval(LAFORTUNE_REAL cx, LAFORTUNE_REAL cz, LAFORTUNE_REAL n, LAFORTUNE_VEC3 u,
                                        LAFORTUNE_VEC3 v) {
    return lafortune_eval_ab(cx, cz, n, u.x * v.x + u.y * v.y, u.z * v.z);
}

// The lobe's radial factor |C u|^N, C = diag(Cx, Cx, Cz) (shared/gshd.h part 5):
// f(u, v) = lafortune_radial(u) * lafortune_normalized(u, v). Clamped at LAFORTUNE_MAX_FINITE
// (in float, a lobe whose height overflows stays finite), 0 where C u = 0.
SHARED_FN LAFORTUNE_REAL lafortune_radial(LAFORTUNE_REAL cx, LAFORTUNE_REAL cz, LAFORTUNE_REAL n, LAFORTUNE_VEC3 u) {
    LAFORTUNE_REAL s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    return s > LAFORTUNE_REAL(0.0) ? min(pow(s, LAFORTUNE_REAL(0.5) * n), LAFORTUNE_REAL(LAFORTUNE_MAX_FINITE))
                                   : LAFORTUNE_REAL(0.0);
}

// f / |C u|^N = max(0, (C u / |C u|).v)^N in [0, 1]: what F tabulates in the warped
// parametrization (shared/gshd.h part 5). 0 where C u = 0.
SHARED_FN LAFORTUNE_REAL lafortune_normalized(LAFORTUNE_REAL cx, LAFORTUNE_REAL cz, LAFORTUNE_REAL n, LAFORTUNE_VEC3 u,
                                              LAFORTUNE_VEC3 v) {
    LAFORTUNE_REAL s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    if (!(s > LAFORTUNE_REAL(0.0))) return LAFORTUNE_REAL(0.0);
    LAFORTUNE_REAL base = lafortune_base(cx, cz, u, v) * inversesqrt(s);
    return base > LAFORTUNE_REAL(0.0) ? pow(min(base, LAFORTUNE_REAL(1.0)), n) : LAFORTUNE_REAL(0.0);
}
