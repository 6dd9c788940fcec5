#version 450
// residuals: one invocation per (particle, view) pair of the current view batch. Walks the
// view's train frames; every frame whose `lit` bit is set owns one output slot (the host
// counted them, so slots are consecutive from key.slot), filled with the specular BRDF
// sample or a drop status. Method: shared/residuals.h; reference:
// engine/specular/residuals_cpu.cpp. Bilinear taps and flags as in the diffuse solve
// and per-tap irradiance gains (shared/lambert.h), so both stages read the same pixel value.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/lambert.h"
#include "shared/residuals.h"

layout(local_size_x_id = 0) in;

struct ParticleGpu {
    vec4 position;
    vec4 normal;
    vec2 bary;
    uint triangle;
    uint texel;
};

layout(std430, set = 0, binding = 0) readonly buffer Particles { ParticleGpu particles[]; };
layout(std430, set = 0, binding = 1) readonly buffer Lit { uint lit[]; };
layout(std430, set = 0, binding = 2) readonly buffer Albedo { vec4 rho_over_pi[]; }; // per particle
layout(std430, set = 0, binding = 3) readonly buffer Views { LambertViewGpu views[]; };
layout(std430, set = 0, binding = 4) readonly buffer Frames { LambertFrameGpu frames[]; };
layout(std430, set = 0, binding = 5) readonly buffer Pixels { uvec4 pixels[]; }; // rgb float bits, flags
layout(std430, set = 0, binding = 6) readonly buffer Keys { LambertPairKey keys[]; };
layout(std430, set = 0, binding = 7) writeonly buffer Samples { ResidualSample samples[]; };

layout(push_constant) uniform PushBlock { ResidualPush pc; }; // shared header: one definition for GLSL and C++

#include "shared/lambert_sample.glsl"

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    LambertPairKey key = keys[e];
    ParticleGpu part = particles[key.particle];
    LambertViewGpu view = views[key.view];
    vec3 P = part.position.xyz;
    vec3 n = part.normal.xyz;
    vec3 rpi = rho_over_pi[key.particle].xyz;
    vec4 Ph = vec4(P, 1.0);
    vec3 xc = vec3(dot(view.w2c0, Ph), dot(view.w2c1, Ph), dot(view.w2c2, Ph));
    vec2 pos = vec2(view.intrinsics.z + view.intrinsics.x * xc.x / (-xc.z),
                    view.intrinsics.w - view.intrinsics.y * xc.y / (-xc.z));
    int w = int(view.width);
    int h = int(view.height);
    LambertTaps t = lambert_taps(pos, w, h);
    vec3 vl = to_tangent_frame(n, normalize(view.center.xyz - P));

    uint slot = key.slot;
    for (uint k = 0u; k < view.frame_count; ++k) {
        LambertFrameGpu fr = frames[view.frame_first + k];
        uint word = lit[key.particle * pc.frame_words + fr.frame / 32u];
        if (((word >> (fr.frame % 32u)) & 1u) == 0u) continue; // shadowed: no slot
        ResidualSample s;
        s.u = vec4(0.0);
        s.v = vec4(vl, 0.0);
        s.f = vec3(0.0);
        vec3 L = fr.light.xyz - P;
        float d2 = dot(L, L);
        vec3 u = L / sqrt(d2);
        float cosl = dot(n, u);
        s.u.xyz = to_tangent_frame(n, u);
        if (!(cosl >= pc.min_light_cos)) {
            s.status = kResidualGrazing;
            samples[slot++] = s;
            continue;
        }
        LambertSample smp = lambert_read_sample(t, w, fr.pixel_offset, fr.light.w, view.surface_offset, fr.light.xyz,
                                                cosl / d2, pc.min_light_cos);
        if (smp.status != kLambertSampleOk) {
            s.status = smp.status == kLambertSampleMissing   ? kResidualMissing
                       : smp.status == kLambertSampleClipped ? kResidualClipped
                                                             : kResidualGrazing;
            samples[slot++] = s;
            continue;
        }
        vec3 c = smp.c;
        vec3 E = residual_irradiance(fr.intensity.xyz, cosl, d2);
        float ebar = (E.x + E.y + E.z) / 3.0;
        s.f = residual_brdf(c, rpi, E);
        s.u.w = ebar * ebar;
        s.v.w = ebar;
        s.status = kResidualUsed;
        samples[slot++] = s;
    }
}
