#pragma once
// In-memory synthetic scenes for the diffuse tests: a preset rendered by engine/synth under
// the thesis rig (train views only), quantized as the chosen file format would be (png8 /
// png16 sRGB, or exr float) and flagged exactly as load_capture flags pixels, then the atlas,
// particles and visibility. Truth: the preset's albedo texture at each particle's mesh UV.
#include "diffuse/lambert_solve.h"
#include "geometry/atlas.h"
#include "synth/synth.h"

#include <functional>
#include <span>
#include <string>
#include <vector>

namespace specula::test {

struct SceneOptions {
    std::string preset = "can";
    bool lambertian = true;
    int size = 128;
    int views = 8;
    int lights = 6;
    double exposure = 1.0;
    synth::ImageFormat format = synth::ImageFormat::Exr;
    double noise_sigma = 0.0;
    double texels_per_pixel = 1.0;
    bool force_rays = false;
    std::vector<double> light_angles_deg; // empty: the rig default
    std::function<void(synth::Preset&)> edit_preset; // applied before rendering (another texture)
    std::function<void(synth::Rig&)> edit_rig;       // applied before rendering (other lights)
};

struct DiffuseScene {
    synth::Preset preset;
    Capture capture;
    Atlas atlas;
    ParticleSet particles;
    Visibility visibility;
    std::vector<glm::vec3> truth; // per particle, linear rho
    std::size_t clipped_pixels = 0;
    double seconds = 0.0;

    [[nodiscard]] LambertInputs inputs() const {
        return lambert_inputs(capture, particles.particles, visibility);
    }
};

[[nodiscard]] DiffuseScene make_scene(const SceneOptions& options);

/// The stages after the images, for `s.capture` (rendered by make_scene, or loaded from a
/// `specula synth` folder) of `s.preset`: the atlas sized by the views with train frames (as
/// reconstruct sizes it, so its texels are those of reconstruct's albedo.exr), particles,
/// visibility, truth.
void build_scene_stages(DiffuseScene& s, double texels_per_pixel = 1.0, bool force_rays = false);

/// The scene the kernel conformance tests share (glossy cologne, 96 px, 6 views, png8,
/// exposure 2: highlights and clipping exercise every rejection path). Built once per binary.
[[nodiscard]] const DiffuseScene& conformance_scene();

/// RMSE of rho over the particles in `select` (all channels), and the count.
struct AlbedoError {
    double rmse = 0.0;
    double max_abs = 0.0;
    std::size_t count = 0;
};
[[nodiscard]] AlbedoError albedo_error(const DiffuseScene& scene, const LambertOutputs& out,
                                       const std::vector<std::uint8_t>& select);
/// The same for any per-particle estimate against any per-particle truth.
[[nodiscard]] AlbedoError albedo_error(std::span<const glm::vec3> estimate, std::span<const glm::vec3> truth,
                                       const std::vector<std::uint8_t>& select);

/// The error on "texels shadowed in some frames" (issue 3: no baked shadows): particles in
/// `select` that the solve gave a value (kLambertOk), that some frame of a view that sees them
/// leaves unlit (rejected_shadow > 0: cast shadow, or facing away from the light) and some
/// frame lights. Over all channels of those particles.
struct ShadowedTexelError {
    std::size_t count = 0;    ///< particles
    double signed_mean = 0.0; ///< mean of (estimate - truth): negative when shadows are baked in
    double median_abs = 0.0;  ///< median |estimate - truth|
    double rmse = 0.0;
};
[[nodiscard]] ShadowedTexelError shadowed_texel_error(const DiffuseScene& scene, const LambertOutputs& out,
                                                      const std::vector<std::uint8_t>& select);

/// The truth box-filtered over each particle's atlas texel: the preset's texture averaged over
/// the parallelogram that one texel square of the particle's patch covers in texture space
/// (the patch's affine map, atlas.h), centred on the particle's uv (a gutter texel's clamped
/// point), from `samples` x `samples` bilinear lookups. The mean value of the albedo over the
/// surface the texel stands for, the value a mipmap level holds (see seen_texels.cpp).
[[nodiscard]] std::vector<glm::vec3> texel_box_truth(const DiffuseScene& scene, int samples = 8);

/// The albedo an atlas texture shows against the truth, over the surface the texels in
/// `select` cover: at `samples` x `samples` points of each texel square that lie inside its
/// triangle's patch (the points a renderer reads for that triangle), the texture's bilinear
/// value there (core/image.h texel convention) against the preset's albedo at the same
/// surface point. Unlike albedo_error, which compares texel centres, this scores the albedo
/// as a function, between texel centres too.
[[nodiscard]] AlbedoError surface_error(const DiffuseScene& scene, const Image& texture,
                                        const std::vector<std::uint8_t>& select, int samples = 4);

/// Particles whose truth the images resolve: every texture texel within `radius_pixels`
/// image pixels (converted to texels with the triangle's footprint in the view that sees the
/// particle best, i.e. with the largest projected area among the views whose `seen` bit is
/// set) of the particle's UV differs by at most `tol` from the truth. Elsewhere the error is
/// the images' resampling of a texture finer than their pixels, not the solve's (see
/// diffuse_test.cpp). Particles no view sees are not flat.
[[nodiscard]] std::vector<std::uint8_t> flat_truth(const DiffuseScene& scene, double radius_pixels, float tol);

} // namespace specula::test
