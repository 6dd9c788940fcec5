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
//   GLSL:  layout(push_constant) uniform Push { SPECULA_DISPATCH_HEADER uint my_field; } pc;
//   C++:   struct MyPush { gpu::DispatchHeader dispatch; uint32_t my_field; };
#ifndef SPECULA_SHARED_DISPATCH_H
#define SPECULA_SHARED_DISPATCH_H
#include "shared/prelude.h"

#ifdef __cplusplus
namespace specula::shared {
struct DispatchHeader {
    uint32_t element_base = 0;
    uint32_t element_count = 0;
};
static_assert(sizeof(DispatchHeader) == 8);
} // namespace specula::shared
#else
#define SPECULA_DISPATCH_HEADER \
    uint element_base;          \
    uint element_count;
#endif

SPECULA_SHARED_BEGIN

const uint kDispatchHeaderBytes = 8u;

SHARED_FN uint dispatch_element(uint element_base, uint invocation) {
    return element_base + invocation;
}

SPECULA_SHARED_END
#endif
