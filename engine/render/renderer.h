#pragma once
/// \file
/// Offscreen raster renderer of a reconstruction (pipeline.md section 7, thesis
/// chapter 4): two passes over the mesh, as in the thesis.
///
///   pass 1, diffuse:   (rho / pi) k_d(u, v) I max(0, n.u) / d^2, rho from the albedo atlas,
///                      k_d the material's diffuse factor (1 for the lafortune family; the
///                      coating's Fresnel transmittances for the coated one), in both modes
///   pass 2, specular:  f_s(u, v) I max(0, n.u) / d^2, blended additively, with f_s
///                      the material's specular BRDF, any family (`analytic`), or
///                      max(0, sum_k G_k(h) H_k(d)) from K pairs of cube-maps (`factorized`,
///                      Kautz-McCool, shared/gshd.h; K = 1 is the thesis, up to kMaxFactorTerms),
///                      (h, d) in the factorization's parametrization (plain, mirrored or warped
///                      GSHD; warped for the lafortune family only)
///
/// The formulas live once in shaders/shared/render.h (with material.h, which evaluates every
/// family: material_specular and material_diffuse_factor, and gshd.h); the material reaches the
/// shaders as shared::MaterialGpu (material_gpu()) in the per-frame parameters. The synth
/// renderer (engine/synth) evaluates the same definitions by ray casting and is the reference of
/// the analytic mode for the lafortune family.
///
/// Cast shadows, on by default (Settings::shadows): before the lit passes a depth-only
/// pass renders the mesh from the point light into a square shadow map (Options::
/// shadow_map_size, D32_SFLOAT where it can be sampled with linear filtering, else D16)
/// through a perspective frustum aimed at the mesh bounds' centre that just covers the
/// bounding sphere (half-angle asin(r / d) plus 2%, near/far from the sphere). Every lit
/// pass multiplies both terms by the light's visibility (render/terms.glsl
/// light_visibility: a depth-compare sampler, 2x2 PCF, normal-offset plus slope-scaled
/// bias), so the captures' ray-traced cast shadows are reproduced. A light inside or
/// within 10% of the bounding sphere gets no shadow pass; FrameInfo::shadow_note says so.
/// `shadows = false` is the thesis's render: no shadows, so pixels that a capture shows
/// in shadow (or lit only by a light behind the geometric surface) differ from it.
///
/// Usage:
///   render::Renderer r(ctx, {.mesh = &mesh, .corner_uv = atlas.corner_uv, .albedo = &texture.image,
///                            .material = {.specular = lobe}});
///   r.set_factorization(factorization.cubes);                  // optional: enables `factorized`
///   render::Frame f = r.render(camera, light, {.mode = render::Mode::Both});
///   f.color (linear RGB, w x h, row 0 at the top), f.mask (255 = covered), f.info (passes, timings)
#include "material/material.h"
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/image.h"
#include "gpu/buffer.h"
#include "gpu/graphics_pipeline.h"
#include "gpu/image.h"
#include "gpu/pass_clock.h"
#include "gpu/render_target.h"
#include "gpu/shadow_map.h"
#include "render/projection.h"
#include "gpu/sequence.h"
#include "shared/render.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula::render {


/// What the renderer draws. Pointers and spans are read during construction only.
struct Scene {
    const Mesh* mesh = nullptr;            ///< positions, smooth unit normals (one per position), triangles
    std::span<const glm::vec2> corner_uv;  ///< 3 per triangle (Atlas::corner_uv): atlas coordinates in [0, 1]
    const Image* albedo = nullptr;         ///< linear RGB rho, the atlas (AlbedoTexture::image); 1 to 4 channels
    /// The specular model, any family (absent or zero: no specular pass; the coated family's
    /// diffuse factor applies even with a zero tint) and, when present, its cube-maps (as
    /// set_factorization takes them).
    Material material;
};

enum class Mode {
    Diffuse,  ///< pass 1 only
    Specular, ///< pass 2 only (pass 1 still lays down depth and coverage, with zero colour)
    Both,     ///< pass 1 + pass 2
};
enum class SpecularPath {
    Analytic,   ///< the lobe, evaluated per fragment
    Factorized, ///< G(h) H(d) cube-map lookups (needs set_factorization)
};
[[nodiscard]] const char* mode_name(Mode mode) noexcept;
[[nodiscard]] const char* specular_path_name(SpecularPath model) noexcept;

/// How the terms are drawn.
enum class Passes {
    Separate, ///< the thesis's two passes: diffuse, then specular blended additively (EQUAL depth)
    Fused,    ///< Mode::Both: one pass whose fragment shader sums the same two terms (render/terms.glsl):
              ///< half the vertex, setup and binning work, which bounds lavapipe on large meshes
    Deferred, ///< every mode: one pass over the mesh stores its interpolated inputs (G-buffer), then
              ///< each pixel is shaded once with the same terms. Where triangles are about a pixel,
              ///< lavapipe shades a 4x4 block per triangle in the forward passes: this does the
              ///< shading work once per pixel instead (gpu::RenderTarget::begin_deferred)
};
[[nodiscard]] const char* passes_name(Passes passes) noexcept;

struct Settings {
    Mode mode = Mode::Both;
    SpecularPath specular = SpecularPath::Analytic;
    Passes passes = Passes::Separate; ///< Fused applies to Mode::Both with a specular term; Deferred to all
    std::optional<double> near; ///< near plane; default near_plane_for(camera, mesh bounds)
    /// Cast shadows from a shadow map (on by default); false: the thesis's unshadowed render.
    bool shadows = true;
};

enum class Culling {
    Auto,   ///< cull back faces when the mesh is closed and outward-facing (is_closed_outward)
    Never,  ///< draw both sides: like ray casting, the nearest surface wins whichever way it faces
    Always, ///< cull back faces (counter-clockwise seen from outside = front)
};

struct Options {
    /// Culling halves the raster work of a closed mesh (the back half is never visible
    /// from outside it) and changes no pixel; open meshes need both sides.
    Culling culling = Culling::Auto;
    /// Side of the square shadow map in texels (2048: a texel is about 1/1000 of the
    /// bounding sphere's diameter, below a 256-1024 px capture's pixel on the object).
    uint32_t shadow_map_size = 2048;
    /// Levels of detail (build_levels_of_detail): 0, the default, draws every triangle. A positive
    /// value lets each frame draw the coarsest level whose geometric error, projected at the
    /// nearest point of the mesh's bounding sphere, is at most this many pixels (choose_level_of_detail);
    /// every pass of the frame, the shadow map's included, draws that level. With cluster_culling
    /// (a closed mesh), each patch of the mesh chooses instead: the coarsest level whose error,
    /// projected at the patch's nearest point, is at most this many pixels, and none of whose
    /// triangles, nor the whole mesh's there, the camera (or, with shadows, the light) sees at a
    /// grazing angle or from both sides (may_graze: there a coarser surface moves a silhouette or
    /// a shadow's edge); the shadow map draws the same patches. For a real-time view: `specula
    /// render` draws the mesh as it is, `specula evaluate --lod` measures what the levels cost.
    double lod_max_error_px = 0.0;
    /// With back faces culled (a closed mesh): each level is ordered in clusters of up to 124
    /// triangles (meshoptimizer's meshlets) and a frame's lit passes draw only the clusters whose
    /// normal cone does not face wholly away from the camera (collected on the CPU into an index
    /// buffer; the shadow map draws every cluster). The same pixels, with fewer back faces set
    /// up only to be culled. For a real-time view.
    bool cluster_culling = false;
};

/// The display PSNR under which specula-view and `specula evaluate --lod` leave a level of
/// detail out (Renderer::accept_levels_of_detail): 42 dB, an RMS change of about 2 of 255 codes
/// over the object. Such a change is not free against a capture: on knot_hd (test 34.3 dB, train
/// 37.9 dB against its 256 px captures) the level kept at 46.8 dB costs 0.03 / 0.39 dB, and one
/// at 40.0 dB would cost 0.22 / 1.0 dB (docs/pipeline.md section 7.4).
inline constexpr double kDefaultLodMinPsnrDb = 42.0;

/// The most triangles of a patch of the levels of detail (build_levels_of_detail).
inline constexpr std::size_t kPatchTriangles = 512;

/// One level of detail: a range of the index buffer over the same vertices.
struct LevelOfDetail {
    uint32_t first_index = 0;
    uint32_t index_count = 0;
    double error = 0.0; ///< geometric error, world units (meshoptimizer's estimate; 0 for level 0)
};

/// A run of triangles whose normals lie in a cone (Options::cluster_culling): seen from a point
/// p with dot(normalize(apex - p), axis) >= cutoff, every one of them faces away.
struct TriangleCluster {
    uint32_t first_index = 0;
    uint32_t index_count = 0;
    glm::vec3 apex{0.0f};
    glm::vec3 axis{0.0f};
    float cutoff = 1.0f;
    glm::vec3 center{0.0f}; ///< a sphere holding the cluster's vertices (meshoptimizer's): what it can cover on screen
    float radius = 0.0f;
    uint32_t patch = 0; ///< the MeshPatch whose triangles it holds (0 without patches)
    float spread = 0.0f; ///< every triangle's normal is within this many radians of `axis`
};

/// A patch of the mesh (build_levels_of_detail): a compact group of the whole mesh's triangles,
/// simplified on its own with its border kept, so that neighbouring patches drawn at different
/// levels meet edge to edge, without cracks.
struct MeshPatch {
    std::vector<LevelOfDetail> levels; ///< its range of the index buffer at each level (error: its own)
    glm::vec3 center{0.0f};            ///< a sphere holding its triangles
    float radius = 0.0f;
};

/// The levels of detail of a mesh: each level is its patches' ranges, in the patches' order.
struct LevelsOfDetail {
    std::vector<LevelOfDetail> levels; ///< [0]: every triangle
    std::vector<MeshPatch> patches;    ///< none when there is one level
};

/// Whether a triangle of `c` may be seen from `eye` at a grazing angle: more than `grazing`
/// radians from its normal and less than pi - `grazing` (facing away), from the cluster's normal
/// cone (axis, spread) and bounding sphere; false only where every point and normal of it is
/// outside that band. A coarser surface moves the point a ray at angle a meets by its error over
/// cos a: error_px x tan a on screen, so a level whose error is e pixels is drawn where no triangle
/// is seen beyond atan(max / e) (Options::lod_max_error_px).
[[nodiscard]] bool may_graze(const TriangleCluster& c, const glm::vec3& eye, float grazing) noexcept;
/// Whether every triangle of `c` faces away from a camera at `eye` (meshoptimizer's cone test).
[[nodiscard]] bool faces_away(const TriangleCluster& c, const glm::vec3& eye) noexcept;

/// What a frame drew and what it cost.
struct FrameInfo {
    bool diffuse_pass = false;        ///< pass 1 wrote the diffuse term (it always writes depth and coverage)
    bool specular_pass = false;       ///< pass 2 ran (or, fused, the specular term was drawn)
    bool fused = false;               ///< both terms in one pass (Passes::Fused); timed as diffuse_gpu_ms
    bool deferred = false;            ///< Passes::Deferred: G-buffer, then per-pixel shading; timed as diffuse_gpu_ms
    std::string specular_note;        ///< why pass 2 did not run ("no lobe: ...", "mode diffuse"), else empty
    bool shadow_pass = false;         ///< the shadow map was drawn and the lit passes are shadowed
    /// render(): the shadow map already held this light's depth (the previous render()'s light,
    /// e.g. one frame drawn with two materials): shadowed from it, not drawn again.
    bool shadow_kept = false;
    std::string shadow_note;          ///< why not ("shadows off", light too close to the mesh), else empty
    std::optional<double> shadow_gpu_ms;   ///< GPU time of the shadow map's depth pass
    std::optional<double> diffuse_gpu_ms;  ///< GPU time of pass 1 (timestamps); nullopt without timestamps
    std::optional<double> specular_gpu_ms; ///< GPU time of pass 2
    std::optional<double> readback_gpu_ms; ///< GPU time of the colour copy to the host buffer
    double wall_ms = 0.0;             ///< render(): parameters, recording, submit, wait, readback, conversion
    std::size_t covered_pixels = 0;
    /// The box of pixels the frame's mesh can cover (projection.h pixels_of_box: the mesh's
    /// bounds, and with Options::cluster_culling the union of the drawn clusters' spheres): no
    /// pass writes outside it, so the target holds its clear, 0, there (the viewer blits only it).
    /// Passes::Deferred shades only these pixels (the shading pass's scissor): outside it the
    /// clear is what the shader writes on an uncovered pixel.
    PixelBox drawn;
    std::size_t triangles = 0;        ///< triangles drawn (the level of detail's; its clusters facing the camera with Options::cluster_culling)
    /// The level of detail drawn (0: the mesh as it is); with patches chosen by the view
    /// (Options::lod_max_error_px with cluster_culling), the coarsest a patch could draw.
    std::size_t lod_level = 0;
    /// With patches chosen by the view: the mesh's patches, and how many of them this frame drew
    /// at level 0 (a silhouette or a shadow's edge in them, or no coarser level within the bound).
    std::size_t patches = 0;
    std::size_t patches_whole = 0;
    /// Passes::Deferred in render(): shaded from the G-buffer the previous deferred frame left, whose
    /// camera (pose, intrinsics, near plane) and level of detail (each patch's) were the same: the mesh is not
    /// drawn again, only the shading pass runs. The same pixels as drawing it (tested); a view's
    /// lights rendered one after the other pay for its G-buffer once.
    bool gbuffer_kept = false;
};

struct Frame {
    Image color;                    ///< linear RGB, w x h, row 0 at the top; 0 where not covered
    std::vector<std::uint8_t> mask; ///< w * h, 255 where the mesh covers the pixel centre
    FrameInfo info;
};

/// Owns the pipelines, the mesh and texture on the GPU, and a render target (resized
/// to each camera's image). Move-only; the Context must outlive it. Not thread-safe.
class Renderer {
public:
    /// Uploads the scene. Throws Error on inconsistent inputs (sizes, missing albedo),
    /// gpu::LimitError when the mesh exceeds one storage binding (about 1.3M triangles on lavapipe).
    Renderer(gpu::Context& ctx, const Scene& scene, const Options& options = {});
    ~Renderer();
    Renderer(Renderer&&) noexcept;
    Renderer& operator=(Renderer&&) noexcept;
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// Replaces the specular model (absent or zero: no specular pass); keeps the cube-maps.
    void set_specular(const std::optional<SpecularModel>& specular);
    [[nodiscard]] const std::optional<SpecularModel>& specular() const noexcept;
    /// True when there is a specular term to draw (a model that is not zero).
    [[nodiscard]] bool has_specular() const noexcept;
    /// The model as the pass shaders read it (material_gpu(specular()), or set_material's).
    [[nodiscard]] shared::MaterialGpu material() const noexcept;
    /// Draws this material instead of the specular model's, diffuse factor included: any family the
    /// shaders evaluate, in particular glTF's core material (material/core_material.h
    /// core_material_gpu: what ordinary viewers show). Analytic path only (a factorized render
    /// throws Error). set_specular() ends it.
    void set_material(const shared::MaterialGpu& material, bool has_specular);

    /// Uploads the factorization's cube-maps: K = terms.size() terms (1..kMaxFactorTerms), each a
    /// G (looked up by h) and an H (by d), each cube-map with its own resolution; the sum is
    /// clamped at 0 per channel. Enables SpecularPath::Factorized. `param` is the parametrization
    /// they were made in (shared/gshd.h parts 4, 5) and `warp` its warp (FactorParam::Warped only:
    /// then the terms are multiplied by the radial factor of the specular model's lobe, which must
    /// be the factorized one; Error when the model is of another family, here or at a factorized
    /// render after set_specular).
    void set_factorization(const FactorizedSpecular& cubes);
    [[nodiscard]] bool has_factorization() const noexcept;
    [[nodiscard]] uint32_t factorization_terms() const noexcept; ///< 0 before set_factorization
    [[nodiscard]] FactorParam factorization_param() const noexcept;
    [[nodiscard]] glm::vec4 factorization_warp() const noexcept;

    /// Renders one frame and reads it back. Throws Error when `settings` asks for the
    /// factorized model before set_factorization(), or for a warped factorization of a model
    /// that is not of the lafortune family.
    [[nodiscard]] Frame render(const Camera& camera, const PointLight& light, const Settings& settings = {});

    /// The same passes as render(), recorded into the caller's command buffer and target
    /// (the viewer's window-sized target, blitted to the swapchain): no submit, no wait,
    /// no readback. The target must be camera-sized; pipelines are compatible with any
    /// gpu::RenderTarget (same formats). Leaves the colour in COLOR_ATTACHMENT_OPTIMAL,
    /// written by the colour-attachment stage. The per-frame parameters are written to a
    /// host-visible buffer now, so the previous frame this renderer recorded (here or in
    /// render()) must have finished executing. Returns what the frame will draw (no
    /// timings, covered_pixels 0).
    /// With `clock` (started by the caller), a timestamp after each pass: "shadow map", then
    /// "g-buffer" and "shading" (deferred), "fused pass", or "diffuse pass" and "specular pass".
    FrameInfo record(VkCommandBuffer cmd, const gpu::RenderTarget& target, const Camera& camera, const PointLight& light,
                     const Settings& settings = {}, gpu::PassClock* clock = nullptr);

    [[nodiscard]] std::size_t triangle_count() const noexcept;
    /// The levels of detail built (one, the whole mesh, unless Options::lod_max_error_px > 0).
    [[nodiscard]] std::span<const LevelOfDetail> levels_of_detail() const noexcept;
    /// Keeps the levels of detail whose renders look like the whole mesh's: renders each view
    /// (`cameras[i]` lit by `lights[i]`, `settings`) with every level, scores each level against level 0 by
    /// masked display PSNR (sRGB, 8-bit codes, over the pixels either covers), and from then on
    /// draws no level past the first whose worst view scores under `min_psnr_db`. The geometric
    /// error alone does not bound what a coarser mesh changes: its triangles interpolate the
    /// atlas coordinates and normals over larger spans, which moves texture edges and highlights
    /// at any distance. Returns each level's worst PSNR (level 0: +infinity).
    std::vector<double> accept_levels_of_detail(std::span<const Camera> cameras, std::span<const PointLight> lights,
                                                const Settings& settings, double min_psnr_db);
    /// The levels that frames may draw (accept_levels_of_detail; all that were built before it).
    [[nodiscard]] std::size_t accepted_levels_of_detail() const noexcept;
    /// Whether back faces are culled (Options::culling, resolved for this mesh).
    [[nodiscard]] bool culls_back_faces() const noexcept;
    /// Format of the albedo texture on the GPU (RGBA32F where filterable, else RGBA16F).
    [[nodiscard]] VkFormat albedo_format() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// True when the mesh is closed (vertices welded by exact position, every edge used by
/// exactly two triangles, once in each direction) and its signed volume is positive
/// (counter-clockwise seen from outside). A camera outside such a mesh sees no back face.
[[nodiscard]] bool is_closed_outward(const Mesh& mesh);

/// The raster passes' vertices and indices, what Renderer uploads: one vertex per distinct
/// (position, atlas coordinate) pair among the triangles' corners, in first-use order, and 3
/// indices per triangle in triangle order. An indexed draw shades a vertex that neighbouring
/// triangles share once (lavapipe's vertex cache), where a non-indexed one shaded every corner:
/// on the 204,800-triangle knot at 512 px the G-buffer pass went from 14.9 to 11.3 ms (median GPU
/// time; reordering for the vertex cache with meshoptimizer gained nothing measurable more).
struct IndexedVertices {
    std::vector<shared::RenderVertex> vertices;
    std::vector<uint32_t> indices;
};
[[nodiscard]] IndexedVertices index_vertices(const Mesh& mesh, std::span<const glm::vec2> corner_uv);

/// Reorders each level's range of `mesh.indices` into clusters (meshopt_buildMeshlets, at most 64
/// vertices and 124 triangles each, the same triangles) and returns each level's clusters. With
/// patches, each patch's range is clustered on its own (TriangleCluster::patch), in their order.
[[nodiscard]] std::vector<std::vector<TriangleCluster>> cluster_levels(IndexedVertices& mesh,
                                                                       std::span<const LevelOfDetail> levels,
                                                                       std::span<const MeshPatch> patches = {});

/// Levels of detail of `mesh` (Options::lod_max_error_px). Level 0 is every triangle, reordered
/// into patches of at most `patch_triangles` (median splits of the triangles' centroids along the
/// longest side of their box). Level k is each patch simplified on its own by meshoptimizer
/// (meshopt_simplify, edge collapses under a quadric error, seams between atlas charts kept, the
/// patch's border locked) to about 1/2^k of its triangles, appended to `mesh.indices`. A simplified
/// patch is kept only if its border is its level 0's, it adds no fold (an edge walked twice the
/// same way, a triangle with two corners at one place) and walks no directed edge another patch
/// walks at any level; else the patch keeps its level before. So any mix of levels, one per
/// patch, is as closed as the mesh. Stops after `max_levels` levels, below 1,000 triangles, or
/// when a level keeps more than 3/4 of the one before (the simplifier stopped at the topology or
/// the borders). The vertices are not changed, so every level reads the same vertex buffer and
/// atlas coordinates. A level's error is its patches' largest.
[[nodiscard]] LevelsOfDetail build_levels_of_detail(IndexedVertices& mesh, std::size_t max_levels = 4,
                                                    std::size_t patch_triangles = kPatchTriangles);
/// The coarsest of `levels` whose error, seen by `camera` at the nearest point of the sphere
/// (`center`, `radius`) that bounds the mesh, is at most `max_error_px` pixels: error x focal /
/// distance, the distance at least `radius` / 100. Level 0 when none is or max_error_px <= 0.
[[nodiscard]] std::size_t choose_level_of_detail(std::span<const LevelOfDetail> levels, const Camera& camera,
                                                 const glm::dvec3& center, double radius, double max_error_px);

} // namespace specula::render
