#version 450
// image_metrics, per-pixel pass: one invocation per pixel. Pixels in P (mask != 0, or
// every pixel without a mask) add their terms of the sums of RMS, DDE, L1, L2 and CO
// (thesis eq. 5.1, 5.4-5.6; definitions in engine/metrics/image_metrics.h) to a
// shared-memory tree reduction; invocation 0 writes the workgroup's MetricsPartial and
// the host adds the partials in double. Every pixel also writes its luminance pair
// (Y_A, Y_B) for the SSIM passes. Reference: accumulate_sums in image_metrics_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "metrics/image_metrics_shared.h"

layout(local_size_x_id = 0) in; // the host sets kMetricsGroupSize (the shared arrays below)

layout(std430, set = 0, binding = 0) readonly buffer ImageA { float a[]; };
layout(std430, set = 0, binding = 1) readonly buffer ImageB { float b[]; };
layout(std430, set = 0, binding = 2) readonly buffer Mask { uint mask[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Partials { MetricsPartial partials[]; };
layout(std430, set = 0, binding = 4) writeonly buffer Luma { vec2 luma[]; };

layout(push_constant) uniform PushBlock { MetricsSumsPush pc; }; // shared header: one definition for GLSL and C++

shared vec4 s0[kMetricsGroupSize]; // count, sum_sq, sum_abs, sum_l2
shared vec4 s1[kMetricsGroupSize]; // sum_ab, sum_aa, sum_bb, 0

void main() {
    uint p = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    uint l = gl_LocalInvocationID.x;
    vec4 t0 = vec4(0.0);
    vec4 t1 = vec4(0.0);
    if (p < pc.dispatch.element_count) {
        uint base = p * pc.channels;
        vec3 va = vec3(0.0);
        vec3 vb = vec3(0.0);
        for (uint c = 0u; c < pc.color_channels; ++c) {
            va[c] = a[base + c];
            vb[c] = b[base + c];
        }
        luma[p] = vec2(metrics_luma(va.x, va.y, va.z, pc.color_channels), metrics_luma(vb.x, vb.y, vb.z, pc.color_channels));
        if (pc.has_mask == 0u || mask[p] != 0u) {
            vec3 d = va - vb;
            float sq = dot(d, d);
            t0 = vec4(1.0, sq, abs(d.x) + abs(d.y) + abs(d.z), sqrt(sq));
            t1 = vec4(dot(va, vb), dot(va, va), dot(vb, vb), 0.0);
        }
    }
    s0[l] = t0;
    s1[l] = t1;
    barrier();
    for (uint stride = kMetricsGroupSize / 2u; stride > 0u; stride >>= 1u) {
        if (l < stride) {
            s0[l] += s0[l + stride];
            s1[l] += s1[l + stride];
        }
        barrier();
    }
    if (l == 0u) {
        uint g = pc.dispatch.element_base / kMetricsGroupSize + gl_WorkGroupID.x;
        MetricsPartial o;
        o.count = s0[0].x;
        o.sum_sq = s0[0].y;
        o.sum_abs = s0[0].z;
        o.sum_l2 = s0[0].w;
        o.sum_ab = s1[0].x;
        o.sum_aa = s1[0].y;
        o.sum_bb = s1[0].z;
        o.reserved = 0.0;
        partials[g] = o;
    }
}
