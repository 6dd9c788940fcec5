// Body of gltf_core.h, included once per scalar type (no include guard on purpose).
// Needs CORE_REAL. See gltf_core.h for the model and its source.

// Schlick's weight (1 - v.h)^5 from cuv = u.v (h = norm(u + v), so v.h = |u + v| / 2).
SHARED_FN CORE_REAL core_schlick_weight(CORE_REAL cuv) {
    CORE_REAL vh = clamp(sqrt(max(CORE_REAL(0.5) + CORE_REAL(0.5) * cuv, CORE_REAL(0.0))), CORE_REAL(0.0), CORE_REAL(1.0));
    CORE_REAL x = CORE_REAL(1.0) - vh;
    CORE_REAL x2 = x * x;
    return x2 * x2 * x;
}

// D V of the specular term (no Fresnel), from ci = n.u, co = n.v, cuv = u.v; 0 at or below the horizon.
SHARED_FN CORE_REAL core_ggx_dv(CORE_REAL ci, CORE_REAL co, CORE_REAL cuv, CORE_REAL roughness) {
    if (!(ci > CORE_REAL(0.0)) || !(co > CORE_REAL(0.0))) return CORE_REAL(0.0);
    CORE_REAL r = max(roughness, CORE_REAL(kCoreMinRoughness));
    CORE_REAL alpha = r * r;
    CORE_REAL a2 = alpha * alpha;
    CORE_REAL len = sqrt(max(CORE_REAL(2.0) + CORE_REAL(2.0) * cuv, CORE_REAL(1e-12)));
    CORE_REAL nh = min((ci + co) / len, CORE_REAL(1.0));
    CORE_REAL t = nh * nh * (a2 - CORE_REAL(1.0)) + CORE_REAL(1.0);
    CORE_REAL d = a2 / (CORE_REAL(kPi) * t * t);
    CORE_REAL gv = ci * sqrt(a2 + (CORE_REAL(1.0) - a2) * co * co);
    CORE_REAL gl = co * sqrt(a2 + (CORE_REAL(1.0) - a2) * ci * ci);
    return d * CORE_REAL(0.5) / max(gv + gl, CORE_REAL(1e-12));
}

// The specular term F D V.
SHARED_FN CORE_REAL core_specular(CORE_REAL ci, CORE_REAL co, CORE_REAL cuv, CORE_REAL roughness, CORE_REAL f0, CORE_REAL f90) {
    CORE_REAL f = f0 + (f90 - f0) * core_schlick_weight(cuv);
    return f * core_ggx_dv(ci, co, cuv, roughness);
}

// The diffuse term's factor on rho / pi: s (1 - F); 0 at or below the horizon.
SHARED_FN CORE_REAL core_diffuse_factor(CORE_REAL ci, CORE_REAL co, CORE_REAL cuv, CORE_REAL f0, CORE_REAL f90, CORE_REAL s) {
    if (!(ci > CORE_REAL(0.0)) || !(co > CORE_REAL(0.0))) return CORE_REAL(0.0);
    CORE_REAL f = f0 + (f90 - f0) * core_schlick_weight(cuv);
    return s * (CORE_REAL(1.0) - f);
}

// KHR_materials_clearcoat as three.js draws it: a second GGX layer with F0 0.04 and F90 1, weight
// cc, over the rest, which it dims by 1 - cc Fcc(n.v) (Fcc: Schlick at the view cosine).
SHARED_FN CORE_REAL core_clearcoat_dim(CORE_REAL co, CORE_REAL cc) {
    CORE_REAL x = CORE_REAL(1.0) - clamp(co, CORE_REAL(0.0), CORE_REAL(1.0));
    CORE_REAL x2 = x * x;
    return CORE_REAL(1.0) - cc * (CORE_REAL(0.04) + CORE_REAL(0.96) * x2 * x2 * x);
}

// The clearcoat layer's reflection, cc F(v.h) D V at its roughness.
SHARED_FN CORE_REAL core_clearcoat_specular(CORE_REAL ci, CORE_REAL co, CORE_REAL cuv, CORE_REAL cc, CORE_REAL roughness) {
    if (!(cc > CORE_REAL(0.0))) return CORE_REAL(0.0);
    return cc * core_specular(ci, co, cuv, roughness, CORE_REAL(0.04), CORE_REAL(1.0));
}
