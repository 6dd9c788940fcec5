#version 450
// Probe for the GPU layer's tests: out[e] = probe_value(e, tag) for every element of
// a 1D dispatch, so a split dispatch can be checked element by element (a missed or
// doubled split shows up as a wrong or missing value).
#extension GL_GOOGLE_include_directive : require
#include "shared/dispatch.h"
#include "test/dispatch_probe.h"

layout(local_size_x_id = 0) in;

layout(std430, set = 0, binding = 0) buffer Out { uint values[]; };

layout(push_constant) uniform PushBlock { ProbePush pc; }; // shared header: one definition for GLSL and C++

void main() {
    uint e = dispatch_element(pc.dispatch.element_base, gl_GlobalInvocationID.x);
    if (e >= pc.dispatch.element_count) return;
    values[e] = e * 2654435761u + pc.tag; // Knuth's multiplicative hash: distinct per element
}
