#pragma once
/// \file
/// Rendering a bundle (engine/export/bundle.h) with the offscreen renderer
/// (engine/render): what `specula render` does, and what evaluate() builds on.
///
///   BundleRenderer r(ctx, bundle, "out/object.glb");
///   Image img = r.render(camera, light, {.mode = render::Mode::Both}).color;
///   write_rendered_image("frame.png", img);   // .exr linear float, .png sRGB 8-bit
#include "capture/camera.h"
#include "capture/capture.h"
#include "core/image.h"
#include "export/bundle.h"
#include "gpu/context.h"
#include "render/renderer.h"

#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>
#include <string>
#include <string_view>

namespace specula::evaluate {

/// A render::Renderer over a bundle's mesh, atlas, Material (any specular family, as it is)
/// and (when present) cube-maps.
class BundleRenderer {
public:
    /// `name` (usually the bundle's path) is used in error messages. Throws Error when the
    /// bundle is inconsistent (no albedo, a vertex without an atlas coordinate).
    /// `options` as render::Renderer takes them (the viewer's levels of detail).
    BundleRenderer(gpu::Context& ctx, const Bundle& bundle, std::string name = "bundle", const render::Options& options = {});

    /// Renders one frame. Throws Error naming the bundle when `settings` asks for the
    /// factorized model and the bundle has no cube-maps.
    [[nodiscard]] render::Frame render(const Camera& camera, const PointLight& light, const render::Settings& settings);

    [[nodiscard]] bool has_factorization() const noexcept { return m_renderer.has_factorization(); }
    /// True when the bundle's material has a specular term to draw (any family, not zero).
    [[nodiscard]] bool has_specular() const noexcept { return m_renderer.has_specular(); }
    [[nodiscard]] render::Renderer& renderer() noexcept { return m_renderer; }
    /// From now on draws glTF's core material `core` (Bundle::core; absent: the diffuse-only core)
    /// instead of the bundle's model, analytic path only: what ordinary viewers show.
    void draw_core_material(const std::optional<CoreMaterial>& core);
    /// From now on draws the bundle's own model again (after draw_core_material).
    void draw_own_material();

private:
    std::string m_name;
    render::Renderer m_renderer;
};

/// The error a factorized render of a bundle without cube-maps gives (checked before any
/// GPU work, so a tool can refuse early). Throws Error naming the bundle; no-op otherwise.
void require_specular_model(const Bundle& bundle, render::SpecularPath model, std::string_view name);

/// A free camera: at `eye` looking at `target` (`up` roughly up), `width` x `height`
/// pixels, principal point at the centre, and either a vertical field of view in degrees
/// or a focal length in pixels (exactly one). Throws UsageError on degenerate input.
[[nodiscard]] Camera free_camera(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up, int width,
                                 int height, std::optional<double> fov_y_degrees, std::optional<double> focal_px);

/// Comma-separated numbers of a command-line option ("1,2,3"): exactly one of `counts`
/// values, each finite. Throws UsageError naming `option` and the expected `form`.
[[nodiscard]] std::vector<double> parse_numbers(const std::string& text, const std::string& option,
                                                std::initializer_list<std::size_t> counts, const std::string& form);

/// A free camera from "--camera eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z"
/// (free_camera's rules for the size and the field of view or focal length).
[[nodiscard]] Camera parse_free_camera(const std::string& text, int width, int height, std::optional<double> fov_y_degrees,
                                       std::optional<double> focal_px);

/// A point light from "--light x,y,z,intensity" or "x,y,z,r,g,b".
[[nodiscard]] PointLight parse_light(const std::string& text);

/// Writes a render by the path's extension: .exr linear 32-bit float; .png sRGB 8-bit
/// (clamped to [0, 1]). Throws UsageError for another extension.
void write_rendered_image(const std::filesystem::path& path, const Image& image);

} // namespace specula::evaluate
