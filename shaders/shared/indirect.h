// The indirect-light gather (engine/indirect/transfer.h): the layouts that
// shaders/indirect/indirect_gather.comp and engine/indirect/transfer_vk.cpp share.
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
#ifndef SPECULA_SHARED_INDIRECT_H
#define SPECULA_SHARED_INDIRECT_H
#include "shared/prelude.h"
#include "shared/dispatch.h"

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

SPECULA_SHARED_END

#ifdef __cplusplus
static_assert(sizeof(specula::shared::IndirectEntry) == 8);
static_assert(sizeof(specula::shared::IndirectGatherPush) == 24);
#endif

#endif
