#version 450
// Vertex stage shared by every raster pass (engine/render/renderer.cpp): pulls the
// vertex from a storage buffer by gl_VertexIndex (non-indexed triangle list, so a
// vertex carries its triangle's atlas coordinates) and projects it with the
// capture's pinhole camera (engine/render/projection.h). The specular pass tests its
// depth for EQUALITY with what the diffuse pass wrote: both passes run this very
// module with the same inputs, and the position is `precise` (no fused or reordered
// arithmetic), so the depths agree bit for bit. (`invariant gl_Position` would say
// the same, but glslang emits it as a block-member decoration that Mesa warns about.)
#extension GL_GOOGLE_include_directive : require
#include "shared/render.h"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(std430, set = 0, binding = 1) readonly buffer Vertices { RenderVertex vertices[]; };

layout(location = 0) out vec3 out_world;
layout(location = 1) out vec3 out_normal;
layout(location = 2) out vec2 out_uv;

void main() {
    RenderVertex vtx = vertices[gl_VertexIndex];
    out_world = vtx.position_u.xyz;
    out_normal = vtx.normal_v.xyz;
    out_uv = vec2(vtx.position_u.w, vtx.normal_v.w);
    precise vec4 clip = params.world_to_clip * vec4(vtx.position_u.xyz, 1.0);
    gl_Position = clip;
}
