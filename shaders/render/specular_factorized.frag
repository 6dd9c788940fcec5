#version 450
// Pass 2, specular, factorized mode (pipeline.md section 6; thesis appendix A; Kautz and
// McCool 1999): f_s(u, v) ~ G(h) H(d), two cube-map lookups by the Gram-Schmidt
// half/difference directions of (u, v) in the tangent frame (shared/gshd.h), times
// I max(0, n.u) / d^2; blended additively onto pass 1.
#extension GL_GOOGLE_include_directive : require
#include "shared/render.h"
#include "shared/gshd.h"
#include "shared/tangent_frame.h"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(set = 0, binding = 3) uniform samplerCube cube_g;
layout(set = 0, binding = 4) uniform samplerCube cube_h;

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
        GshdCoords c = gshd_from_uv(u, v);
        color = texture(cube_g, c.h).rgb * texture(cube_h, c.d).rgb * irradiance;
    }
    out_color = vec4(color, 0.0);
}
