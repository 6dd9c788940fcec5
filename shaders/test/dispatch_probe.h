// Push constants of the GPU layer's probe kernel (test/dispatch_probe.comp; tests/gpu/gpu_test.cpp).
#ifndef SPECULA_TEST_DISPATCH_PROBE_H
#define SPECULA_TEST_DISPATCH_PROBE_H
#include "shared/prelude.h"
#include "shared/dispatch.h"

SPECULA_SHARED_BEGIN

struct ProbePush {
    DispatchHeader dispatch;
    uint tag;
    uint pad;
};

SPECULA_SHARED_END

#ifdef __cplusplus
static_assert(sizeof(specula::shared::ProbePush) == 16);
#endif

#endif
