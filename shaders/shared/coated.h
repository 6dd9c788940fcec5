// The coated material family (an addition to the thesis, docs/pipeline.md section 5.7): a
// Lambertian base under a dielectric interface of refractive index eta, plus a microfacet
// specular reflection off that interface. Isotropic; every function takes the cosines of the
// light and view directions with the normal (ci = n.u, co = n.v) and cuv = u.v, so neither a
// tangent frame nor the azimuth is needed.
//
// Specular (Walter, Marschner, Li and Torrance 2007, "Microfacet models for refraction through
// rough surfaces", EGSR): Cook-Torrance with the GGX (Trowbridge-Reitz) distribution (eq. 33),
// the separable Smith masking-shadowing G = G1(u) G1(v) (eq. 34) and the exact dielectric
// Fresnel reflectance (eq. 22) at the microfacet, all with the same eta:
//     f_s(u, v) = tint F(u.h, eta) D(n.h) G1(n.u) G1(n.v) / (4 (n.u) (n.v)),   h = norm(u + v)
//     D(c)  = alpha^2 / (pi (c^2 (alpha^2 - 1) + 1)^2)
//     G1(c) = 2 / (1 + sqrt(1 + alpha^2 (1 - c^2) / c^2))
// Diffuse: the light that reaches the base crosses the interface twice, so the Lambertian
// term is weighted by the Fresnel transmittance T = 1 - F at the light and at the viewer
// (the smooth-coating layer of Weidlich and Wilkie 2007, "Arbitrarily layered micro-facet
// surfaces", GRAPHITE; Kelemen and Szirmay-Kalos 2001 couple the two terms the same way):
//     f_d(u, v) = (rho / pi) T(n.u) T(n.v) / T(1)^2
// The physical layer also scales the base's albedo by eta^-2 / (1 - F_dr) (radiance
// compression and the internal reflections, F_dr the hemispherical average of the internal
// Fresnel reflectance); that factor is the same for every texel, so it is folded into rho,
// and dividing by T(1)^2 makes rho the normal-incidence diffuse reflectance: comparable with
// the Lambertian albedo of the lafortune family, and independent of eta during the fit
// (only the angular shape of T(n.u) T(n.v) depends on it). coated_base_albedo (C++) converts.
//
// Written once over COATED_REAL (coated_impl.h), instantiated for float (GLSL and C++:
// specula::shared) and double (C++: specula::shared::f64).
#ifndef SPECULA_SHARED_COATED_H
#define SPECULA_SHARED_COATED_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// Parameter bounds the fit and the bundle accept (the plausible range and beyond):
// alpha below 0.002 is a mirror the images cannot resolve; eta 1.0 is no interface.
const float kCoatedMinAlpha = 0.002f;
const float kCoatedMaxAlpha = 1.0f;
const float kCoatedMinEta = 1.01f;
const float kCoatedMaxEta = 3.0f;

#define COATED_REAL float
#include "shared/coated_impl.h"
#undef COATED_REAL

SPECULA_SHARED_END

#ifdef __cplusplus
namespace specula::shared::f64 {
using namespace glm;
#define COATED_REAL double
#include "shared/coated_impl.h"
#undef COATED_REAL
} // namespace specula::shared::f64
#endif

#endif
