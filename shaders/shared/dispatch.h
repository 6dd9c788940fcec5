// Push-constant convention of 1D element kernels, split by gpu::Sequence::dispatch_1d
// when `count` needs more workgroups than maxComputeWorkGroupCount[0] allows (65,535 on
// lavapipe: 4,194,240 elements at 64 per group):
//
//   bytes 0..3   uint element_base    first element of this split  (written by dispatch_1d)
//   bytes 4..7   uint element_count   elements of the whole logical dispatch (written by dispatch_1d)
//   bytes 8..    the kernel's own fields, std430 push-constant layout (align a vec4 at 16)
//
// The kernel's element index is dispatch_element(element_base, gl_GlobalInvocationID.x);
// invocations with an index >= element_count return at once. Every split sees the same
// buffers at the same offsets: index buffers by the element index, not by the invocation.
// A kernel's push constants are one struct, defined once in a shared header that both
// glslang and the C++ compiler read (with static_asserted offsets), starting with the header:
//   shared header: struct MyPush { DispatchHeader dispatch; uint my_field; };
//   GLSL:          layout(push_constant) uniform PushBlock { MyPush pc; };  ... pc.my_field
//   C++:           seq.dispatch_1d(pipeline, buffers, count, shared::MyPush{.my_field = 1});
// (push-constant blocks use the std430 layout, so C++ and GLSL offsets agree where the
// static_asserts say so.)
#ifndef SPECULA_SHARED_DISPATCH_H
#define SPECULA_SHARED_DISPATCH_H
#include "shared/prelude.h"

SPECULA_SHARED_BEGIN

struct DispatchHeader {
    uint element_base;
    uint element_count;
};

const uint kDispatchHeaderBytes = 8u;

SHARED_FN uint dispatch_element(uint element_base, uint invocation) {
    return element_base + invocation;
}

SPECULA_SHARED_END

#ifdef __cplusplus
static_assert(sizeof(specula::shared::DispatchHeader) == 8);
#endif

#endif
