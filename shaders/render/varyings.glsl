// The raster passes' interpolated inputs (written by raster.vert): two vec4 slots,
// the atlas coordinates riding in the w components. Every interpolated slot costs
// lavapipe per-triangle setup work on its single-threaded front end, and 2 slots
// draw measurably faster than 3 (world, normal, uv) on meshes of many small triangles.
#ifndef SPECULA_RENDER_VARYINGS_GLSL
#define SPECULA_RENDER_VARYINGS_GLSL
layout(location = 0) in vec4 in_world_u;
layout(location = 1) in vec4 in_normal_v;
#define in_world (in_world_u.xyz)
#define in_normal (in_normal_v.xyz)
#define in_uv (vec2(in_world_u.w, in_normal_v.w))
#endif
