#version 450
// The directed lobe's first bounce (engine/indirect/lobe.h; layouts in shared/indirect.h): one
// invocation per row of a chunk, looping over the batch's frames kBlock at a time, so that each
// entry (source, weight, direction, the source's normal) is read once per kBlock frames; the
// frames left over (fewer than kBlock) go one at a time.
//     out[f * rows + i] += (sum over row i's entries k of
//                           (pi w_k g) max(material_specular(m, N_j.u, v_k.w, u.v_k), 0) I_f, 0)
// in float, each frame's terms summed from 0 in entry order and then added to out, as the C++
// float path (add_directed_lobe_float); reference: engine/indirect/lobe.cpp (add_directed_lobe_cpu).
// Why this shape: as the gather (indirect_gather.comp), one invocation per row keeps a row's
// entries in one invocation's loop. bench/indirect_bench, lavapipe on 2 threads, 200k rows of
// 32 entries, 16 frames, the Lafortune lobe, the dispatch time: blocks of 8 frames 765-770 ms,
// of 4 805 ms, of 16 806 ms, one frame at a time 1089 ms (the coating: 716-726, 755-761, 752,
// 1039 ms).
#extension GL_GOOGLE_include_directive : require
#include "shared/indirect.h"

layout(local_size_x_id = 0) in;

// Bindings: the chunk's rows + 1 offsets (global), its entries and their directions (v in xyz,
// N_j.v in w); per source, its mean unit normal (xyz); sources x frames of the batch, the
// direction toward the light (xyz) and the geometry factor (w); per frame, the intensity (rgb);
// frames x rows of the chunk, what the term is added to.
layout(std430, set = 0, binding = 0) readonly buffer RowBegin { uint row_begin[]; };
layout(std430, set = 0, binding = 1) readonly buffer Entries { IndirectEntry entries[]; };
layout(std430, set = 0, binding = 2) readonly buffer Directions { vec4 directions[]; };
layout(std430, set = 0, binding = 3) readonly buffer Normals { vec4 normals[]; };
layout(std430, set = 0, binding = 4) readonly buffer Light { vec4 light[]; };
layout(std430, set = 0, binding = 5) readonly buffer Intensity { vec4 intensity[]; };
layout(std430, set = 0, binding = 6) buffer Added { vec4 added[]; };

layout(push_constant) uniform PushBlock { IndirectLobePush pc; };

const uint kBlock = 8u;

// One term: the light of frame f that source j (normal n) sends along entry direction v, times
// the entry's pi w; 0 where the source is unlit or the light is behind it.
vec3 lobe_term(vec3 n, vec4 v, float w, vec4 l, vec3 i) {
    if (!(l.w > 0.0f)) return vec3(0.0f);
    vec3 u = l.xyz;
    float ci = dot(n, u);
    if (!(ci > 0.0f)) return vec3(0.0f);
    vec3 fs = material_specular(pc.material, ci, v.w, dot(u, v.xyz));
    return (w * l.w) * max(fs, vec3(0.0f)) * i;
}

void main() {
    uint row = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (row >= pc.dispatch.element_count) return;
    uint begin = row_begin[row] - pc.entry_base;
    uint end = row_begin[row + 1u] - pc.entry_base;
    uint f = 0u;
    for (; f + kBlock <= pc.frames; f += kBlock) {
        vec3 s[kBlock];
        vec3 i[kBlock];
        for (uint q = 0u; q < kBlock; ++q) {
            s[q] = vec3(0.0f);
            i[q] = intensity[f + q].xyz;
        }
        for (uint k = begin; k < end; ++k) {
            vec4 v = directions[k];
            if (!(v.w > 0.0f)) continue; // leaves the source from under its surface
            uint j = entries[k].source;
            float w = kPi * entries[k].weight;
            vec3 n = normals[j].xyz;
            uint l = j * pc.frames + f;
            for (uint q = 0u; q < kBlock; ++q) s[q] += lobe_term(n, v, w, light[l + q], i[q]);
        }
        for (uint q = 0u; q < kBlock; ++q) added[(f + q) * pc.rows + row] += vec4(s[q], 0.0f);
    }
    for (; f < pc.frames; ++f) {
        vec3 s = vec3(0.0f);
        vec3 i = intensity[f].xyz;
        for (uint k = begin; k < end; ++k) {
            vec4 v = directions[k];
            if (!(v.w > 0.0f)) continue;
            uint j = entries[k].source;
            s += lobe_term(normals[j].xyz, v, kPi * entries[k].weight, light[j * pc.frames + f], i);
        }
        added[f * pc.rows + row] += vec4(s, 0.0f);
    }
}
