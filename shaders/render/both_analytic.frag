#version 450
// Both terms in one pass (Settings::passes = Fused), analytic specular: the diffuse
// term plus the material's specular, summed here instead of by the blend unit. Alpha = 1: coverage.
#extension GL_GOOGLE_include_directive : require
#include "render/terms.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(set = 0, binding = 1) uniform sampler2D albedo_atlas;
SPECULA_SHADOW_SAMPLER

#include "render/varyings.glsl"
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(in_normal);
    float v = light_visibility(params, shadow_map, in_world, n);
    out_color = vec4(diffuse_term(params, albedo_atlas, in_world, n, in_uv, v) + specular_analytic_term(params, in_world, n, v), 1.0);
}
