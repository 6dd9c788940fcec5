#version 450
// Pass 2, specular, analytic mode: the Lafortune lobe (shared/lafortune.h) evaluated
// per fragment in the appendix-B tangent frame of the interpolated normal
// (shared/tangent_frame.h), times I max(0, n.u) / d^2; blended additively onto pass 1
// (alpha is kept by the blend state, so it stays the coverage). The same definitions
// as the synth renderer (engine/synth/render_cpu.cpp), which is this mode's reference.
#extension GL_GOOGLE_include_directive : require
#include "shared/render.h"
#include "shared/lafortune.h"
#include "shared/tangent_frame.h"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };

layout(location = 0) in vec3 in_world;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(in_normal);
    vec3 irradiance = point_light_irradiance(n, in_world, params.light_position.xyz, params.light_intensity.rgb);
    vec3 color = vec3(0.0);
    if (irradiance != vec3(0.0)) {
        vec3 u = to_tangent_frame(n, direction_to(in_world, params.light_position.xyz));
        vec3 v = to_tangent_frame(n, direction_to(in_world, params.eye.xyz));
        color = lafortune_eval_rgb(params.lobe_cx.rgb, params.lobe_cz.rgb, params.lobe_n.rgb, u, v) * irradiance;
    }
    out_color = vec4(color, 0.0);
}
