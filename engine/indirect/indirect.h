#pragma once
// Indirect light of a capture (issue 16; the model and its reference in transfer.h): the
// transfer of the particles' hemispheres (built once, Embree rays), each view's pixels mapped
// to the atlas (built once, one ray per pixel centre), and per frame the indirect radiance
// image that the current albedo estimate sends toward the frame's camera.
//
// The rows are blocks of particles (TransferOptions::block, transfer.h); a block J sends its
// particles' mean radiosity and each particle gets its block's irradiance. Per frame f, with rho
// the albedo per particle, rho_J a block's mean, and k_d the material's diffuse factor
// (shared/material.h; 1 for the lafortune family):
//   direct irradiance     E0_j = I max(0, N_j.u_j) / d_j^2 where the visibility says frame f
//                         lights particle j, else 0 (the stand-in point light of a directional one)
//   sources, bounce 1     B1_J = mean over J's particles of rho_j k_d(N_j.u_j, 2/3) E0_j
//   bounce b              E_b = T B_b,   B_{b+1} = rho_J k_d(2/3, 2/3) E_b
//   indirect irradiance   E_ind = E_1 + ... + E_bounces
//   radiance, particle i  L_i = rho_i / pi E_ind_J(i)   (held in an atlas image, texel of particle i)
//   radiance, pixel       L(x) = bilinear(L, the atlas point pixel x's centre ray hits) k_d(2/3, N.v)
// 2/3 is the mean cosine of a cosine-weighted hemisphere: light that arrives from all over the
// hemisphere meets the coating's Fresnel transmittance (the coated family's k_d) at that mean
// angle, and a source's diffuse light leaves at it.
// With a specular model, its lobe's first bounce goes where the lobe sends it
// (IndirectOptions::lobe_directions): an entry's rays left source J toward row I in direction
// v, so E_1,I += pi T_IJ f_s(u_J, v) E0_J (u_J toward the light from J's mean position). Its
// later bounces add its directional albedo a_s(c) (the integral of f_s(u, w) N.w over the
// hemisphere, u at cosine c) to the sources' reflectance, spread diffusely: B_{b+1} += a_s(2/3)
// E_b (and, without directions, B1_J += a_s(N.u) E0). A receiver's lobe reflects the light that
// arrives from all over its hemisphere toward the camera: L(x) += a_s(N.v) bilinear(E_ind / pi).
#include "capture/capture.h"
#include "core/image.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "indirect/lobe.h"
#include "indirect/transfer.h"
#include "material/material.h"
#include "visibility/visibility.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace specula {

/// Rays per row of a transfer by default: 12 x 12. With 64 the directed lobe's light is noisy
/// (knot, 2 bounces, 512 px: test PSNR 35.26 dB and 2.13% albedo RMSE in the hollows, against
/// 35.64 dB and 1.99% with 144; 256 rays give 35.79 dB and 1.88% for 17 s more).
inline constexpr std::uint32_t kTransferRays = 144;
/// Texels a side of a transfer's blocks by default (TransferOptions::block): against single
/// particles the knot's predicted light changes by under 0.2% (bench/indirect_model), for a
/// quarter of the rows, rays and gathers. The pipeline's floor (transfer_block_for).
inline constexpr std::uint32_t kTransferBlock = 2;
/// The rows transfer_block_for aims at. The light a surface sends itself varies over the
/// object's own features, while the atlas's texels shrink as the captures' pixels do, so a
/// denser atlas takes wider blocks for the same light. Measured (knot and can path-traced with
/// 2 bounces; albedo RMSE in the hollows, test PSNR): the knot at 256 px (190k particles)
/// 2.51% with blocks of 2 (47k rows), 2.54% with 3; at 512 px (748k) 2.00% with 2 (187k rows),
/// 1.92% with 3 (89k rows), 2.06% with 4, and 35.65 / 35.62 / 35.58 dB; the can at 256 px 1.42% with 2,
/// 1.81% with 3. Blocks of 3 take the knot's reconstruction at 512 px from 47.7 s to 38.5 s.
inline constexpr double kTransferBlockRows = 100000.0;

/// The block for `particles` when none is asked for: the nearest whole number to
/// sqrt(particles / kTransferBlockRows), at least kTransferBlock (2 below 625k particles, 3 from
/// there to 1.225 M: the captures at 512 px, 730k to 750k).
[[nodiscard]] std::uint32_t transfer_block_for(std::size_t particles);

struct TransferOptions {
    /// Rays per row (a particle, or a block), stratified on a g x g grid of the cosine-weighted
    /// hemisphere (g = ceil(sqrt(rays)): the count is rounded up to a square).
    std::uint32_t rays = kTransferRays;
    /// The rows: blocks of block x block texels of one chart (of one triangle's patch in the
    /// patchwork atlas), whose particles receive and send as one (transfer.h); 1: every particle
    /// its own row. A block's rays start from its particles in turn, each ray in its own
    /// particle's hemisphere, so the row is the mean of its particles' rows.
    std::uint32_t block = kTransferBlock;
    unsigned threads = 2;
    std::uint64_t seed = 1; ///< the strata's jitter: a hash of (seed, particle, ray)
};

struct TransferStats {
    std::uint64_t rays = 0;          ///< cast
    std::uint64_t hits = 0;          ///< that reached the object's front side and a particle
    std::uint64_t below_surface = 0; ///< directions under the particle's face (not cast)
    std::uint64_t back_faces = 0;    ///< hits on the back of a face (the inside of the object: ignored)
    std::uint64_t unmapped = 0;      ///< hits on a texel that holds no particle
    std::uint32_t block = 1;         ///< the rows' blocks, texels a side (TransferOptions::block)
    double seconds = 0.0;
};

/// The transfer of `particles` (transfer.h): deterministic for a seed, whatever the thread
/// count. With block 1 its rows are the particles in order (row_of empty).
[[nodiscard]] IndirectTransfer build_transfer(std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                                              const Atlas& atlas, const TransferOptions& options,
                                              TransferStats* stats = nullptr);

/// Per particle, the first particle (in particle order) of its row: whose light rays answer for
/// the row's particles that no view of a frame sees (complete_lit's stand_in: the row sends their
/// mean light). Empty for a transfer of single particles.
[[nodiscard]] std::vector<std::uint32_t> row_stand_ins(const IndirectTransfer& transfer);

/// One view's pixels on the atlas: per pixel (row-major), the atlas point (texel coordinates)
/// that the ray through its centre hits first, and the cosine N.v there; x = -1 where it misses.
/// `reads`: the particles whose texels the pixels' bilinear taps read, in particle order (a
/// frame's light fills those texels only).
struct ViewAtlasMap {
    int width = 0;
    int height = 0;
    std::vector<glm::vec2> texel;
    std::vector<float> cos_view;
    std::vector<std::uint32_t> reads;
};
/// `hits`: the view's pixel hits when the visibility kept them (Visibility::pixel_hits), else null:
/// they are cast here, a ray a pixel.
[[nodiscard]] ViewAtlasMap build_view_atlas_map(const Camera& camera, const Mesh& mesh, const RayScene& scene,
                                                const Atlas& atlas, std::span<const Particle> particles, unsigned threads = 2,
                                                const PixelHits* hits = nullptr);

struct IndirectOptions {
    std::uint32_t bounces = 2;
    /// The Vulkan kernel of the gather (transfer.h), or null: gather_indirect_float runs it.
    IndirectGatherVk* kernel = nullptr;
    /// The Vulkan kernel of the directed lobe's first bounce (lobe.h), or null:
    /// add_directed_lobe_float runs it.
    IndirectLobeVk* lobe_kernel = nullptr;
    unsigned threads = 2;
    std::uint32_t batch_frames = 8;  ///< frames gathered at once
    /// With a lobe and a transfer that keeps its entries' directions: the lobe's first bounce
    /// sent where the lobe sends it (f_s toward each entry's direction); false: spread diffusely.
    bool lobe_directions = true;
};

/// What the indirect light of a capture needs, built once (geometry and cameras only).
struct IndirectScene {
    std::span<const Particle> particles;
    const Visibility* visibility = nullptr; ///< its `lit` bits: which frames light each particle
    std::span<const PointLight> lights;     ///< per frame
    std::span<const std::uint32_t> frame_view; ///< per frame: index into view_maps
    const Atlas* atlas = nullptr;
    const IndirectTransfer* transfer = nullptr;
    std::span<const ViewAtlasMap> view_maps; ///< per view
};

/// Per frame of `frames`: the indirect irradiance of every particle (E_ind above; w = 0),
/// out[k * particles + i] for frames[k].
[[nodiscard]] std::vector<glm::vec4> indirect_irradiance(const IndirectScene& scene, std::span<const std::size_t> frames,
                                                         std::span<const glm::vec3> albedo,
                                                         const std::optional<SpecularModel>& material,
                                                         const IndirectOptions& options);

/// indirect_images for many calls on one scene, albedo and material: the checks (the transfer's
/// entries among them) and the set-up (the lobe's table, the rows' means, the atlas images) once,
/// where a caller asks batch after batch (the evaluation). Keeps `scene`'s spans and `albedo`.
class IndirectImages {
public:
    IndirectImages(const IndirectScene& scene, std::span<const glm::vec3> albedo, const std::optional<SpecularModel>& material,
                   const IndirectOptions& options);
    ~IndirectImages();
    IndirectImages(const IndirectImages&) = delete;
    IndirectImages& operator=(const IndirectImages&) = delete;
    /// As indirect_images below.
    void render(std::span<const std::size_t> frames, const std::function<void(std::size_t frame, const Image& image)>& sink,
                std::vector<float>* ratio = nullptr);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// Per frame of `frames`, in order: the indirect radiance image (linear RGB, the size of the
/// frame's view, 0 where no surface is seen), handed to `sink` (called from one thread; the image
/// holds until the call returns).
/// With `ratio`: per particle, its indirect irradiance over its direct irradiance (r + g + b),
/// each summed over the frames of `frames` that light it and whose view sees it (0 where none
/// does): the R of a solve on frames less this light (pipeline: the damped rounds).
void indirect_images(const IndirectScene& scene, std::span<const std::size_t> frames, std::span<const glm::vec3> albedo,
                     const std::optional<SpecularModel>& material, const IndirectOptions& options,
                     const std::function<void(std::size_t frame, const Image& image)>& sink,
                     std::vector<float>* ratio = nullptr);

} // namespace specula
