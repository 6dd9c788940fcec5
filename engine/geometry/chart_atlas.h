#pragma once
// The chart atlas (AtlasMode::Charts, the default; pipeline.md section 1): connected UV
// charts, each flattened by a least-squares conformal map, packed into one texture.
// Vertices are shared within a chart, so the bundle's mesh keeps the input's vertices
// except along the seams (charts' borders), and a tool like Blender sees a connected,
// editable surface instead of loose triangles.
//
// 1. Charts. Triangles are adjacent across a mesh edge (by position index) used by
//    exactly two consistently wound triangles whose dihedral angle is at most
//    kChartCreaseDegrees. A chart grows from a seed (the lowest-numbered unassigned
//    triangle) over that adjacency, the triangle whose normal is closest to the chart's
//    area-weighted mean normal first, taking a triangle only while its normal stays
//    within kChartConeDegrees of that mean (Specula's heuristic: such a chart is nearly a
//    height field over its mean plane, so it flattens without folding). Lloyd iterations
//    of variational shape approximation on normals (Cohen-Steiner, Alliez and Desbrun
//    2004) then regrow all charts at once from their triangles closest to their mean
//    normals, borders are straightened (a triangle with two neighbours in another chart
//    moves there), and neighbouring charts merge, smallest first, while the union's
//    normals stay within the cone (fewer, larger charts: fewer seams, fewer split vertices).
// 2. Flattening: the least-squares conformal map (LSCM) of Levy, Petitjean, Ray and
//    Maillot 2002, "Least squares conformal maps for automatic texture atlas generation"
//    (SIGGRAPH): per triangle, with E_j the complex edge opposite corner j in the
//    triangle's own orthonormal frame and U_j = u_j + i v_j,
//        sum_j E_j U_j = 0        (dU/d(zbar) = 0: the map is conformal on the triangle),
//    weighted by 1 / sqrt(area), in least squares over the chart with two vertices (an
//    approximate diameter) pinned; solved by the normal equations (Eigen's sparse
//    Cholesky, SimplicialLDLT).
// 3. Checks, per chart, after scaling its flattening to the chart's surface area: every
//    triangle keeps its orientation, sigma1 / sigma2 of its Jacobian (angle distortion)
//    is at most kChartMaxAngleDistortion, sigma1 sigma2 (area distortion) lies within
//    [1 / kChartMaxAreaDistortion, kChartMaxAreaDistortion], the chart's boundary does
//    not cross itself, and (from 16 triangles) the chart fills at least kChartMinRectFill
//    of its smallest bounding rectangle (curved bands and rings would waste the texture).
//    A chart that fails is split in two (breadth-first regions
//    grown from its two farthest triangles, each connected) and both are flattened again.
// 4. Texel density: a chart's scale gives it sum over its triangles of
//    kChartTexelsPerPatchTexel x texels_per_pixel x the triangle's pixel area in its best
//    train view (best_pixel_footprint, which sizes the patchwork's patches; a triangle no
//    camera sees asks for min_patch^2 / 2 texels); without cameras, texels follow surface
//    area, scaled to fill the budget. Why 1.5: a patch holds texels_per_pixel x footprint
//    texels inside its triangle, but each triangle also owns a ring of gutter texels that
//    sample its edges (2.9x the interior texels on the can at 512 px, 6.8x at 256 px),
//    which the renderer interpolates as well; charts have gutters only at their borders.
//    Measured at 256 px (README "The atlas"): 1.5 scores 0.1 to 0.9 dB more masked test
//    PSNR than 1.0 on every preset, for 1.5x the particles, still 26-41% of the
//    patchwork's; on the sphere at 128 px, whose checker edges lie on mesh edges (the
//    patchwork's best case: its patches keep them sharp), 1.0 fell 1.5 dB below the
//    patchwork, 1.5 0.7 dB.
// 5. Packing: each chart is turned to its smallest bounding rectangle (one side lies along
//    an edge of the convex hull: Freeman and Shapira 1975, "Determining the minimum-area
//    encasing rectangle for an arbitrary closed curve"). Its reserved texels, those whose
//    centers lie within kChartMargin + 0.5 of its triangles, are rasterized to a bitmap
//    (in cells of several texels on large atlases, so a search stays within about 768
//    cells across). Charts, largest first, go first fit on the atlas's occupancy bitmap:
//    of four quarter-turn orientations, the position whose bottom is highest (then
//    leftmost), scanning rows top down, bit-parallel over columns. Reserved texels never
//    overlap, so charts' triangles stay 2 kChartMargin apart (were two points closer, the
//    texel center nearest their midpoint would be reserved by both); a chart may sit in
//    another's ring or hollow. Two widths are tried (the square of the expected area and
//    1.25x wider), the smaller texture kept; sides are rounded up to multiples of 4 so that
//    mip levels 1 and 2 halve exactly. When the budget is exceeded every chart is scaled
//    by one factor until it fits, and the summary says so.
// 6. Texels. A texel whose center lies in a triangle (in_patch of its barycentric
//    coordinates; the first triangle of the chart wins on a shared edge) is interior; a
//    texel within Chebyshev distance kChartGutterReach = 1.25 of the chart's triangles (the
//    texels a bilinear lookup inside the chart can read, within distance 1, with a quarter
//    texel to spare for a GPU's sub-texel rounding, as the patchwork keeps) is a gutter
//    texel of the chart's triangle closest to its center (Euclidean: the particle shows
//    the chart's closest point). Charts' triangles are at least 2 kChartMargin = 6 texels
//    apart, so a bilinear lookup at mip level 0 or 1 inside a chart reads only that
//    chart's texels and the albedo texture's dilation of them (diffuse/albedo_texture.h).
#include "geometry/atlas.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace specula {

inline constexpr double kChartTexelsPerPatchTexel = 1.5;  ///< chart texels per texel a patch would hold (step 4)
inline constexpr double kChartConeDegrees = 60.0;        ///< a chart's normals stay within this of its mean normal
inline constexpr double kChartCreaseDegrees = 60.0;      ///< edges with a sharper dihedral angle are seams
inline constexpr double kChartMaxAngleDistortion = 2.0;  ///< sigma1 / sigma2 per triangle
inline constexpr double kChartMaxAreaDistortion = 3.0;   ///< texel area per surface area, relative to the chart's
inline constexpr std::uint32_t kChartMargin = 3;         ///< empty texels around each chart's triangles, per side
inline constexpr double kChartGutterReach = 1.25;        ///< gutter texels: centers within this (Chebyshev) of the chart
inline constexpr double kChartMinRectFill = 0.5;         ///< a chart fills at least this of its bounding rectangle

/// Charts and their flattening, before scaling and packing.
struct ChartSet {
    std::size_t charts = 0;
    std::vector<std::uint32_t> chart_of; ///< per triangle
    std::vector<glm::dvec2> corner_uv;   ///< 3 per triangle: the chart's flattening, in surface units (its UV area = its area)
    std::size_t seam_edges = 0;          ///< shared mesh edges whose triangles lie in different charts
    std::size_t crease_edges = 0;        ///< shared edges sharper than kChartCreaseDegrees
    std::size_t splits = 0;              ///< charts split because their flattening failed a check
};

/// Segments the mesh into charts and flattens each (steps 1 to 3 above).
[[nodiscard]] ChartSet make_charts(const Mesh& mesh);

/// Builds the chart atlas (steps 1 to 6); called by build_atlas for AtlasMode::Charts.
[[nodiscard]] Atlas build_chart_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options);

/// The atlas a textured mesh already has (a bundle's: export/bundle.h, or any glTF's), for the
/// particles of a bundle (evaluate/indirect_light.h): corners from the vertices' texture
/// coordinates on a width x height texture; charts are the triangles joined through shared
/// vertices (a vertex holds one coordinate); texels owned as step 6 assigns them. On a bundle
/// that build_chart_atlas laid out, this gives back its charts and owners (up to the charts'
/// numbering and float rounding of the coordinates). Overlapping charts (a foreign glTF's
/// mirrored halves) share texels: the first triangle wins. A triangle without area in the
/// texture owns no texel. Throws Error when the mesh has no texture coordinates or one is not
/// finite, or the size is 0 or above Atlas::kMaxDimension.
[[nodiscard]] Atlas atlas_from_texture_coordinates(const Mesh& mesh, std::uint32_t width, std::uint32_t height);

/// Singular values (sigma1 >= sigma2) of the linear map taking the 3D triangle (p0, p1, p2)
/// to the 2D triangle (q0, q1, q2); sigma2 < 0 when the map flips orientation.
[[nodiscard]] glm::dvec2 triangle_stretch(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2, const glm::dvec2& q0,
                                          const glm::dvec2& q1, const glm::dvec2& q2);

} // namespace specula
