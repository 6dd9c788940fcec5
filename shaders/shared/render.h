// The raster passes' shared layouts and shading math (pipeline.md section 7; C++:
// engine/render/renderer.cpp fills the layouts, tests evaluate the functions).
//
// Radiometry (capture-format.md, "Radiometry"), for a surface point p with unit
// shading normal n, a point light at l with RGB intensity I, u = (l - p) / d,
// d = |l - p|, v the unit direction from p to the camera:
//     pass 1 (diffuse):   (rho / pi) k_d(u, v) * I max(0, n.u) / d^2
//     pass 2 (specular):  f_s(u, v)            * I max(0, n.u) / d^2      added by blending
// with k_d and f_s the material's (shared/material.h: material_diffuse_factor, 1 for the
// lafortune family, and material_specular, evaluated in the analytic mode), or f_s from the
// Kautz-McCool cube-maps (factorized mode, shared/gshd.h; k_d is still evaluated: the
// factorization tabulates the specular part only).
// Both terms are multiplied by the light's visibility V in [0, 1] (cast shadows,
// render/terms.glsl light_visibility: a shadow map with 2x2 PCF); V = 1 everywhere
// when shadows are off (shadow.x == 0), the thesis's unshadowed render.
#ifndef SPECULA_SHARED_RENDER_H
#define SPECULA_SHARED_RENDER_H
#include "shared/prelude.h"
#include "shared/material.h"

SPECULA_SHARED_BEGIN

// Per-frame parameters (one std430 storage buffer, set 0 binding 0).
struct RenderParams {
    mat4 world_to_clip;   // Vulkan projection (engine/render/projection.h) * world_to_camera
    vec4 eye;             // xyz: camera centre (world)
    vec4 light_position;  // xyz: point light (world)
    vec4 light_intensity; // rgb: radiant intensity
    MaterialGpu material; // the specular model (shared/material.h; engine/material material_gpu): every
                          // family's f_s and k_d; the zero material without one
    uvec4 flags;          // x: 1 = pass 1 writes the diffuse term, 0 = depth and coverage only;
                          // y: unused (0); the factorized passes have the term count and the
                          // parametrization as specialization constants (render/terms.glsl);
                          // z: 1 = the deferred shading pass adds the specular term; w: unused (0)
    mat4 light_to_clip;   // the shadow map's projection * view (light at light_position)
    vec4 shadow;          // x: 1 = sample the shadow map, 0 = no shadows (V = 1);
                          // y: world size of one map texel per unit of distance from the light;
                          // z: normal offset in texels at grazing light; w: constant normal offset in texels
    vec4 factor_warp;     // the warp (s, k_r, k_g, k_b) of kGshdWarped (shared/gshd.h part 5); 1 otherwise
};

// One vertex of the non-indexed triangle list (vertex input binding 0).
struct RenderVertex {
    vec4 position_u; // xyz: world position; w: atlas u
    vec4 normal_v;   // xyz: vertex normal (unit); w: atlas v
};

// I max(0, n.u) / d^2 for a point light at `light_position` seen from `p`.
SHARED_FN vec3 point_light_irradiance(vec3 n, vec3 p, vec3 light_position, vec3 intensity) {
    vec3 to_light = light_position - p;
    float d2 = dot(to_light, to_light);
    float cos_theta = dot(n, to_light) / sqrt(d2);
    return intensity * (max(cos_theta, 0.0f) / d2);
}

// Where a normal-offset shadow lookup samples from: p moved along n by
// texel (w + z sin(theta)) world units, texel = y d the map's texel footprint at the
// distance d from the light. Moving along the normal (rather than biasing depth alone)
// keeps a lit surface out of its own depth samples at grazing angles (Holbert 2011,
// "Normal offset shadows"). n unit.
SHARED_FN vec3 shadow_lookup_point(vec3 n, vec3 p, vec3 light_position, vec4 shadow) {
    vec3 to_light = light_position - p;
    float d = length(to_light);
    float cos_theta = clamp(dot(n, to_light) / d, 0.0f, 1.0f);
    float sin_theta = sqrt(1.0f - cos_theta * cos_theta);
    float texel = shadow.y * d;
    return p + n * (texel * (shadow.w + shadow.z * sin_theta));
}

// Unit direction from p toward a point q.
SHARED_FN vec3 direction_to(vec3 p, vec3 q) {
    return normalize(q - p);
}

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::RenderParams) == 288, "std430 size of RenderParams");
static_assert(offsetof(specula::shared::RenderParams, material) == 112 && offsetof(specula::shared::RenderParams, flags) == 176 &&
                  offsetof(specula::shared::RenderParams, light_to_clip) == 192 &&
                  offsetof(specula::shared::RenderParams, factor_warp) == 272,
              "std430 offsets of RenderParams (MaterialGpu is 16-aligned in std430)");
static_assert(sizeof(specula::shared::RenderVertex) == 32, "std430 stride of RenderVertex");
#endif

#endif
