#version 450
// lsq3_solve: one invocation per element solves its weighted 3x3 least squares
// (math, thresholds and statuses: shared/solve3.h). Rows are in CSR form: element e
// owns rows [row_offsets[e], row_offsets[e + 1]) - row_base, so the host can bind
// one chunk of a larger problem at a time (row_base = row_offsets[first element]).
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/solve3.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer RowOffsets { uint row_offsets[]; };
layout(std430, set = 0, binding = 1) readonly buffer Rows { Lsq3Row rows[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Results { Lsq3Result results[]; };

layout(push_constant) uniform Push {
    DispatchHeader dispatch;
    uint row_base;
} pc;

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint begin = row_offsets[e] - pc.row_base;
    uint end = row_offsets[e + 1u] - pc.row_base;

    Lsq3Normal n = lsq3_normal_zero();
    for (uint i = begin; i < end; ++i) {
        Lsq3Row r = rows[i];
        lsq3_accumulate(n, vec3(r.a_x, r.a_y, r.a_z), r.b, r.w);
    }
    Lsq3Solution s = lsq3_solve_normal(n);
    float rss = 0.0f;
    if (s.status == kLsq3Ok) {
        for (uint i = begin; i < end; ++i) {
            Lsq3Row r = rows[i];
            rss += lsq3_residual_term(vec3(r.a_x, r.a_y, r.a_z), r.b, r.w, s.g);
        }
    }
    Lsq3Result o;
    o.g_x = s.g.x;
    o.g_y = s.g.y;
    o.g_z = s.g.z;
    o.rcond = s.rcond;
    o.rss = rss;
    o.status = s.status;
    o.rows = n.rows;
    o.reserved = 0u;
    results[e] = o;
}
