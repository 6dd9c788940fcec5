#pragma once
// The directed lobe's first bounce (indirect.h, IndirectOptions::lobe_directions): the light
// that a glossy source's lobe sends where it points, added to the gathered irradiance of the
// first bounce. Model: an entry k of row i (transfer.h) holds the rays of row i that reached
// source j = source_k, which left j toward row i in the mean direction v_k (entry_direction:
// xyz, its cosine to j's mean normal in w). Lit by frame f's light from the unit direction
// u_jf at geometry factor g_jf (the mean of max(0, N.u) / d^2 over j's particles), source j
// sends pi f_s(u_jf, v_k) g_jf I_f along v_k (E = pi x the cosine-weighted mean of the radiance
// the rays meet, transfer.h), so per frame f of a batch and row i
//     out[f * rows + i] += sum over row i's entries k with v_k.w > 0 and frames with g_jf > 0
//                          and ci = N_j.u_jf > 0 of  (pi w_k g_jf) max(f_s(ci, v_k.w, u_jf.v_k), 0) I_f
// where f_s is shared::material_specular (shared/material.h: any family), N_j the source row's
// mean unit normal and I_f the frame's light intensity (rgb). Entries that leave their source
// from under its surface (v.w <= 0), sources the light does not reach (g <= 0) and lights
// behind the source (ci <= 0) add nothing.
//
// Three implementations of one term: add_directed_lobe_cpu, the reference (double); the
// pipeline's float path (add_directed_lobe_float, the Vulkan kernel's arithmetic); and
// IndirectLobeVk (shaders/indirect/indirect_lobe.comp). tests/kernels/indirect_lobe_test.cpp
// holds both float paths to the reference within a bound derived there.
#include "indirect/transfer.h"
#include "shared/material.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>

namespace specula {

/// The checks every implementation below makes first: validate_transfer, that the transfer
/// keeps its entries' directions, and that row_normal holds one value per row, light_geometry
/// rows x frames (row-major: r * frames + f), intensity one per frame and out frames x rows
/// (Error naming `who` and the field otherwise).
void validate_directed_lobe(const IndirectTransfer& transfer, std::size_t row_normals, std::size_t light_geometry,
                            std::size_t intensities, std::uint32_t frames, std::size_t out_values, const char* who);

/// The reference: every term in double (ci and u.v from the float inputs, f_s by
/// shared::f64::material_specular), each row's terms summed in double in entry order and added
/// to out's value with one rounding; out's w is left as it is. `threads` threads over rows.
void add_directed_lobe_cpu(const IndirectTransfer& transfer, const shared::MaterialGpu& material,
                           std::span<const glm::vec3> row_normal, std::span<const glm::vec4> light_geometry,
                           std::span<const glm::vec3> intensity, std::uint32_t frames, std::span<glm::vec4> out,
                           unsigned threads = 2);

/// The same term as the pipeline runs it on the CPU: in float, each row's terms of a frame summed
/// in entry order from 0, then added to out (the Vulkan kernel's arithmetic). The lafortune
/// family takes 8 frames at a time where the processor has AVX2 and FMA (x86-64 with glibc's
/// vector math library, libmvec), the power as exp(N log base) there, as GLSL's pow is
/// exp2(N log2 base) (detail::lobe_simd).
void add_directed_lobe_float(const IndirectTransfer& transfer, const shared::MaterialGpu& material,
                             std::span<const glm::vec3> row_normal, std::span<const glm::vec4> light_geometry,
                             std::span<const glm::vec3> intensity, std::uint32_t frames, std::span<glm::vec4> out,
                             unsigned threads = 2);

namespace detail {
/// add_directed_lobe_float without its checks, for a caller whose inputs are right by
/// construction and whose transfer is checked once for many batches (indirect.cpp, Bouncer).
void add_directed_lobe_float_unchecked(const IndirectTransfer& transfer, const shared::MaterialGpu& material,
                                       std::span<const glm::vec3> row_normal, std::span<const glm::vec4> light_geometry,
                                       std::span<const glm::vec3> intensity, std::uint32_t frames, std::span<glm::vec4> out,
                                       unsigned threads);
/// Whether add_directed_lobe_float takes the lafortune family 8 frames at a time (AVX2, FMA and
/// libmvec here, and not turned off); set_lobe_simd(false) makes it take one frame at a time, so
/// that tests check both ways on a machine that has both. Not for use while a term is computed.
[[nodiscard]] bool lobe_simd();
void set_lobe_simd(bool on);
} // namespace detail

/// How the last IndirectLobeVk::run split its work.
struct IndirectLobeStats {
    std::uint32_t row_chunks = 0;    ///< chunks of rows whose entries' directions fit one binding
    std::uint32_t frame_batches = 0; ///< batches of frames whose light geometry fits one binding
    std::optional<double> gpu_ms;    ///< time of the dispatches; nullopt without timestamps
};

/// The Vulkan kernel of the same term (shaders/indirect/indirect_lobe.comp), in float as
/// add_directed_lobe_float. Splits the rows and the frames into dispatches whose buffers stay
/// within the device's storage-buffer range, or within `max_binding_bytes` when that is lower
/// (0: the device's range; tests lower it to reach the split). Throws gpu::LimitError when one
/// frame's light geometry (rows x 16 bytes) exceeds that range (every other binding can be cut
/// below it: lobe_vk.cpp).
class IndirectLobeVk {
public:
    explicit IndirectLobeVk(gpu::Context& ctx, std::uint64_t max_binding_bytes = 0);
    ~IndirectLobeVk();
    IndirectLobeVk(const IndirectLobeVk&) = delete;
    IndirectLobeVk& operator=(const IndirectLobeVk&) = delete;
    void run(const IndirectTransfer& transfer, const shared::MaterialGpu& material, std::span<const glm::vec3> row_normal,
             std::span<const glm::vec4> light_geometry, std::span<const glm::vec3> intensity, std::uint32_t frames,
             std::span<glm::vec4> out);
    [[nodiscard]] const IndirectLobeStats& last_run() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace specula
