#version 450
// image_metrics, SSIM horizontal pass: one invocation per pixel filters the luminance
// pairs along the row with the 1D Gaussian (11 taps, sigma 1.5), truncated at the image
// border and renormalised, giving mu_A, mu_B, E[Y_A^2], E[Y_B^2], E[Y_A Y_B] for the
// vertical pass (Wang et al. 2004; the window is separable: image_metrics_shared.h).
// Reference: ssim_sum in engine/metrics/image_metrics_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "metrics/image_metrics_shared.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer Luma { vec2 luma[]; };
layout(std430, set = 0, binding = 1) writeonly buffer Moments { SsimMoments moments[]; };

layout(push_constant) uniform PushBlock { SsimHPush pc; }; // shared header: one definition for GLSL and C++

void main() {
    uint p = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (p >= pc.dispatch.element_count) return;
    int x = int(p % pc.width);
    uint row = p - uint(x);
    float wsum = 0.0;
    float mu_a = 0.0, mu_b = 0.0, aa = 0.0, bb = 0.0, ab = 0.0;
    for (int d = -kSsimRadius; d <= kSsimRadius; ++d) {
        int xx = x + d;
        if (xx < 0 || xx >= int(pc.width)) continue;
        float t = ssim_gauss_tap(d);
        vec2 y = luma[row + uint(xx)];
        wsum += t;
        mu_a += t * y.x;
        mu_b += t * y.y;
        aa += t * y.x * y.x;
        bb += t * y.y * y.y;
        ab += t * y.x * y.y;
    }
    SsimMoments m;
    m.mu_a = mu_a / wsum;
    m.mu_b = mu_b / wsum;
    m.aa = aa / wsum;
    m.bb = bb / wsum;
    m.ab = ab / wsum;
    moments[p] = m;
}
