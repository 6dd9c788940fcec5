#pragma once
/// \file
/// What a material is: the appearance Specula reconstructs, renders, exports and evaluates
/// (docs/pipeline.md sections 5, 6, 7 and 10), as one type every stage shares.
///
/// A material is a diffuse albedo (a texture: per texel, linear RGB rho, held apart because
/// it is an image) plus
///   - a specular model from a closed set of families (SpecularModel, a std::variant: every
///     consumer handles every family, and the compiler says where one is missing):
///       LafortuneRgb  the thesis's model: Lambert + one isotropic Lafortune lobe per channel;
///       CoatedParams  a Lambertian base under a dielectric coating: the diffuse term weighted
///                     by the coating's Fresnel transmittance at the light and the viewer, plus
///                     a GGX microfacet reflection off the coating (shaders/shared/coated.h);
///   - optionally, the Kautz-McCool factorization of that model's specular part
///     (FactorizedSpecular: K pairs of cube-maps looked up in one parametrization), which the
///     real-time renderer uses instead of evaluating the model.
/// The formulas themselves live once in shaders/shared/ (lafortune.h, coated.h, and material.h,
/// which evaluates any family), shared with the shaders; material_gpu() packs a model for them.
#include "material/factor_param.h"
#include "material/lafortune.h"
#include "shared/material.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace specula {

/// The coated family's global parameters (shaders/shared/coated.h): the coating's refractive
/// index eta, the GGX roughness alpha, and the specular tint (1, 1, 1 for a clear dielectric).
/// The diffuse albedo rho is per texel, like every family's.
struct CoatedParams {
    float eta = 1.5f;
    float alpha = 0.1f;
    glm::vec3 tint{1.0f};
    /// A zero tint: no specular reflection (the diffuse term keeps its Fresnel weighting).
    [[nodiscard]] bool is_zero() const noexcept { return tint == glm::vec3(0.0f); }
};

/// The families of specular models, in the order of SpecularModel's alternatives. The numeric
/// values are the shaders' (shared/material.h kMaterial*) and the bundle's.
enum class MaterialFamily : std::uint32_t { Lafortune = 0, Coated = 1 };
inline constexpr std::size_t kMaterialFamilyCount = 2;

/// The closed set of specular models.
using SpecularModel = std::variant<LafortuneRgb, CoatedParams>;

[[nodiscard]] constexpr MaterialFamily family_of(const SpecularModel& m) noexcept {
    return static_cast<MaterialFamily>(m.index());
}
/// "lafortune": the spelling of the command line, report.json and the bundle.
[[nodiscard]] constexpr const char* to_string(MaterialFamily f) noexcept {
    switch (f) {
    case MaterialFamily::Lafortune: return "lafortune";
    case MaterialFamily::Coated: return "coated";
    }
    return "?";
}
/// The inverse of to_string; nullopt for anything else.
[[nodiscard]] std::optional<MaterialFamily> material_family_from_string(const std::string& s) noexcept;

/// True when the model adds no specular light.
[[nodiscard]] bool is_zero(const SpecularModel& m) noexcept;

/// Why the parameters are unusable (non-finite, or outside the bounds of shared/coated.h for
/// the coated family), naming the parameter; nullopt when they are fine.
[[nodiscard]] std::optional<std::string> invalid_parameters(const SpecularModel& m);

/// The model as the kernels and shaders read it (shared/material.h). Absent: the zero material
/// (no specular light, a Lambertian diffuse term).
[[nodiscard]] shared::MaterialGpu material_gpu(const std::optional<SpecularModel>& m) noexcept;

/// The directional albedo of the whole material, diffuse albedo rho included, for light leaving
/// at polar angle acos(cos_o) (the white-furnace integral: at most 1 for an energy-conserving
/// material), by a deterministic quadrature of `n` x 4n cells over the hemisphere (double).
[[nodiscard]] glm::dvec3 directional_albedo(const SpecularModel& m, const glm::dvec3& rho, double cos_o, int n = 128);

/// The coated family: the hemispherical average of the internal Fresnel reflectance
/// F_dr = 2 int_0^1 F(c, 1/eta) c dc (light inside the coating reaching it from below).
[[nodiscard]] double coated_internal_reflectance(double eta);
/// The largest diffuse albedo rho (normal-incidence, as shared/coated.h defines it) a coated
/// surface can have: that of a white base, eta^-2 T(1)^2 / (1 - F_dr) (Weidlich and Wilkie
/// 2007); with it the material's directional albedo is at most 1.
[[nodiscard]] double coated_max_albedo(double eta);

/// A float RGB cube-map: 6 faces of resolution x resolution texels, [face][row][col] in Vulkan's
/// face order (+X, -X, +Y, -Y, +Z, -Z) and orientation (shared/gshd.h part 3): the layout the
/// factorization writes, the renderer uploads and the bundle stores.
struct CubeMap {
    std::uint32_t resolution = 0;
    std::vector<glm::vec3> texels; ///< 6 * resolution^2
    [[nodiscard]] const glm::vec3& at(std::uint32_t face, std::uint32_t row, std::uint32_t col) const {
        return texels[(std::size_t{face} * resolution + row) * resolution + col];
    }
};

/// One separable term G_k(h) H_k(d).
struct FactorTerm {
    CubeMap g; ///< looked up by the half vector h
    CubeMap h; ///< looked up by the difference vector d
};

/// Most terms a factorization has: the renderer binds a fixed number of samplers (lavapipe has
/// no descriptor indexing), and the bundle has a field per term.
inline constexpr std::uint32_t kMaxFactorTerms = 4;

/// The specular part as K separable terms (Kautz and McCool 1999; thesis appendix A):
///     f ~ R(u) max(0, sum_k G_k(h) H_k(d))
/// with (h, d) in the parametrization `param` (shared/gshd.h parts 1, 4, 5) and R the lobe's
/// radial factor in the warped parametrization (1 otherwise). terms[0] is the thesis's term.
struct FactorizedSpecular {
    FactorParam param = FactorParam::Gshd;
    glm::vec4 warp{1.0f}; ///< (s, k_r, k_g, k_b) of FactorParam::Warped (warp_for_lobe)
    std::vector<FactorTerm> terms; ///< 1..kMaxFactorTerms
};

/// A material without its albedo texture.
struct Material {
    std::optional<SpecularModel> specular; ///< absent: no specular term (Lambertian, or left out)
    std::vector<std::string> status;       ///< per channel, as the fit reported it (may be empty)
    std::optional<FactorizedSpecular> factorized; ///< the specular's cube-maps, when computed
    /// True when a specular term is there to draw.
    [[nodiscard]] bool has_specular() const noexcept { return specular && !is_zero(*specular); }
};

} // namespace specula
