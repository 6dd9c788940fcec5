#version 450
// Pass 1, diffuse: (rho / pi) I max(0, n.u) / d^2 (render/terms.glsl), n the
// interpolated vertex normal, normalized per fragment (as the synth renderer does).
// Alpha = 1 marks coverage. With params.flags.x == 0 the pass lays down depth and
// coverage only (the specular-only mode).
#extension GL_GOOGLE_include_directive : require
#include "render/terms.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(set = 0, binding = 1) uniform sampler2D albedo_atlas;
SPECULA_SHADOW_SAMPLER

#include "render/varyings.glsl"
layout(location = 0) out vec4 out_color;

void main() {
    vec3 color = vec3(0.0);
    if (params.flags.x != 0u) {
        vec3 n = normalize(in_normal);
        color = diffuse_term(params, albedo_atlas, in_world, n, in_uv, light_visibility(params, shadow_map, in_world, n));
    }
    out_color = vec4(color, 1.0);
}
