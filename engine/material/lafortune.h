#pragma once
// One isotropic Lafortune lobe per RGB channel, in the thesis's (Cx, Cz, N) form
// (thesis eq. 2.1 with rho_d = 0; Lafortune et al. 1997):
//     f_s(u, v) = max(0, Cx (ux vx + uy vy) + Cz uz vz) ^ N      (per channel)
// The one C++ type every stage uses for a lobe (synth's truth, the fit's result, the
// factorization's input, the renderer's lobe, the bundle). The formula itself lives in
// shaders/shared/lafortune.h, shared with the shaders.
#include <glm/glm.hpp>

namespace specula {

struct LafortuneRgb {
    glm::vec3 cx{0.0f};
    glm::vec3 cz{0.0f};
    glm::vec3 n{1.0f};
    /// Cx = Cz = 0: no specular term (a Lambertian surface).
    [[nodiscard]] bool is_zero() const noexcept { return cx == glm::vec3(0.0f) && cz == glm::vec3(0.0f); }
};

} // namespace specula
