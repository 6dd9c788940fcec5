#pragma once
// The albedo texture (pipeline.md section 3.9): particles -> atlas texels, for either atlas
// mode. Every owned texel (interior and gutter: gutters are particles clamped to the
// triangle's edge, solved like the others) gets its particle's albedo. Particles without a
// value (no view sees them, or no valid sample) are inpainted from their neighbours in the atlas:
//   1. same patch: repeatedly, every empty texel with filled 8-neighbours OWNED BY THE SAME
//      TRIANGLE takes their mean, until nothing changes;
//   2. across patches: the same with any owned filled 8-neighbour, alternating with step 1;
//   3. what is still empty (a patch no filled texel touches) gets the mean of all filled texels.
// Then the texels no triangle owns, so that no filter, at any mip level, reads an unfilled
// (black) texel:
//   4. gutters: kGutterDilationPasses rings around the owned texels, each texel the mean of
//      its filled 8-neighbours in the rings before (with the chart atlas's margins, a bilinear
//      lookup inside a chart at mip level 0 or 1 reads only the chart and these rings,
//      geometry/chart_atlas.h);
//   5. the rest by pull-push (a smooth blend of the charts around).
// Each step's count is reported.
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "core/image.h"

#include <filesystem>
#include <vector>

namespace specula {

/// Rings of unowned texels step 4 fills around the owned ones (the chart atlas's margin).
inline constexpr int kGutterDilationPasses = 3;

struct AlbedoTextureStats {
    std::size_t texels = 0;            ///< owned texels (= particles)
    std::size_t solved = 0;            ///< from their own solve
    std::size_t filled_same_patch = 0; ///< inpainted from neighbours of the same triangle
    std::size_t filled_across = 0;     ///< inpainted across patches
    std::size_t filled_global = 0;     ///< got the global mean
    std::size_t filled_dilation = 0;   ///< unowned texels filled by the gutter dilation (step 4)
    std::size_t filled_pull_push = 0;  ///< unowned texels filled by pull-push (step 5)
    double seconds = 0.0;
};

struct AlbedoTexture {
    Image image; ///< linear RGB rho, atlas width x height
    AlbedoTextureStats stats;
};

/// `albedo[p]` and `valid[p]` per particle (parallel to `particles`).
[[nodiscard]] AlbedoTexture make_albedo_texture(const Atlas& atlas, std::span<const Particle> particles,
                                                std::span<const glm::vec3> albedo, std::span<const std::uint8_t> valid);

/// From a solve's outputs: valid = status has kLambertOk.
[[nodiscard]] AlbedoTexture make_albedo_texture(const Atlas& atlas, std::span<const Particle> particles,
                                                const LambertOutputs& solve);

/// Writes `stem`.png (sRGB, 8 bits) and, with `exr`, `stem`.exr (linear float).
void write_albedo_texture(const AlbedoTexture& texture, const std::filesystem::path& stem, bool exr = true);

} // namespace specula
