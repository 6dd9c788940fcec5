#pragma once
// Which parametrization of a pair of directions the Kautz-McCool factorization of a lobe
// uses (shaders/shared/gshd.h parts 1 and 4). The factorization chooses it per lobe, the
// bundle records it (docs/SPECULA_lafortune.md, "parametrization") and the renderer looks
// the cube-maps up with it; the numeric values are the shaders' kGshdPlain / kGshdMirrored /
// kGshdWarped.
//   Gshd:     (h, d) = GSHD of (u, v), the thesis's (eq. A.5)
//   Mirrored: (h, d) = GSHD of (r(u), v), r(u) = (-ux, -uy, uz) the mirror direction of u:
//             rank 1 for a Phong-like lobe (Cx = -Cz), where the plain GSHD is far from it
//   Warped:   (h, d) = GSHD of (w(u), v), w(u) = norm(s ux, s uy, k uz), F = the lobe over its
//             radial factor |C u|^N: rank 1 for every Lafortune lobe (gshd.h part 5); the warp
//             (s, k per channel) comes from the lobe (warp_for_lobe below)
#include "material/lafortune.h"

#include <glm/glm.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace specula {

inline constexpr std::size_t kFactorParamCount = 3;

enum class FactorParam : std::uint32_t { Gshd = 0, Mirrored = 1, Warped = 2 };

/// "gshd", "mirrored" or "warped": the spelling of the CLI (--factor-param), report.json and the bundle.
[[nodiscard]] constexpr const char* to_string(FactorParam p) noexcept {
    return p == FactorParam::Mirrored ? "mirrored" : p == FactorParam::Warped ? "warped" : "gshd";
}

/// The inverse of to_string; nullopt for anything else.
[[nodiscard]] constexpr std::optional<FactorParam> factor_param_from_string(std::string_view s) noexcept {
    if (s == "gshd") return FactorParam::Gshd;
    if (s == "mirrored") return FactorParam::Mirrored;
    if (s == "warped") return FactorParam::Warped;
    return std::nullopt;
}

/// Range of the warp's k that warp_for_lobe accepts: beyond it w(u) crowds every light
/// direction against the normal (k large) or the horizon (k small) and the grids resolve nothing.
inline constexpr double kWarpMinK = 1.0 / 64.0;
inline constexpr double kWarpMaxK = 64.0;

/// The warp of the warped parametrization for this lobe (shared/gshd.h part 5), as
/// (s, k_r, k_g, k_b): s = sign(Cx Cz), the same in every channel, and k_c = |Cz_c| / |Cx_c|.
/// nullopt (with the reason in *why) when a channel has Cx or Cz zero or not finite, the
/// channels' signs of Cx Cz differ, or a k is outside [kWarpMinK, kWarpMaxK].
inline std::optional<glm::vec4> warp_for_lobe(const LafortuneRgb& lobe, std::string* why = nullptr) {
    glm::vec4 w(0.0f);
    for (int c = 0; c < 3; ++c) {
        const double cx = lobe.cx[c], cz = lobe.cz[c];
        if (!std::isfinite(cx) || !std::isfinite(cz) || cx == 0.0 || cz == 0.0) {
            if (why) *why = "Cx or Cz is zero or not finite";
            return std::nullopt;
        }
        const float s = cx * cz > 0.0 ? 1.0f : -1.0f;
        if (c > 0 && s != w.x) {
            if (why) *why = "the channels' signs of Cx Cz differ";
            return std::nullopt;
        }
        w.x = s;
        const double k = std::abs(cz) / std::abs(cx);
        if (!(k >= kWarpMinK && k <= kWarpMaxK)) {
            if (why) *why = "|Cz| / |Cx| is outside [1/64, 64]";
            return std::nullopt;
        }
        w[c + 1] = static_cast<float>(k);
    }
    return w;
}

/// One warp for the three channels: (s, k, k, k) with k the geometric mean of the channels' k.
/// Each channel's F is then rank 1 only where its k is that one, but a pixel computes one pair of
/// coordinates and makes 2 K cube-map lookups instead of 6 K (render/terms.glsl), where lavapipe
/// spends most of the factorized shading pass (docs/pipeline.md 7.4).
inline glm::vec4 shared_warp_of(const glm::vec4& warp) {
    const float k = static_cast<float>(std::cbrt(static_cast<double>(warp.y) * warp.z * warp.w));
    return {warp.x, k, k, k};
}

/// True when the warp's three k are equal: one pair of coordinates serves every channel.
inline bool is_shared_warp(const glm::vec4& warp) { return warp.y == warp.z && warp.z == warp.w; }

/// Whether w is a warp warp_for_lobe could return: s = +-1, every k in [kWarpMinK, kWarpMaxK].
[[nodiscard]] inline bool valid_warp(const glm::vec4& w) noexcept {
    if (std::abs(w.x) != 1.0f) return false;
    for (int c = 1; c < 4; ++c)
        if (!(w[c] >= kWarpMinK && w[c] <= kWarpMaxK)) return false;
    return true;
}

/// Channel c's warp (s, k_c), the pair shared/gshd.h's functions take.
[[nodiscard]] inline glm::vec2 channel_warp(const glm::vec4& w, int c) noexcept { return {w.x, w[c + 1]}; }

} // namespace specula
