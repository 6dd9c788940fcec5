#version 450
// Deferred pass, shading subpass, factorized specular (render/deferred.glsl).
#extension GL_GOOGLE_include_directive : require
#include "render/deferred.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(set = 0, binding = 1) uniform sampler2D albedo_atlas;
SPECULA_SHADOW_SAMPLER
SPECULA_FACTOR_SAMPLERS
SPECULA_GBUFFER_INPUTS(11, 12)

layout(location = 0) out vec4 out_color;

void main() {
    const GbufferTexel t = gbuffer_texel(subpassLoad(gbuffer0), subpassLoad(gbuffer1));
    if (!t.covered) {
        out_color = vec4(0.0);
        return;
    }
    float v = light_visibility(params, shadow_map, t.world, t.n);
    vec3 color = vec3(0.0);
    if (params.flags.x != 0u) color += diffuse_term(params, albedo_atlas, t.world, t.n, t.uv, v);
    if (params.flags.z != 0u) color += specular_factorized_term(params, SPECULA_FACTOR_SAMPLER_ARGS, t.world, t.n, v);
    out_color = vec4(color, 1.0);
}
