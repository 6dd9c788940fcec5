#pragma once
// Ground-truth renderer of synthetic captures (CPU, Embree). For every pixel,
// one ray through the pixel centre (capture-format.md pixel convention); at its
// hit, with the interpolated unit shading normal n, light direction u, view
// direction v, distance d to the light (capture-format.md, "Radiometry"):
//     pixel = f(u, v) * I * max(0, n.u) / d^2     when the light is visible
//     pixel = 0                                   when it is shadowed
//     f     = albedo(uv) / pi * k_d(n.u, n.v) + f_s(u, v)
// with k_d = material_diffuse_factor and f_s from shaders/shared/material.h, the one
// evaluation of every family that the kernels use (engine/material/material.h):
//   lafortune: k_d = 1, f_s = lafortune_eval_rgb(Cx, Cz, N, u_local, v_local), u_local and
//              v_local in the tangent frame of shaders/shared/tangent_frame.h;
//   coated:    k_d = T(n.u) T(n.v) / T(1)^2, f_s = tint F D G1 G1 / (4 (n.u) (n.v))
//              (shared/coated.h), material_specular in double.
// No noise and no clipping here (noise.h).
//
// Interreflections (Interreflection, bounces N >= 1): the pixel adds the light the object
// reflects onto itself, by path tracing from the primary hit x (the direct term above is
// unchanged). Each of S paths leaves x in a direction w drawn from a mixture of cosine-weighted
// directions and the material's specular lobe (path_sampling.h), with density pdf(w); at the
// point y it hits it picks up the direct light at y (the formula above, with v = -w), and it
// continues from y in the same way, up to N bounces:
//     pixel += 1/S sum over paths of  sum_k T_k * f_{y_k}(u, -w_k) I max(0, n.u) / d^2
//     T_1 = f_x(w_1, v) (n.w_1) / pdf(w_1),  T_{k+1} = T_k * f_{y_k}(w_{k+1}, -w_k) (n.w_{k+1}) / pdf(w_{k+1})
// (with cosine sampling alone, (n.w) / pdf(w) = pi). At each vertex the shading normal is
// taken on the side the ray arrived from. Paths that leave the object see black (no
// environment); directions below the geometric surface carry no light. The first direction of
// each path is stratified (a Hammersley set, rotated per pixel); the rest are independent. A
// pixel's random numbers depend only on (seed, frame, pixel): images do not depend on the
// thread count. Unbiased: light reflected by a glossy point toward a diffuse one (a caustic of
// the highlight) is found only by chance, and is the noise that remains.
#include "material/lafortune.h"
#include "material/material.h"
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/image.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

namespace specula::synth {

/// One isotropic Lafortune lobe per RGB channel (thesis eq. 2.1, table 5.2 form).
using LafortuneRgb = specula::LafortuneRgb; // engine/material/lafortune.h

/// The known surface of a synthetic object: albedo (texture or constant) and a specular model
/// of one family: a Lafortune lobe (the default), or coated parameters.
struct Material {
    /// Linear RGB albedo texture sampled at the mesh's texture coordinates
    /// (see sample_albedo). Empty: `albedo_value` everywhere.
    Image albedo_texture;
    glm::vec3 albedo_value{0.5f};
    /// The lafortune family's lobe (zero: Lambertian). Must be zero when `coated` is set: a
    /// material has one family, and nothing reading `lobe` may take it for a coated truth.
    LafortuneRgb lobe;
    /// Set: the coated family (shared/coated.h) with these parameters, and rho the albedo.
    std::optional<CoatedParams> coated;

    [[nodiscard]] MaterialFamily family() const noexcept { return coated ? MaterialFamily::Coated : MaterialFamily::Lafortune; }
    /// The specular model rendered: `*coated` when set, `lobe` otherwise.
    [[nodiscard]] SpecularModel specular() const { return coated ? SpecularModel(*coated) : SpecularModel(lobe); }
};

/// Bilinear lookup with the texel centre convention: texel (i, j) is centred at
/// ((i + 0.5) / w, (j + 0.5) / h); v = 0 is the top row (glTF); u repeats, v clamps.
[[nodiscard]] glm::vec3 sample_albedo(const Image& texture, const glm::vec2& uv);

/// Indirect light of a frame: bounces = 0 renders direct light only, exactly as without it.
struct Interreflection {
    static constexpr int kMaxBounces = 4;     // no Russian roulette needed up to here
    static constexpr int kMaxSamples = 65536; // a bound on a frame's time, far past any need
    int bounces = 0;                          // reflections before the last one, toward the camera
    int samples = 512;                        // paths per pixel (the default: docs/pipeline.md section 12)
    std::uint64_t seed = 1;
    std::uint64_t frame = 0; // the frame's index in its capture: each frame has its own samples
    /// Draw directions from the specular lobe too (path_sampling.h); false: cosine-weighted
    /// only (the same mean with more noise on glossy materials: for tests and comparisons).
    bool lobe_sampling = true;
};

struct RenderedFrame {
    Image color;                     // linear RGB radiance, no noise, no clipping
    std::vector<std::uint8_t> mask;  // w * h, 255 where the centre ray hits the object
    std::size_t lit_pixels = 0;      // object pixels facing and seeing the light
    std::size_t shadowed_pixels = 0; // object pixels facing the light but occluded
};

/// Owns the Embree device and scene of one mesh (move-only). Rendering is
/// read-only and thread-safe; results do not depend on the thread count.
class Renderer {
public:
    Renderer(Mesh mesh, Material material);
    ~Renderer();
    Renderer(Renderer&&) noexcept;
    Renderer& operator=(Renderer&&) noexcept;
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// Renders one frame: `threads` threads over rows (core/parallel.h; at least 1). Throws Error
    /// when `indirect` has bounces outside [0, kMaxBounces] or, with bounces, samples outside [1, kMaxSamples].
    [[nodiscard]] RenderedFrame render(const Camera& camera, const PointLight& light, int threads = 2,
                                       const Interreflection& indirect = {}) const;

    /// Only the object mask of a view (primary rays, no shading).
    [[nodiscard]] std::vector<std::uint8_t> render_mask(const Camera& camera, int threads = 2) const;

    [[nodiscard]] const Mesh& mesh() const noexcept;
    [[nodiscard]] const Material& material() const noexcept;
    /// Offset of shadow-ray origins along the geometric normal (scale-relative).
    [[nodiscard]] float shadow_epsilon() const noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// Convenience: builds a Renderer and renders one frame.
[[nodiscard]] RenderedFrame render_frame(const Mesh& mesh, const Material& material, const Camera& camera,
                                         const PointLight& light, int threads = 2, const Interreflection& indirect = {});

} // namespace specula::synth
