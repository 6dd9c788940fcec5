// The shading terms of the raster passes (pipeline.md section 7), one definition
// each, called by the pass shaders: diffuse.frag and specular_*.frag (the thesis's
// two passes, blended additively) and both_*.frag (the two terms summed in one pass,
// Settings::passes = Fused: the same arithmetic with half the vertex and triangle work).
// GLSL only (samplers); the radiometry and the material are in shared/render.h and
// shared/material.h (every family's f_s and k_d, the one evaluation the kernels and the C++
// references share), the factorization's coordinates in shared/gshd.h.
#ifndef SPECULA_RENDER_TERMS_GLSL
#define SPECULA_RENDER_TERMS_GLSL
#include "shared/render.h"
#include "shared/gshd.h"
#include "shared/lafortune.h"
#include "shared/material.h"
#include "shared/tangent_frame.h"

// The lit passes' specialization constants: render::Renderer builds their pipelines for the
// frame's factorization, material family and shadows (Renderer::Impl::use_constants). Constants,
// not parameters, because lavapipe runs both sides of a branch on a uniform value, texture
// lookups included. Measured on knot_hd at 512 px: a one-term warped factorization read from
// the parameters paid for 32 cube-map lookups a pixel instead of 6 (shading 39 -> 13 ms); the
// analytic shading evaluated all three families and sampled the shadow map with shadows off
// (6.3 -> 4.1 ms).
layout(constant_id = 0) const uint kFactorTerms = 1u;    // K, 1..4
layout(constant_id = 1) const uint kFactorParam = 0u;    // kGshdPlain, kGshdMirrored or kGshdWarped
layout(constant_id = 2) const uint kMaterialFamily = 0u; // params.material.family.x
layout(constant_id = 3) const bool kShadows = true;      // false: the shadow map is never sampled
layout(constant_id = 4) const bool kSharedWarp = false;  // kGshdWarped with one warp for the channels

// The frame's material with its family as the constant (the same value), so that the shaders
// keep only that family's code.
MaterialGpu frame_material(RenderParams p) {
    MaterialGpu m = p.material;
    m.family.x = kMaterialFamily;
    return m;
}

// The light's visibility V in [0, 1] at a surface point (1 = lit): the shadow map
// (set 0 binding 2, a sampler2DShadow with compare LESS_OR_EQUAL, 2x2 PCF where the depth
// format filters linearly) looked up from the normal-offset point (shared/render.h
// shadow_lookup_point). Every pass multiplies both terms by it. p.shadow.x == 0: 1.
float light_visibility(RenderParams p, sampler2DShadow shadow_map, vec3 world, vec3 n) {
    if (!kShadows || p.shadow.x == 0.0) return 1.0;
    vec3 q = shadow_lookup_point(n, world, p.light_position.xyz, p.shadow);
    vec4 clip = p.light_to_clip * vec4(q, 1.0);
    if (clip.w <= 0.0) return 1.0; // behind the light: outside its frustum
    vec3 ndc = clip.xyz / clip.w;
    return texture(shadow_map, vec3(ndc.xy * 0.5 + 0.5, ndc.z));
}

// The pass shaders' declaration of the shadow map (set 0 binding 2).
#define SPECULA_SHADOW_SAMPLER layout(set = 0, binding = 2) uniform sampler2DShadow shadow_map;

// (rho / pi) k_d V I max(0, n.u) / d^2, rho bilinear from the atlas (the gutters make
// bilinear safe, engine/geometry/atlas.h), k_d the material's diffuse factor
// (shared/material.h material_diffuse_factor_uv: exactly 1 for the lafortune family, so its
// renders are the thesis's bit for bit; the coating's Fresnel transmittances for the coated
// one; s (1 - F) for glTF's core material); n unit, V = light_visibility. Both specular paths draw this same term.
vec3 diffuse_term(RenderParams p, sampler2D atlas, vec3 world, vec3 n, vec2 uv, float visibility) {
    vec3 irradiance = visibility * point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 rho = texture(atlas, uv).rgb;
    vec3 u = direction_to(world, p.light_position.xyz);
    vec3 v = direction_to(world, p.eye.xyz);
    float k_d = material_diffuse_factor_uv(frame_material(p), dot(n, u), dot(n, v), dot(u, v));
    return rho / kPi * irradiance * k_d;
}

// The material's specular BRDF (shared/material.h material_specular, from n.u, n.v and u.v:
// isotropic, so no tangent frame), times V I max(0, n.u) / d^2.
vec3 specular_analytic_term(RenderParams p, vec3 world, vec3 n, float visibility) {
    vec3 irradiance = visibility * point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 color = vec3(0.0);
    if (irradiance != vec3(0.0)) {
        vec3 u = direction_to(world, p.light_position.xyz);
        vec3 v = direction_to(world, p.eye.xyz);
        color = material_specular(frame_material(p), dot(n, u), dot(n, v), dot(u, v)) * irradiance;
    }
    return color;
}

// max(0, sum_k G_k(h) H_k(d)) over the first kFactorTerms (1..4) terms of the Kautz-McCool
// factorization (shared/gshd.h; K = 1 is the thesis's G(h) H(d)) at the coordinates c.
vec3 factor_terms(RenderParams p, samplerCube g0, samplerCube g1, samplerCube g2, samplerCube g3, samplerCube h0,
                  samplerCube h1, samplerCube h2, samplerCube h3, GshdCoords c) {
    vec3 f = texture(g0, c.h).rgb * texture(h0, c.d).rgb;
    if (kFactorTerms > 1u) f += texture(g1, c.h).rgb * texture(h1, c.d).rgb;
    if (kFactorTerms > 2u) f += texture(g2, c.h).rgb * texture(h2, c.d).rgb;
    if (kFactorTerms > 3u) f += texture(g3, c.h).rgb * texture(h3, c.d).rgb;
    return max(f, vec3(0.0));
}

// The factorized lobe times V I max(0, n.u) / d^2, with (h, d) in the factorization's
// parametrization kFactorParam: kGshdPlain, the GSHD of (u, v); kGshdMirrored, of (r(u), v)
// (shared/gshd.h part 4); kGshdWarped, of (w_c(u), v) with channel c's warp
// (p.factor_warp.x, p.factor_warp[c + 1]), a lookup per channel, and the sum times the lobe's
// radial factor |C u|^N (part 5; lafortune family only: p.material's a, b, c are Cx, Cz, N, and
// the renderer refuses a warped factorization of another family).
// Four fixed sampler pairs (no descriptor indexing on lavapipe): the pass shaders declare
// them at bindings 3..6 (G) and 7..10 (H) and pass them in.
vec3 specular_factorized_term(RenderParams p, samplerCube g0, samplerCube g1, samplerCube g2, samplerCube g3,
                              samplerCube h0, samplerCube h1, samplerCube h2, samplerCube h3, vec3 world, vec3 n,
                              float visibility) {
    vec3 irradiance = visibility * point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 color = vec3(0.0);
    if (irradiance != vec3(0.0)) {
        vec3 u = to_tangent_frame(n, direction_to(world, p.light_position.xyz));
        vec3 v = to_tangent_frame(n, direction_to(world, p.eye.xyz));
        vec3 f;
        if (kFactorParam == kGshdWarped) {
            if (kSharedWarp) { // one pair of coordinates, every channel of each lookup
                f = factor_terms(p, g0, g1, g2, g3, h0, h1, h2, h3,
                                 gshd_from_uv_warped(u, v, kGshdWarped, p.factor_warp.xy));
            } else {
                for (int ch = 0; ch < 3; ++ch) {
                    GshdCoords c = gshd_from_uv_warped(u, v, kGshdWarped, vec2(p.factor_warp.x, p.factor_warp[ch + 1]));
                    f[ch] = factor_terms(p, g0, g1, g2, g3, h0, h1, h2, h3, c)[ch];
                }
            }
            vec3 radial = lafortune_radial_rgb(p.material.a.rgb, p.material.b.rgb, p.material.c.rgb, u);
            f = min(radial * f, vec3(kGshdMaxValue)); // radial <= kGshdMaxValue: finite, 0 where f is
        } else {
            f = factor_terms(p, g0, g1, g2, g3, h0, h1, h2, h3, gshd_from_uv_param(u, v, kFactorParam));
        }
        // Outside F's domain (the view below the shading normal's horizon, which interpolated
        // normals give near silhouettes) the cube-maps hold no value of the model. The coated
        // family is zero there (shared/coated.h), as its analytic term; a Lafortune lobe is
        // defined there, and its factorized term keeps the lookups (the thesis's renders, as they
        // were). Measured on the knot lit from 130 degrees off the camera (coated, alpha 0.4):
        // 39.4 dB against the analytic render with the lookups, 52 dB without.
        if (kMaterialFamily == kMaterialCoated && v.z <= 0.0) f = vec3(0.0);
        color = f * irradiance;
    }
    return color;
}

// The pass shaders' declarations of the factorization's samplers (set 0, bindings 3..10).
#define SPECULA_FACTOR_SAMPLERS                                   \
    layout(set = 0, binding = 3) uniform samplerCube cube_g0;     \
    layout(set = 0, binding = 4) uniform samplerCube cube_g1;     \
    layout(set = 0, binding = 5) uniform samplerCube cube_g2;     \
    layout(set = 0, binding = 6) uniform samplerCube cube_g3;     \
    layout(set = 0, binding = 7) uniform samplerCube cube_h0;     \
    layout(set = 0, binding = 8) uniform samplerCube cube_h1;     \
    layout(set = 0, binding = 9) uniform samplerCube cube_h2;    \
    layout(set = 0, binding = 10) uniform samplerCube cube_h3;
#define SPECULA_FACTOR_SAMPLER_ARGS cube_g0, cube_g1, cube_g2, cube_g3, cube_h0, cube_h1, cube_h2, cube_h3

#endif
