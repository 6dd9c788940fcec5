#pragma once
// The input of the factorization: one fitted Lafortune lobe per colour channel
// (pipeline.md section 5; thesis eq. 2.1 with rho_d = 0), in the thesis's (Cx, Cz, N) form:
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N      (per channel)
#include "core/lafortune.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>

namespace specula::factorization {

using LafortuneRgb = specula::LafortuneRgb; // engine/core/lafortune.h (set cx, cz, n explicitly)

/// The same lobe in double (shared/lafortune.h lafortune_eval is float-only): the CPU
/// reference and the error measurements evaluate the formula above with this.
inline double lafortune_eval_f64(double cx, double cz, double n, const glm::dvec3& u, const glm::dvec3& v) {
    const double base = cx * (u.x * v.x + u.y * v.y) + cz * (u.z * v.z);
    return base > 0.0 ? std::pow(base, n) : 0.0;
}

/// |C u|^N, C = diag(Cx, Cx, Cz) (shared/lafortune.h lafortune_radial), in double, not clamped.
inline double lafortune_radial_f64(double cx, double cz, double n, const glm::dvec3& u) {
    const double s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    return s > 0.0 ? std::pow(s, 0.5 * n) : 0.0;
}

/// f / |C u|^N = max(0, (C u / |C u|).v)^N in [0, 1]: what F tabulates in the warped
/// parametrization (shared/gshd.h part 5). 0 where C u = 0.
inline double lafortune_normalized_f64(double cx, double cz, double n, const glm::dvec3& u, const glm::dvec3& v) {
    const double s = cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * (u.z * u.z);
    if (!(s > 0.0)) return 0.0;
    const double base = (cx * (u.x * v.x + u.y * v.y) + cz * (u.z * v.z)) / std::sqrt(s);
    return base > 0.0 ? std::pow(std::min(base, 1.0), n) : 0.0;
}

} // namespace specula::factorization
