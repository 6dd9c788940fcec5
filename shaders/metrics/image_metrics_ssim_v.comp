#version 450
// image_metrics, SSIM vertical pass: one invocation per pixel filters the horizontal
// moments along the column (same truncated, renormalised Gaussian), evaluates the SSIM
// index (Wang et al. 2004, eq. 13: ssim_index in image_metrics_shared.h) and adds it,
// for pixels in P, to a shared-memory reduction: one vec2 (sum, count) per workgroup,
// added on the host in double. Reference: ssim_sum in engine/metrics/image_metrics_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "metrics/image_metrics_shared.h"

layout(local_size_x_id = 0) in; // kMetricsGroupSize

layout(std430, set = 0, binding = 0) readonly buffer Moments { SsimMoments moments[]; };
layout(std430, set = 0, binding = 1) readonly buffer Mask { uint mask[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Partials { vec2 partials[]; };

layout(push_constant) uniform PushBlock { SsimVPush pc; }; // shared header: one definition for GLSL and C++

shared vec2 s[kMetricsGroupSize];

void main() {
    uint p = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    uint l = gl_LocalInvocationID.x;
    vec2 t = vec2(0.0);
    if (p < pc.dispatch.element_count && (pc.has_mask == 0u || mask[p] != 0u)) {
        int y = int(p / pc.width);
        uint x = p - uint(y) * pc.width;
        float wsum = 0.0;
        float mu_a = 0.0, mu_b = 0.0, aa = 0.0, bb = 0.0, ab = 0.0;
        for (int d = -kSsimRadius; d <= kSsimRadius; ++d) {
            int yy = y + d;
            if (yy < 0 || yy >= int(pc.height)) continue;
            float w = ssim_gauss_tap(d);
            SsimMoments m = moments[uint(yy) * pc.width + x];
            wsum += w;
            mu_a += w * m.mu_a;
            mu_b += w * m.mu_b;
            aa += w * m.aa;
            bb += w * m.bb;
            ab += w * m.ab;
        }
        t = vec2(ssim_index(mu_a / wsum, mu_b / wsum, aa / wsum, bb / wsum, ab / wsum, pc.c1, pc.c2), 1.0);
    }
    s[l] = t;
    barrier();
    for (uint stride = kMetricsGroupSize / 2u; stride > 0u; stride >>= 1u) {
        if (l < stride) s[l] += s[l + stride];
        barrier();
    }
    if (l == 0u) partials[pc.dispatch.element_base / kMetricsGroupSize + gl_WorkGroupID.x] = s[0];
}
