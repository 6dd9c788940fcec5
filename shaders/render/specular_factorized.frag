#version 450
// Pass 2, specular, factorized mode (pipeline.md section 6; thesis appendix A; Kautz and
// McCool 1999): f_s(u, v) ~ max(0, sum_k G_k(h) H_k(d)), K pairs of cube-map lookups by the Gram-Schmidt
// half/difference directions of (u, v) in the tangent frame (render/terms.glsl),
// times I max(0, n.u) / d^2; blended additively onto pass 1.
#extension GL_GOOGLE_include_directive : require
#include "render/terms.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
SPECULA_SHADOW_SAMPLER
SPECULA_FACTOR_SAMPLERS

#include "render/varyings.glsl"
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(in_normal);
    out_color = vec4(specular_factorized_term(params, SPECULA_FACTOR_SAMPLER_ARGS, in_world, n,
                                              light_visibility(params, shadow_map, in_world, n)),
                     0.0);
}
