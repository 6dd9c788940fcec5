#version 450
// lambert_solve, combine step: one invocation per particle of a chunk, over its pairs
// (CSR: pairs [offsets[e], offsets[e + 1]) of the chunk, in view order). Cross-view
// outlier rejection against the lower median, best view and robust mean (shared/lambert.h;
// reference: lambert_combine_cpu in engine/diffuse/lambert_solve_cpu.cpp).
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

layout(std430, set = 0, binding = 0) readonly buffer Offsets { uint offsets[]; };
layout(std430, set = 0, binding = 1) readonly buffer Pairs { LambertPairResult pairs[]; };
layout(std430, set = 0, binding = 2) readonly buffer Particles { ParticleGpu particles[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Results { LambertParticleResult results[]; };

layout(push_constant) uniform PushBlock { LambertCombinePush pc; }; // shared header: one definition for GLSL and C++

float lum(LambertPairResult p) {
    return p.albedo.x + p.albedo.y + p.albedo.z;
}

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint begin = offsets[e];
    uint end = offsets[e + 1u];
    LambertParticleResult r;
    r.albedo_best = vec4(0.0, 0.0, 0.0, -1.0);
    r.albedo_robust = vec4(0.0);
    r.normal = vec4(particles[pc.particle_base + e].normal.xyz, 0.0);
    r.status = 0u;
    r.best_view = kLambertNoView;
    r.views = end - begin;
    r.used = 0u;
    r.rejected_shadow = 0u;
    r.rejected_clipped = 0u;
    r.rejected_missing = 0u;
    r.rejected_grazing = 0u;
    r.rejected_highlight = 0u;
    r.rejected_view = 0u;
    r.rejected_low = 0u;
    r.pad1 = 0u;
    uint with_sample = 0u;
    for (uint i = begin; i < end; ++i) {
        LambertPairResult p = pairs[i];
        r.rejected_shadow += p.shadow;
        r.rejected_clipped += p.clipped;
        r.rejected_missing += p.missing;
        r.rejected_grazing += p.grazing;
        r.rejected_highlight += p.highlight;
        r.rejected_low += p.low;
        if ((p.status & kLambertPairHasSample) != 0u) ++with_sample;
    }
    if (begin == end) {
        r.status = kLambertNotSeen;
    } else if (with_sample == 0u) {
        r.status = kLambertNoSample;
    } else {
        // Lower median of the views' luminance weighted by their used samples (shared/lambert.h):
        // in (luminance, position) order, the view where the cumulative weight reaches half.
        uint total = 0u;
        for (uint i = begin; i < end; ++i)
            if ((pairs[i].status & kLambertPairHasSample) != 0u) total += pairs[i].used;
        float ref = 0.0;
        for (uint i = begin; i < end; ++i) {
            if ((pairs[i].status & kLambertPairHasSample) == 0u) continue;
            float li = lum(pairs[i]);
            uint below = 0u;
            for (uint j = begin; j < end; ++j) {
                if ((pairs[j].status & kLambertPairHasSample) == 0u) continue;
                float lj = lum(pairs[j]);
                if (lj < li || (lj == li && j < i)) below += pairs[j].used;
            }
            uint cum = below + pairs[i].used;
            if (2u * below < total && 2u * cum >= total) ref = li;
        }
        vec3 sum = vec3(0.0);
        float weight = 0.0;
        float best_cos = -2.0;
        uint best = end;
        uint kept_views = 0u;
        for (uint i = begin; i < end; ++i) {
            LambertPairResult p = pairs[i];
            if ((p.status & kLambertPairHasSample) == 0u) continue;
            uint used = p.used;
            if (lambert_view_outlier(lum(p), ref, pc.view_tau, pc.view_abs)) {
                r.rejected_view += used;
                r.status |= kLambertViewsRejected;
                continue;
            }
            ++kept_views;
            r.used += used;
            sum += float(used) * p.albedo.xyz;
            weight += float(used);
            if (p.albedo.w > best_cos) {
                best_cos = p.albedo.w;
                best = i;
            }
        }
        if (best < end) {
            LambertPairResult b = pairs[best];
            r.status |= kLambertOk;
            r.best_view = b.view;
            r.albedo_best = vec4(b.albedo.xyz, float(b.view));
            r.albedo_robust = vec4(sum / weight, float(kept_views));
            r.normal = b.normal;
            if ((b.status & kLambertPairFallback) != 0u) r.status |= kLambertFallback;
        } else {
            r.status |= kLambertNoSample; // cannot happen: ref's own view is kept
        }
    }
    results[e] = r;
}
