// The shading terms of the raster passes (pipeline.md section 7), one definition
// each, called by the pass shaders: diffuse.frag and specular_*.frag (the thesis's
// two passes, blended additively) and both_*.frag (the two terms summed in one pass,
// Settings::passes = Fused: the same arithmetic with half the vertex and triangle work).
// GLSL only (samplers); the radiometry and the lobe are in shared/render.h,
// shared/lafortune.h and shared/gshd.h, which the synth renderer shares.
#ifndef SPECULA_RENDER_TERMS_GLSL
#define SPECULA_RENDER_TERMS_GLSL
#include "shared/render.h"
#include "shared/gshd.h"
#include "shared/lafortune.h"
#include "shared/tangent_frame.h"

const float kPi = 3.14159265358979;

// (rho / pi) I max(0, n.u) / d^2, rho bilinear from the atlas (the gutters make
// bilinear safe, engine/geometry/atlas.h); n unit.
vec3 diffuse_term(RenderParams p, sampler2D atlas, vec3 world, vec3 n, vec2 uv) {
    vec3 irradiance = point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 rho = texture(atlas, uv).rgb;
    return rho / kPi * irradiance;
}

// The Lafortune lobe in the appendix-B tangent frame of n, times I max(0, n.u) / d^2.
vec3 specular_analytic_term(RenderParams p, vec3 world, vec3 n) {
    vec3 irradiance = point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 color = vec3(0.0);
    if (irradiance != vec3(0.0)) {
        vec3 u = to_tangent_frame(n, direction_to(world, p.light_position.xyz));
        vec3 v = to_tangent_frame(n, direction_to(world, p.eye.xyz));
        color = lafortune_eval_rgb(p.lobe_cx.rgb, p.lobe_cz.rgb, p.lobe_n.rgb, u, v) * irradiance;
    }
    return color;
}

// G(h) H(d) from the Kautz-McCool cube-maps (shared/gshd.h), times I max(0, n.u) / d^2.
vec3 specular_factorized_term(RenderParams p, samplerCube g, samplerCube h, vec3 world, vec3 n) {
    vec3 irradiance = point_light_irradiance(n, world, p.light_position.xyz, p.light_intensity.rgb);
    vec3 color = vec3(0.0);
    if (irradiance != vec3(0.0)) {
        vec3 u = to_tangent_frame(n, direction_to(world, p.light_position.xyz));
        vec3 v = to_tangent_frame(n, direction_to(world, p.eye.xyz));
        GshdCoords c = gshd_from_uv(u, v);
        color = texture(g, c.h).rgb * texture(h, c.d).rgb * irradiance;
    }
    return color;
}

#endif
