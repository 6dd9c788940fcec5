// Tangent (TBN) frame of a surface point, thesis appendix B: the normal is +Z,
// model +Y is the helper, +X = normalize(Y x Z), then +Y = Z x X. When the
// normal is (nearly) parallel to model +Y the helper becomes model +Z (our
// fallback; the thesis leaves this case open). Rows of the returned basis map
// world directions to local ones: local = vec3(dot(w, x), dot(w, y), dot(w, z)).
// Written once over TANGENT_REAL / TANGENT_VEC3 (tangent_frame_impl.h), instantiated for
// float (GLSL and C++: specula::shared) and double (C++: specula::shared::f64).
#ifndef SPECULA_SHARED_TANGENT_FRAME_H
#define SPECULA_SHARED_TANGENT_FRAME_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

// |n.y| above this uses the fallback helper (the same float threshold in both precisions,
// so the CPU reference switches helpers exactly where the kernels do).
const float kTangentHelperSwitch = 0.9999f;

#define TANGENT_REAL float
#define TANGENT_VEC3 vec3
#include "shared/tangent_frame_impl.h"
#undef TANGENT_REAL
#undef TANGENT_VEC3

SPECULA_SHARED_END

#ifdef __cplusplus
namespace specula::shared::f64 {
using namespace glm;
using specula::shared::kTangentHelperSwitch;
#define TANGENT_REAL double
#define TANGENT_VEC3 dvec3
#include "shared/tangent_frame_impl.h"
#undef TANGENT_REAL
#undef TANGENT_VEC3
} // namespace specula::shared::f64
#endif

#endif
