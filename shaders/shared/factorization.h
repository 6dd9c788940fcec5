// Push constants of the factorization kernels (shaders/factorization/*.comp; pipeline.md
// section 6, thesis appendix A), read by glslang and by the C++ compiler
// (engine/factorization/*_vk.cpp): one definition, offsets checked below.
#ifndef SPECULA_SHARED_FACTORIZATION_H
#define SPECULA_SHARED_FACTORIZATION_H
#include "shared/prelude.h"
#include "shared/dispatch.h"
#include "shared/material.h"

SPECULA_SHARED_BEGIN

// brdf_matrix.comp: the specular model sampled as F[h, d].
struct BrdfMatrixPush {
    DispatchHeader dispatch;
    uint res_h;
    uint res_d;
    MaterialGpu material; // any family (shared/material.h); kGshdWarped: the lafortune family's Cx, Cz, N in a, b, c
    uint param; // kGshdPlain, kGshdMirrored or kGshdWarped (shared/gshd.h)
    float warp_s;
    float warp_k[3]; // per channel
    float weight_q;  // entries times (h.z d.z)^weight_q (0: none; engine/factorization/brdf_matrix.h)
};

// normalized_decomposition.comp: G (pass 0), then H (pass 1).
struct DecompositionPush {
    DispatchHeader dispatch;
    uint rows;
    uint cols;
    uint pass_index; // 0: G, 1: H
    float p;
    uint weighting;  // factorization::DecompositionWeighting
};

// residual_term.comp: one further separable term by alternating least squares.
struct ResidualTermPush {
    DispatchHeader dispatch;
    uint rows;
    uint cols;
    uint term;
    uint pass_index; // 0: H start (column RMS), 1: G from H, 2: H from G
};

// cubemaps.comp: a hemisphere grid resampled into a cube-map.
struct CubemapPush {
    DispatchHeader dispatch;
    uint grid_res;
    uint cube_res;
};

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::BrdfMatrixPush) == 104 && offsetof(specula::shared::BrdfMatrixPush, material) == 16 &&
              offsetof(specula::shared::BrdfMatrixPush, param) == 80 && offsetof(specula::shared::BrdfMatrixPush, warp_k) == 88 &&
              offsetof(specula::shared::BrdfMatrixPush, weight_q) == 100);
static_assert(sizeof(specula::shared::DecompositionPush) == 28 && offsetof(specula::shared::DecompositionPush, weighting) == 24);
static_assert(sizeof(specula::shared::ResidualTermPush) == 24);
static_assert(sizeof(specula::shared::CubemapPush) == 16);
#endif

#endif
