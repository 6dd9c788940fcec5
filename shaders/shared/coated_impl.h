// Body of coated.h, included once per scalar type (no include guard on purpose).
// Needs COATED_REAL. See coated.h for the model and its sources.

// Fresnel reflectance of unpolarized light arriving at cosine c (> 0) on an interface of
// relative index eta (> 1: from the outside), Walter et al. 2007 eq. 22:
//     g = sqrt(eta^2 - 1 + c^2),  F = (g - c)^2 / (2 (g + c)^2) (1 + ((c (g + c) - 1) / (c (g - c) + 1))^2)
SHARED_FN COATED_REAL coated_fresnel(COATED_REAL c, COATED_REAL eta) {
    c = clamp(c, COATED_REAL(0.0), COATED_REAL(1.0));
    COATED_REAL g2 = eta * eta - COATED_REAL(1.0) + c * c;
    if (!(g2 > COATED_REAL(0.0))) return COATED_REAL(1.0); // total internal reflection (eta < 1 only)
    COATED_REAL g = sqrt(g2);
    COATED_REAL a = (g - c) / (g + c);
    COATED_REAL b = (c * (g + c) - COATED_REAL(1.0)) / (c * (g - c) + COATED_REAL(1.0));
    return COATED_REAL(0.5) * a * a * (COATED_REAL(1.0) + b * b);
}

// Fresnel transmittance T = 1 - F.
SHARED_FN COATED_REAL coated_transmittance(COATED_REAL c, COATED_REAL eta) {
    return COATED_REAL(1.0) - coated_fresnel(c, eta);
}

// The diffuse term's angular factor T(ci) T(co) / T(1)^2 (1 at normal incidence); 0 below the horizon.
SHARED_FN COATED_REAL coated_diffuse_factor(COATED_REAL ci, COATED_REAL co, COATED_REAL eta) {
    if (!(ci > COATED_REAL(0.0)) || !(co > COATED_REAL(0.0))) return COATED_REAL(0.0);
    COATED_REAL t1 = coated_transmittance(COATED_REAL(1.0), eta);
    return coated_transmittance(ci, eta) * coated_transmittance(co, eta) / (t1 * t1);
}

// GGX (Trowbridge-Reitz) distribution of microfacet normals at cosine c from the normal (eq. 33).
SHARED_FN COATED_REAL coated_ggx_d(COATED_REAL c, COATED_REAL alpha) {
    COATED_REAL a2 = alpha * alpha;
    COATED_REAL t = c * c * (a2 - COATED_REAL(1.0)) + COATED_REAL(1.0);
    return a2 / (COATED_REAL(kPi) * t * t);
}

// Smith's G1 for GGX at cosine c (> 0) of a direction with the normal (eq. 34, for m along h
// and the direction on the same side of the microfacet, true for reflection with c > 0).
SHARED_FN COATED_REAL coated_smith_g1(COATED_REAL c, COATED_REAL alpha) {
    COATED_REAL c2 = c * c;
    COATED_REAL tan2 = max(COATED_REAL(1.0) - c2, COATED_REAL(0.0)) / c2;
    return COATED_REAL(2.0) / (COATED_REAL(1.0) + sqrt(COATED_REAL(1.0) + alpha * alpha * tan2));
}

// The microfacet reflection without the tint: F D G1 G1 / (4 ci co), from ci = n.u, co = n.v,
// cuv = u.v (unit vectors). 0 when either direction is at or below the horizon.
SHARED_FN COATED_REAL coated_specular(COATED_REAL ci, COATED_REAL co, COATED_REAL cuv, COATED_REAL alpha, COATED_REAL eta) {
    if (!(ci > COATED_REAL(0.0)) || !(co > COATED_REAL(0.0))) return COATED_REAL(0.0);
    // |u + v|^2 = 2 + 2 u.v; h = (u + v) / |u + v|: n.h = (ci + co) / |u + v|, u.h = |u + v| / 2.
    COATED_REAL len = sqrt(max(COATED_REAL(2.0) + COATED_REAL(2.0) * cuv, COATED_REAL(1e-12)));
    COATED_REAL nh = min((ci + co) / len, COATED_REAL(1.0));
    COATED_REAL uh = COATED_REAL(0.5) * len;
    COATED_REAL f = coated_fresnel(uh, eta) * coated_ggx_d(nh, alpha) * coated_smith_g1(ci, alpha) * coated_smith_g1(co, alpha);
    return f / (COATED_REAL(4.0) * ci * co);
}
