// The indirect-light gather (engine/indirect/transfer.h) and the directed lobe's first bounce
// (engine/indirect/lobe.h): the layouts that shaders/indirect/indirect_gather.comp and
// engine/indirect/transfer_vk.cpp, and shaders/indirect/indirect_lobe.comp and
// engine/indirect/lobe_vk.cpp, share.
//
// Per frame f of a batch and row i of a chunk of the transfer matrix T:
//     out[f * rows + i] = (sum over row i's entries k of weight_k * radiosity[f * sources + source_k].xyz, 0)
// accumulated in float, in entry order (the C++ reference accumulates the same terms in double).
//
// Splitting (no binding may exceed maxStorageBufferRange, 128 MiB on lavapipe): the host cuts
// the rows into chunks whose entries fit one binding and the frames into batches whose
// radiosity (every source of each frame: a row may reach any particle) fits one binding; one
// dispatch per (chunk, batch). A chunk's row offsets are uploaded as they are (global entry
// indices) and entry_base, the chunk's first entry, is subtracted in the kernel.
//
// The directed lobe (model in lobe.h), per frame f of a batch and row i of a chunk:
//     out[f * rows + i] += (sum over row i's entries k of
//                           (pi w_k g) max(material_specular(m, N_j.u, v_k.w, u.v_k), 0) I_f, 0)
// with (u, g) = light[j * frames + f] (source j = source_k; terms with v_k.w <= 0, g <= 0 or
// N_j.u <= 0 skipped), summed in float in entry order from 0 and then added to out. Split the
// same way: the rows into chunks whose entries' directions (16 bytes each, the largest
// per-entry binding) fit one binding, the frames into batches whose light geometry (every
// source of each frame, 16 bytes a source and frame) fits one binding.
#ifndef SPECULA_SHARED_INDIRECT_H
#define SPECULA_SHARED_INDIRECT_H
#include "shared/prelude.h"
#include "shared/dispatch.h"
#include "shared/material.h"

SPECULA_SHARED_BEGIN

// One entry of a transfer row (std430, 8 bytes; TransferEntry in transfer.h).
struct IndirectEntry {
    uint source;
    float weight;
};

// Push constants of indirect/indirect_gather.comp. The logical dispatch covers the chunk's
// rows (element = row); each invocation loops over the batch's frames.
struct IndirectGatherPush {
    DispatchHeader dispatch;
    uint rows;       // rows of the chunk
    uint entry_base; // global index of the chunk's first entry (index 0 of its entry buffer)
    uint frames;     // frames of the batch
    uint sources;    // rows of the whole matrix: one frame's stride in the radiosity buffer
};

// Push constants of indirect/indirect_lobe.comp (96 bytes of the 128 guaranteed): the logical
// dispatch covers the chunk's rows (element = row); each invocation loops over the batch's
// frames. The padding puts the material at offset 32 in C++ as std430 does in GLSL (a struct
// with vec4 members is 16-byte aligned).
struct IndirectLobePush {
    DispatchHeader dispatch;
    uint rows;       // rows of the chunk: one frame's stride in the output
    uint entry_base; // global index of the chunk's first entry (index 0 of its entry and direction buffers)
    uint frames;     // frames of the batch: one source's stride in the light geometry
    uint pad0;
    uint pad1;
    uint pad2;
    MaterialGpu material;
};

SPECULA_SHARED_END

#ifdef __cplusplus
#include <cstddef>
static_assert(sizeof(specula::shared::IndirectEntry) == 8);
static_assert(sizeof(specula::shared::IndirectGatherPush) == 24);
static_assert(sizeof(specula::shared::IndirectLobePush) == 96 && offsetof(specula::shared::IndirectLobePush, frames) == 16 &&
              offsetof(specula::shared::IndirectLobePush, material) == 32);
#endif

#endif
