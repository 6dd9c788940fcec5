#version 450
// image_metrics, directed Hausdorff pass h(X, Y) (thesis eq. 5.2; d and the search are
// defined in engine/metrics/image_metrics.h): one invocation per pixel p of X in P finds
// min over q in P of d(X_p, Y_q)^2 by Chebyshev rings around p, stopping once the ring
// is farther (delta k) than the best so far, up to max_radius rings. A shared-memory
// reduction gives each workgroup's max d^2 and whether any pixel hit the ring cap;
// the host takes the max over workgroups and over both directions (eq. 5.3).
// Reference: directed_hausdorff_d2 in engine/metrics/image_metrics_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "metrics/image_metrics_shared.h"

layout(local_size_x_id = 0) in; // kMetricsGroupSize

layout(std430, set = 0, binding = 0) readonly buffer ImageX { float xs[]; };
layout(std430, set = 0, binding = 1) readonly buffer ImageY { float ys[]; };
layout(std430, set = 0, binding = 2) readonly buffer Mask { uint mask[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Partials { vec2 partials[]; }; // max d^2, capped (0/1)

layout(push_constant) uniform PushBlock { HausdorffPush pc; }; // shared header: one definition for GLSL and C++

shared vec2 s[kMetricsGroupSize];

vec3 x_value;
float best;
int px;
int py;

void visit(int qx, int qy) {
    if (qx < 0 || qy < 0 || qx >= int(pc.width) || qy >= int(pc.height)) return;
    uint q = uint(qy) * pc.width + uint(qx);
    if (pc.has_mask != 0u && mask[q] == 0u) return;
    float c2 = 0.0;
    for (uint c = 0u; c < pc.color_channels; ++c) {
        float d = x_value[c] - ys[q * pc.channels + c];
        c2 += d * d;
    }
    best = min(best, hausdorff_d2(qx - px, qy - py, pc.delta, c2));
}

void main() {
    uint p = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    uint l = gl_LocalInvocationID.x;
    vec2 t = vec2(0.0);
    if (p < pc.dispatch.element_count && (pc.has_mask == 0u || mask[p] != 0u)) {
        py = int(p / pc.width);
        px = int(p - uint(py) * pc.width);
        x_value = vec3(0.0);
        for (uint c = 0u; c < pc.color_channels; ++c) x_value[c] = xs[p * pc.channels + c];
        best = 3.0e38;
        visit(px, py); // q = p is in P
        int k = 1;
        for (; k <= pc.max_radius; ++k) {
            if (hausdorff_d2(k, 0, pc.delta, 0.0) >= best) break;
            for (int dx = -k; dx <= k; ++dx) {
                visit(px + dx, py - k);
                visit(px + dx, py + k);
            }
            for (int dy = -k + 1; dy <= k - 1; ++dy) {
                visit(px - k, py + dy);
                visit(px + k, py + dy);
            }
        }
        bool capped = k > pc.max_radius && hausdorff_d2(pc.max_radius + 1, 0, pc.delta, 0.0) < best;
        t = vec2(best, capped ? 1.0 : 0.0);
    }
    s[l] = t;
    barrier();
    for (uint stride = kMetricsGroupSize / 2u; stride > 0u; stride >>= 1u) {
        if (l < stride) s[l] = max(s[l], s[l + stride]);
        barrier();
    }
    if (l == 0u) partials[pc.dispatch.element_base / kMetricsGroupSize + gl_WorkGroupID.x] = s[0];
}
