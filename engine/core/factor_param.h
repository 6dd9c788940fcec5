#pragma once
// Which parametrization of a pair of directions the Kautz-McCool factorization of a lobe
// uses (shaders/shared/gshd.h parts 1 and 4). The factorization chooses it per lobe, the
// bundle records it (docs/SPECULA_lafortune.md, "parametrization") and the renderer looks
// the cube-maps up with it; the numeric values are the shaders' kGshdPlain / kGshdMirrored.
//   Gshd:     (h, d) = GSHD of (u, v), the thesis's (eq. A.5)
//   Mirrored: (h, d) = GSHD of (r(u), v), r(u) = (-ux, -uy, uz) the mirror direction of u:
//             rank 1 for a Phong-like lobe (Cx = -Cz), where the plain GSHD is far from it
#include <cstdint>
#include <optional>
#include <string_view>

namespace specula {

enum class FactorParam : std::uint32_t { Gshd = 0, Mirrored = 1 };

/// "gshd" or "mirrored": the spelling of the CLI (--factor-param), report.json and the bundle.
[[nodiscard]] constexpr const char* to_string(FactorParam p) noexcept {
    return p == FactorParam::Mirrored ? "mirrored" : "gshd";
}

/// The inverse of to_string; nullopt for anything else.
[[nodiscard]] constexpr std::optional<FactorParam> factor_param_from_string(std::string_view s) noexcept {
    if (s == "gshd") return FactorParam::Gshd;
    if (s == "mirrored") return FactorParam::Mirrored;
    return std::nullopt;
}

} // namespace specula
