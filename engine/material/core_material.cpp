#include "material/core_material.h"

#include <algorithm>
#include <cmath>

namespace specula {

namespace {
constexpr double kIorReflectanceLimit = 0.25; // ((3 - 1) / (3 + 1))^2: IOR 3
double reflectance_of_ior(double ior) noexcept { return std::pow((ior - 1.0) / (ior + 1.0), 2.0); }
} // namespace

CoreGltfFields core_gltf_fields(const CoreMaterial& c) noexcept {
    CoreGltfFields g;
    g.roughness_factor = std::clamp(c.roughness, 0.0, 1.0);
    g.specular_factor = std::clamp(c.f90, 0.0, 1.0);
    g.clearcoat_factor = std::clamp(c.clearcoat, 0.0, 1.0);
    g.clearcoat_roughness_factor = std::clamp(c.clearcoat_roughness, 0.0, 1.0);
    if (!(g.specular_factor > 0.0)) return g; // no specular: IOR 1.5, colour 1
    const double base = std::clamp(c.f0 / g.specular_factor, 0.0, 1.0);
    if (base <= kIorReflectanceLimit) {
        const double r = std::sqrt(base);
        g.ior = (1.0 + r) / (1.0 - r);
        g.specular_color_factor = 1.0;
    } else {
        g.ior = 3.0;
        g.specular_color_factor = base / kIorReflectanceLimit;
    }
    return g;
}

CoreMaterial core_from_gltf_fields(const CoreGltfFields& g) noexcept {
    CoreMaterial c;
    c.roughness = std::clamp(g.roughness_factor, 0.0, 1.0);
    c.f90 = std::clamp(g.specular_factor, 0.0, 1.0);
    c.f0 = std::min(reflectance_of_ior(g.ior) * g.specular_color_factor, 1.0) * c.f90;
    c.clearcoat = std::clamp(g.clearcoat_factor, 0.0, 1.0);
    c.clearcoat_roughness = std::clamp(g.clearcoat_roughness_factor, 0.0, 1.0);
    return c;
}

std::optional<std::string> invalid_parameters(const CoreMaterial& c) {
    for (const auto& [name, v] : {std::pair{"roughness", c.roughness}, std::pair{"clearcoat", c.clearcoat},
                                  std::pair{"clearcoat_roughness", c.clearcoat_roughness}, std::pair{"f90", c.f90}})
        if (!(v >= 0.0 && v <= 1.0)) return std::string(name) + ": outside [0, 1]";
    if (!(c.f0 >= 0.0 && c.f0 <= c.f90 && c.f0 < 1.0)) return std::string("f0: outside [0, f90] (and below 1)");
    return std::nullopt;
}

shared::MaterialGpu core_material_gpu(const CoreMaterial& c) noexcept {
    shared::MaterialGpu m{};
    m.family = glm::uvec4(shared::kMaterialGltfCore, 0u, 0u, 0u);
    m.a = glm::vec4(static_cast<float>(c.roughness), static_cast<float>(c.f0), static_cast<float>(c.f90),
                    static_cast<float>(c.base_color_scale()));
    m.b = glm::vec4(static_cast<float>(c.clearcoat), static_cast<float>(c.clearcoat_roughness), 0.0f, 0.0f);
    return m;
}

nlohmann::json to_json(const CoreMaterial& c) {
    const CoreGltfFields g = core_gltf_fields(c);
    return {{"roughness", c.roughness},
            {"f0", c.f0},
            {"f90", c.f90},
            {"clearcoat", c.clearcoat},
            {"clearcoat_roughness", c.clearcoat_roughness},
            {"base_color_scale", c.base_color_scale()},
            {"gltf",
             {{"roughnessFactor", g.roughness_factor},
              {"ior", g.ior},
              {"specularFactor", g.specular_factor},
              {"specularColorFactor", g.specular_color_factor},
              {"clearcoatFactor", g.clearcoat_factor},
              {"clearcoatRoughnessFactor", g.clearcoat_roughness_factor}}}};
}

} // namespace specula
