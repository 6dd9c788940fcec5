#pragma once
/// \file
/// glTF's core material as Specula writes it for ordinary viewers (docs/SPECULA_lafortune.md,
/// "Viewer approximation"): metallic 0, a roughness, and KHR_materials_ior / KHR_materials_specular
/// for the Fresnel reflectance, evaluated as shaders/shared/gltf_core.h says viewers do. It is
/// fitted to the captured frames in image space (specular/core_fit.h); Specula's own renderer can
/// draw it too (render::Renderer::set_material), which is how report.json says what ordinary
/// viewers show.
///
///   CoreMaterial c{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8};
///   CoreGltfFields g = core_gltf_fields(c);   // roughnessFactor, ior, specular factors
///   base colour = albedo * c.base_color_scale()
#include "shared/material.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace specula {

struct CoreMaterial {
    double roughness = 1.0; ///< glTF's roughnessFactor (alpha = roughness^2), in [0, 1]
    double f0 = 0.0;        ///< Fresnel reflectance at normal incidence, in [0, f90]
    double f90 = 0.0;       ///< at grazing incidence: KHR_materials_specular's specularFactor, in [0, 1]
    double clearcoat = 0.0; ///< KHR_materials_clearcoat's clearcoatFactor, in [0, 1] (0: none)
    double clearcoat_roughness = 0.0; ///< its clearcoatRoughnessFactor, in [0, 1]
    /// The base colour is the albedo times this, 1 / ((1 - f0)(1 - 0.04 clearcoat)): glTF's diffuse
    /// term is weighted by 1 - F and the clearcoat's 1 - Fcc, so at normal incidence a viewer then
    /// shows the albedo's diffuse light.
    [[nodiscard]] double base_color_scale() const noexcept { return 1.0 / ((1.0 - f0) * (1.0 - 0.04 * clearcoat)); }
    [[nodiscard]] bool has_specular() const noexcept { return f90 > 0.0 || clearcoat > 0.0; }
};

/// The glTF fields that give a CoreMaterial in a viewer (KHR_materials_specular with
/// KHR_materials_ior: F0 = min(((ior - 1) / (ior + 1))^2 specularColorFactor, 1) specularFactor,
/// F90 = specularFactor). The IOR carries F0 / F90 up to 0.25 (IOR 3); above, the specular colour
/// (a grey) carries the rest. f90 = 0: specularFactor 0, IOR 1.5.
struct CoreGltfFields {
    double roughness_factor = 1.0;
    double ior = 1.5;
    double specular_factor = 0.0;
    double specular_color_factor = 1.0; ///< grey
    double clearcoat_factor = 0.0;      ///< KHR_materials_clearcoat (written when above 0)
    double clearcoat_roughness_factor = 0.0;
};
[[nodiscard]] CoreGltfFields core_gltf_fields(const CoreMaterial& c) noexcept;

/// The material from its glTF fields (specularColorFactor's mean stands for a grey); base colour
/// scale as above. Inverse of core_gltf_fields.
[[nodiscard]] CoreMaterial core_from_gltf_fields(const CoreGltfFields& g) noexcept;

/// Why the parameters are not a core material, naming the parameter ("f0: outside [0, f90] (and
/// below 1)"): 0 <= f0 <= f90 <= 1, f0 < 1, roughness, clearcoat and clearcoat_roughness in [0, 1];
/// nullopt when they are fine.
[[nodiscard]] std::optional<std::string> invalid_parameters(const CoreMaterial& c);

/// For the shaders (family kMaterialGltfCore).
[[nodiscard]] shared::MaterialGpu core_material_gpu(const CoreMaterial& c) noexcept;

/// {roughness, f0, f90, clearcoat, clearcoat_roughness, base_color_scale, gltf: {roughnessFactor, ior,
/// specularFactor, specularColorFactor, clearcoatFactor, clearcoatRoughnessFactor}}.
[[nodiscard]] nlohmann::json to_json(const CoreMaterial& c);

} // namespace specula
