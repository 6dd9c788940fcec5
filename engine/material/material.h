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
///   - optionally, the Kautz-McCool factorization of that model's specular part
///     (FactorizedSpecular: K pairs of cube-maps looked up in one parametrization), which the
///     real-time renderer uses instead of evaluating the model.
/// The formulas themselves live once in shaders/shared/ (lafortune.h), shared with the shaders.
#include "material/factor_param.h"
#include "material/lafortune.h"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace specula {

/// The families of specular models, in the order of SpecularModel's alternatives. The numeric
/// values are the shaders' (shared/material.h) and the bundle's.
enum class MaterialFamily : std::uint32_t { Lafortune = 0 };
inline constexpr std::size_t kMaterialFamilyCount = 1;

/// The closed set of specular models.
using SpecularModel = std::variant<LafortuneRgb>;

[[nodiscard]] constexpr MaterialFamily family_of(const SpecularModel& m) noexcept {
    return static_cast<MaterialFamily>(m.index());
}
/// "lafortune": the spelling of the command line, report.json and the bundle.
[[nodiscard]] constexpr const char* to_string(MaterialFamily f) noexcept {
    switch (f) {
    case MaterialFamily::Lafortune: return "lafortune";
    }
    return "?";
}
/// The inverse of to_string; nullopt for anything else.
[[nodiscard]] std::optional<MaterialFamily> material_family_from_string(const std::string& s) noexcept;

/// True when the model adds no light (a Lambertian surface).
[[nodiscard]] bool is_zero(const SpecularModel& m) noexcept;

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
