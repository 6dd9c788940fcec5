#version 450
// The shadow map's depth pass (engine/render/renderer.cpp): the mesh seen from the point
// light through params.light_to_clip, depth only (no fragment shader). Both sides are
// drawn (open meshes cast shadows from either side); the lit passes look the map up in
// render/terms.glsl light_visibility.
#extension GL_GOOGLE_include_directive : require
#include "shared/render.h"

layout(std430, set = 0, binding = 0) readonly buffer Params { RenderParams params; };
layout(location = 0) in vec4 in_position_u; // RenderVertex, vertex input binding 0

void main() {
    gl_Position = params.light_to_clip * vec4(in_position_u.xyz, 1.0);
}
