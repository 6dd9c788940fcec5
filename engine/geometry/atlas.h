#pragma once
// The thesis's "patchwork" texture atlas (section 3.1.2, figure 4.1): every
// triangle owns a right-triangle patch of texels, two triangles share one
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
// Why bilinear filtering never bleeds. Bilinear filtering at a point p reads
// the 2x2 texels whose centers lie within Chebyshev distance 1 of p (per axis
// |c - p| <= 1, the farther ones with weight 0). So the texels any point of a
// patch R can read are those with centers in R (+) [-1, 1]^2, the Minkowski
// sum ("footprint"). A texel is owned by a triangle exactly when its center is
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
// Texels owned by a triangle whose centers lie inside its patch are interior
// texels: their barycentric (s, t) = the center's coordinates in the patch.
// The others are gutter texels: (s, t) of the closest point of the patch,
// i.e. clamped to the triangle, so texels on both sides of a shared mesh edge
// show points of that same edge.
//
// Patch sizes follow each triangle's pixel footprint in the view that sees it
// best (largest projected area among cameras it faces): a patch of leg n has
// n^2 / 2 texels, set to texels_per_pixel times the projected pixel area.
// Without cameras, patch area follows the triangle's surface area, scaled to
// fill the budget. Triangles are sorted by size and paired (a block takes the
// larger leg of its pair), and blocks are packed in shelves. When the packed
// atlas would exceed the budget (max_width x max_height), every desired leg is
// scaled by the same factor until it fits, and the summary says so.
//
// Texture coordinates: texel (x, y) covers [x, x+1) x [y, y+1); row 0 is the
// first row of the image in memory. Normalized uv = texel coordinates /
// (width, height), i.e. uv (0, 0) is the top-left corner of the first texel,
// the convention of Vulkan and glTF.
#include "capture/camera.h"
#include "capture/mesh.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace specula {

struct AtlasOptions {
    std::uint32_t max_width = 4096;       ///< budget: the atlas never exceeds max_width x max_height
    std::uint32_t max_height = 4096;
    double texels_per_pixel = 1.0;        ///< patch texels per pixel of the best view (> 1: sharper edges for other views, at a cost)
    std::uint32_t min_patch = 1;          ///< leg length bounds (texels)
    std::uint32_t max_patch = 512;
};

/// Where one triangle's patch lies in the atlas.
struct PatchPlacement {
    std::uint32_t block_x = 0; ///< the block's top-left texel
    std::uint32_t block_y = 0;
    std::uint32_t size = 0;    ///< leg length n (texels); the block is n + 4 square
    std::uint32_t half = 0;    ///< 0: lower-left half of the block, 1: upper-right half
};

/// What the atlas chose and why, for the report.
struct AtlasSummary {
    std::string size_source;              ///< "cameras" or "surface area"
    std::size_t triangles = 0;
    std::size_t blocks = 0;
    std::size_t triangles_seen_by_no_camera = 0; ///< they got min_patch (only with cameras)
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t patch_min = 0;          ///< leg lengths actually used
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

    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<PatchPlacement> patches; ///< one per triangle
    std::vector<glm::vec2> corner_uv;    ///< 3 per triangle (v0, v1, v2), normalized to [0, 1]
    std::vector<std::uint32_t> owner;    ///< width * height, row-major: the triangle owning each texel, or kEmpty
    AtlasSummary summary;

    [[nodiscard]] std::uint32_t owner_at(std::uint32_t x, std::uint32_t y) const { return owner[std::size_t(y) * width + x]; }
    /// Corner k (0..2) of a triangle's patch in texel coordinates (not normalized).
    [[nodiscard]] glm::dvec2 corner_texel(std::uint32_t triangle, int k) const;
    /// Unclamped (s, t) of a point given in texel coordinates, in a triangle's patch.
    [[nodiscard]] glm::dvec2 patch_bary(std::uint32_t triangle, const glm::dvec2& texel_point) const;
};

/// Projected area, in pixels, of each triangle in the camera that sees it best
/// (front-facing, in front of the camera, centroid inside the image); 0 when no camera does.
[[nodiscard]] std::vector<double> best_pixel_footprint(const Mesh& mesh, std::span<const Camera> cameras);

/// Builds the atlas. Patch sizes follow best_pixel_footprint(mesh, cameras),
/// or surface area when `cameras` is empty. Throws Error when even min_patch
/// blocks do not fit the budget.
[[nodiscard]] Atlas build_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options = {});

/// Closest point of the standard triangle {s >= 0, t >= 0, s + t <= 1} to (s, t)
/// (Euclidean in (s, t), which is isotropic texel space for our right-isosceles patches).
[[nodiscard]] glm::dvec2 clamp_to_triangle(const glm::dvec2& st);

/// True when (s, t) lies in the standard triangle. Texel centers give (s, t)
/// that are multiples of 1/(4 n), so the 1e-9 tolerance only absorbs rounding.
[[nodiscard]] inline bool in_patch(const glm::dvec2& st) {
    constexpr double kTol = 1e-9;
    return st.x >= -kTol && st.y >= -kTol && st.x + st.y <= 1.0 + kTol;
}

/// Multi-line text of the summary for logs and the report.
[[nodiscard]] std::string describe(const AtlasSummary& summary);

} // namespace specula
