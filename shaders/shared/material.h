// A material's parameters as the kernels and shaders read them, and the one evaluation of each
// family that every kernel, shader and C++ reference calls (engine/material/material.h is the
// C++ type; material_gpu() there fills this struct). Isotropic models only: each function takes
// ci = n.u, co = n.v (light and view cosines with the normal) and cuv = u.v.
//   family kMaterialLafortune: a = Cx rgb, b = Cz rgb, c = N rgb        (shared/lafortune.h)
//                              f_d = rho / pi,  f_s = max(0, Cx (u.v - ci co) + Cz ci co)^N
//   family kMaterialCoated:    a = (eta, alpha, 0, 0), b = tint rgb     (shared/coated.h)
//                              f_d = rho / pi T(ci) T(co) / T(1)^2,  f_s = tint F D G / (4 ci co)
//   family kMaterialGltfCore:  a = (roughness, f0, f90, s), b = (clearcoat, its roughness, 0, 0)
//                              (shared/gltf_core.h) f_d = rho / pi s (1 - F(u.v)) dim,
//                              f_s = F D V dim + clearcoat: glTF's core material as
//                              ordinary viewers draw it; rendered only (no kernel fits it), and its
//                              diffuse factor needs u.v: material_diffuse_factor_uv
// A zero material (family lafortune, every parameter 0) adds no specular light and leaves the
// diffuse term Lambertian: what the kernels get when no model is known yet.
#ifndef SPECULA_SHARED_MATERIAL_H
#define SPECULA_SHARED_MATERIAL_H
#include "shared/prelude.h"
#include "shared/coated.h"
#include "shared/gltf_core.h"
#include "shared/lafortune.h"

SPECULA_SHARED_BEGIN

const uint kMaterialLafortune = 0u;
const uint kMaterialCoated = 1u;
const uint kMaterialGltfCore = 2u;

struct MaterialGpu {
    uvec4 family; // x: kMaterial*
    vec4 a;
    vec4 b;
    vec4 c;
};

#define MATERIAL_REAL float
#define MATERIAL_VEC3 vec3
#include "shared/material_impl.h"
#undef MATERIAL_REAL
#undef MATERIAL_VEC3

SPECULA_SHARED_END

#ifdef __cplusplus
static_assert(sizeof(specula::shared::MaterialGpu) == 64, "std430 size of MaterialGpu");
namespace specula::shared::f64 {
using namespace glm;
using specula::shared::MaterialGpu;
using specula::shared::kMaterialCoated;
using specula::shared::kMaterialGltfCore;
using specula::shared::kMaterialLafortune;
#define MATERIAL_REAL double
#define MATERIAL_VEC3 dvec3
#include "shared/material_impl.h"
#undef MATERIAL_REAL
#undef MATERIAL_VEC3
} // namespace specula::shared::f64
#endif

#endif
