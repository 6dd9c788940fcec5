#version 450
// lambert_solve, pair step: one invocation per (particle, view) pair of the current view
// batch. Samples every train frame of the view at the particle's projection (bilinear),
// scales each tap to the particle's irradiance (view surface map), rejects shadowed, grazing,
// missing, clipped and highlight samples, and solves albedo or
// photometric mode (method and thresholds: shared/lambert.h; reference:
// engine/diffuse/lambert_solve_cpu.cpp, which follows this step for step).
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/lambert.h"
#include "shared/solve3.h"

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
layout(std430, set = 0, binding = 6) writeonly buffer Results { LambertPairResult results[]; };

#include "shared/lambert_sample.glsl"

layout(push_constant) uniform PushBlock { LambertPairPush pc; }; // shared header: one definition for GLSL and C++

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

    LambertPairResult r;
    r.view = pc.global_view_base + key.view;
    vec3 vdir = normalize(view.center.xyz - P);
    float nv = dot(n, vdir);
    r.albedo = vec4(0.0, 0.0, 0.0, nv);
    r.normal = vec4(n, 0.0);
    r.status = 0u;
    uint shadow = 0u, clipped = 0u, missing = 0u, grazing = 0u;

    vec3 sc[kLambertMaxFramesPerView];
    vec3 se[kLambertMaxFramesPerView];
    vec3 si[kLambertMaxFramesPerView];
    vec3 sa[kLambertMaxFramesPerView];
    float sq[kLambertMaxFramesPerView];
    float ses[kLambertMaxFramesPerView];
    bool skept[kLambertMaxFramesPerView];
    uint ns = 0u;
    for (uint k = 0u; k < view.frame_count; ++k) {
        LambertFrameGpu fr = frames[view.frame_first + k];
        uint word = lit[key.particle * pc.frame_words + fr.frame / 32u];
        if (((word >> (fr.frame % 32u)) & 1u) == 0u) { ++shadow; continue; }
        vec3 L = fr.light.xyz - P;
        float d2 = dot(L, L);
        vec3 u = L / sqrt(d2);
        float cosl = dot(n, u);
        if (!(cosl >= pc.min_light_cos)) { ++grazing; continue; }
        LambertSample smp = lambert_read_sample(t, w, fr.pixel_offset, fr.light.w, view.surface_offset, fr.light.xyz,
                                                cosl / d2, pc.min_light_cos);
        if (smp.status == kLambertSampleMissing) { ++missing; continue; }
        if (smp.status == kLambertSampleClipped) { ++clipped; continue; }
        if (smp.status == kLambertSampleGrazing) { ++grazing; continue; }
        si[ns] = fr.intensity.xyz;
        se[ns] = fr.intensity.xyz * (cosl / d2);
        float lb = cosl * nv;
        float la = dot(u, vdir) - lb;
        vec3 spec = vec3(lafortune_eval_ab(pc.lobe[0], pc.lobe[3], pc.lobe[6], la, lb),
                         lafortune_eval_ab(pc.lobe[1], pc.lobe[4], pc.lobe[7], la, lb),
                         lafortune_eval_ab(pc.lobe[2], pc.lobe[5], pc.lobe[8], la, lb));
        sc[ns] = smp.c - spec * se[ns];
        sa[ns] = u / d2;
        ses[ns] = se[ns].x + se[ns].y + se[ns].z;
        sq[ns] = (sc[ns].x + sc[ns].y + sc[ns].z) / ses[ns];
        skept[ns] = true;
        ++ns;
    }

    // Highlights: lower median of q, then iterated refits (shared/lambert.h).
    uint kept = 0u;
    uint low = 0u;
    if (ns > 0u) {
        uint rank = (ns - 1u) / 2u;
        float est = 0.0;
        for (uint i = 0u; i < ns; ++i) { // the element with `rank` smaller ones (ties by index)
            uint below = 0u;
            for (uint j = 0u; j < ns; ++j)
                if (sq[j] < sq[i] || (sq[j] == sq[i] && j < i)) ++below;
            if (below == rank) est = sq[i];
        }
        for (uint it = 0u; it < pc.iterations; ++it) {
            bool changed = false;
            float num = 0.0, den = 0.0;
            for (uint i = 0u; i < ns; ++i) {
                bool keep = lambert_keep(sq[i], ses[i], est, pc.tau, pc.k_sigma) &&
                            !lambert_low(sq[i], ses[i], est, pc.tau, pc.k_sigma);
                changed = changed || keep != skept[i];
                skept[i] = keep;
                if (keep) {
                    num += sq[i] * ses[i] * ses[i];
                    den += ses[i] * ses[i];
                }
            }
            if (den > 0.0) est = num / den;
            if (!changed && it > 0u) break;
        }
        for (uint i = 0u; i < ns; ++i) {
            kept += skept[i] ? 1u : 0u;
            if (!skept[i] && sq[i] < est) ++low;
        }
    }
    uint highlight = ns - kept - low;

    if (kept > 0u) {
        r.status |= kLambertPairHasSample;
        vec3 rho = vec3(0.0);
        bool solved = false;
        if (pc.mode == kLambertModePhotometric) {
            if (kept >= kLsq3MinRows) {
                Lsq3Normal n0 = lsq3_normal_zero();
                Lsq3Normal n1 = lsq3_normal_zero();
                Lsq3Normal n2 = lsq3_normal_zero();
                for (uint i = 0u; i < ns; ++i) {
                    if (!skept[i]) continue;
                    lsq3_accumulate(n0, si[i].x * sa[i], sc[i].x, 1.0);
                    lsq3_accumulate(n1, si[i].y * sa[i], sc[i].y, 1.0);
                    lsq3_accumulate(n2, si[i].z * sa[i], sc[i].z, 1.0);
                }
                Lsq3Solution s0 = lsq3_solve_normal(n0);
                Lsq3Solution s1 = lsq3_solve_normal(n1);
                Lsq3Solution s2 = lsq3_solve_normal(n2);
                bool ok = s0.status == kLsq3Ok && s0.rcond >= pc.min_rcond && s1.status == kLsq3Ok &&
                          s1.rcond >= pc.min_rcond && s2.status == kLsq3Ok && s2.rcond >= pc.min_rcond;
                vec3 sum = s0.g + s1.g + s2.g;
                float len = length(sum);
                if (ok && len > 0.0 && dot(sum, n) > 0.0) {
                    vec3 nr = sum / len;
                    rho = kPi * vec3(length(s0.g), length(s1.g), length(s2.g));
                    r.normal = vec4(nr, lambert_angle_deg(nr, n));
                    r.status |= kLambertPairPhotometric;
                    solved = true;
                }
            }
            if (!solved) r.status |= kLambertPairFallback;
        }
        if (!solved) {
            vec3 num = vec3(0.0), den = vec3(0.0);
            for (uint i = 0u; i < ns; ++i) {
                if (!skept[i]) continue;
                num += sc[i] * se[i];
                den += se[i] * se[i];
            }
            rho.x = den.x > 0.0 ? kPi * num.x / den.x : 0.0;
            rho.y = den.y > 0.0 ? kPi * num.y / den.y : 0.0;
            rho.z = den.z > 0.0 ? kPi * num.z / den.z : 0.0;
        }
        r.albedo.xyz = rho;
    }
    r.counts0 = lambert_pack4(kept, shadow, clipped, missing);
    r.counts1 = lambert_pack4(grazing, highlight, view.frame_count, low);
    results[key.slot] = r;
}
