#pragma once
// Visibility of the surface particles (pipeline.md section 2).
//
// View v SEES particle p when
//   1. p faces the camera: the particle's normal (eq. 3.3) AND its triangle's
//      geometric normal point toward the camera center (the geometric test
//      makes the answer exact on convex meshes, see convexity.h; a point whose
//      face turns away from the camera is hidden by the surface itself),
//   2. p projects in front of the camera and inside the image,
//   3. the pixel it projects to carries none of options.reject_flags
//      (kOutsideMask by default) when the view has per-pixel flags,
//   4. the ray from p (offset by RayScene::ray_offset() along its normal) to
//      the camera center is unoccluded.
// Frame f LIGHTS particle p when p faces the light (both normals, n.u > 0)
// and the ray from p to the light is unoccluded.
// When the mesh is convex (closed, connected, every edge convex), the rays of
// tests 4 cannot hit anything: they are skipped (stats.skipped says why,
// stats.rays_avoided how many); options.force_rays casts them anyway.
//
// Result layout (for upload as std430 uint arrays):
//   seen[p * view_words + v / 32]  bit (v % 32): view v sees particle p
//   lit [p * frame_words + f / 32] bit (f % 32): frame f lights particle p
// with view_words = ceil(views / 32), frame_words = ceil(frames / 32)
// (at least 1). best_view[p]: the seeing view whose direction from p is
// closest to p's normal (thesis 3.1.2), -1 when none sees it.
//
// Work is split over options.threads threads by particle; every particle's
// bits depend on that particle alone, so results do not depend on the thread count.
#include "capture/capture.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "visibility/convexity.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace specula {

/// What the ray through each pixel centre of a view hits first (the camera centre's ray,
/// RayScene::intersect from t = 0 on): row-major w x h, the triangle (kMiss where the ray leaves
/// the mesh) and the hit's barycentrics (u, v).
struct PixelHits {
    static constexpr std::uint32_t kMiss = 0xffffffffu;
    int width = 0;
    int height = 0;
    std::vector<std::uint32_t> triangle;
    std::vector<glm::vec2> uv;
    /// True when these are a w x h image's hits (the size of `camera`'s image).
    [[nodiscard]] bool fits(const Camera& camera) const noexcept {
        const auto n = static_cast<std::size_t>(std::max(width, 0)) * static_cast<std::size_t>(std::max(height, 0));
        return width == camera.intrinsics.w && height == camera.intrinsics.h && triangle.size() == n && uv.size() == n;
    }
};
/// One ray a pixel of `camera`, on `threads` workers.
[[nodiscard]] PixelHits cast_pixel_hits(const RayScene& scene, const Camera& camera, unsigned threads);

struct VisibilityView {
    Camera camera;
    /// Optional per-pixel PixelFlag sets, w x h row-major (FrameImage::flags);
    /// empty: every pixel of the image counts.
    std::vector<std::uint8_t> flags;
};

struct VisibilityOptions {
    unsigned threads = 2;
    bool force_rays = false;                  ///< cast occlusion rays even on a convex mesh
    /// Cast no occlusion rays at all, and run no footprint test, even where the mesh can occlude
    /// itself (the planner's forced "off", to measure what the rays cost; the result is then
    /// biased where the mesh shadows or hides itself). Wins over force_rays.
    bool skip_rays = false;
    std::uint8_t reject_flags = kOutsideMask; ///< pixel flags that make a view not see a particle
    /// Footprint test (on meshes that can occlude themselves): a view sees a particle only
    /// when the 4 pixels its bilinear sample reads show the particle's own surface, not an
    /// occluder in front of it or a surface behind an edge. Each view's depth map (one
    /// primary ray per pixel center) is compared with the particle's tangent plane.
    bool footprint_test = true;
    /// Tolerance of that test, in pixel footprints at the particle (divided by the view
    /// cosine, floored at kFootprintMinCos, since depth varies faster at grazing views).
    float footprint_tolerance = 2.0f;
    /// Per frame, the view (index into `views`) whose image it is (VisibilityInputs::frame_view).
    /// When given, with the footprint test on, a frame lights a particle only when the 4 pixels
    /// its bilinear sample reads are lit too: a shadow edge inside the footprint would mix
    /// black pixels into a lit sample. Each frame's pixels get a shadow map: a pixel is dark
    /// when the surface it shows faces away from the light (its interpolated normal or the
    /// seen side of its face, as the synthetic renderer shades it) or one shadow ray from it
    /// is occluded (cast only for the facing ones).
    std::span<const std::uint32_t> frame_view;
    /// Keep each view's surface map (SurfaceMap: what the ray through each pixel centre hits),
    /// for the per-tap irradiance of the diffuse solve and the residual samples
    /// (shared/lambert.h). Its rays are the footprint test's depth rays where that test runs.
    bool surface_maps = true;
    /// Keep each view's PixelHits (Visibility::pixel_hits: 12 bytes a pixel) where its depth rays
    /// are cast (the footprint test or the surface maps), for the passes that would cast them again.
    bool keep_pixel_hits = false;
    /// With frame_view: cast a frame's light rays only for the particles its view sees (the
    /// solves and the residuals read no other pair); the other particles' bits of that frame
    /// stay clear until complete_lit casts them (the indirect light, whose emitters need not be
    /// seen). On the knot at 384 px about half the light rays.
    bool lit_seen_only = false;
    /// With frame_view and the footprint test: the frames' pixel shadow maps answer for the
    /// particle's light rays. A frame whose view sees the particle, the light in front of it,
    /// lights it when none of its 4 taps is dark in the frame's shadow map: their shadow rays,
    /// from the surface around the particle, reached the light. Only an occluder thinner than
    /// the gap between those rays (under a pixel) could answer otherwise, and the sample would
    /// still read the taps' lit pixels. false (the default): a ray per pair as well.
    bool shadow_maps_answer_lights = false;
};

inline constexpr float kFootprintMinCos = 0.2f;

struct VisibilityStats {
    std::size_t particles = 0;
    std::size_t views = 0;
    std::size_t frames = 0;
    std::size_t seen_by_no_view = 0;
    std::size_t lit_by_no_frame = 0; ///< with lit_seen_only: by no frame of a view that sees them
    std::uint64_t rays_completed = 0; ///< light rays complete_lit cast later (lit_seen_only)
    std::uint64_t rays_cast = 0;     ///< occlusion rays traced
    std::uint64_t rays_occluded = 0; ///< of those, how many hit something
    std::uint64_t rays_avoided = 0;  ///< rays the convexity test made unnecessary
    std::uint64_t depth_rays = 0;    ///< primary rays of the per-view depth maps (footprint test, surface maps)
    std::size_t surface_maps = 0;    ///< views with a surface map (per-tap irradiance)
    std::uint64_t footprint_rejected = 0; ///< (particle, view) pairs dropped: a bilinear tap shows another surface
    std::uint64_t shadow_map_rays = 0;    ///< shadow rays of the per-frame pixel shadow maps
    /// (particle, frame) pairs unlit without a light ray: the frame's view sees the particle and a
    /// bilinear tap is dark in the frame's shadow map (cast shadow or facing away)
    std::uint64_t shadow_edge_rejected = 0;
    std::uint64_t rays_answered = 0; ///< (particle, frame) pairs the shadow maps answered without a light ray (shadow_maps_answer_lights)
    ConvexityReport convexity;
    std::string skipped;             ///< why occlusion rays were skipped; empty when they were cast
    unsigned threads = 0;
    double seconds = 0.0;
};

/// What one view's pixels show: per pixel (row-major, w x h), the point the ray through its
/// centre hits first and the interpolated normal there (eq. 3.3, as surface_point computes it
/// for the particles), packed as shared/lambert.h lays out surface maps (4 words a pixel:
/// position float bits, octahedral snorm16 normal; kLambertNoHit where the ray misses).
struct SurfaceMap {
    int width = 0;
    int height = 0;
    std::vector<std::uint32_t> words; ///< 4 per pixel
    std::uint64_t hits = 0;           ///< pixels that show the surface

    /// Pixel (x, y): false on a miss, else its position and unit normal.
    [[nodiscard]] bool at(int x, int y, glm::vec3& position, glm::vec3& normal) const;
};

/// The 4 words of a surface-map pixel (shared/lambert.h) and back.
void pack_surface_pixel(const glm::vec3& position, const glm::vec3& normal, std::uint32_t* words);
[[nodiscard]] glm::vec3 unpack_surface_normal(std::uint32_t word);

struct Visibility {
    std::uint32_t particle_count = 0;
    std::uint32_t view_count = 0;
    std::uint32_t frame_count = 0;
    std::uint32_t view_words = 1;
    std::uint32_t frame_words = 1;
    std::vector<std::uint32_t> seen;     ///< particle_count * view_words
    std::vector<std::uint32_t> lit;      ///< particle_count * frame_words
    std::vector<std::int32_t> best_view; ///< particle_count
    std::vector<SurfaceMap> surfaces;    ///< per view when VisibilityOptions::surface_maps, else empty
    std::vector<PixelHits> pixel_hits;   ///< per view when VisibilityOptions::keep_pixel_hits (and depth rays), else empty
    /// Per frame: 1 when its lit bits hold for every particle, 0 when only for the particles
    /// its view sees (VisibilityOptions::lit_seen_only, until complete_lit).
    std::vector<std::uint8_t> lit_complete;
    VisibilityStats stats;

    [[nodiscard]] bool sees(std::size_t particle, std::size_t view) const {
        return (seen[particle * view_words + view / 32] >> (view % 32)) & 1u;
    }
    [[nodiscard]] bool lights(std::size_t particle, std::size_t frame) const {
        return (lit[particle * frame_words + frame / 32] >> (frame % 32)) & 1u;
    }
};

/// `mesh` must be the mesh `scene` and `particles` were built from.
[[nodiscard]] Visibility compute_visibility(std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                                            std::span<const VisibilityView> views, std::span<const PointLight> lights,
                                            const VisibilityOptions& options = {});

/// Casts the light rays that VisibilityOptions::lit_seen_only left out, for `frames` (those not
/// complete yet): the particles that do not see a frame's view get their bits of it as
/// compute_visibility would have given them (the same facing tests and rays; the shadow-edge
/// test applies to seen pairs only, which were done). `views`, `lights` and `frame_view` as given
/// to compute_visibility. Marks the frames complete.
/// With `stand_in` (one per particle): a particle whose stand-in is another particle casts no
/// ray; where it faces a frame's light that its view does not see, it takes the stand-in's bit
/// (cast here, or known from the visibility where the stand-in's view sees it). The indirect
/// light's blocks (indirect.h) send their particles' mean light: one ray a block and frame
/// answers for the block's unseen particles. Empty: every particle its own.
void complete_lit(Visibility& vis, std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                  std::span<const VisibilityView> views, std::span<const PointLight> lights,
                  std::span<const std::uint32_t> frame_view, std::span<const std::size_t> frames, unsigned threads,
                  std::span<const std::uint32_t> stand_in = {});

/// Undoes complete_lit for `frames`: the bits of the particles that do not see a frame's view are
/// cleared and the frame marked incomplete, as compute_visibility with lit_seen_only left it (to
/// complete it again with other stand-ins). Frames not complete are left as they are.
void uncomplete_lit(Visibility& vis, std::span<const std::uint32_t> frame_view, std::span<const std::size_t> frames);

/// The views (in capture.views order, each with the OR of its frames' pixel
/// flags when images are loaded) and the lights of all frames (in
/// capture.desc.frames order) of a capture.
struct VisibilityInputs {
    std::vector<VisibilityView> views;
    std::vector<PointLight> lights;       ///< per frame
    std::vector<std::uint32_t> frame_view; ///< per frame: index into views
};
[[nodiscard]] VisibilityInputs visibility_inputs(const Capture& capture);

/// Multi-line text of the statistics for logs and the report.
[[nodiscard]] std::string describe(const VisibilityStats& stats);

/// Fraction of the particles above which visibility_warnings warns that they are seen by no
/// view (or lit by no frame): most of the surface is then not measured.
inline constexpr double kUnseenWarningFraction = 0.5;

/// Warnings about legal but useless input, from the statistics alone (pure): more than
/// kUnseenWarningFraction of the particles seen by no view, or lit by no frame. Empty when
/// there is nothing to say. (The pipeline adds them to the run's warnings.)
[[nodiscard]] std::vector<std::string> visibility_warnings(const VisibilityStats& stats);

/// Refuses a capture that leaves nothing to reconstruct: throws InputError(capture, "", why)
/// when no particle is seen by any view, or when no particle is lit by a frame of a view that
/// sees it (every sample would be in shadow). `frame_view` maps each frame of vis's lit bits to
/// its view (VisibilityInputs::frame_view); `frames` limits the frames that count (e.g. the
/// train frames; empty: all). `capture` names the capture in the error (its capture.json).
void require_usable_visibility(const Visibility& vis, std::span<const std::uint32_t> frame_view,
                               const std::filesystem::path& capture, std::span<const std::size_t> frames = {});

} // namespace specula
