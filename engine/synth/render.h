#pragma once
// Ground-truth renderer of synthetic captures (CPU, Embree). For every pixel,
// one ray through the pixel centre (capture-format.md pixel convention); at its
// hit, with the interpolated unit shading normal n, light direction u, view
// direction v, distance d to the light (capture-format.md, "Radiometry"):
//     pixel = f(u, v) * I * max(0, n.u) / d^2     when the light is visible
//     pixel = 0                                   when it is shadowed
//     f     = albedo(uv) / pi + lafortune_eval_rgb(Cx, Cz, N, u_local, v_local)
// with u_local, v_local in the tangent frame of shaders/shared/tangent_frame.h,
// the very definitions the GPU kernels use. No noise and no clipping here (noise.h).
#include "material/lafortune.h"
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/image.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace specula::synth {

/// One isotropic Lafortune lobe per RGB channel (thesis eq. 2.1, table 5.2 form).
using LafortuneRgb = specula::LafortuneRgb; // engine/material/lafortune.h

/// The known surface of a synthetic object: albedo (texture or constant) and one lobe.
struct Material {
    /// Linear RGB albedo texture sampled at the mesh's texture coordinates
    /// (see sample_albedo). Empty: `albedo_value` everywhere.
    Image albedo_texture;
    glm::vec3 albedo_value{0.5f};
    LafortuneRgb lobe;
};

/// Bilinear lookup with the texel centre convention: texel (i, j) is centred at
/// ((i + 0.5) / w, (j + 0.5) / h); v = 0 is the top row (glTF); u repeats, v clamps.
[[nodiscard]] glm::vec3 sample_albedo(const Image& texture, const glm::vec2& uv);

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

    /// Renders one frame: `threads` threads over rows (core/parallel.h; at least 1).
    [[nodiscard]] RenderedFrame render(const Camera& camera, const PointLight& light, int threads = 2) const;

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
                                         const PointLight& light, int threads = 2);

} // namespace specula::synth
