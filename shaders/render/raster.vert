#version 450
// Vertex stage shared by every raster pass (engine/render/renderer.cpp): takes the
// vertex from vertex input binding 0 (shared::RenderVertex; a non-indexed triangle
// list, so a vertex carries its triangle's atlas coordinates; fixed-function fetch is
// cheaper than pulling from a storage buffer on lavapipe's one-thread vertex stage),
// passes it on in two interpolated slots (render/varyings.glsl) and projects it with the
// capture's pinhole camera (engine/render/projection.h). The specular pass tests its
// depth for EQUALITY with what the diffuse pass wrote: both passes run this very
// module with the same inputs, and the position is `precise` (no fused or reordered
// arithmetic), so the depths agree bit for bit. (`invariant gl_Position` would say
// the same, but glslang emits it as a block-member decoration that Mesa warns about.)
#extension GL_GOOGLE_include_directive : require
#include "shared/render.h"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(location = 0) in vec4 in_position_u; // RenderVertex, vertex input binding 0
layout(location = 1) in vec4 in_normal_v;

layout(location = 0) out vec4 out_world_u; // render/varyings.glsl
layout(location = 1) out vec4 out_normal_v;

void main() {
    out_world_u = in_position_u;
    out_normal_v = in_normal_v;
    precise vec4 clip = params.world_to_clip * vec4(in_position_u.xyz, 1.0);
    gl_Position = clip;
}
