#include "evaluate/bundle_render.h"

#include "core/error.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace specula::evaluate {

namespace {

render::Scene scene_of(const Bundle& bundle, const std::vector<glm::vec2>& corner_uv) {
    // All K terms of the factorization, when there is one (docs/SPECULA_lafortune.md: cubeG/cubeH,
    // cubeTerms, parametrization): the renderer uploads them with the model.
    return render::Scene{.mesh = &bundle.mesh, .corner_uv = corner_uv, .albedo = &bundle.albedo, .material = bundle.material};
}

render::Renderer make_renderer(gpu::Context& ctx, const Bundle& bundle, const std::string& name,
                               const render::Options& options) {
    if (bundle.albedo.empty()) throw Error(name + ": the bundle has no albedo atlas");
    if (!bundle.mesh.has_texcoords())
        throw Error(name + ": mesh: every vertex needs an atlas coordinate (" + std::to_string(bundle.mesh.texcoords.size()) +
                    " texcoords for " + std::to_string(bundle.mesh.positions.size()) + " vertices)");
    const std::vector<glm::vec2> corner_uv = corner_uvs(bundle.mesh);
    return render::Renderer(ctx, scene_of(bundle, corner_uv), options);
}

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

} // namespace

void require_specular_model(const Bundle& bundle, render::SpecularPath model, std::string_view name) {
    if (model != render::SpecularPath::Factorized) return;
    if (!bundle.material.factorized)
        throw Error(std::string(name) +
                    ": the bundle has no factorization cube-maps (SPECULA_lafortune cube_g / cube_h): "
                    "render with --specular analytic, or reconstruct with the factorization");
}

BundleRenderer::BundleRenderer(gpu::Context& ctx, const Bundle& bundle, std::string name, const render::Options& options)
    : m_name(std::move(name)), m_renderer(make_renderer(ctx, bundle, m_name, options)) {}

void BundleRenderer::draw_core_material(const std::optional<CoreMaterial>& core) {
    const CoreMaterial c = core.value_or(CoreMaterial{});
    m_renderer.set_material(core_material_gpu(c), c.has_specular());
}

void BundleRenderer::draw_own_material() {
    const std::optional<SpecularModel> own = m_renderer.specular(); // set_material left the model as it was
    m_renderer.set_specular(own);
}

render::Frame BundleRenderer::render(const Camera& camera, const PointLight& light, const render::Settings& settings) {
    if (settings.specular == render::SpecularPath::Factorized && !m_renderer.has_factorization())
        throw Error(m_name +
                    ": the bundle has no factorization cube-maps (SPECULA_lafortune cube_g / cube_h): "
                    "render with --specular analytic, or reconstruct with the factorization");
    return m_renderer.render(camera, light, settings);
}

std::vector<double> parse_numbers(const std::string& text, const std::string& option, std::initializer_list<std::size_t> counts,
                                  const std::string& form) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            const double d = std::stod(item, &used);
            if (used != item.size() || !std::isfinite(d)) throw std::invalid_argument(item);
            v.push_back(d);
        } catch (const std::exception&) {
            throw UsageError(option + ": '" + item + "' is not a number (expected " + form + ")");
        }
    }
    for (const std::size_t c : counts)
        if (v.size() == c) return v;
    throw UsageError(option + ": expected " + form + ", got " + std::to_string(v.size()) + " values");
}

Camera parse_free_camera(const std::string& text, int width, int height, std::optional<double> fov_y_degrees,
                         std::optional<double> focal_px) {
    const auto c = parse_numbers(text, "--camera", {9}, "eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z");
    return free_camera({c[0], c[1], c[2]}, {c[3], c[4], c[5]}, {c[6], c[7], c[8]}, width, height, fov_y_degrees, focal_px);
}

PointLight parse_light(const std::string& text) {
    const auto l = parse_numbers(text, "--light", {4, 6}, "x,y,z,intensity or x,y,z,r,g,b");
    PointLight light;
    light.position = {l[0], l[1], l[2]};
    light.intensity = l.size() == 4 ? glm::dvec3(l[3]) : glm::dvec3(l[3], l[4], l[5]);
    return light;
}

Camera free_camera(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up, int width, int height,
                   std::optional<double> fov_y_degrees, std::optional<double> focal_px) {
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
        throw UsageError("--size: " + std::to_string(width) + "x" + std::to_string(height) + " is not a valid image size (1 to 16384)");
    if (fov_y_degrees.has_value() == focal_px.has_value())
        throw UsageError("--camera: give exactly one of --fov (degrees) and --fl (pixels)");
    if (!(glm::length(eye - target) > 0.0) || !std::isfinite(glm::length(eye - target)))
        throw UsageError("--camera: eye and target must be distinct finite points");
    if (!(glm::length(glm::cross(up, eye - target)) > 1e-12 * glm::length(up) * glm::length(eye - target)))
        throw UsageError("--camera: up must not be parallel to the viewing direction");
    double fl = 0.0;
    if (fov_y_degrees) {
        if (!(*fov_y_degrees > 0.0 && *fov_y_degrees < 180.0)) throw UsageError("--fov: must be in (0, 180) degrees");
        fl = 0.5 * height / std::tan(0.5 * glm::radians(*fov_y_degrees));
    } else {
        if (!(*focal_px > 0.0) || !std::isfinite(*focal_px)) throw UsageError("--fl: must be a positive focal length in pixels");
        fl = *focal_px;
    }
    const Intrinsics k{width, height, fl, fl, 0.5 * width, 0.5 * height};
    return Camera(k, look_at_camera_to_world(eye, target, up));
}

void write_rendered_image(const std::filesystem::path& path, const Image& image) {
    const std::string ext = lower(path.extension().string());
    if (ext == ".exr")
        write_image(path, image, ColorSpace::Linear);
    else if (ext == ".png")
        write_image(path, image, ColorSpace::Srgb, 8);
    else
        throw UsageError(path.string() + ": output must end in .exr (linear float) or .png (sRGB 8-bit)");
}

} // namespace specula::evaluate
