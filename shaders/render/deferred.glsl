// The deferred pass's shading subpass (Settings::passes = Deferred): reads what
// gbuffer.frag stored for this pixel and sums the terms (render/terms.glsl) the frame
// asks for: params.flags.x the diffuse term, params.flags.z the specular term. A pixel
// no triangle covered (normal slot 0) gets colour and alpha 0, as the forward passes
// leave it; a covered one alpha 1 (the coverage).
#ifndef SPECULA_RENDER_DEFERRED_GLSL
#define SPECULA_RENDER_DEFERRED_GLSL
#include "render/terms.glsl"

// The G-buffer as input attachments 0 and 1 at set 0 bindings `first` and `first` + 1.
#define SPECULA_GBUFFER_INPUTS(first, second)                                                      \
    layout(input_attachment_index = 0, set = 0, binding = first) uniform subpassInput gbuffer0; \
    layout(input_attachment_index = 1, set = 0, binding = second) uniform subpassInput gbuffer1;

struct GbufferTexel {
    bool covered;
    vec3 world;
    vec3 n; // unit
    vec2 uv;
};

GbufferTexel gbuffer_texel(vec4 world_u, vec4 normal_v) {
    GbufferTexel t;
    t.covered = normal_v.xyz != vec3(0.0);
    t.world = world_u.xyz;
    t.n = t.covered ? normalize(normal_v.xyz) : vec3(0.0, 0.0, 1.0);
    t.uv = vec2(world_u.w, normal_v.w);
    return t;
}
#endif
