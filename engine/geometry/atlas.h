#pragma once
// The texture atlas: where each triangle's texels lie. Two modes fill the same
// Atlas (corner texel coordinates per triangle corner, the owner of each texel):
//
//   - charts (the default, geometry/chart_atlas.h): connected UV charts flattened by
//     least-squares conformal maps, seams only where a chart would distort too much or
//     at sharp creases, vertices shared within a chart;
//   - patchwork (the thesis's, below): every triangle its own patch, no vertex shared.
//
// Common to both. Bilinear filtering at a point p reads the 2x2 texels whose centers
// lie within Chebyshev distance 1 of p (per axis |c - p| <= 1, the farther ones with
// weight 0). A texel is owned by a triangle when its center lies in the region that
// bilinear lookups inside the triangle's patch (or chart) can read; owned texels whose
// centers lie inside their triangle are interior texels, with barycentric (s, t) = the
// center's coordinates in the triangle; the others are gutter texels, with (s, t) of the
// closest point of the triangle (in texel space), so texels on both sides of a shared
// mesh edge show points of that same edge. Surface particles are the owned texels
// (geometry/particles.h).
//
// Texture coordinates: texel (x, y) covers [x, x+1) x [y, y+1); row 0 is the
// first row of the image in memory. Normalized uv = texel coordinates /
// (width, height), i.e. uv (0, 0) is the top-left corner of the first texel,
// the convention of Vulkan and glTF. Every triangle has positive signed area
// cross(c1 - c0, c2 - c0) in texel coordinates.
//
// ---- The patchwork (thesis section 3.1.2, figure 4.1) ----
// Every triangle owns a right-triangle patch of texels, two triangles share one
// square block.
//
// Layout of one block (texel units, origin at the block's corner, x right,
// y down the rows). A block for leg length n (texels) is W = n + 4 texels
// square; a = kPatchInset = 0.75:
//
//     lower half (half 0): v0 = (a, a),         v1 = (a + n, a),       v2 = (a, a + n)
//     upper half (half 1): v0 = (W - a, W - a), v1 = (W - a - n, W - a), v2 = (W - a, W - a - n)
//
// The two right angles sit in opposite corners, so the hypotenuses are
// parallel, at x + y = n + 1.5 and x + y = n + 6.5: the halves are offset by
// 5/sqrt(2) texels across the diagonal.
//
// Why bilinear filtering never bleeds. The texels any point of a patch R can
// read are those with centers in R (+) [-1, 1]^2, the Minkowski sum
// ("footprint"). A texel is owned by a triangle exactly when its center is
// in that triangle's footprint: for the lower half
//     x >= a - 1, y >= a - 1, x <= a + n + 1, y <= a + n + 1, x + y <= 2a + n + 2
// (the upper half mirrors it through the block's center). Texel centers sit at
// half-integers, so their x + y is an integer; the lower footprint ends at
// x + y = n + 3.5, the upper one starts at n + 4.5: no center lies in both, and
// the centers on the line x + y = n + 4 belong to neither. Toward the block's
// sides the footprints end at -0.25 and W + 0.25, inside the half texel
// beyond the first and last texel centers, so neighbouring blocks never read
// each other either. Every footprint keeps >= 0.25 texel from any texel it does
// not own, so GPU filtering with 1/256-texel sub-texel precision cannot bleed
// either (tests/geometry/atlas_test.cpp checks this with 0.2-texel margins).
//
// The patch coordinates (s, t) of a patch are isotropic texel coordinates (the
// patch is right-isosceles), so clamping (s, t) to the triangle gives the
// closest point in texel space.
//
// Patch sizes follow each triangle's pixel footprint in the view that sees it
// best (largest projected area among cameras it faces): a patch of leg n has
// n^2 / 2 texels, set to texels_per_pixel times the projected pixel area.
// Without cameras, patch area follows the triangle's surface area, scaled to
// fill the budget. Triangles are sorted by size and paired (a block takes the
// larger leg of its pair), and blocks are packed in shelves. When the packed
// atlas would exceed the budget (max_width x max_height), every desired leg is
// scaled by the same factor until it fits, and the summary says so.
#include "capture/camera.h"
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula {

/// Charts: connected LSCM charts (geometry/chart_atlas.h); Patchwork: the thesis's one patch per triangle.
enum class AtlasMode { Charts, Patchwork };
[[nodiscard]] const char* to_string(AtlasMode mode);
/// "charts" or "patchwork"; nullopt otherwise.
[[nodiscard]] std::optional<AtlasMode> atlas_mode_from_string(std::string_view name);

struct AtlasOptions {
    AtlasMode mode = AtlasMode::Charts;   ///< charts (default) or the thesis's patchwork
    std::uint32_t max_width = 4096;       ///< budget: the atlas never exceeds max_width x max_height
    std::uint32_t max_height = 4096;
    double texels_per_pixel = 1.0;        ///< patch texels per pixel of the best view (> 1: sharper edges for other views, at a cost)
    std::uint32_t min_patch = 1;          ///< patchwork: leg length bounds (texels); charts: a triangle no camera
    std::uint32_t max_patch = 512;        ///< sees asks for min_patch^2 / 2 texels, as its patch would hold
};

/// Where one triangle's patch lies in the atlas.
struct PatchPlacement {
    std::uint32_t block_x = 0; ///< the block's top-left texel
    std::uint32_t block_y = 0;
    std::uint32_t size = 0;    ///< leg length n (texels); the block is n + 4 square
    std::uint32_t half = 0;    ///< 0: lower-left half of the block, 1: upper-right half
};

/// Where one chart lies in the atlas (chart mode).
struct ChartPlacement {
    std::uint32_t x = 0;         ///< the chart's rectangle (texels), its margins included
    std::uint32_t y = 0;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t triangles = 0; ///< triangles in the chart
    std::uint32_t vertices = 0;  ///< distinct mesh positions of its triangles (shared within the chart)
};

/// What the atlas chose and why, for the report.
struct AtlasSummary {
    std::string mode;                     ///< "charts" or "patchwork"
    std::string size_source;              ///< "cameras" or "surface area"
    std::size_t triangles = 0;
    std::size_t blocks = 0;               ///< patchwork: square blocks (two triangles each)
    std::size_t charts = 0;               ///< charts: connected charts
    std::size_t seam_edges = 0;           ///< charts: mesh edges shared by two triangles of different charts
    std::size_t crease_edges = 0;         ///< charts: shared edges whose dihedral angle exceeds the crease angle
    std::size_t mesh_vertices = 0;        ///< the mesh's positions
    std::size_t atlas_vertices = 0;       ///< vertices once split to one atlas coordinate each (what the bundle gets)
    std::uint32_t chart_triangles_max = 0;
    std::uint32_t chart_triangles_median = 0;
    double angle_distortion_mean = 0.0;   ///< charts: area-weighted mean of sigma1 / sigma2 over triangles (1: conformal)
    double angle_distortion_max = 0.0;
    double area_distortion_min = 0.0;     ///< charts: smallest / largest texel area per surface area of a triangle,
    double area_distortion_max = 0.0;     ///<   relative to its chart's mean (1: the chart's density)
    double area_distortion_p05 = 0.0;     ///< area-weighted 5% / 95% quantiles of the same
    double area_distortion_p95 = 0.0;
    std::size_t triangles_seen_by_no_camera = 0; ///< they got min_patch (only with cameras)
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t patch_min = 0;          ///< patchwork: leg lengths actually used
    std::uint32_t patch_max = 0;
    double patch_mean = 0.0;
    std::uint32_t patch_median = 0;
    std::size_t interior_texels = 0;
    std::size_t gutter_texels = 0;
    double fill_ratio = 0.0;              ///< owned texels / (width * height)
    double interior_ratio = 0.0;          ///< interior texels / (width * height)
    double desired_texels = 0.0;          ///< sum of desired patch areas before any budget scaling
    bool budget_clipped = false;          ///< the budget forced patches smaller than the footprint asked for
    double budget_scale = 1.0;            ///< factor applied to every desired leg length (< 1 when clipped, or in
                                          ///< surface-area mode when the fill estimate overshot)
    std::vector<std::string> notes;       ///< human-readable remarks (clipping, unseen triangles)
};

struct Atlas {
    static constexpr std::uint32_t kEmpty = 0xFFFFFFFFu; ///< owner of a texel no triangle uses
    static constexpr double kPatchInset = 0.75;          ///< a, see the header comment
    static constexpr std::uint32_t kBlockPadding = 4;    ///< block side = leg + kBlockPadding
    static constexpr std::uint32_t kMaxDimension = 32767; ///< texel coordinates fit 15 bits (see Particle)

    AtlasMode mode = AtlasMode::Patchwork;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<glm::dvec2> corners;     ///< 3 per triangle: corner texel coordinates (both modes)
    std::vector<glm::vec2> corner_uv;    ///< 3 per triangle (v0, v1, v2), normalized to [0, 1]
    std::vector<std::uint32_t> owner;    ///< width * height, row-major: the triangle owning each texel, or kEmpty
    std::vector<PatchPlacement> patches; ///< patchwork: one per triangle (empty for charts)
    std::vector<std::uint32_t> chart_of; ///< charts: the chart of each triangle (empty for the patchwork)
    std::vector<ChartPlacement> charts;  ///< charts: one per chart (empty for the patchwork)
    AtlasSummary summary;

    [[nodiscard]] std::uint32_t owner_at(std::uint32_t x, std::uint32_t y) const { return owner[std::size_t(y) * width + x]; }
    /// Corner k (0..2) of a triangle's patch in texel coordinates (not normalized).
    [[nodiscard]] glm::dvec2 corner_texel(std::uint32_t triangle, int k) const { return corners[3 * std::size_t(triangle) + std::size_t(k)]; }
    /// Unclamped (s, t) of a point given in texel coordinates, in a triangle's patch:
    /// point = c0 + s (c1 - c0) + t (c2 - c0).
    [[nodiscard]] glm::dvec2 patch_bary(std::uint32_t triangle, const glm::dvec2& texel_point) const;
    /// (s, t) of the point of the triangle closest to `texel_point` in texel space (Euclidean):
    /// patch_bary for points inside, clamped to the triangle's edges for the others (gutter texels).
    [[nodiscard]] glm::dvec2 closest_bary(std::uint32_t triangle, const glm::dvec2& texel_point) const;
};

/// Projected area, in pixels, of each triangle in the camera that sees it best
/// (front-facing, in front of the camera, centroid inside the image); 0 when no camera does.
[[nodiscard]] std::vector<double> best_pixel_footprint(const Mesh& mesh, std::span<const Camera> cameras);

/// Builds the atlas in options.mode. Texel densities follow best_pixel_footprint(mesh, cameras),
/// or surface area when `cameras` is empty. Throws Error when even min_patch blocks (or
/// the charts at the smallest scale) do not fit the budget.
[[nodiscard]] Atlas build_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options = {});

/// Closest point of the standard triangle {s >= 0, t >= 0, s + t <= 1} to (s, t)
/// (Euclidean in (s, t), which is isotropic texel space for our right-isosceles patches).
[[nodiscard]] glm::dvec2 clamp_to_triangle(const glm::dvec2& st);

/// (s, t) of the point of the 2D triangle (c0, c1, c2) closest to p (Euclidean), with
/// point = c0 + s (c1 - c0) + t (c2 - c0). For a non-degenerate triangle.
[[nodiscard]] glm::dvec2 closest_point_bary(const glm::dvec2& c0, const glm::dvec2& c1, const glm::dvec2& c2, const glm::dvec2& p);

/// The vertices the atlas splits the mesh into: one per distinct (position index, atlas
/// coordinate) of the triangle corners, the count make_bundle (engine/export) writes.
[[nodiscard]] std::size_t atlas_vertex_count(const Mesh& mesh, const Atlas& atlas);

/// True when (s, t) lies in the standard triangle. Texel centers give (s, t)
/// that are multiples of 1/(4 n), so the 1e-9 tolerance only absorbs rounding.
[[nodiscard]] inline bool in_patch(const glm::dvec2& st) {
    constexpr double kTol = 1e-9;
    return st.x >= -kTol && st.y >= -kTol && st.x + st.y <= 1.0 + kTol;
}

/// Multi-line text of the summary for logs and the report.
[[nodiscard]] std::string describe(const AtlasSummary& summary);

} // namespace specula
