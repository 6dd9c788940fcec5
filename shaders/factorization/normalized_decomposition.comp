#version 450
// normalized_decomposition (thesis eq. A.3; Kautz and McCool 1999, section 4): from the
// channel-planar matrix F (brdf_matrix.comp), per channel
//   pass 0, one invocation per (h, c):  G(h) = m (mean_d (|F(h, d)| / m)^p)^(1/p),
//           m = max_d |F(h, d)| (scaling keeps |F|^p finite); G = 0 when m < kGshdMinValue
//   pass 1, one invocation per (d, c):  H(d) = mean_h F(h, d) / G(h) over rows with G > 0
//           (weighting 0, eq. A.3), or with weights G(h)^2 (weighting 1, "energy"):
//           H(d) = sum_h G F / sum_h G^2, computed with w = G / G_max so nothing overflows:
//           H = sum w (F / G_max) / sum w^2
// Means run over valid entries only (kGshdInvalid skipped). Sums are blocked by
// kGshdSumBlock (error bound in shared/gshd.h). G and H are rgb-interleaved: g[3 h + c].
// Reference: engine/factorization/normalized_decomposition_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/gshd.h"
#include "shared/factorization.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer Matrix { float f[]; };
layout(std430, set = 0, binding = 1) buffer GValues { float g[]; };
layout(std430, set = 0, binding = 2) writeonly buffer HValues { float hv[]; };

layout(push_constant) uniform PushBlock { DecompositionPush pc; }; // shared header: one definition for GLSL and C++

float power_term(float x) {
    if (pc.p == 2.0f) return x * x;
    if (pc.p == 1.0f) return x;
    return pow(x, pc.p);
}

float power_root(float x) {
    if (pc.p == 2.0f) return sqrt(x);
    if (pc.p == 1.0f) return x;
    return pow(x, 1.0f / pc.p);
}

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint c = e % 3u;
    uint plane = c * pc.rows * pc.cols;
    float total = 0.0f;
    float block = 0.0f;
    uint in_block = 0u;
    uint count = 0u;
    if (pc.pass_index == 0u) {
        uint base = plane + (e / 3u) * pc.cols;
        float m = 0.0f;
        for (uint d = 0u; d < pc.cols; ++d) m = max(m, f[base + d]);
        if (m < kGshdMinValue) {
            g[e] = 0.0f;
            return;
        }
        for (uint d = 0u; d < pc.cols; ++d) {
            float v = f[base + d];
            if (v < 0.0f) continue;
            ++count;
            block += power_term(v / m);
            if (++in_block == kGshdSumBlock) {
                total += block;
                block = 0.0f;
                in_block = 0u;
            }
        }
        total += block;
        g[e] = m * power_root(total / float(count));
    } else {
        uint col = e / 3u;
        float gmax = 0.0f;
        if (pc.weighting == 1u) {
            for (uint h = 0u; h < pc.rows; ++h) gmax = max(gmax, g[3u * h + c]);
        }
        float wtotal = 0.0f;
        float wblock = 0.0f;
        for (uint h = 0u; h < pc.rows; ++h) {
            float gv = g[3u * h + c];
            float v = f[plane + h * pc.cols + col];
            if (v < 0.0f || gv <= 0.0f) continue;
            ++count;
            if (pc.weighting == 1u) {
                float w = gv / gmax;
                block += w * (v / gmax);
                wblock += w * w;
            } else {
                block += v / gv;
            }
            if (++in_block == kGshdSumBlock) {
                total += block;
                wtotal += wblock;
                block = 0.0f;
                wblock = 0.0f;
                in_block = 0u;
            }
        }
        total += block;
        wtotal += wblock;
        if (pc.weighting == 1u) hv[e] = wtotal > 0.0f ? total / wtotal : 0.0f;
        else hv[e] = count > 0u ? total / float(count) : 0.0f;
    }
}
