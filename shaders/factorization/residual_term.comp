#version 450
// residual_term: terms 2..K of the multi-term factorization F ~ sum_k G_k(h) H_k(d)
// (engine/factorization/residual_term.h). Term k is the rank-1 least-squares fit of the
// residual R_k = F - sum_{j<k} G_j H_j over the valid entries of F (kGshdInvalid skipped),
// found by alternating least squares (power iteration), values of either sign:
//   pass 0, per (d, c):  H_k(d) = sqrt(mean_h R_k(h, d)^2)            (start: column RMS)
//   pass 1, per (h, c):  G_k(h) = sum_d R_k H_k / sum_d H_k^2          (0 when the sum is 0)
//   pass 2, per (d, c):  H_k(d) = sum_h R_k G_k / sum_h G_k^2
// R_k is not stored: each pass recomputes it from F and the earlier terms. G and H hold
// all terms, term-major and rgb-interleaved: g[(k rows + h) 3 + c], hv[(k cols + d) 3 + c]
// (term 0 is the normalized decomposition's, at offset 0). Sums are blocked by
// kGshdSumBlock. Reference: engine/factorization/residual_term_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/gshd.h"
#include "shared/factorization.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer Matrix { float f[]; };
layout(std430, set = 0, binding = 1) buffer GValues { float g[]; };
layout(std430, set = 0, binding = 2) buffer HValues { float hv[]; };

layout(push_constant) uniform PushBlock { ResidualTermPush pc; }; // shared header: one definition for GLSL and C++

// R_term(h, d) for channel c (callers skip the invalid entries of F).
float residual(uint c, uint h, uint d) {
    float r = f[c * pc.rows * pc.cols + h * pc.cols + d];
    for (uint j = 0u; j < pc.term; ++j) r -= g[(j * pc.rows + h) * 3u + c] * hv[(j * pc.cols + d) * 3u + c];
    return r;
}

struct Blocked {
    float total;
    float block;
    float wtotal;
    float wblock;
    uint in_block;
    uint count;
};

void blocked_add(inout Blocked s, float x, float w) {
    ++s.count;
    s.block += x;
    s.wblock += w;
    if (++s.in_block == kGshdSumBlock) {
        s.total += s.block;
        s.wtotal += s.wblock;
        s.block = 0.0f;
        s.wblock = 0.0f;
        s.in_block = 0u;
    }
}

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint c = e % 3u;
    uint i = e / 3u;
    Blocked s = Blocked(0.0f, 0.0f, 0.0f, 0.0f, 0u, 0u);
    if (pc.pass_index == 0u) {
        for (uint h = 0u; h < pc.rows; ++h) {
            if (f[c * pc.rows * pc.cols + h * pc.cols + i] < 0.0f) continue;
            float r = residual(c, h, i);
            blocked_add(s, r * r, 0.0f);
        }
        float total = s.total + s.block;
        hv[(pc.term * pc.cols + i) * 3u + c] = s.count > 0u ? sqrt(total / float(s.count)) : 0.0f;
    } else if (pc.pass_index == 1u) {
        for (uint d = 0u; d < pc.cols; ++d) {
            if (f[c * pc.rows * pc.cols + i * pc.cols + d] < 0.0f) continue;
            float r = residual(c, i, d);
            float x = hv[(pc.term * pc.cols + d) * 3u + c];
            blocked_add(s, r * x, x * x);
        }
        float num = s.total + s.block;
        float den = s.wtotal + s.wblock;
        g[(pc.term * pc.rows + i) * 3u + c] = den > 0.0f ? num / den : 0.0f;
    } else {
        for (uint h = 0u; h < pc.rows; ++h) {
            if (f[c * pc.rows * pc.cols + h * pc.cols + i] < 0.0f) continue;
            float r = residual(c, h, i);
            float x = g[(pc.term * pc.rows + h) * 3u + c];
            blocked_add(s, r * x, x * x);
        }
        float num = s.total + s.block;
        float den = s.wtotal + s.wblock;
        hv[(pc.term * pc.cols + i) * 3u + c] = den > 0.0f ? num / den : 0.0f;
    }
}
