#version 450
// Deferred pass, subpass 0 (Settings::passes = Deferred): stores the interpolated
// inputs, exactly as the forward passes receive them (render/varyings.glsl), in the two
// G-buffer images; subpass 1 (deferred_*.frag) shades every pixel once from them. On
// lavapipe a mesh of pixel-sized triangles runs the fragment shader on a 4x4 block per
// triangle, so shading per triangle costs many times shading per pixel.
// The normal slot stays 0 (the clear) where no triangle is drawn: that is the coverage.
#extension GL_GOOGLE_include_directive : require
#include "render/varyings.glsl"

layout(location = 0) out vec4 out_world_u;
layout(location = 1) out vec4 out_normal_v;

void main() {
    out_world_u = in_world_u;
    out_normal_v = in_normal_v;
}
