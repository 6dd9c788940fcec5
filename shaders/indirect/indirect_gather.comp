#version 450
// The indirect-light gather (engine/indirect/transfer.h; layouts in shared/indirect.h): one
// invocation per row of a chunk, looping over the batch's frames 8 at a time, so that each
// entry is read once per 8 frames; the frames left over (fewer than 8) go one at a time.
//     out[f * rows + i] = (sum over row i's entries of weight * radiosity[f * sources + source].xyz, 0)
// in float, in entry order. Reference: engine/indirect/transfer.cpp (gather_indirect_cpu).
// Why this shape (bench/indirect_bench, lavapipe on 2 threads, 200k rows of 32 entries, the
// best of the interleaved runs' dispatch times): 16 frames take 438 ms here, 592 ms with one
// invocation per (frame, row) (neighbouring invocations on neighbouring rows), 858 ms with one
// per (row, frame) (neighbouring invocations on the frames of one row), 479 ms with passes of
// 4 frames; one frame takes the same ~41 ms as one invocation per (frame, row).
#extension GL_GOOGLE_include_directive : require
#include "shared/indirect.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer RowBegin { uint row_begin[]; };     // the chunk's rows + 1 offsets (global)
layout(std430, set = 0, binding = 1) readonly buffer Entries { IndirectEntry entries[]; }; // the chunk's entries
layout(std430, set = 0, binding = 2) readonly buffer Radiosity { vec4 radiosity[]; };     // frames x sources, rgb
layout(std430, set = 0, binding = 3) writeonly buffer Gathered { vec4 gathered[]; };      // frames x rows

layout(push_constant) uniform PushBlock { IndirectGatherPush pc; };

void main() {
    uint row = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (row >= pc.dispatch.element_count) return;
    uint begin = row_begin[row] - pc.entry_base;
    uint end = row_begin[row + 1u] - pc.entry_base;
    uint stride = pc.sources;
    uint f = 0u;
    for (; f + 8u <= pc.frames; f += 8u) {
        vec3 s0 = vec3(0.0f), s1 = vec3(0.0f), s2 = vec3(0.0f), s3 = vec3(0.0f);
        vec3 s4 = vec3(0.0f), s5 = vec3(0.0f), s6 = vec3(0.0f), s7 = vec3(0.0f);
        for (uint k = begin; k < end; ++k) {
            uint j = f * stride + entries[k].source;
            float w = entries[k].weight;
            s0 += w * radiosity[j].xyz;
            s1 += w * radiosity[j + stride].xyz;
            s2 += w * radiosity[j + 2u * stride].xyz;
            s3 += w * radiosity[j + 3u * stride].xyz;
            s4 += w * radiosity[j + 4u * stride].xyz;
            s5 += w * radiosity[j + 5u * stride].xyz;
            s6 += w * radiosity[j + 6u * stride].xyz;
            s7 += w * radiosity[j + 7u * stride].xyz;
        }
        uint o = f * pc.rows + row;
        gathered[o] = vec4(s0, 0.0f);
        gathered[o + pc.rows] = vec4(s1, 0.0f);
        gathered[o + 2u * pc.rows] = vec4(s2, 0.0f);
        gathered[o + 3u * pc.rows] = vec4(s3, 0.0f);
        gathered[o + 4u * pc.rows] = vec4(s4, 0.0f);
        gathered[o + 5u * pc.rows] = vec4(s5, 0.0f);
        gathered[o + 6u * pc.rows] = vec4(s6, 0.0f);
        gathered[o + 7u * pc.rows] = vec4(s7, 0.0f);
    }
    for (; f < pc.frames; ++f) {
        vec3 s = vec3(0.0f);
        for (uint k = begin; k < end; ++k) s += entries[k].weight * radiosity[f * stride + entries[k].source].xyz;
        gathered[f * pc.rows + row] = vec4(s, 0.0f);
    }
}
