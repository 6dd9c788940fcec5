#version 450
// Pass 2, specular, analytic mode: the material's specular BRDF (render/terms.glsl,
// shared/material.h: any family) evaluated per fragment; blended additively onto pass 1
// (alpha is kept by the blend state, so it stays the coverage). The same definitions as the
// synth renderer (engine/synth/render_cpu.cpp), which is this mode's reference.
#extension GL_GOOGLE_include_directive : require
#include "render/terms.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
SPECULA_SHADOW_SAMPLER

#include "render/varyings.glsl"
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(in_normal);
    out_color = vec4(specular_analytic_term(params, in_world, n, light_visibility(params, shadow_map, in_world, n)), 0.0);
}
