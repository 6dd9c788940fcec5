#pragma once
/// \file
/// Light that bounced off the object itself (indirect/indirect.h), added to the renders of the
/// evaluation and of `specula render`: the bundle's renderer draws direct light only.
///
///  - IndirectLightAdder: a frame's indirect radiance image added to its render, for a caller
///    that asks frame by frame in rising order (evaluate()'s EvaluateOptions::add_light); used
///    by the pipeline's own evaluation on the reconstruction's particles.
///  - BundleIndirectLight: the same from a bundle alone (`specula evaluate --indirect`,
///    `specula render --indirect`). Its particles come from the bundle's own texture
///    coordinates (geometry/chart_atlas.h atlas_from_texture_coordinates), its albedo from the
///    bundle's albedo texture, its material from the bundle; then what the pipeline builds for
///    the stage: the visibility of the particles for the frames' lights, the transfer, the views'
///    atlas maps (the cost of each is in stats()).
///
///   BundleIndirectLight light(bundle, views, lights, frame_view, {});
///   evaluate::EvaluateOptions eo;
///   eo.add_light = [&](std::size_t f, Image& im) { light.add(f, im); };
#include "capture/camera.h"
#include "core/image.h"
#include "export/bundle.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "indirect/indirect.h"
#include "visibility/visibility.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace specula::evaluate {

/// True when the bundle says its albedo had the light that bounced off the object removed
/// (info.indirect_light.removed_from_albedo: reconstruct's indirect stage ran), so a render needs
/// it added to match the object.
[[nodiscard]] bool indirect_removed_from_albedo(const Bundle& bundle);
/// The bounces the bundle's reconstruction modelled (info.indirect_light.bounces, 1 to 8), else 2.
[[nodiscard]] std::uint32_t indirect_bounces_of(const Bundle& bundle);
/// The transfer the bundle's reconstruction built (info.indirect_light.transfer: rays a row, 1 to
/// 4096, and block texels, 1 to 64), else what it built before the bundle recorded it (kTransferRays
/// and kTransferBlock), so the renders see the light the albedo had removed.
struct BundleTransfer {
    std::uint32_t rays = kTransferRays;
    std::uint32_t block = kTransferBlock;
};
[[nodiscard]] BundleTransfer indirect_transfer_of(const Bundle& bundle);

/// Each particle's albedo as a texture holds it: the texel of the particle (RGB; a grey texture
/// gives grey). The pipeline's inpainted albedo texture, or a bundle's.
[[nodiscard]] std::vector<glm::vec3> particle_albedo(std::span<const Particle> particles, const Image& texture);

/// Adds frames' indirect radiance to their renders. A frame not computed yet starts a batch of
/// options.batch_frames frames: it and the frames after it in the order the caller said it will
/// ask them (expect; by default every frame in rising order). The gather is cheaper a batch at a
/// time; frames asked in that order are computed once. Keeps `scene`'s spans; holds the albedo.
class IndirectLightAdder {
public:
    IndirectLightAdder(const IndirectScene& scene, std::vector<glm::vec3> albedo, const std::optional<SpecularModel>& material,
                       const IndirectOptions& options);
    /// The frames the caller will ask, in order (evaluated_frames: a sample of them).
    void expect(std::vector<std::size_t> frames);
    /// Adds frame `frame`'s indirect radiance to `rendered`. Throws Error when the render's size
    /// is not the frame's view's, or the frame is not one of the scene's.
    void add(std::size_t frame, Image& rendered);
    /// Wall time spent computing the light, over all calls.
    [[nodiscard]] double seconds() const noexcept { return m_seconds; }

private:
    std::size_t m_frames = 0;
    std::uint32_t m_batch = 1;
    std::vector<std::size_t> m_order; // expect's frames; empty: all in rising order
    std::vector<glm::vec3> m_albedo; // before m_images, which keeps a span of it
    IndirectImages m_images;
    std::map<std::size_t, Image> m_ready;
    double m_seconds = 0.0;
};

struct BundleIndirectOptions {
    std::uint32_t bounces = 2;
    std::uint32_t rays = kTransferRays;
    std::uint32_t block = kTransferBlock;
    bool lobe_directions = true;
    unsigned threads = 2;
};

struct BundleIndirectStats {
    std::size_t particles = 0;
    std::size_t charts = 0;
    std::size_t rows = 0;
    std::size_t entries = 0;
    double atlas_s = 0.0;      ///< the atlas from the texture coordinates and the particles
    double visibility_s = 0.0; ///< which frames light each particle (Embree)
    double transfer_s = 0.0;
    double view_maps_s = 0.0;
    [[nodiscard]] double setup_s() const noexcept { return atlas_s + visibility_s + transfer_s + view_maps_s; }
};

/// The indirect light of a bundle's renders for given frames (a view and a light each).
class BundleIndirectLight {
public:
    /// `views`: the cameras (with their pixel flags when a capture has them); `lights` and
    /// `frame_view`: per frame, its light and its view. Throws Error when the bundle has no albedo
    /// or texture coordinates, or the frames and views do not match.
    BundleIndirectLight(const Bundle& bundle, std::span<const VisibilityView> views, std::span<const PointLight> lights,
                        std::span<const std::uint32_t> frame_view, const BundleIndirectOptions& options = {});
    ~BundleIndirectLight();
    BundleIndirectLight(const BundleIndirectLight&) = delete;
    BundleIndirectLight& operator=(const BundleIndirectLight&) = delete;

    /// IndirectLightAdder::expect and add for frames (indices into `lights`).
    void expect(std::vector<std::size_t> frames);
    void add(std::size_t frame, Image& rendered);
    [[nodiscard]] const BundleIndirectStats& stats() const noexcept { return m_stats; }
    /// Wall time of the light itself (the bounces and the images), over all add calls.
    [[nodiscard]] double light_seconds() const noexcept;

private:
    Mesh m_mesh;
    Atlas m_atlas;
    ParticleSet m_particles;
    std::optional<RayScene> m_scene;
    Visibility m_visibility;
    std::vector<PointLight> m_lights;
    std::vector<std::uint32_t> m_frame_view;
    IndirectTransfer m_transfer;
    std::vector<ViewAtlasMap> m_view_maps;
    BundleIndirectStats m_stats;
    std::unique_ptr<IndirectLightAdder> m_adder;
};

} // namespace specula::evaluate
