#version 450
// One triangle over the whole target (vertices 0..2 of a non-indexed draw, no inputs):
// the deferred pass's shading subpass runs its fragment shader once per pixel.
void main() {
    const vec2 p = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2)); // (0,0) (2,0) (0,2)
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
