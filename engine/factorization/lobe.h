#pragma once
// The input of the factorization: one fitted Lafortune lobe per colour channel
// (pipeline.md section 5; thesis eq. 2.1 with rho_d = 0), in the thesis's (Cx, Cz, N) form:
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N      (per channel)
#include "core/lafortune.h"

#include <glm/glm.hpp>

#include <cmath>

namespace specula::factorization {

using LafortuneRgb = specula::LafortuneRgb; // engine/core/lafortune.h (set cx, cz, n explicitly)

/// The same lobe in double (shared/lafortune.h lafortune_eval is float-only): the CPU
/// reference and the error measurements evaluate the formula above with this.
inline double lafortune_eval_f64(double cx, double cz, double n, const glm::dvec3& u, const glm::dvec3& v) {
    const double base = cx * (u.x * v.x + u.y * v.y) + cz * (u.z * v.z);
    return base > 0.0 ? std::pow(base, n) : 0.0;
}

} // namespace specula::factorization
