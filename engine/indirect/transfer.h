#pragma once
// Light that bounced off the object itself (inverse global illumination; Yu, Debevec, Malik and
// Hawkins 1999, "Inverse Global Illumination: Recovering Reflectance Models of Real Scenes from
// Photographs", SIGGRAPH: estimate the reflectance, compute the light the scene sends to each
// point with that estimate, remove it from the observations, estimate again).
//
// The geometry and the cameras are fixed while the light moves, so what depends on the geometry
// alone is computed once per capture: the TRANSFER, a sparse matrix T over the surface particles
// (or blocks of them: IndirectTransfer::row_of). Row i holds, for the cosine-weighted hemisphere
// of particle i (its normal N_i), the particles that its rays reach first: of K stratified rays,
// those that hit the object add 1 / (rays cast) each to the entry of the particle whose texel
// holds the hit (and the entry keeps their mean direction). Rays that leave the object add
// nothing (the capture's surroundings are black); directions under the particle's face (where
// its interpolated normal tilts away from the face) are not cast, and the cast ones stand for
// them. For a diffuse source of radiosity B (W/m^2 leaving the surface, B = pi L), the
// irradiance that reaches particle i is then
//     E_i = sum_j T_ij B_j,
// since a cosine-weighted mean of the radiance L over the hemisphere is E / pi.
//
// One frame, one bounce: the sources' radiosity is B_j = rho_j k_d E_dir_j (the direct
// irradiance of the frame's light at j, zero where the visibility says the light does not reach
// it). Two bounces: E2 = T (rho k_d E1); and so on. The indirect radiance that particle i sends
// to a camera is (rho_i / pi) k_d (E1 + E2 + ...), which the pipeline removes from the captured
// pixels before the diffuse solve (indirect/indirect.h).
#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace specula {

namespace gpu {
class Context;
}

/// One entry of a transfer row (std430, 8 bytes): the source particle and its weight (the
/// fraction of the row's cast rays that reached it).
struct TransferEntry {
    std::uint32_t source = 0;
    float weight = 0.0f;
};
static_assert(sizeof(TransferEntry) == 8, "std430 layout of TransferEntry");

/// The sparse transfer matrix (compressed rows; within a row, entries by increasing source).
/// Its rows are particles, or BLOCKS of particles (indirect.h, TransferOptions::block): the
/// indirect light varies slowly over the surface, so a block of texels of one chart receives
/// and sends as one, with its particles' mean radiosity, and each of its particles gets the
/// block's irradiance.
struct IndirectTransfer {
    std::uint32_t rows = 0;                  ///< blocks (receivers); the sources are the same blocks
    std::uint32_t rays_per_row = 0;          ///< K, cast per row (a block's rays start from its particles in turn)
    std::vector<std::uint32_t> row_begin;    ///< rows + 1 offsets into entries
    std::vector<TransferEntry> entries;
    /// Per particle: the row (block) that receives and sends for it; empty: row i is particle i.
    std::vector<std::uint32_t> row_of;
    /// Per entry, or empty: the mean unit direction of its rays from the source toward the row's
    /// particles (xyz) and its cosine to the source row's mean normal (w), where a glossy source
    /// sends its light (indirect.h).
    std::vector<glm::vec4> entry_direction;

    [[nodiscard]] std::size_t entry_count() const noexcept { return entries.size(); }
};

/// Throws Error when the matrix is malformed (row_begin not rows + 1 offsets from 0 to the
/// entry count, offsets not rising, a source out of range or not above the row's previous one,
/// a weight not finite or negative, a row whose weights sum above 1 + 1e-4, a particle's row
/// out of range, entry directions that are not one per entry or not finite unit vectors with a
/// cosine in [-1, 1]); the message names the row and the entry, or the particle.
void validate_transfer(const IndirectTransfer& transfer);

/// The checks both gathers below make first: validate_transfer, then that radiosity and out
/// hold `frames` x rows values each (Error naming `who` otherwise).
void validate_gather(const IndirectTransfer& transfer, std::size_t radiosity_values, std::uint32_t frames,
                     std::size_t out_values, const char* who);

/// The per-frame step, for `frames` frames at once: with radiosity laid out frame by frame
/// (radiosity[f * rows + j], rgb in xyz, w ignored),
///     out[f * rows + i] = (sum over row i's entries of weight * radiosity[f * rows + source], 0).
/// The C++ reference: accumulates in double, in entry order; `threads` threads over rows.
void gather_indirect_cpu(const IndirectTransfer& transfer, std::span<const glm::vec4> radiosity, std::uint32_t frames,
                         std::span<glm::vec4> out, unsigned threads = 2);

/// How the last IndirectGatherVk::run split its work.
struct IndirectGatherStats {
    std::uint32_t row_chunks = 0;    ///< chunks of rows whose entries fit one binding
    std::uint32_t frame_batches = 0; ///< batches of frames whose radiosity fits one binding
    std::optional<double> gpu_ms;    ///< time of the dispatches; nullopt without timestamps
};

/// The same step as the pipeline runs it on the CPU: accumulates in float, in entry order (the
/// Vulkan kernel's arithmetic), four lanes at a time; within (n + 2) 2^-24 S of the reference for a
/// row of n entries whose exact sum is S (tests/indirect/transfer_test.cpp). The reference's
/// double sums cost about twice as much.
void gather_indirect_float(const IndirectTransfer& transfer, std::span<const glm::vec4> radiosity, std::uint32_t frames,
                           std::span<glm::vec4> out, unsigned threads = 2);

namespace detail {
/// Entries ahead whose sources the C++ gathers ask the cache for: the sources are scattered, and
/// a row's sum waits on each one's cache lines (the gather twice as fast, bench/indirect_bench).
inline constexpr std::size_t kPrefetchAhead = 8;
/// Asks the cache for the `bytes` bytes at `p`, a 64-byte line at a time.
inline void prefetch(const void* p, std::size_t bytes) {
    for (std::size_t b = 0; b < bytes; b += 64) __builtin_prefetch(static_cast<const char*>(p) + b);
}

/// Rows [first, last) of a transfer whose entries a dispatch takes at once.
struct TransferRowChunk {
    std::uint32_t first = 0, last = 0;
};
/// Consecutive chunks of rows, each holding at most `max_entries` entries (a row with more is a
/// chunk of its own): how the kernels split a transfer so that each binding stays in range.
[[nodiscard]] std::vector<TransferRowChunk> transfer_row_chunks(const IndirectTransfer& t, std::uint64_t max_entries);

/// gather_indirect_float without its checks, for a caller that has run validate_gather once for
/// many gathers of the same transfer (indirect.cpp: every batch and bounce of a pass). `scratch`,
/// when given, holds the sources' values frame by frame between calls (no fresh pages a call).
void gather_indirect_float_unchecked(const IndirectTransfer& transfer, std::span<const glm::vec4> radiosity,
                                     std::uint32_t frames, std::span<glm::vec4> out, unsigned threads,
                                     std::vector<glm::vec4>* scratch = nullptr);
} // namespace detail

/// The Vulkan kernel of the same step (shaders/indirect/indirect_gather.comp), accumulating in
/// float in entry order. Splits the rows and the frames into dispatches whose buffers stay
/// within the device's storage-buffer range, or within `max_binding_bytes` when that is lower
/// (0: the device's range; tests lower it to reach the split without 128 MiB buffers). Throws
/// gpu::LimitError when one frame's radiosity (rows x 16 bytes) exceeds that range (every other
/// binding can be cut below it: transfer_vk.cpp).
class IndirectGatherVk {
public:
    explicit IndirectGatherVk(gpu::Context& ctx, std::uint64_t max_binding_bytes = 0);
    ~IndirectGatherVk();
    IndirectGatherVk(const IndirectGatherVk&) = delete;
    IndirectGatherVk& operator=(const IndirectGatherVk&) = delete;
    void run(const IndirectTransfer& transfer, std::span<const glm::vec4> radiosity, std::uint32_t frames,
             std::span<glm::vec4> out);
    [[nodiscard]] const IndirectGatherStats& last_run() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace specula
