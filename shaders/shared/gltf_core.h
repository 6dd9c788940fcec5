// glTF's core material as ordinary viewers draw it: the metallic-roughness model with metallic 0
// (a dielectric) and KHR_materials_ior / KHR_materials_specular, lit by a point light, evaluated
// as three.js r187 does (WebGLRenderer, lights_physical_pars_fragment: RE_Direct_Physical), which
// is the glTF 2.0 specification's appendix B with Fresnel applied per channel:
//     f(u, v) = (base / pi) (1 - F) + F D V,        h = norm(u + v)
//     F = f0 + (f90 - f0) (1 - v.h)^5               (Schlick; f90 = specularFactor)
//     D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2),   alpha = roughness^2   (GGX)
//     V = 0.5 / (ci sqrt(alpha^2 + (1 - alpha^2) co^2) + co sqrt(alpha^2 + (1 - alpha^2) ci^2))
//         (Smith's height-correlated visibility, G / (4 ci co))
// with f0 = min(((ior - 1) / (ior + 1))^2 specularColorFactor, 1) specularFactor. Specula writes
// the base colour as the albedo over (1 - f0) (engine/material/core_material.h), so at normal
// incidence the diffuse term is the albedo's: here `s` is that scale, base = rho s.
// Left out, as small: three.js's multiple-scattering compensation of the specular term (a factor
// 1 + f0 (1 / E_ss - 1), E_ss the lobe's directional albedo: below 1.05 for f0 <= 0.1 and
// roughness <= 0.6) and the roughness it adds from the normal's screen-space derivative.
// With KHR_materials_clearcoat (weight cc, roughness rc), as three.js adds it:
//     f_total = (1 - cc Fcc(n.v)) f + cc F_c D_c V_c,   Fcc, F_c Schlick with F0 0.04, F90 1
// (Fcc at n.v, F_c at v.h); the base colour scale is then 1 / ((1 - f0)(1 - 0.04 cc)).
// Grey parameters (one f0, one f90). Written once over CORE_REAL (gltf_core_impl.h),
// instantiated for float (GLSL and C++: specula::shared) and double (specula::shared::f64).
#ifndef SPECULA_SHARED_GLTF_CORE_H
#define SPECULA_SHARED_GLTF_CORE_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// three.js's floor on roughness for punctual lights (BRDF_GGX: max(roughness, 0.045)).
const float kCoreMinRoughness = 0.045f;

#define CORE_REAL float
#include "shared/gltf_core_impl.h"
#undef CORE_REAL

SPECULA_SHARED_END

#ifdef __cplusplus
namespace specula::shared::f64 {
using namespace glm;
using specula::shared::kCoreMinRoughness;
#define CORE_REAL double
#include "shared/gltf_core_impl.h"
#undef CORE_REAL
} // namespace specula::shared::f64
#endif

#endif
