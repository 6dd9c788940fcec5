#version 450
// lambert_solve, gather step: one invocation per (particle, view segment) of the current
// image batch. For each frame of the segment, the sample as the solve uses it (shared/lambert.h):
// shadowed and grazing light, the 4 bilinear taps (missing, clipped, per-tap irradiance), the
// known material's diffuse factor k_d and specular light; written as one record
// (rgb: the value with the specular light subtracted, w: k_d or minus the reason it was
// rejected). The pair step (lambert_solve.comp) fits the records of all the view's frames.
// Reference: lambert_pair_cpu in engine/diffuse/lambert_solve_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/lambert.h"

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
layout(std430, set = 0, binding = 2) readonly buffer Views { LambertViewGpu views[]; };
layout(std430, set = 0, binding = 3) readonly buffer Frames { LambertFrameGpu frames[]; };
layout(std430, set = 0, binding = 4) readonly buffer Pixels { uvec4 pixels[]; }; // rgb float bits, flags
layout(std430, set = 0, binding = 5) readonly buffer Keys { LambertPairKey keys[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Records { vec4 records[]; };

#include "shared/lambert_sample.glsl"

layout(push_constant) uniform PushBlock { LambertGatherPush pc; }; // shared header: one definition for GLSL and C++

vec4 rejected(uint reason) {
    return vec4(0.0, 0.0, 0.0, -float(reason));
}

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    LambertPairKey key = keys[e];
    ParticleGpu part = particles[key.particle];
    LambertViewGpu view = views[key.view];
    vec3 P = part.position.xyz;
    vec3 n = part.normal.xyz;
    vec4 Ph = vec4(P, 1.0);
    vec3 xc = vec3(dot(view.w2c0, Ph), dot(view.w2c1, Ph), dot(view.w2c2, Ph));
    vec2 pos = vec2(view.intrinsics.z + view.intrinsics.x * xc.x / (-xc.z),
                    view.intrinsics.w - view.intrinsics.y * xc.y / (-xc.z));
    int w = int(view.width);
    int h = int(view.height);
    LambertTaps t = lambert_taps(pos, w, h);
    vec3 vdir = normalize(view.center.xyz - P);
    float nv = dot(n, vdir);

    for (uint k = 0u; k < view.frame_count; ++k) {
        LambertFrameGpu fr = frames[view.frame_first + k];
        uint at = key.slot + k;
        uint word = lit[key.particle * pc.frame_words + fr.frame / 32u];
        if (((word >> (fr.frame % 32u)) & 1u) == 0u) { records[at] = rejected(kLambertRecordShadow); continue; }
        vec3 L = fr.light.xyz - P;
        float d2 = dot(L, L);
        vec3 u = L / sqrt(d2);
        float cosl = dot(n, u);
        if (!(cosl >= pc.min_light_cos)) { records[at] = rejected(kLambertRecordGrazing); continue; }
        LambertSample smp = lambert_read_sample(t, w, fr.pixel_offset, fr.light.w, view.surface_offset, fr.light.xyz,
                                                cosl / d2, pc.min_light_cos);
        if (smp.status == kLambertSampleMissing) { records[at] = rejected(kLambertRecordMissing); continue; }
        if (smp.status == kLambertSampleClipped) { records[at] = rejected(kLambertRecordClipped); continue; }
        if (smp.status == kLambertSampleGrazing) { records[at] = rejected(kLambertRecordGrazing); continue; }
        float kd = material_diffuse_factor(pc.material, cosl, nv);
        if (!(kd > 0.0)) { records[at] = rejected(kLambertRecordGrazing); continue; } // the known diffuse term is dark here
        vec3 e_light = fr.intensity.xyz * (cosl / d2);
        records[at] = vec4(smp.c - material_specular(pc.material, cosl, nv, dot(u, vdir)) * e_light, kd);
    }
}
