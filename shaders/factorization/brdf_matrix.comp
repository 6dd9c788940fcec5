#version 450
// brdf_matrix: one invocation per entry F[h, d] of the sampled specular model (thesis appendix
// A, step 1; math: shared/gshd.h; the model, any family: shared/material.h material_specular). Rows are the cells of the h grid (res_h x res_h),
// columns the cells of the d grid (res_d x res_d); element e = row * cols + col.
// Output is channel-planar: f[c * rows * cols + e]. Entries whose (u, v) leaves the upper
// hemisphere are kGshdInvalid; values are flushed below kGshdMinValue and clamped at
// kGshdMaxValue. pc.param picks the parametrization (shared/gshd.h parts 4 and 5: kGshdPlain,
// the thesis's GSHD, kGshdMirrored, or kGshdWarped with channel c's warp (warp_s, warp_k[c]),
// whose F is the Lafortune lobe over its radial factor, lafortune family only; the validity test
// is per channel there). pc.weight_q != 0: valid entries are the model times (h.z d.z)^weight_q
// (the separable weight of a weighted least-squares factorization, brdf_matrix.h), clamped after.
// Reference: engine/factorization/brdf_matrix_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/gshd.h"
#include "shared/lafortune.h"
#include "shared/material.h"
#include "shared/factorization.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) writeonly buffer Matrix { float f[]; };

layout(push_constant) uniform PushBlock { BrdfMatrixPush pc; }; // shared header: one definition for GLSL and C++


void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint cols = pc.res_d * pc.res_d;
    uint row = e / cols;
    uint col = e - row * cols;
    vec3 h = gshd_grid_dir(row, pc.res_h);
    vec3 d = gshd_grid_dir(col, pc.res_d);
    vec3 value = vec3(kGshdInvalid);
    float weight = pc.weight_q != 0.0 ? pow(h.z * d.z, pc.weight_q) : 1.0; // cell centres have z > 0
    if (pc.param == kGshdWarped) { // each channel's pair in its own warp
        for (uint c = 0u; c < 3u; ++c) {
            GshdPair p = gshd_to_uv_warped(h, d, pc.param, vec2(pc.warp_s, pc.warp_k[c]));
            if (p.u.z > kGshdMinCos && p.v.z > kGshdMinCos)
                value[c] = gshd_clamp_value(vec3(lafortune_normalized(pc.material.a[c], pc.material.b[c], pc.material.c[c],
                                                                      p.u, p.v) * weight)).x;
        }
    } else {
        GshdPair p = gshd_to_uv_param(h, d, pc.param);
        if (p.u.z > kGshdMinCos && p.v.z > kGshdMinCos)
            value = gshd_clamp_value(material_specular(pc.material, p.u.z, p.v.z, dot(p.u, p.v)) * weight);
    }
    uint plane = pc.dispatch.element_count;
    f[e] = value.x;
    f[plane + e] = value.y;
    f[2u * plane + e] = value.z;
}
