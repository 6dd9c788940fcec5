#version 450
// cubemaps (thesis appendix A, Algorithm 2): one invocation per cube-map texel
// (e = (face * res + row) * res + col, Vulkan face order, shared/gshd.h): texels whose
// centre direction is below the horizon are 0 but for the horizon gutter (shared/gshd.h
// cube_texel_kept), the others the bilinear interpolation of the hemisphere grid (G or H,
// rgb-interleaved) at that direction (the gutter: at the horizon point of its azimuth).
// Reference: engine/factorization/cubemaps_cpu.cpp.
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "shared/gshd.h"
#include "shared/factorization.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) readonly buffer Grid { float grid[]; };
layout(std430, set = 0, binding = 1) writeonly buffer Cube { float cube[]; };

layout(push_constant) uniform PushBlock { CubemapPush pc; }; // shared header: one definition for GLSL and C++

vec3 fetch(uint i) { return vec3(grid[3u * i], grid[3u * i + 1u], grid[3u * i + 2u]); }

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    uint face_texels = pc.cube_res * pc.cube_res;
    uint face = e / face_texels;
    uint rem = e - face * face_texels;
    uint row = rem / pc.cube_res;
    uint col = rem - row * pc.cube_res;
    vec3 dir = cube_texel_dir(face, col, row, pc.cube_res);
    vec3 value = vec3(0.0f);
    if (cube_texel_kept(dir, pc.cube_res)) {
        GshdBilinear b = gshd_grid_bilinear(dir, pc.grid_res);
        value = gshd_bilinear_mix(b, fetch(b.i00), fetch(b.i10), fetch(b.i01), fetch(b.i11));
    }
    cube[3u * e] = value.x;
    cube[3u * e + 1u] = value.y;
    cube[3u * e + 2u] = value.z;
}
